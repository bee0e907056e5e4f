"""rbdkit.Handle: every operation equals the rbdkit.RBD method of the same
name; algorithm subsets and dependency resolution (the C++ table, read
through the binding); available_operations / has; bad input; float32; the
output-convention pass-through; and the routing of the fast operations to the
batch engine, exercised with a fake engine object that records its calls."""

import inspect
import re

import numpy as np
import pytest

import rbdkit
from rbdkit import _core, _handle
from rbdkit._handle import ALGORITHMS, OPERATIONS, OPERATION_ALGORITHM

# the operations of the C++ registry (include/rbdkit/ops/registry.hpp)
REGISTERED = [op[0] for op in _core.registered_operations()]
from rbdkit._integrators import INTEGRATORS
from test_bad_input import METHODS as BAD_INPUT_METHODS, bad_shapes, valid_args

B = 3
# operations of this table not (yet) in rbdkit.RBD in this build: calling them says so
PENDING = set()

# ---- one valid call of every operation: (positional argument names, extra keywords)
CALLS = {
    "integrate": (("q", "v"), {}), "difference": (("q0", "q1"), {}), "dIntegrate": (("q", "v"), {}),
    "dDifference": (("q0", "q1"), {}), "d2Integrate": (("q", "v"), {}),
    "inverse_dynamics": (("q", "qd", "qdd"), {}), "generalized_gravity": (("q",), {}),
    "nonlinear_effects": (("q", "qd"), {}), "apply_external_forces": (("f_in", "f_ext"), {}),
    "inverse_dynamics_fpass": (("q", "qd", "qdd"), {}), "inverse_dynamics_bpass": (("q", "f"), {}),
    "crba": (("q",), {}), "minv": (("q",), {}), "minv_bpass": (("q",), {}), "minv_fpass": (("q", "minv_b"), {}),
    "aba": (("q", "qd", "tau"), {}), "forward_dynamics": (("q", "qd", "u"), {}),
    "inverse_dynamics_gradient": (("q", "qd", "qdd"), {}),
    "inverse_dynamics_gradient_fpass_dq": (("q", "qd", "qdd"), {}),
    "inverse_dynamics_gradient_fpass_dqd": (("q", "qd", "qdd"), {}),
    "inverse_dynamics_gradient_bpass_dq": (("q", "qd", "qdd", "cols", "cols2"), {}),
    "inverse_dynamics_gradient_bpass_dqd": (("q", "qd", "qdd", "cols", "cols2"), {}),
    "forward_dynamics_gradient": (("q", "qd", "u"), {}),
    "forward_kinematics": (("q",), {}), "frame_placement": (("q", "frame"), {}),
    "frame_jacobian": (("q", "frame"), {"reference_frame": "WORLD"}),
    "frame_jacobian_dot": (("q", "qd", "frame"), {"reference_frame": "LOCAL_WORLD_ALIGNED"}),
    "end_effector_pose": (("q",), {}), "end_effector_pose_gradient": (("q",), {}),
    "end_effector_pose_hessian": (("q",), {}), "end_effector_pose_hessian_analytic": (("q",), {}),
    "osc_inertia": (("q",), {}), "f_ext_gradient": (("q",), {}),
    "kinetic_energy": (("q", "qd"), {}), "potential_energy": (("q",), {}), "mechanical_energy": (("q", "qd"), {}),
    "coriolis_matrix": (("q", "qd"), {}), "com": (("q",), {}), "jacobian_com": (("q",), {}),
    "ccrba": (("q", "qd"), {}), "centroidal_momentum": (("q", "qd"), {}), "dccrba": (("q",), {}),
    "dccrba_fd": (("q",), {}), "cmm_time_variation": (("q", "qd"), {}), "cmm_time_variation_fd": (("q", "qd"), {}),
    "centroidal_momentum_time_variation": (("q", "qd", "qdd"), {}),
    "centroidal_dynamics_derivatives": (("q", "qd", "qdd"), {}),
    "inverse_dynamics_regressor": (("q", "qd", "qdd"), {}), "kinetic_energy_regressor": (("q", "qd"), {}),
    "potential_energy_regressor": (("q",), {}), "inverse_dynamics_regressor_gradient": (("q", "qd", "qdd"), {}),
    "forward_dynamics_parameter_gradient": (("q", "qd", "u"), {}),
    "idsva_so": (("q", "qd", "qdd"), {}), "idsva_so_body_frame": (("q", "qd", "qdd"), {}),
    "idsva_so_world_frame": (("q", "qd", "qdd"), {}), "fdsva_so": (("q", "qd", "u"), {}),
    "integrator": (("q", "qd", "u", "dt"), {"integrator_type": "rk4"}),
    "plant_step": (("x", "u", "dt"), {"integrator_type": "midpoint"}),
    "integrator_gradient": (("q", "qd", "u", "dt"), {"integrator_type": "rk4"}),
    "integrator_f_ext_gradient": (("q", "qd", "u", "dt"), {"integrator_type": "trapezoidal"}),
    "plant_step_gradient": (("x", "u", "dt"), {"integrator_type": "semi_implicit_euler"}),
    "plant_step_hessian": (("x", "u", "dt"), {"integrator_type": "euler"}),
    "quadratic_state_cost": (("x", "x_des", "Q"), {}), "quadratic_state_cost_tangent": (("x", "x_des", "Q2"), {}),
    "quadratic_input_cost": (("u", "qd", "R"), {}),
    "ee_pos_cost": (("q", "p3", "w3"), {}), "com_cost": (("q", "p3", "w3"), {}),
    "momentum_cost": (("q", "qd", "h6", "w6"), {}),
    "joint_position_barrier": (("q", "q_lo", "q_hi", "mu"), {}),
    "joint_velocity_barrier": (("qd", "v_lo", "v_hi", "mu"), {}),
    "joint_torque_barrier": (("u", "v_lo", "v_hi", "mu"), {}),
    "state_to_mujoco": (("x",), {}), "state_from_mujoco": (("x_mj",), {}),
    "force_to_mujoco": (("qpos", "u"), {}), "force_from_mujoco": (("qpos", "u"), {}),
    "mujoco_integrate": (("qpos", "v"), {}), "mujoco_difference": (("qpos", "qpos1"), {}),
}


def values(model, batch=B, seed=0):
    """named valid arguments, batched on axis 0"""
    rng = np.random.default_rng(seed)
    nq, nv, nb = model.nq, model.nv, model.nb
    tan = lambda: rng.uniform(-1, 1, (batch, nv))
    q = np.stack([model.random_configuration(rng) for _ in range(batch)])
    q1 = np.stack([model.random_configuration(rng) for _ in range(batch)])
    qd = tan()
    x = np.concatenate([q, qd], axis=1)
    x_des = np.concatenate([q1, tan()], axis=1)
    x_mj, x_des_mj = rbdkit.RBD(model).state_to_mujoco(x), rbdkit.RBD(model).state_to_mujoco(x_des)
    return {
        "q": q, "q0": q, "q1": q1, "v": tan(), "qd": qd, "qdd": tan(), "tau": tan(), "u": tan(),
        "f_in": rng.uniform(-1, 1, (batch, nb, 6)), "f_ext": rng.uniform(-1, 1, (batch, nb, 6)),
        "f": rng.uniform(-1, 1, (batch, nb, 6)), "minv_b": rng.uniform(-1, 1, (batch, nv, nv)),
        "cols": rng.uniform(-1, 1, (batch, nb, 6, 6)), "cols2": rng.uniform(-1, 1, (batch, nb, 6, 6)),
        "frame": model.frame_names[-1], "dt": 0.01, "x": x, "x_des": x_des,
        "x_mj": x_mj, "qpos": x_mj[:, :nq], "qpos1": x_des_mj[:, :nq],
        "Q": rng.uniform(0.5, 2, (batch, nq + nv)), "Q2": rng.uniform(0.5, 2, (batch, 2 * nv)),
        "R": rng.uniform(0.5, 2, (batch, nv)),
        "p3": rng.uniform(-1, 1, (batch, 3)), "w3": rng.uniform(0.5, 2, (batch, 3)),
        "h6": rng.uniform(-1, 1, (batch, 6)), "w6": rng.uniform(0.5, 2, (batch, 6)),
        "q_lo": q - 1, "q_hi": q + 1, "v_lo": np.full((batch, nv), -2.0), "v_hi": np.full((batch, nv), 2.0),
        "mu": 0.1,
    }


def one_sample(vals):
    """the first sample of values(), without the batch axis"""
    return {k: (x[0] if isinstance(x, np.ndarray) else x) for k, x in vals.items()}


def call(obj, op, vals):
    names, kw = CALLS[op]
    return getattr(obj, op)(*[vals[n] for n in names], **kw)


def assert_same(a, b, rtol=0.0):
    """equal results (tuples elementwise); rtol relative to max(1, max |b|)"""
    if isinstance(b, tuple):
        assert isinstance(a, tuple) and len(a) == len(b)
        for x, y in zip(a, b):
            assert_same(x, y, rtol)
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    if rtol == 0:
        np.testing.assert_array_equal(a, b)
    else:
        scale = max(1.0, float(np.max(np.abs(b)))) if b.size else 1.0
        np.testing.assert_allclose(a, b, rtol=0, atol=rtol * scale)


def handle_result(op, r):
    """what the handle returns for the RBD method's result r"""
    return r[0] if op == "inverse_dynamics" else r


@pytest.fixture(scope="module")
def iiwa():
    return rbdkit.robots.load("iiwa")


@pytest.fixture(scope="module")
def hyq():
    return rbdkit.robots.load("hyq", floating_base=True)


# ------------------------------------------------------------ the table


def test_table_covers_every_rbd_operation():
    public = {n for n, _ in inspect.getmembers(rbdkit.RBD, inspect.isfunction) if not n.startswith("_")}
    assert public - set(OPERATIONS) == {"time_per_call"}  # a timing helper, not an operation
    assert {op for op in OPERATIONS if not hasattr(rbdkit.RBD, op)} <= PENDING
    assert set(CALLS) == set(OPERATIONS)


def test_table_is_closed_and_ordered():
    seen = set()
    for name, (ops, deps) in ALGORITHMS.items():
        assert set(deps) <= seen, name  # dependencies come first
        seen.add(name)
    assert len(OPERATION_ALGORITHM) == sum(len(ops) for ops, _ in ALGORITHMS.values())  # each op once
    assert rbdkit.Handle.algorithm_table() == ALGORITHMS


# what selecting an algorithm must bring (the spec's dependencies)
DEPENDENCIES = {
    "plant_step_hessian": {"fdsva_so", "integrator_gradient", "integrator", "forward_dynamics_gradient"},
    "com_cost": {"com", "ccrba"},
    "momentum_cost": {"dccrba", "ccrba", "com"},
    "integrator_gradient": {"integrator", "forward_dynamics_gradient", "forward_dynamics", "configuration"},
    "integrator": {"forward_dynamics", "configuration"},
    "fdsva_so": {"idsva_so", "forward_dynamics_gradient"},
    "forward_dynamics_gradient": {"inverse_dynamics_gradient", "forward_dynamics"},
    "ee_pos_cost": {"kinematics"},
    "state_costs": {"configuration"},
}


@pytest.mark.parametrize("algorithm", list(DEPENDENCIES))
def test_dependencies_resolved(iiwa, algorithm):
    h = rbdkit.Handle(iiwa, algorithms=[algorithm])
    assert DEPENDENCIES[algorithm] | {algorithm} <= set(h.algorithms)
    # exactly the transitive closure, in table order
    closure, pending = set(), [algorithm]
    while pending:
        a = pending.pop()
        if a not in closure:
            closure.add(a)
            pending += ALGORITHMS[a][1]
    assert h.algorithms == tuple(a for a in ALGORITHMS if a in closure)


def test_subset_has_only_its_operations(iiwa):
    h = rbdkit.Handle(iiwa, algorithms=["com_cost", "crba"])
    expected = ["crba", "com", "jacobian_com", "ccrba", "centroidal_momentum", "com_cost"]
    assert h.available_operations() == expected
    for op in OPERATIONS:
        assert h.has(op) == (op in expected)
    v = values(iiwa)
    for op in OPERATIONS:
        if op in expected:
            call(h, op, v)
            continue
        alg = OPERATION_ALGORITHM[op]
        with pytest.raises(ValueError, match=rf"^{op}: this handle was not built with it; add '{alg}' to algorithms"):
            call(h, op, v)


def test_full_handle_has_everything_in_this_build(hyq):
    h = rbdkit.Handle(hyq)
    assert h.algorithms == tuple(ALGORITHMS)
    assert h.available_operations() == [op for op in OPERATIONS if hasattr(rbdkit.RBD, op)]
    assert not h.has("nope") and not h.has("time_per_call")
    with pytest.raises(TypeError, match="^name: expected an operation name"):
        h.has(3)


def test_robots_handle_and_urdf_path():
    h = rbdkit.robots.handle("hyq", floating_base=True, algorithms=["crba"], dtype="float32", threads=1)
    assert (h.nq, h.nv, h.dtype, h.threads) == (19, 18, np.float32, 1)
    h2 = rbdkit.Handle(rbdkit.robots.path("iiwa"), algorithms=["aba"])
    assert h2.nv == 7 and h2.available_operations() == ["aba"]
    assert "dtype=float32" in repr(h)


# ------------------------------------------------------------ results equal RBD's


def _full_handle_cases():
    return [(m, op) for m in ("iiwa", "hyq") for op in OPERATIONS]


@pytest.mark.parametrize("robot,op", _full_handle_cases(), ids=[f"{m}-{o}" for m, o in _full_handle_cases()])
def test_operation_equals_rbd(request, robot, op):
    model = request.getfixturevalue(robot)
    h, rbd = rbdkit.Handle(model), rbdkit.RBD(model)
    assert hasattr(rbdkit.RBD, op)  # every table operation is an RBD method
    fast = op in h.fast_operations()  # the engine: same maths, other summation order
    for batch in (B, None):
        v = values(model) if batch else one_sample(values(model))
        assert_same(call(h, op, v), handle_result(op, call(rbd, op, v)), rtol=1e-10 if fast else 0)


def test_signature_and_doc_follow_rbd():
    for op in OPERATIONS:
        if hasattr(rbdkit.RBD, op):
            assert inspect.signature(getattr(rbdkit.Handle, op)) == inspect.signature(getattr(rbdkit.RBD, op))
            assert getattr(rbdkit.Handle, op).__doc__ == getattr(rbdkit.RBD, op).__doc__


# ------------------------------------------------------------ float32


@pytest.mark.parametrize("op", [op for op in OPERATIONS if hasattr(rbdkit.RBD, op)])
def test_float32_results(hyq, op):
    h32, h64 = rbdkit.Handle(hyq, dtype="float32"), rbdkit.Handle(hyq)
    v = values(hyq)
    r32, r64 = call(h32, op, v), call(h64, op, v)
    flat32 = r32 if isinstance(r32, tuple) else (r32,)
    flat64 = r64 if isinstance(r64, tuple) else (r64,)
    for a, b in zip(flat32, flat64):
        assert a.dtype == np.float32
        if op not in h32.fast_operations():  # float64 maths rounded to float32
            np.testing.assert_array_equal(a, np.asarray(b).astype(np.float32))
        else:  # the engine's float32 maths
            scale = max(1.0, float(np.max(np.abs(b))))
            # central differences with eps = 1e-5 keep about two float32 digits (docs/engine.md)
            tol = 1e-1 if op.endswith("_fd") else 1e-4
            assert np.max(np.abs(a - b)) <= tol * scale, op


# ------------------------------------------------------------ bad input


def test_bad_constructor_arguments(iiwa):
    for bad in ("iiwa_not_a_file", 3, None, iiwa._core, rbdkit.RBD(iiwa)):
        with pytest.raises((TypeError, FileNotFoundError), match="^(model: expected an rbdkit.Model|path: no URDF)"):
            rbdkit.Handle(bad)
    with pytest.raises(ValueError, match=r"^algorithms: unknown algorithm 'rk3'; expected names from: "
                                         r"configuration, inverse_dynamics, .*plant_step_hessian"):
        rbdkit.Handle(iiwa, algorithms=["crba", "rk3"])
    with pytest.raises(ValueError, match="^algorithms: 'com_cost_x' is an operation|^algorithms: unknown"):
        rbdkit.Handle(iiwa, algorithms=["com_cost_x"])
    with pytest.raises(ValueError, match="^algorithms: 'plant_step' is an operation, not an algorithm; it is "
                                         "provided by algorithm 'integrator'"):
        rbdkit.Handle(iiwa, algorithms=["plant_step"])
    for bad in (3, {"crba": 1}):
        with pytest.raises(TypeError, match="^algorithms: expected a list of algorithm names"):
            rbdkit.Handle(iiwa, algorithms=bad)
    with pytest.raises(TypeError, match="^algorithms: expected algorithm names \\(str\\)"):
        rbdkit.Handle(iiwa, algorithms=["crba", 3])
    assert rbdkit.Handle(iiwa, algorithms="crba").available_operations() == ["crba"]
    with pytest.raises(ValueError, match=r"^algorithms: expected at least one algorithm name \(None for every"):
        rbdkit.Handle(iiwa, algorithms=[])
    for bad in ("gpu", "CPU", None, 0):  # backend='cuda': tests/python/test_cuda.py
        with pytest.raises(ValueError, match="^backend: expected 'cpu' or 'cuda'"):
            rbdkit.Handle(iiwa, backend=bad)
    for bad in (0, -1, -8):
        with pytest.raises(ValueError, match=f"^threads: expected a positive integer or None .*got {bad}$"):
            rbdkit.Handle(iiwa, threads=bad)
    for bad in (1.5, 2.0, "2", True, [2]):
        with pytest.raises(TypeError, match="^threads: expected a positive integer or None"):
            rbdkit.Handle(iiwa, threads=bad)
    for bad in ("float16", "int32", "double", np.int32, None, "f8", 3):
        with pytest.raises(ValueError, match="^dtype: expected 'float64' or 'float32'"):
            rbdkit.Handle(iiwa, dtype=bad)
    for ok in (np.float32, np.dtype("float32"), "float32"):
        assert rbdkit.Handle(iiwa, algorithms=["crba"], dtype=ok).dtype == np.float32
    for bad in ("MuJoCo", "pin", None, 1):
        with pytest.raises(ValueError, match="^output_convention: expected 'pinocchio' or 'mujoco'"):
            rbdkit.Handle(iiwa, output_convention=bad)


BAD_INPUT_CASES = [(m, a) for m, args in BAD_INPUT_METHODS.items() for a in args if m in OPERATIONS]


def same_error(f, g):
    """f and g raise the same exception type with the same message"""
    with pytest.raises(Exception) as e1:
        f()
    with pytest.raises(Exception) as e2:
        g()
    assert (type(e1.value), str(e1.value)) == (type(e2.value), str(e2.value))


def bad_input_call(obj, method, args):
    if method in ("integrator", "integrator_gradient", "integrator_f_ext_gradient"):
        return getattr(obj, method)(dt=0.01, integrator_type="rk4", **args)
    return getattr(obj, method)(**args)


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("method,arg", BAD_INPUT_CASES, ids=[f"{m}-{a}" for m, a in BAD_INPUT_CASES])
def test_bad_arrays_as_rbd(hyq, threads, method, arg):
    # the bad-input suite's shapes and values give the RBD method's errors,
    # whether the handle's engine runs the call or RBD's serial loop does
    h, rbd = rbdkit.Handle(hyq, threads=threads), rbdkit.RBD(hyq)
    cases = []
    for shape in bad_shapes(hyq, method, arg)[:3]:
        args = valid_args(hyq, method)
        args[arg] = np.zeros(shape)
        cases.append(args)
    for bad in (np.nan, np.inf):
        args = valid_args(hyq, method)
        x = np.stack([np.asarray(args[arg], dtype=float)] * 2)
        x[1].reshape(-1)[-1] = bad
        cases.append({k: (x if k == arg else v) for k, v in args.items()})
    args = valid_args(hyq, method)
    args[arg] = "abc"
    cases.append(args)
    if arg in ("q", "q0", "q1"):
        args = valid_args(hyq, method)
        q = np.stack([args[arg]] * 2)
        q[1, 3:7] = [0, 0, 0, 2]
        cases.append({**args, arg: q})
    for args in cases:
        same_error(lambda: bad_input_call(h, method, args), lambda: bad_input_call(rbd, method, args))


@pytest.mark.parametrize("threads", [1, 2])
def test_bad_options_as_rbd(hyq, threads):
    h, rbd = rbdkit.Handle(hyq, threads=threads), rbdkit.RBD(hyq)
    v = values(hyq)
    for kw in ({"integrator_type": "rk3"}, {"integrator_type": 3}, {"dt": 0.0}, {"dt": np.nan}, {"gravity": "g"},
               {"gravity": np.inf}):
        for op in ("integrator", "integrator_gradient"):
            a = {"q": v["q"], "qd": v["qd"], "u": v["u"], "dt": 0.01, **kw}
            same_error(lambda: getattr(h, op)(**a), lambda: getattr(rbd, op)(**a))
        a = {"x": v["x"], "u": v["u"], "dt": 0.01, **kw}
        same_error(lambda: h.plant_step(**a), lambda: rbd.plant_step(**a))
    with pytest.raises(TypeError, match="^output_dense: expected a bool"):
        h.minv(v["q"], output_dense=1)


# ------------------------------------------------------------ output convention


def test_output_convention_not_supported_raises(hyq, iiwa):
    h = rbdkit.Handle(hyq, output_convention="mujoco")
    v = values(hyq)
    with pytest.raises(ValueError, match=r"^crba: does not support output_convention='mujoco' on a model with "
                                         r"free-flyer or spherical joints"):
        h.crba(v["q"])
    # a model without quaternion joints reads the same in both conventions
    hi = rbdkit.Handle(iiwa, output_convention="mujoco")
    vi = values(iiwa)
    assert_same(hi.crba(vi["q"]), rbdkit.RBD(iiwa).crba(vi["q"]), rtol=1e-12)  # the engine: rounding


def test_mujoco_convention_handle_equals_rbd(hyq):
    # the methods that take output_convention get the handle's; the
    # conversions work in either convention; the others raise
    h, rbd = rbdkit.Handle(hyq, output_convention="mujoco"), rbdkit.RBD(hyq)
    v = values(hyq)
    qpos, u = v["qpos"], v["u"]
    qvel = v["x_mj"][:, hyq.nq:]
    assert_same(h.integrator(qpos, qvel, u, 0.01, "semi_implicit_euler"),
                rbd.integrator(qpos, qvel, u, 0.01, "semi_implicit_euler", output_convention="mujoco"), rtol=1e-12)
    assert_same(h.plant_step_gradient(v["x_mj"], u, 0.01, "rk4"),
                rbd.plant_step_gradient(v["x_mj"], u, 0.01, "rk4", output_convention="mujoco"), rtol=1e-12)
    assert_same(h.quadratic_state_cost_tangent(v["x_mj"], v["x_mj"][::-1], v["Q2"]),
                rbd.quadratic_state_cost_tangent(v["x_mj"], v["x_mj"][::-1], v["Q2"], output_convention="mujoco"),
                rtol=1e-12)
    assert_same(h.state_from_mujoco(v["x_mj"]), v["x"], rtol=1e-14)
    assert_same(h.mujoco_difference(qpos, v["qpos1"]), rbd.mujoco_difference(qpos, v["qpos1"]), rtol=1e-12)
    with pytest.raises(ValueError, match="^aba: does not support output_convention='mujoco'"):
        h.aba(qpos, qvel, u)


def test_output_convention_passed_through(hyq):
    # a method that takes output_convention (as the integrators and costs do)
    # receives the handle's; a per-call keyword wins (the C++ handle decides)
    v = values(hyq)
    h = rbdkit.Handle(hyq, output_convention="mujoco")
    ref = rbdkit.RBD(hyq)
    assert type(h.integrator).__name__ == "Operation"
    assert_same(h.integrator(v["q"], v["qd"], v["u"], 0.01), ref.integrator(v["q"], v["qd"], v["u"], 0.01,
                                                                              output_convention="mujoco"), rtol=1e-12)
    assert_same(h.integrator(v["q"], v["qd"], v["u"], 0.01, output_convention="pinocchio"),
                ref.integrator(v["q"], v["qd"], v["u"], 0.01), rtol=1e-12)
    assert not np.allclose(h.integrator(v["q"], v["qd"], v["u"], 0.01),
                           h.integrator(v["q"], v["qd"], v["u"], 0.01, output_convention="pinocchio"))
    # the Pinocchio convention runs the compiled callable of the C++ handle
    hp = rbdkit.Handle(hyq, output_convention="pinocchio")
    assert type(hp.integrator).__name__ == "Operation"
    assert_same(hp.integrator(v["q"], v["qd"], v["u"], 0.01), ref.integrator(v["q"], v["qd"], v["u"], 0.01),
                rtol=1e-12)


# ------------------------------------------------------------ the registered operations in C++


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("op", REGISTERED)
def test_registered_operations_run_in_cpp(hyq, op, dtype):
    # the C++ handle's callable, in the handle's dtype with its threads, batched and one sample
    h, rbd = rbdkit.Handle(hyq, dtype=dtype, threads=2), rbdkit.RBD(hyq)
    assert h._core.threads == 2 and h._core.dtype == dtype
    assert op in h.fast_operations()
    assert type(getattr(h, op)).__name__ == "Operation"
    for batch in (B, None):
        v = values(hyq) if batch else one_sample(values(hyq))
        r = call(h, op, v)
        ref = handle_result(op, call(rbd, op, v))
        flat, flat_ref = (r, ref) if isinstance(r, tuple) else ((r,), (ref,))
        for a, b in zip(flat, flat_ref):
            assert a.dtype == np.dtype(dtype) and a.shape == b.shape
            scale = max(1.0, float(np.max(np.abs(b))))
            tol = 1e-10 if dtype == "float64" else 1e-1 if op.endswith("_fd") else 1e-4  # see test_float32_results
            assert np.max(np.abs(a - b)) <= tol * scale, op


def test_f_ext_and_options_run_in_cpp(hyq):
    # f_ext and output_dense=False go to the same callables
    h, rbd = rbdkit.Handle(hyq, threads=2), rbdkit.RBD(hyq)
    v = values(hyq)
    assert_same(h.inverse_dynamics(v["q"], v["qd"], v["qdd"], f_ext=v["f_ext"]),
                rbd.inverse_dynamics(v["q"], v["qd"], v["qdd"], f_ext=v["f_ext"])[0], rtol=1e-10)
    assert_same(h.aba(v["q"], v["qd"], v["tau"], f_ext=v["f_ext"]), rbd.aba(v["q"], v["qd"], v["tau"], f_ext=v["f_ext"]),
                rtol=1e-10)
    assert_same(h.integrator(v["q"], v["qd"], v["u"], 0.01, "rk4", f_ext=v["f_ext"]),
                rbd.integrator(v["q"], v["qd"], v["u"], 0.01, "rk4", f_ext=v["f_ext"]), rtol=1e-10)
    assert_same(h.minv(v["q"], output_dense=False), rbd.minv(v["q"], output_dense=False), rtol=1e-10)
    assert_same(h.aba(v["q"], v["qd"], v["tau"], f_ext=[]), rbd.aba(v["q"], v["qd"], v["tau"]), rtol=1e-10)
    assert set(h.fast_operations()) == set(OPERATIONS)  # every operation is registered
    # a handle with the MuJoCo convention on a floating base: every operation is a compiled callable
    # too (the C++ handle applies the convention), the conversions between the conventions included
    hm = rbdkit.Handle(hyq, output_convention="mujoco")
    assert set(hm.fast_operations()) == set(OPERATIONS)
    assert type(hm.state_to_mujoco).__name__ == "Operation" and type(hm.integrator).__name__ == "Operation"
    assert_same(hm.force_from_mujoco(v["qpos"], v["u"]), rbd.force_from_mujoco(v["qpos"], v["u"]), rtol=0)


def test_every_registered_operation_is_fast(hyq):
    h = rbdkit.Handle(hyq)
    assert set(h.fast_operations()) == set(REGISTERED) and h.engine_available()
