"""Silent wrong results and unclear errors (issue 12, items 4 and 5), each
case a regression test:

  * rbdkit.Handle refuses None for a required array, as rbdkit.RBD does
    (it used to compute with zeros), on every operation;
  * a joint that moves no mass (a massless link on a revolute joint under
    the fixed world) raises an error naming the joint from every operation
    that inverts the mass matrix, in float64 and float32, RBD and Handle
    (1/0 = inf used to pass the positive-definiteness test: NaN results);
  * boolean options must be booleans ("no", 1, arrays are refused);
  * finite but huge inputs (1e300) and model values are refused, naming
    them; dt has an upper bound; a model value of 1e308 or an axis of
    1e200 1e200 1e200 loads correctly or is refused;
  * integer options beyond int's range name the option (not bad_cast);
  * a model without joints (nq = 0) gives empty results of the right shapes;
  * invalid UTF-8 in a URDF name is a ValueError naming the element;
  * every keyword the README documents is a keyword of the method.
"""

import inspect
import os
import re
import warnings

import numpy as np
import pytest

import rbdkit
from rbdkit import _checks
from rbdkit._handle import OPERATIONS
from test_bad_input import METHOD_ARGS, METHODS, WITH_GRAVITY, call as rbd_call, valid_args
from test_handle import CALLS, values

README = os.path.join(os.path.dirname(__file__), "..", "..", "README.md")


def error_of(f):
    try:
        f()
    except Exception as e:  # noqa: BLE001 - the test compares exception types and messages
        return type(e), str(e)
    return None


@pytest.fixture(scope="module")
def hyq():
    return rbdkit.robots.load("hyq", floating_base=True)


# ------------------------------------------------------------ Handle: None for required arrays
NOT_ARRAYS = ("frame", "dt", "mu")
NONE_CASES = [(op, k) for op in OPERATIONS if op in CALLS for k, n in enumerate(CALLS[op][0]) if n not in NOT_ARRAYS]


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("op,k", NONE_CASES, ids=[f"{o}-{k}" for o, k in NONE_CASES])
def test_handle_treats_none_as_rbd_does(hyq, op, k, dtype):
    # None where RBD refuses it: the same error; where RBD takes it (an optional
    # qdd = zero acceleration): the same result
    h = rbdkit.Handle(hyq, dtype=dtype)
    names, kw = CALLS[op]
    vals = values(hyq, batch=2)
    args = [vals[n] for n in names]
    args[k] = None
    param = list(inspect.signature(getattr(rbdkit.RBD, op)).parameters.values())[k + 1]  # after self
    expected = error_of(lambda: getattr(h.rbd, op)(*args, **kw))
    if expected is None:
        assert param.name == "qdd", f"RBD.{op} takes None for {param.name}"
        r, ref = getattr(h, op)(*args, **kw), getattr(h.rbd, op)(*args, **kw)
        ref = ref[0] if op == "inverse_dynamics" else ref
        tol = dict(rtol=0, atol=1e-9) if dtype == "float64" else dict(rtol=1e-3, atol=1e-2)
        np.testing.assert_allclose(r, ref, **tol)
        return
    assert expected[0] is TypeError and expected[1].startswith(f"{param.name}: expected"), expected
    assert error_of(lambda: getattr(h, op)(*args, **kw)) == expected


def test_handle_none_examples_of_the_issue(hyq):
    h = rbdkit.Handle(hyq)
    q = hyq.neutral()
    with pytest.raises(TypeError, match="^q: expected a real numeric array, got NoneType"):
        h.crba(None)
    with pytest.raises(TypeError, match="^q: expected a real numeric array"):
        h.aba(None, None, None)
    with pytest.raises(TypeError, match="^qd: expected a real numeric array"):
        h.aba(q, None, np.zeros(hyq.nv))
    with pytest.raises(TypeError, match="^q: expected a real numeric array"):
        h.integrator(None, None, None, .01)
    # plant_step_gradient(None, ...) used to reach nanobind ("incompatible function arguments")
    with pytest.raises(TypeError, match="^x: expected a real numeric array"):
        h.plant_step_gradient(None, None, .01)
    # the optional qdd of inverse_dynamics stays optional: None is zero acceleration
    qd = np.linspace(-1, 1, hyq.nv)
    np.testing.assert_array_equal(h.inverse_dynamics(q, qd), h.nonlinear_effects(q, qd))


# ------------------------------------------------------------ a joint that moves no mass
ARM = """<?xml version="1.0"?><robot name="cam_arm"><link name="base"/>
  <link name="arm"><inertial><mass value="2"/><origin xyz="0.3 0 0"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="arm_joint" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <link name="arm2"><inertial><mass value="1"/><origin xyz="0.2 0 0"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="elbow" type="revolute"><parent link="arm"/><child link="arm2"/><origin xyz="0.6 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <link name="camera_link"/>
  <joint name="cam_joint" type="revolute"><parent link="base"/><child link="camera_link"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>"""

# operations that invert the mass matrix, and their arguments
SINGULAR_OPS = {
    "aba": ("q", "qd", "tau"), "forward_dynamics": ("q", "qd", "u"), "minv": ("q",),
    "forward_dynamics_gradient": ("q", "qd", "u"), "f_ext_gradient": ("q",), "minv_bpass": ("q",),
    "forward_dynamics_parameter_gradient": ("q", "qd", "u"), "fdsva_so": ("q", "qd", "u"),
    "osc_inertia": ("q",),
    "integrator": ("q", "qd", "u", 0.01, "rk4"), "integrator_gradient": ("q", "qd", "u", 0.01, "euler"),
    "plant_step": ("x", "u", 0.01, "midpoint"), "plant_step_gradient": ("x", "u", 0.01, "rk4"),
    "plant_step_hessian": ("x", "u", 0.01, "euler"),
}


def singular_args(model, op, batch):
    v = values(model, batch=batch or 1, seed=1)
    v = v if batch else {k: (x[0] if isinstance(x, np.ndarray) else x) for k, x in v.items()}
    return [v[a] if isinstance(a, str) and a in v else a for a in SINGULAR_OPS[op]]


def test_massless_joint_loads_and_its_mass_matrix_is_singular():
    m = rbdkit.Model.from_urdf_string(ARM)
    M = rbdkit.RBD(m).crba(m.neutral())
    k = m.joint("cam_joint")["v_index"]
    assert M[k, k] == 0 and not M[k].any()  # the closed form: a joint that moves no mass has a zero row


@pytest.mark.parametrize("dtype", [None, "float64", "float32"])
@pytest.mark.parametrize("op", list(SINGULAR_OPS))
def test_joint_that_moves_no_mass_is_named(op, dtype):
    m = rbdkit.Model.from_urdf_string(ARM)
    obj = rbdkit.RBD(m) if dtype is None else rbdkit.Handle(m, dtype=dtype, threads=2)
    for batch in (0, 3):
        # an error naming the joint, never a silent NaN
        with pytest.raises(RuntimeError, match=r"joint 'cam_joint' moves no mass.*: the mass matrix is singular"):
            getattr(obj, op)(*singular_args(m, op, batch))


def test_massless_joint_message_of_the_issue():
    m = rbdkit.Model.from_urdf_string(ARM)
    q = m.neutral()
    z = np.zeros(m.nv)
    with pytest.raises(RuntimeError, match=r"^aba: joint 'cam_joint' moves no mass: the mass matrix is singular"):
        rbdkit.RBD(m).aba(q, z, z)


def test_rounding_level_articulated_inertia_is_singular():
    # a thin rod along u = (1, 1, 0)/√2 turning about u: D = a(1 - |u|²) is zero
    # or rounding noise (1e-19), whose inverse the old D > 0 test let through
    xml = ARM.replace('<link name="camera_link"/>', '<link name="camera_link"><inertial><mass value="1"/>'
                      '<inertia ixx="0.0005" iyy="0.0005" izz="0.001" ixy="-0.0005" ixz="0" iyz="0"/>'
                      '</inertial></link>').replace('<axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1"',
                                                    '<axis xyz="1 1 0"/><limit lower="-3" upper="3" effort="1"')
    m = rbdkit.Model.from_urdf_string(xml)
    assert m.joint("cam_joint")["nv"] == 1
    q = m.neutral()
    z = np.zeros(m.nv)
    for f in (lambda: rbdkit.RBD(m).aba(q, z, z), lambda: rbdkit.RBD(m).minv(q),
              lambda: rbdkit.Handle(m, dtype="float32").aba(q, z, z)):
        with pytest.raises(RuntimeError, match="joint 'cam_joint' moves no mass"):
            f()


def test_light_but_massive_joints_still_work():
    # the relative test does not reject a light body: a 1 g, 1e-9 kg m² link
    light = ARM.replace('<link name="camera_link"/>', '<link name="camera_link"><inertial><mass value="0.001"/>'
                        '<inertia ixx="1e-9" iyy="1e-9" izz="1e-9" ixy="0" ixz="0" iyz="0"/></inertial></link>')
    m = rbdkit.Model.from_urdf_string(light)
    rbd = rbdkit.RBD(m)
    q = np.array([0.3, -0.2, 0.5])[:m.nq]
    qd, tau = np.array([0.1, 0.2, -0.3])[:m.nv], np.array([1.0, -0.5, 1e-9])[:m.nv]
    qdd = rbd.aba(q, qd, tau)
    np.testing.assert_allclose(rbd.inverse_dynamics(q, qd, qdd)[0], tau, rtol=1e-9, atol=1e-15)
    M = rbd.crba(q)
    np.testing.assert_allclose(rbd.minv(q) @ M, np.eye(m.nv), atol=1e-8)
    for dtype in ("float64", "float32"):
        np.testing.assert_allclose(rbdkit.Handle(m, dtype=dtype).aba(q, qd, tau), qdd, rtol=1e-3)


# ------------------------------------------------------------ booleans must be booleans
NOT_BOOLS = ["no", "False", 1, 0, None, np.array([1, 0]), 1.0]


@pytest.mark.parametrize("bad", NOT_BOOLS, ids=repr)
def test_boolean_options_must_be_booleans(hyq, bad):
    urdf = rbdkit.robots.path("iiwa")
    for f, name in [(lambda: rbdkit.Model.from_urdf(urdf, floating_base=bad), "floating_base"),
                    (lambda: rbdkit.Model.from_urdf(urdf, strict=bad), "strict"),
                    (lambda: rbdkit.Model.from_urdf(urdf, mimic=bad), "mimic"),
                    (lambda: rbdkit.robots.load("iiwa", floating_base=bad), "floating_base"),
                    (lambda: rbdkit.robots.handle("iiwa", floating_base=bad), "floating_base"),
                    (lambda: rbdkit.RBD(hyq).minv(hyq.neutral(), output_dense=bad), "output_dense"),
                    (lambda: rbdkit.Handle(hyq).minv(hyq.neutral(), output_dense=bad), "output_dense"),
                    (lambda: rbdkit.solve_trajectory(hyq, np.zeros(hyq.nq + hyq.nv), 2, 0.01, ddp=bad,
                                                     max_iterations=0), "ddp")]:
        with pytest.raises(TypeError, match=f"^{name}: expected"):
            f()
    from rbdkit import cli
    with pytest.raises(TypeError, match="^floating_base: expected True or False"):
        cli.report("iiwa", floating_base=bad)


def test_numpy_array_flag_is_a_type_error_not_numpys_truth_value_message():
    with pytest.raises(TypeError, match=r"^floating_base: expected True or False, got array\(\[1, 0\]\)"):
        rbdkit.Model.from_urdf(rbdkit.robots.path("iiwa"), floating_base=np.array([1, 0]))
    # numpy booleans are booleans
    assert rbdkit.Model.from_urdf(rbdkit.robots.path("iiwa"), floating_base=np.True_).floating_base


# ------------------------------------------------------------ huge values
@pytest.mark.parametrize("method,arg", METHOD_ARGS, ids=[f"{m}-{a}" for m, a in METHOD_ARGS])
def test_huge_values_are_refused_naming_the_argument(hyq, method, arg):
    rbd = rbdkit.RBD(hyq)
    for bad in (1e300, -1e101):
        args = valid_args(hyq, method)
        x = np.array(args[arg])
        x.reshape(-1)[0] = bad
        args[arg] = x
        with pytest.raises(ValueError, match=rf"^{arg}(\[\d+\])?: expected values of magnitude at most 1e\+100"):
            rbd_call(rbd, method, args)
    # 1e100 itself is within the bound on the way in (its results may still overflow: then an error, never NaN)
    args = valid_args(hyq, method)
    x = np.array(args[arg])
    x.reshape(-1)[0] = 1e50 if method != "time_per_call" else 1.0
    args[arg] = x
    e = error_of(lambda: rbd_call(rbd, method, args))
    assert e is None or "expected values of magnitude" not in e[1], e


@pytest.mark.parametrize("method", WITH_GRAVITY)
def test_huge_gravity_is_refused(hyq, method):
    with pytest.raises(ValueError, match="^gravity: expected (a magnitude of|values of magnitude) at most 1e\\+100"):
        rbd_call(rbdkit.RBD(hyq), method, {**valid_args(hyq, method), "gravity": 1e200})


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_huge_values_on_the_handle_fast_path(hyq, dtype):
    h = rbdkit.Handle(hyq, dtype=dtype)
    bound = "1e\\+100" if dtype == "float64" else "1e\\+15"
    q, z = hyq.neutral(), np.zeros(hyq.nv)
    big = np.array(z)
    big[4] = 1e300
    for f, name in [(lambda: h.aba(q, big, z), "qd"), (lambda: h.aba(q, z, big), "tau"),
                    (lambda: h.integrator(q, z, big, 0.01), "u"), (lambda: h.crba(np.r_[1e300, q[1:]]), "q"),
                    (lambda: h.aba(q, z, z, gravity=-1e300), "gravity")]:
        with pytest.raises(ValueError, match=f"^{name}: expected (a magnitude of|values of magnitude) at most {bound}"):
            f()
    # a revolute angle beyond the precision bound is named with its joint
    qa = np.array(q)
    qa[7] = 1e13
    with pytest.raises(ValueError, match=r"^q: the angle of joint '\w+' \(q\[7\]\) must have magnitude at most"):
        h.crba(qa)
    with pytest.raises(ValueError, match=r"^q: the angle of joint '\w+' \(q\[7\]\) must have magnitude at most"):
        h.rbd.crba(qa)


@pytest.mark.parametrize("dt", [1e300, 1e7, 0.0, -0.01])
def test_dt_is_bounded_and_named(hyq, dt):
    rbd = rbdkit.RBD(hyq)
    q, z = hyq.neutral(), np.zeros(hyq.nv)
    x = np.r_[q, z]
    for f in (lambda: rbd.integrator(q, z, z, dt), lambda: rbd.integrator_gradient(q, z, z, dt),
              lambda: rbd.plant_step(x, z, dt), lambda: rbd.plant_step_hessian(x, z, dt),
              lambda: rbdkit.Handle(hyq).integrator(q, z, z, dt),
              lambda: rbdkit.Handle(hyq, dtype="float32").plant_step_gradient(x, z, dt),
              lambda: rbdkit.solve_trajectory(hyq, x, 2, dt, max_iterations=0)):
        with pytest.raises(ValueError, match=r"^dt: expected a positive time step of at most 1e\+06 s"):
            f()


def test_overflowing_results_raise_instead_of_nan(hyq):
    # inputs within the bounds whose step overflows: an error naming the operation, never NaN
    rbd = rbdkit.RBD(hyq)
    q, z = hyq.neutral(), np.zeros(hyq.nv)
    qd = np.full(hyq.nv, 1e100)
    for f, what in [(lambda: rbd.integrator(q, qd, z, 1e6, "rk4"), "integrator"),
                    (lambda: rbd.integrator_gradient(q, qd, z, 1e6, "midpoint"), "integrator_gradient"),
                    (lambda: rbdkit.Handle(hyq).integrator(q, qd, z, 1e6, "rk4"), "integrator"),
                    (lambda: rbdkit.Handle(hyq, dtype="float32").integrator(q, qd / 1e85, z, 1e6, "rk4"),
                     "integrator")]:
        e = error_of(f)
        assert e is not None and e[0] is RuntimeError and e[1].startswith(f"{what}:"), e
        assert "overflow" in e[1], e
    # at the bound itself the single-pass algorithms stay finite (qd² · inertia ≪ 1e308)
    for r in (rbd.aba(q, qd, z), rbd.inverse_dynamics(q, qd, qd)[0], rbd.forward_dynamics(q, qd, qd)):
        assert np.all(np.isfinite(r))


# ------------------------------------------------------------ huge model values (src/parsers/builder.cpp)
def one_link(inertial, axis="0 0 1"):
    return (f'<?xml version="1.0"?><robot name="t"><link name="a"/><link name="b">{inertial}</link>'
            f'<joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="{axis}"/>'
            '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')


INERTIA = '<inertial><mass value="{m}"/><inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/></inertial>'


def test_huge_mass_is_refused_naming_the_link():
    with pytest.raises(ValueError, match=r"body 'b': the inertia has 1e\+308, expected finite values of magnitude"):
        rbdkit.Model.from_urdf_string(one_link(INERTIA.format(m="1e308", i="0.1")))
    with pytest.raises(ValueError, match=r"body 'b': the inertia has 1e\+300"):
        rbdkit.Model.from_urdf_string(one_link(INERTIA.format(m="1", i="1e300")))


def test_huge_axis_normalises_to_a_unit_axis():
    # 1e200² overflows: the scaled normalisation gives (1, 1, 1)/√3, not 0 (or NaN)
    m = rbdkit.Model.from_urdf_string(one_link(INERTIA.format(m="1", i="0.1"), axis="1e200 1e200 1e200"))
    ref = rbdkit.Model.from_urdf_string(one_link(INERTIA.format(m="1", i="0.1"), axis="1 1 1"))
    q, qd, tau = np.array([0.4]), np.array([0.3]), np.array([0.2])
    r, r0 = rbdkit.RBD(m), rbdkit.RBD(ref)
    np.testing.assert_allclose(r.crba(q), r0.crba(q), rtol=1e-14)
    np.testing.assert_allclose(r.aba(q, qd, tau), r0.aba(q, qd, tau), rtol=1e-14)
    # the closed form for a revolute joint through the centre of mass: M = u·I·u = 0.1
    np.testing.assert_allclose(r.crba(q), [[0.1]], rtol=1e-14)


# ------------------------------------------------------------ triangle inequality (src/parsers/urdf.cpp)
def test_triangle_inequality_warns_and_strict_refuses():
    # principal moments 0.1, 0.1, 0.5: PSD, but 0.1 + 0.1 < 0.5, which no mass distribution gives
    xml = one_link('<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.5" ixy="0" ixz="0" iyz="0"/>'
                   '</inertial>')
    with pytest.warns(UserWarning, match=r"link 'b'.*triangle inequality"):
        m = rbdkit.Model.from_urdf_string(xml)
    assert m.nv == 1
    with pytest.raises(ValueError, match=r"link 'b'.*triangle inequality"):
        rbdkit.Model.from_urdf_string(xml, strict=True)


# ------------------------------------------------------------ integer options beyond int
@pytest.mark.parametrize("name", ["horizon", "max_iterations", "line_search_steps"])
def test_solver_integers_beyond_int_are_named(hyq, name):
    x0 = np.r_[hyq.neutral(), np.zeros(hyq.nv)]
    kw = {"horizon": 2, "max_iterations": 0}
    for bad in (2**31, 2**63, np.int64(2**40)):
        kw2 = {**kw, name: bad}
        with pytest.raises(ValueError, match=f"^{name}: expected an integer of at most 2147483647 .*, got {bad}"):
            rbdkit.solve_trajectory(hyq, x0, kw2.pop("horizon"), 0.01, **kw2)


def test_solver_binding_names_an_option_it_cannot_convert(hyq):
    # below the Python checks: the binding's conversion names the key, not std::bad_cast
    from rbdkit import _core
    x0 = np.r_[hyq.neutral(), np.zeros(hyq.nv)]
    problem = {"horizon": 2**31, "dt": 0.01, "integrator": "euler", "gravity": -9.81, "x0": x0}
    with pytest.raises(ValueError, match="^horizon: expected"):
        _core.solve_trajectory(hyq._core, problem, {"max_iterations": 0}, None, None, None, None, None, None)


# ------------------------------------------------------------ a model without joints
NO_JOINTS = {
    "one-link": '<?xml version="1.0"?><robot name="t"><link name="a"><inertial><mass value="1"/>'
                '<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link></robot>',
    "fixed-joints": '<?xml version="1.0"?><robot name="t"><link name="a"/><link name="b"/>'
                    '<joint name="f" type="fixed"><parent link="a"/><child link="b"/></joint></robot>',
}


# ------------------------------------------------------------ names that are not UTF-8 (src/parsers/urdf.cpp)
@pytest.mark.parametrize("element", ["link", "joint"])
def test_invalid_utf8_name_is_a_value_error(tmp_path, element):
    # a str cannot carry invalid UTF-8 into from_urdf_string: the bytes go through a file
    link_b = b"b\xffx" if element == "link" else b"b"
    joint_j = b"j\xffx" if element == "joint" else b"j"
    xml = (b'<?xml version="1.0"?><robot name="t"><link name="a"/><link name="' + link_b + b'"><inertial>'
           b'<mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
           b'<joint name="' + joint_j + b'" type="revolute"><parent link="a"/><child link="' + link_b + b'"/>'
           b'<axis xyz="0 0 1"/></joint></robot>')
    p = tmp_path / "bad_name.urdf"
    p.write_bytes(xml)
    with pytest.raises(ValueError, match=rf"a {element} name is not valid UTF-8 \(at byte 1\)") as e:
        rbdkit.Model.from_urdf(p)
    assert not isinstance(e.value, UnicodeDecodeError)


def test_invalid_utf8_in_quoted_text_reads_back_as_str(tmp_path):
    # a mimic target or a number that is not UTF-8 is quoted with '?' in the
    # warning or the error, which Python reads as str
    base = (b'<?xml version="1.0"?><robot name="t"><link name="a"/><link name="b"><inertial><mass value="1"/>'
            b'<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
            b'<joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>%s</joint></robot>')
    p = tmp_path / "mimic.urdf"
    p.write_bytes(base % b'<mimic joint="n\xffo"/>')
    with pytest.warns(UserWarning, match=r"joint 'j' mimics joint 'n\?o', which is not defined"):
        m = rbdkit.Model.from_urdf(p)
    assert m.nv == 1
    p.write_bytes(base % b'<origin xyz="0 1\xff 0"/>')
    with pytest.raises(ValueError, match=r"origin xyz has '1\?', expected a finite number"):
        rbdkit.Model.from_urdf(p)


# ------------------------------------------------------------ the README's keywords
def documented_calls():
    """(method, [keyword, ...]) of every `name(args)` in the README's method tables"""
    out = []
    with open(README, encoding="utf-8") as f:
        for line in f:
            if not line.startswith("| `"):
                continue
            cell = line.split(" | ")[0]
            for name, args in re.findall(r"`(\w+)\(([^`]*)\)`", cell):
                out.append((name, re.findall(r"(\w+)=", args)))
    return out


def test_readme_documents_real_keywords():
    calls = [(n, kws) for n, kws in documented_calls() if hasattr(rbdkit.RBD, n)]
    assert len(calls) > 40 and any(n == "frame_jacobian" for n, _ in calls)
    for name, kws in calls:
        params = inspect.signature(getattr(rbdkit.RBD, name)).parameters
        for kw in kws:
            assert kw in params, f"README: {name}(..., {kw}=...) but the keyword is not a parameter"


def test_frame_jacobian_documented_keyword_works(hyq):
    rbd = rbdkit.RBD(hyq)
    q, qd = hyq.neutral(), np.linspace(-1, 1, hyq.nv)
    frame = hyq.frame_names[-1]
    for rf in ("LOCAL", "WORLD", "LOCAL_WORLD_ALIGNED"):
        J = rbd.frame_jacobian(q, frame, reference_frame=rf)
        np.testing.assert_array_equal(J, rbd.frame_jacobian(q, frame, rf))
        np.testing.assert_array_equal(rbd.frame_jacobian_dot(q, qd, frame, reference_frame=rf),
                                      rbd.frame_jacobian_dot(q, qd, frame, rf))


# operations whose result is undefined without joints: (exception, message)
NEEDS_MASS = ("com", "jacobian_com", "ccrba", "centroidal_momentum", "dccrba", "cmm_time_variation",
              "centroidal_momentum_time_variation", "centroidal_dynamics_derivatives", "com_cost", "momentum_cost")
NEEDS_END_EFFECTOR = ("end_effector_pose", "end_effector_pose_gradient", "end_effector_pose_hessian",
                      "end_effector_pose_hessian_analytic", "osc_inertia", "ee_pos_cost")


@pytest.mark.parametrize("case", list(NO_JOINTS))
def test_model_without_joints(case):
    # empty results of the right shapes where they are meaningful (RBD and Handle,
    # float64 and float32 alike); a clear error where they are not
    m = rbdkit.Model.from_urdf_string(NO_JOINTS[case])
    assert (m.nq, m.nv, m.nb) == (0, 0, 0)
    rbd = rbdkit.RBD(m)
    handles = [rbdkit.Handle(m), rbdkit.Handle(m, dtype="float32")]
    q = np.zeros(0)
    assert rbd.crba(q).shape == (0, 0) and rbd.minv(q).shape == (0, 0)
    assert rbd.inverse_dynamics(q, q)[0].shape == (0,) and rbd.aba(q, q, q).shape == (0,)
    assert rbd.integrator(q, q, q, 0.01).shape == (0,) and rbd.plant_step_gradient(q, q, 0.01).shape == (0, 0)
    assert rbd.kinetic_energy(q, q) == 0 and rbd.potential_energy(q) == 0
    for op in OPERATIONS:
        if op not in CALLS:
            continue
        for batch in (0, 2):
            v = values(m, batch=batch or 1)
            v = v if batch else {k: (x[0] if isinstance(x, np.ndarray) else x) for k, x in v.items()}
            names, kw = CALLS[op]
            args = [v[n] for n in names]
            if op in NEEDS_MASS:
                with pytest.raises(RuntimeError, match="the robot has no mass"):
                    getattr(rbd, op)(*args, **kw)
            elif op in NEEDS_END_EFFECTOR:
                with pytest.raises(ValueError, match=r"the model has no joints \(nq = 0\), so it has no end effector"):
                    getattr(rbd, op)(*args, **kw)
            ref = error_of(lambda: getattr(rbd, op)(*args, **kw))
            if ref is not None:
                for h in handles:
                    assert error_of(lambda: getattr(h, op)(*args, **kw)) == ref, op
                continue
            r = getattr(rbd, op)(*args, **kw)
            r = r[0] if op == "inverse_dynamics" else r
            for h in handles:
                rh = getattr(h, op)(*args, **kw)
                for a, b in zip(rh if isinstance(rh, tuple) else (rh,), r if isinstance(r, tuple) else (r,)):
                    assert np.shape(a) == np.shape(b), op
                    np.testing.assert_allclose(a, b, atol=1e-6)
                    assert (np.shape(a)[0] == batch) if batch else True, op
    with pytest.raises(ValueError, match=r"^ee_frame: the model has no joints"):
        rbdkit.solve_trajectory(m, np.zeros(0), 2, 0.01, ee_target=np.zeros(3), max_iterations=0)
