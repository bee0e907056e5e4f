"""Bad input raises a clear exception of the right type whose message names
the offending argument (or the offending URDF element); valid but unusual
input (integer arrays, lists, f_ext=[], broadcasting) works.

The array-argument cases run on floating-base HyQ, where nq (19) != nv (18),
so a configuration of width nv is always a wrong shape."""

import os
import re
import warnings

import numpy as np
import pytest

import rbdkit
from pinref import URDF_DIR

SPHERICAL = os.path.join(URDF_DIR, "spherical.urdf")

# every RBD method and its array arguments, by keyword
METHODS = {
    "inverse_dynamics": ("q", "qd", "qdd", "f_ext"),
    "aba": ("q", "qd", "tau", "f_ext"),
    "forward_dynamics": ("q", "qd", "u", "f_ext"),
    "crba": ("q",),
    "minv": ("q",),
    "generalized_gravity": ("q",),
    "nonlinear_effects": ("q", "qd"),
    "apply_external_forces": ("f_in", "f_ext"),
    "integrate": ("q", "v"),
    "difference": ("q0", "q1"),
    "dIntegrate": ("q", "v"),
    "dDifference": ("q0", "q1"),
    "d2Integrate": ("q", "v"),
    "time_per_call": ("q", "qd", "tau"),
    "inverse_dynamics_gradient": ("q", "qd", "qdd", "f_ext"),
    "forward_dynamics_gradient": ("q", "qd", "u", "f_ext"),
    "f_ext_gradient": ("q",),
    "inverse_dynamics_fpass": ("q", "qd", "qdd", "f_ext"),
    "inverse_dynamics_bpass": ("q", "f"),
    "minv_bpass": ("q",),
    "minv_fpass": ("q", "minv_b"),
    "inverse_dynamics_gradient_fpass_dq": ("q", "qd", "qdd"),
    "inverse_dynamics_gradient_fpass_dqd": ("q", "qd", "qdd"),
    "inverse_dynamics_gradient_bpass_dq": ("q", "qd", "qdd", "dV_dq", "dA_dq"),
    "inverse_dynamics_gradient_bpass_dqd": ("q", "qd", "qdd", "S", "dA_dqd"),
    "integrator": ("q", "qd", "u", "f_ext"),
    "integrator_gradient": ("q", "qd", "u", "f_ext"),
    "integrator_f_ext_gradient": ("q", "qd", "u", "f_ext"),
    "inverse_dynamics_regressor": ("q", "qd", "qdd"),
    "inverse_dynamics_regressor_gradient": ("q", "qd", "qdd"),
    "forward_dynamics_parameter_gradient": ("q", "qd", "u"),
    "kinetic_energy_regressor": ("q", "qd"),
    "potential_energy_regressor": ("q",),
    "kinetic_energy": ("q", "qd"),
    "potential_energy": ("q",),
    "mechanical_energy": ("q", "qd"),
    "coriolis_matrix": ("q", "qd"),
    "com": ("q",),
    "jacobian_com": ("q",),
    "ccrba": ("q", "qd"),
    "centroidal_momentum": ("q", "qd"),
    "dccrba": ("q",),
    "dccrba_fd": ("q",),
    "cmm_time_variation": ("q", "qd"),
    "cmm_time_variation_fd": ("q", "qd"),
    "centroidal_momentum_time_variation": ("q", "qd", "qdd"),
    "centroidal_dynamics_derivatives": ("q", "qd", "qdd"),
    "idsva_so_body_frame": ("q", "qd", "qdd"),
    "idsva_so_world_frame": ("q", "qd", "qdd"),
    "idsva_so": ("q", "qd", "qdd"),
    "fdsva_so": ("q", "qd", "u"),
    "plant_step": ("x", "u", "f_ext"),
    "plant_step_gradient": ("x", "u", "f_ext"),
    "plant_step_hessian": ("x", "u"),
    "state_to_mujoco": ("x",),
    "state_from_mujoco": ("x",),
    "force_to_mujoco": ("qpos", "u"),
    "force_from_mujoco": ("qpos", "u"),
    "mujoco_integrate": ("qpos", "v"),
    "mujoco_difference": ("qpos0", "qpos1"),
    "quadratic_state_cost": ("x", "x_des", "Q"),
    "quadratic_input_cost": ("u", "u_des", "R"),
    "quadratic_state_cost_tangent": ("x", "x_des", "Q"),
    "com_cost": ("q", "p_des", "W"),
    "momentum_cost": ("q", "qd", "h_des", "W"),
    "joint_position_barrier": ("q", "lower", "upper"),
    "joint_velocity_barrier": ("qd", "lower", "upper"),
    "joint_torque_barrier": ("u", "lower", "upper"),
    "forward_kinematics": ("q",),
    "frame_placement": ("q",),
    "frame_jacobian": ("q",),
    "frame_jacobian_dot": ("q", "qd"),
    "ee_pos_cost": ("q", "p_des", "W", "ee_offset"),
    "end_effector_pose": ("q", "ee_offsets"),
    "end_effector_pose_gradient": ("q", "ee_offsets"),
    "end_effector_pose_hessian_analytic": ("q", "offsets"),
    "end_effector_pose_hessian": ("q", "offsets"),
    "osc_inertia": ("q", "ee_offsets"),
}
FRAME_METHODS = ("frame_placement", "frame_jacobian", "frame_jacobian_dot")
BARRIERS = ("joint_position_barrier", "joint_velocity_barrier", "joint_torque_barrier")
N_LEAVES = 4  # HyQ's end effectors by default: its four lower legs
KIND = {"q": "config", "q0": "config", "q1": "config", "qd": "tangent", "qdd": "tangent", "tau": "tangent",
        "u": "tangent", "v": "tangent", "f_ext": "force", "f_in": "force", "f": "force", "minv_b": "matrix",
        "dV_dq": "cols", "dA_dq": "cols", "S": "cols", "dA_dqd": "cols",
        "x": "state", "qpos": "config", "qpos0": "config", "qpos1": "config", "x_des": "state", "u_des": "tangent",
        "R": "weights", "p_des": "point", "h_des": "wrench", "ee_offsets": "ee_points", "offsets": "ee_points"}
# names whose kind depends on the method
KIND_OF = {("quadratic_state_cost", "Q"): "state_weights", ("quadratic_state_cost_tangent", "Q"): "tangent_weights",
           ("com_cost", "W"): "point_weights", ("momentum_cost", "W"): "wrench_weights",
           ("ee_pos_cost", "W"): "point_weights", ("ee_pos_cost", "ee_offset"): "point",
           ("joint_position_barrier", "q"): "coords_q", ("joint_position_barrier", "lower"): "lower_q",
           ("joint_position_barrier", "upper"): "upper_q",
           ("joint_velocity_barrier", "lower"): "lower_v", ("joint_velocity_barrier", "upper"): "upper_v",
           ("joint_torque_barrier", "lower"): "lower_v", ("joint_torque_barrier", "upper"): "upper_v"}
BOUND_KINDS = ("lower_q", "upper_q", "lower_v", "upper_v")
# the position barrier's q: nq coordinates, each against its bounds (no unit-quaternion check)


def kind_of(method, name):
    return KIND_OF.get((method, name)) or KIND[name]
OPTIONAL = {("integrator", "f_ext"), ("integrator_gradient", "f_ext"), ("integrator_f_ext_gradient", "f_ext"),
            ("plant_step", "f_ext"), ("plant_step_gradient", "f_ext"), ("inverse_dynamics_gradient", "qdd"),
            ("inverse_dynamics_gradient", "f_ext"),
            ("forward_dynamics_gradient", "f_ext"), ("inverse_dynamics_fpass", "qdd"),
            ("inverse_dynamics_fpass", "f_ext"), ("inverse_dynamics_gradient_fpass_dq", "qdd"),
            ("inverse_dynamics_gradient_fpass_dqd", "qdd"), ("inverse_dynamics_gradient_bpass_dq", "qdd"),
            ("inverse_dynamics_gradient_bpass_dqd", "qdd"),
            ("inverse_dynamics", "qdd"), ("inverse_dynamics", "f_ext"), ("aba", "f_ext"),
            ("forward_dynamics", "f_ext"), ("inverse_dynamics_regressor", "qdd"),
            ("inverse_dynamics_regressor_gradient", "qdd"), ("ee_pos_cost", "ee_offset"),
            ("end_effector_pose", "ee_offsets"), ("end_effector_pose_gradient", "ee_offsets"),
            ("end_effector_pose_hessian_analytic", "offsets"), ("end_effector_pose_hessian", "offsets"),
            ("osc_inertia", "ee_offsets")}
WITH_GRAVITY = ("inverse_dynamics", "aba", "forward_dynamics", "generalized_gravity", "nonlinear_effects",
                "inverse_dynamics_gradient", "forward_dynamics_gradient", "inverse_dynamics_fpass",
                "inverse_dynamics_gradient_fpass_dq", "inverse_dynamics_gradient_fpass_dqd",
                "inverse_dynamics_gradient_bpass_dq", "inverse_dynamics_gradient_bpass_dqd",
                "inverse_dynamics_regressor", "inverse_dynamics_regressor_gradient",
                "forward_dynamics_parameter_gradient", "potential_energy_regressor", "potential_energy",
                "mechanical_energy",
                "idsva_so_body_frame", "idsva_so_world_frame", "idsva_so", "fdsva_so", "plant_step",
                "plant_step_gradient", "plant_step_hessian")
METHOD_ARGS = [(m, a) for m, args in METHODS.items() for a in args]
MULTI = [m for m, args in METHODS.items() if len(args) > 1]


@pytest.fixture(scope="module")
def hyq():
    return rbdkit.robots.load("hyq", floating_base=True)


@pytest.fixture(scope="module")
def rbd(hyq):
    return rbdkit.RBD(hyq)


def valid_value(model, method, name, seed=0):
    rng = np.random.default_rng(seed)
    kind = kind_of(method, name)
    if kind.endswith("weights"):
        return rng.uniform(0, 1, width(model, method, name))
    if kind in ("point", "wrench", "ee_points"):
        return rng.uniform(-1, 1, width(model, method, name))
    if kind in BOUND_KINDS:  # wide bounds around any valid value, the first one infinite
        b = np.full(width(model, method, name), 1e3 if kind.startswith("upper") else -1e3)
        b[0] = np.inf if kind.startswith("upper") else -np.inf
        return b
    if kind in ("config", "coords_q"):
        return model.random_configuration(rng)
    if kind == "tangent":
        return rng.uniform(-1, 1, model.nv)
    if kind == "matrix":
        return rng.uniform(-1, 1, (model.nv, model.nv))
    if kind == "cols":
        return rng.uniform(-1, 1, (model.nb, 6, 6))
    if kind == "state":
        return np.concatenate([model.random_configuration(rng), rng.uniform(-1, 1, model.nv)])
    return rng.uniform(-1, 1, (model.nb, 6))


def valid_args(model, method):
    return {a: valid_value(model, method, a, seed=k) for k, a in enumerate(METHODS[method])}


def call(rbd, method, args):
    if method == "time_per_call":
        return rbd.time_per_call("crba", iters=1, **args)
    if method in ("integrator", "integrator_gradient", "integrator_f_ext_gradient", "plant_step", "plant_step_gradient",
                  "plant_step_hessian"):
        return getattr(rbd, method)(dt=0.01, integrator_type="rk4", **args)
    if method in BARRIERS:
        return getattr(rbd, method)(mu=0.1, **args)
    if method in FRAME_METHODS:
        return getattr(rbd, method)(frame_name="lf_lowerleg", **args)
    return getattr(rbd, method)(**args)


def width(model, method, name):
    return {"config": (model.nq,), "tangent": (model.nv,), "force": (model.nb, 6), "matrix": (model.nv, model.nv),
            "cols": (model.nb, 6, 6), "state": (model.nq + model.nv,), "weights": (model.nv,),
            "state_weights": (model.nq + model.nv,), "tangent_weights": (2 * model.nv,), "point": (3,),
            "point_weights": (3,), "wrench": (6,), "wrench_weights": (6,), "lower_q": (model.nq,),
            "upper_q": (model.nq,), "lower_v": (model.nv,), "upper_v": (model.nv,),
            "coords_q": (model.nq,), "ee_points": (N_LEAVES, 3)}[kind_of(method, name)]


def bad_shapes(model, method, name):
    nq, nv, nb = model.nq, model.nv, model.nb
    kind = kind_of(method, name)
    if kind in ("point", "point_weights", "wrench", "wrench_weights"):
        n = width(model, method, name)[0]
        return [(n + 1,), (n, 1), (2, 2, n), ()]
    if kind == "tangent_weights":
        return [(nv,), (2 * nv + 1,), (2, 2, 2 * nv), ()]
    if kind == "ee_points":  # (3,) is one tool point for all
        return [(2,), (N_LEAVES + 1, 3), (N_LEAVES, 4), (2, 2, N_LEAVES, 3), ()]
    if kind == "state_weights":
        return [(nq,), (nq + nv + 1,), (2, 2, nq + nv), ()]
    if kind == "weights":
        kind = "tangent"
    if kind in BOUND_KINDS or kind == "coords_q":
        kind = "config" if kind.endswith("_q") else "tangent"
    if kind == "config":
        return [(nv,), (nq + 1,), (2, 2, nq), (), (nq, 1), (1, 1, nq)]
    if kind == "tangent":
        return [(nq,), (nv - 1,), (2, 2, nv), (), (nv, 1)]
    if kind == "matrix":
        return [(nv,), (nv, nq), (2, 2, nv, nv), ()]
    if kind == "cols":
        return [(nb, 6), (nb, 6, 3), (nb + 1, 6, 6), (2, 2, nb, 6, 6)]
    if kind == "state":
        return [(nq,), (nq + nv + 1,), (2, 2, nq + nv), (), (nq + nv, 1)]
    return [(nb, 3), (nb + 1, 6), (nb * 6,), (2, 2, nb, 6), (6, nb)]


def test_every_registered_operation_is_listed():
    # a new registered operation gets every generic case below once it is
    # listed here with its array arguments, in the registry's order
    for name, _alg, _family, _doc, args in rbdkit._core.registered_operations():
        assert METHODS.get(name) == tuple(a for a, kind, _ in args if kind in ("array", "optional")), name


def test_valid_arguments_work(rbd, hyq):
    # the baseline of every bad-input case below: the same call with valid arguments runs
    for method in METHODS:
        out = call(rbd, method, valid_args(hyq, method))
        assert out is not None


# ------------------------------------------------------------ shapes


@pytest.mark.parametrize("method,arg", METHOD_ARGS, ids=[f"{m}-{a}" for m, a in METHOD_ARGS])
def test_wrong_shape(rbd, hyq, method, arg):
    dim = {"config": f"nq={hyq.nq}", "tangent": f"nv={hyq.nv}", "force": f"nb={hyq.nb}", "matrix": f"nv={hyq.nv}",
           "cols": f"nb={hyq.nb}", "state": rf"nq\+nv={hyq.nq + hyq.nv}", "weights": f"nv={hyq.nv}",
           "state_weights": rf"nq\+nv={hyq.nq + hyq.nv}", "tangent_weights": f"2nv={2 * hyq.nv}", "point": "3=3",
           "point_weights": "3=3", "wrench": "6=6", "wrench_weights": "6=6", "lower_q": f"nq={hyq.nq}",
           "upper_q": f"nq={hyq.nq}", "lower_v": f"nv={hyq.nv}", "upper_v": f"nv={hyq.nv}",
           "coords_q": f"nq={hyq.nq}", "ee_points": f"n_ee={N_LEAVES}"}[kind_of(method, arg)]
    for shape in bad_shapes(hyq, method, arg):
        args = valid_args(hyq, method)
        args[arg] = np.zeros(shape)
        with pytest.raises(ValueError, match=rf"^{arg}: expected shape .*{dim}.*got shape {re.escape(str(shape))}$"):
            call(rbd, method, args)


@pytest.mark.parametrize("method", MULTI)
def test_mismatched_batch_sizes(rbd, hyq, method):
    names = METHODS[method]
    first = names[0]
    for other in names[1:]:
        args = valid_args(hyq, method)
        args[first] = np.stack([args[first]] * 3)
        args[other] = np.stack([args[other]] * 2)
        with pytest.raises(ValueError, match=rf"^{other}: batch size 2 does not match {first}'s batch size 3$"):
            call(rbd, method, args)
        # and the other way round
        args[first], args[other] = args[first][:2], np.stack([args[other][0]] * 3)
        with pytest.raises(ValueError, match=rf"^{other}: batch size 3 does not match {first}'s batch size 2$"):
            call(rbd, method, args)


@pytest.mark.parametrize("method,arg", METHOD_ARGS, ids=[f"{m}-{a}" for m, a in METHOD_ARGS])
def test_empty_batch(rbd, hyq, method, arg):
    args = valid_args(hyq, method)
    args[arg] = np.zeros((0,) + width(hyq, method, arg))
    with pytest.raises(ValueError, match=rf"^{arg}: the batch is empty"):
        call(rbd, method, args)


def test_time_per_call_rejects_a_batch(rbd, hyq):
    args = {k: np.stack([v, v]) for k, v in valid_args(hyq, "time_per_call").items()}
    with pytest.raises(ValueError, match="time_per_call: expected one sample, not a batch"):
        rbd.time_per_call("crba", iters=1, **args)


def test_time_per_call_unknown_operation(rbd, hyq):
    with pytest.raises(ValueError, match="^op: expected one of 'inverse_dynamics'"):
        rbd.time_per_call("nope", iters=1, **valid_args(hyq, "time_per_call"))
    for iters in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="^iters: expected a positive integer"):
            rbd.time_per_call("crba", iters=iters, **valid_args(hyq, "time_per_call"))


# ------------------------------------------------------------ dtypes


def bad_dtype_values(model, method, arg):
    shape = width(model, method, arg)
    vals = [
        "abc",
        np.full(shape, "x"),                           # strings of the right shape
        np.zeros(shape, dtype=complex),
        np.zeros(shape, dtype=object),
        np.ones(shape, dtype=bool),
        {"a": 1},
        [[0.0] * 3, [0.0]],                            # ragged
    ]
    if (method, arg) not in OPTIONAL:
        vals.append(None)
    return vals


@pytest.mark.parametrize("method,arg", METHOD_ARGS, ids=[f"{m}-{a}" for m, a in METHOD_ARGS])
def test_wrong_dtype(rbd, hyq, method, arg):
    for bad in bad_dtype_values(hyq, method, arg):
        args = valid_args(hyq, method)
        args[arg] = bad
        with pytest.raises(TypeError, match=rf"^{arg}: expected a real numeric array"):
            call(rbd, method, args)


def test_complex_with_zero_imaginary_part_is_still_rejected(rbd, hyq):
    # no silent discarding of an imaginary part, even a zero one
    q = hyq.neutral().astype(complex)
    with pytest.raises(TypeError, match="^q: .*complex128"):
        rbd.crba(q)


# ------------------------------------------------------------ values


NONFINITE_CASES = [(m, a) for m, a in METHOD_ARGS if kind_of(m, a) not in BOUND_KINDS]  # bounds: below


@pytest.mark.parametrize("method,arg", NONFINITE_CASES, ids=[f"{m}-{a}" for m, a in NONFINITE_CASES])
def test_nonfinite_values(rbd, hyq, method, arg):
    for bad in (np.nan, np.inf, -np.inf):
        for pos in (0, -1):  # first and last entry (for q: translation and the quaternion's w)
            args = valid_args(hyq, method)
            x = np.array(args[arg])
            x.reshape(-1)[pos] = bad
            args[arg] = x
            with pytest.raises(ValueError, match=rf"^{arg}: expected finite values"):
                call(rbd, method, args)
        # in the second sample of a batch
        if method == "time_per_call":
            continue
        args = valid_args(hyq, method)
        x = np.stack([args[arg], args[arg]])
        x[1].reshape(-1)[1] = bad
        args[arg] = x
        with pytest.raises(ValueError, match=rf"^{arg}(\[1\])?: expected finite values"):
            call(rbd, method, args)


@pytest.mark.parametrize("method", BARRIERS)
def test_bad_barrier_bounds(rbd, hyq, method):
    # NaN, an infinity on the wrong side, an empty interval: one message naming both bounds; +inf above and
    # -inf below are no bound
    for arg, bad in (("lower", np.nan), ("upper", np.nan), ("lower", np.inf), ("upper", -np.inf), ("lower", 2e3),
                     ("upper", -2e3)):
        for batched in (False, True):
            args = valid_args(hyq, method)
            x = np.stack([args[arg]] * 2) if batched else np.array(args[arg])
            x.reshape(-1)[-1] = bad
            args[arg] = x
            where = rf"sample 1, flat index {x.shape[-1] - 1}" if batched else rf"flat index {x.shape[-1] - 1}"
            with pytest.raises(ValueError, match=rf"^lower, upper: expected lower < upper .* at {where}$"):
                call(rbd, method, args)
    for arg in ("lower", "upper"):  # a finite bound beyond the input bound: named alone
        args = valid_args(hyq, method)
        args[arg] = np.array(args[arg])
        args[arg][-1] = 1e160 if arg == "upper" else -1e160
        with pytest.raises(ValueError, match=rf"^{arg}: expected values of magnitude at most 1e\+100"):
            call(rbd, method, args)
    for bad in (0.0, -1.0):
        with pytest.raises(ValueError, match="^mu: expected a positive barrier weight"):
            getattr(rbd, method)(**valid_args(hyq, method), mu=bad)
    with pytest.raises(TypeError, match="missing required argument 'mu'"):
        getattr(rbd, method)(**valid_args(hyq, method))


@pytest.mark.parametrize("method", BARRIERS)
def test_bad_barrier_bounds_float32(hyq, method):
    # a float32 handle: a finite bound beyond float32's input bound is refused before it rounds to inf
    h = rbdkit.Handle(hyq, dtype="float32")
    for arg in ("lower", "upper"):
        args = valid_args(hyq, method)
        args[arg] = np.array(args[arg])
        args[arg][-1] = 1e39 if arg == "upper" else -1e39
        with pytest.raises(ValueError, match=rf"^{arg}: expected values of magnitude at most 1e\+15"):
            h.__getattribute__(method)(mu=0.1, **args)
    np.testing.assert_array_equal(np.isfinite(h.__getattribute__(method)(mu=0.1, **valid_args(hyq, method))[0]),
                                  True)  # infinite bounds are no bound


def test_names_without_utf8(rbd, hyq):
    # a str with a lone surrogate has no UTF-8 text: a ValueError naming the argument
    q = hyq.neutral()
    bad = "lf_\ud800"
    with pytest.raises(ValueError, match="^frame_name: expected a name in valid UTF-8"):
        rbd.frame_placement(q, frame_name=bad)
    with pytest.raises(ValueError, match="^ee_joint_names: expected a name in valid UTF-8"):
        rbd.end_effector_pose(q, ee_joint_names=[bad])
    with pytest.raises(ValueError, match="^ee_joint_names: expected a name in valid UTF-8"):
        rbd.end_effector_pose(q, ee_joint_names=bad)
    with pytest.raises(ValueError, match="^integrator_type: expected a name in valid UTF-8"):
        rbd.integrator(q, np.zeros(hyq.nv), np.zeros(hyq.nv), 0.01, integrator_type=bad)
    with pytest.raises(ValueError, match="^reference_frame: expected one of"):
        rbd.frame_jacobian(q, frame_name="lf_lowerleg", reference_frame=bad)


@pytest.mark.parametrize("method", WITH_GRAVITY)
def test_bad_gravity(rbd, hyq, method):
    for bad in (np.nan, np.inf, -np.inf):
        with pytest.raises(ValueError, match="^gravity: expected a finite number"):
            call(rbd, method, {**valid_args(hyq, method), "gravity": bad})
    for bad in ("9.81", None, True, np.array(-9.81), [-9.81], 1j):
        with pytest.raises(TypeError, match="^gravity: expected a real number"):
            call(rbd, method, {**valid_args(hyq, method), "gravity": bad})


CONFIG_CASES = [(m, a) for m, a in METHOD_ARGS if kind_of(m, a) == "config"]


def set_quat(q, start, quat):
    q = np.array(q)
    q[start:start + 4] = quat
    return q


@pytest.mark.parametrize("method,arg", CONFIG_CASES, ids=[f"{m}-{a}" for m, a in CONFIG_CASES])
def test_bad_floating_base_quaternion(rbd, hyq, method, arg):
    for quat, norm in (([0, 0, 0, 0], "0"), ([0, 0, 0, 2], "2"), ([0.6, 0.6, 0.6, 0.6], "1.2"),
                       ([0, 0, 0, 1 + 1e-4], "1.0001")):
        args = valid_args(hyq, method)
        args[arg] = set_quat(args[arg], 3, quat)
        with pytest.raises(ValueError, match=rf"^{arg}: the quaternion of joint 'root_joint' \(q\[3:7\].*"
                                             rf"must have unit norm, got norm {re.escape(norm)}"):
            call(rbd, method, args)
        if method == "time_per_call":
            continue
        # the second sample of a batch, named by its index
        args = valid_args(hyq, method)
        args[arg] = np.stack([args[arg], set_quat(args[arg], 3, quat)])
        with pytest.raises(ValueError, match=rf"^{arg}\[1\]: the quaternion of joint 'root_joint'"):
            call(rbd, method, args)


@pytest.mark.parametrize("floating_base", [False, True])
def test_bad_spherical_joint_quaternion(floating_base):
    model = rbdkit.Model.from_urdf(SPHERICAL, floating_base=floating_base)
    rbd = rbdkit.RBD(model)
    v = np.zeros(model.nv)
    for name in ("ball1", "ball2", "ball3"):
        j = model.joint(name)
        i = j["q_index"]
        for quat in ([0, 0, 0, 0], [0, 0, 0, 1.01], [1, 1, 0, 0]):
            q = set_quat(model.neutral(), i, quat)
            pattern = rf"the quaternion of joint '{name}' \(q\[{i}:{i + 4}\].*unit norm"
            with pytest.raises(ValueError, match="^q: " + pattern):
                rbd.crba(q)
            with pytest.raises(ValueError, match="^q: " + pattern):
                rbd.inverse_dynamics(q, v)
            with pytest.raises(ValueError, match="^q: " + pattern):
                rbd.integrate(q, v)
            with pytest.raises(ValueError, match="^q1: " + pattern):
                rbd.difference(model.neutral(), q)
            with pytest.raises(ValueError, match="^q0: " + pattern):
                rbd.dDifference(q, model.neutral(), "from")


# ------------------------------------------------------------ option arguments


def test_bad_with_respect_to(rbd, hyq):
    q, v = hyq.neutral(), np.zeros(hyq.nv)
    for bad in ("x", "Q", "", "from", "v ", None, 0, True):
        with pytest.raises(ValueError, match="^with_respect_to: expected one of 'q', 'v'"):
            rbd.dIntegrate(q, v, with_respect_to=bad)
    for bad in ("x", "q", "v", "From", "", None, 1):
        with pytest.raises(ValueError, match="^with_respect_to: expected one of 'from', 'to'"):
            rbd.dDifference(q, q, with_respect_to=bad)
    for bad in ("x", "V", None, 0):
        with pytest.raises(ValueError, match="^arg1: expected one of 'q', 'v'"):
            rbd.d2Integrate(q, v, bad, "v")
        with pytest.raises(ValueError, match="^arg2: expected one of 'q', 'v'"):
            rbd.d2Integrate(q, v, "v", bad)


@pytest.mark.parametrize("method", ["dccrba_fd", "cmm_time_variation_fd"])
def test_bad_finite_difference_step(rbd, hyq, method):
    for bad in (0, 0.0, -1e-5, np.nan, np.inf):
        with pytest.raises(ValueError, match="^eps: expected a (positive finite-difference step|finite number)"):
            call(rbd, method, {**valid_args(hyq, method), "eps": bad})
    for bad in ("1e-5", None, True, [1e-5]):
        with pytest.raises(TypeError, match="^eps: expected a real number"):
            call(rbd, method, {**valid_args(hyq, method), "eps": bad})


def test_output_dense_must_be_bool(rbd, hyq):
    for bad in (1, 0, 1.0, "True", "False", None, np.array(True), [True]):
        with pytest.raises(TypeError, match="^output_dense: expected a bool"):
            rbd.minv(hyq.neutral(), output_dense=bad)


# ------------------------------------------------------------ models and names


def test_rbd_needs_a_model(hyq):
    for bad in ("hyq", None, 3, hyq._core, rbdkit.RBD(hyq), rbdkit.robots.path("hyq")):
        with pytest.raises(TypeError, match="^model: expected an rbdkit.Model"):
            rbdkit.RBD(bad)


def test_model_constructor_needs_a_core_model():
    with pytest.raises(TypeError, match="Model.from_urdf"):
        rbdkit.Model("iiwa")


def test_unknown_robot():
    for bad in ("nope", "", "iiwa7", "hyq "):
        with pytest.raises(ValueError, match=rf"^name: unknown robot {re.escape(repr(bad))}; bundled robots are atlas, hyq, iiwa"):
            rbdkit.robots.load(bad)
    with pytest.raises(TypeError, match="^name: expected a robot name"):
        rbdkit.robots.load(3)


def test_unknown_frame_and_joint(hyq):
    with pytest.raises(ValueError, match="unknown frame 'nope' in robot 'hyq'"):
        hyq.frame("nope")
    with pytest.raises(ValueError, match="unknown joint 'nope' in robot 'hyq'"):
        hyq.joint("nope")
    # a link is a frame but not a joint
    link = next(f for f in hyq.frame_names if f not in {j["name"] for j in hyq.joints})
    hyq.frame(link)
    with pytest.raises(ValueError, match=f"unknown joint '{link}'"):
        hyq.joint(link)
    with pytest.raises(TypeError, match="^name: expected a frame name"):
        hyq.frame(3)
    with pytest.raises(TypeError, match="^name: expected a joint name"):
        hyq.joint(None)


def test_from_urdf_missing_file(tmp_path):
    missing = tmp_path / "missing.urdf"
    for p in (str(missing), missing):
        with pytest.raises(FileNotFoundError, match=r"^path: no URDF file at '.*missing\.urdf'"):
            rbdkit.Model.from_urdf(p)
    with pytest.raises(FileNotFoundError, match="^path: no URDF file"):
        rbdkit.Model.from_urdf(tmp_path)  # a directory


def test_from_urdf_non_path():
    for bad in (3, None, b"robots/iiwa.urdf", ["robots/iiwa.urdf"], 1.5):
        with pytest.raises(TypeError, match="^path: expected a file path"):
            rbdkit.Model.from_urdf(bad)
    for bad in (None, b"<robot/>", 3):
        with pytest.raises(TypeError, match="^xml: expected the URDF text as str"):
            rbdkit.Model.from_urdf_string(bad)


# ------------------------------------------------------------ URDF documents

INERTIAL = '<inertial><mass value="{m}"/><inertia ixx="{ixx}" ixy="{ixy}" ixz="0" iyy="{iyy}" iyz="0" izz="0.1"/></inertial>'


def link(name, m=1, ixx=0.1, iyy=0.1, ixy=0):
    return f'<link name="{name}">{INERTIAL.format(m=m, ixx=ixx, iyy=iyy, ixy=ixy)}</link>'


def joint(name, parent, child, type="revolute", extra=""):
    return (f'<joint name="{name}" type="{type}"><parent link="{parent}"/><child link="{child}"/>'
            f'<axis xyz="0 0 1"/>{extra}</joint>')


def robot(*parts):
    return '<?xml version="1.0"?><robot name="t">' + "".join(parts) + "</robot>"


GOOD = robot(link("a"), link("b"), link("c"), joint("j1", "a", "b"), joint("j2", "b", "c"))

BAD_URDF = {
    "malformed-xml": ('<robot name="t"><link name="a">', r"^URDF: malformed XML"),
    "empty-document": ("", r"^URDF: malformed XML"),
    "no-robot": ('<model name="t"><link name="a"/></model>', r"^URDF: no <robot> element"),
    "no-links": ('<robot name="t"/>', r"^URDF: the robot has no <link>"),
    "cycle": (robot(link("a"), link("b"), joint("j1", "a", "b"), joint("j2", "b", "a")),
              r"^URDF: the joints form a cycle"),
    "cycle-beside-a-root": (robot(link("r"), link("a"), link("b"), link("c"), joint("j0", "r", "c"),
                                  joint("j1", "a", "b"), joint("j2", "b", "a")),
                            r"^URDF: the joints form a cycle through link '(a|b)'"),
    "two-roots": (robot(link("a"), link("b"), link("c"), joint("j1", "a", "b")),
                  r"^URDF: the robot has 2 root links \('a' and 'c'\)"),
    "missing-parent-link": (robot(link("a"), link("b"), joint("j1", "zz", "b")),
                            r"^URDF: joint 'j1' names parent link 'zz', which is not defined"),
    "missing-child-link": (robot(link("a"), link("b"), joint("j1", "a", "zz")),
                           r"^URDF: joint 'j1' names child link 'zz', which is not defined"),
    "unknown-joint-type": (robot(link("a"), link("b"), joint("j1", "a", "b", type="wobbly")),
                           r"^URDF: joint 'j1' has unknown type 'wobbly'"),
    "negative-mass": (robot(link("a"), link("b", m=-1), joint("j1", "a", "b")),
                      r"^URDF: link 'b' has negative mass"),
    "negative-moment": (robot(link("a"), link("b", iyy=-1), joint("j1", "a", "b")),
                        r"^URDF: link 'b' has a negative principal moment of inertia iyy="),
    "mimic-cycle": (robot(link("a"), link("b"), link("c"), joint("j1", "a", "b", extra='<mimic joint="j2"/>'),
                          joint("j2", "b", "c", extra='<mimic joint="j1"/>')),
                    r"^URDF: mimic joints form a cycle through joint 'j[12]'"),
    "mimic-self": (robot(link("a"), link("b"), joint("j1", "a", "b", extra='<mimic joint="j1"/>')),
                   r"^URDF: mimic joints form a cycle through joint 'j1'"),
    "link-with-two-parents": (robot(link("a"), link("b"), link("c"), joint("j1", "a", "c"), joint("j2", "b", "c"),
                                    joint("j3", "a", "b")),
                              r"^URDF: link 'c' is the child of two joints \('j1' and 'j2'\)"),
    "malformed-number-in-origin": (robot(link("a"), link("b"),
                                         joint("j1", "a", "b", extra='<origin xyz="0 0.1x 0" rpy="0 0 0"/>')),
                                   r"^URDF: joint 'j1' origin xyz has '0\.1x', expected a finite number"),
    "too-few-numbers-in-origin": (robot(link("a"), link("b"), joint("j1", "a", "b", extra='<origin rpy="0 1"/>')),
                                  r"^URDF: joint 'j1' origin rpy must have 3 numbers"),
    "nan-in-origin": (robot(link("a"), link("b"), joint("j1", "a", "b", extra='<origin xyz="0 nan 0"/>')),
                      r"^URDF: joint 'j1' origin xyz has 'nan', expected a finite number"),
}


@pytest.mark.parametrize("case", list(BAD_URDF), ids=list(BAD_URDF))
def test_bad_urdf(case):
    xml, pattern = BAD_URDF[case]
    for strict in (False, True):
        for fb in (False, True):
            with pytest.raises(ValueError, match=pattern):
                rbdkit.Model.from_urdf_string(xml, floating_base=fb, strict=strict)


def test_bad_urdf_file_reports_the_same(tmp_path):
    xml, pattern = BAD_URDF["missing-parent-link"]
    p = tmp_path / "bad.urdf"
    p.write_text(xml)
    with pytest.raises(ValueError, match=pattern):
        rbdkit.Model.from_urdf(p)


def test_good_urdf_loads_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = rbdkit.Model.from_urdf_string(GOOD)
    assert (m.nq, m.nv, m.nb) == (2, 2, 2)


def test_non_psd_inertia():
    # ixx = iyy = izz = 0.1 with ixy = 0.5: each moment >= 0, but eigenvalue 0.1 - 0.5 < 0
    xml = robot(link("a"), link("b", ixy=0.5), joint("j1", "a", "b"))
    with pytest.raises(ValueError, match=r"^URDF: link 'b' has a rotational inertia .*not positive semi-definite"):
        rbdkit.Model.from_urdf_string(xml, strict=True)
    with pytest.warns(UserWarning, match=r"link 'b' has a rotational inertia .*not positive semi-definite"):
        m = rbdkit.Model.from_urdf_string(xml)
    assert m.nv == 1


# ------------------------------------------------------------ valid but unusual input


def test_unusual_but_valid_input():
    model = rbdkit.robots.load("iiwa")
    rbd = rbdkit.RBD(model)
    n = model.nv
    rng = np.random.default_rng(3)
    qi = rng.integers(-2, 3, n)
    qdi = rng.integers(-2, 3, n)
    qddi = rng.integers(-2, 3, n)
    tau_f = rbd.inverse_dynamics(qi.astype(float), qdi.astype(float), qddi.astype(float))[0]

    # integer arrays on a fixed-base robot
    assert qi.dtype.kind == "i"
    np.testing.assert_array_equal(rbd.inverse_dynamics(qi, qdi, qddi)[0], tau_f)
    np.testing.assert_array_equal(rbd.crba(qi), rbd.crba(qi.astype(float)))
    np.testing.assert_array_equal(rbd.crba(qi.astype(np.int32)), rbd.crba(qi.astype(float)))
    # lists (of ints and floats), also nested lists for a batch
    np.testing.assert_array_equal(rbd.inverse_dynamics(list(qi), [float(x) for x in qdi], qddi.tolist())[0], tau_f)
    np.testing.assert_array_equal(rbd.inverse_dynamics([qi.tolist()] * 2, qdi, qddi)[0], np.stack([tau_f] * 2))
    # float32 and non-contiguous arrays
    np.testing.assert_allclose(rbd.crba(qi.astype(np.float32)), rbd.crba(qi.astype(float)), rtol=0, atol=0)
    strided = np.zeros((n, 2))
    strided[:, 0] = qi
    np.testing.assert_array_equal(rbd.crba(strided[:, 0]), rbd.crba(qi.astype(float)))

    # f_ext=[] (and ()) mean no external forces
    q, qd, tau = rng.uniform(-1, 1, (3, n))
    np.testing.assert_array_equal(rbd.inverse_dynamics(q, qd, f_ext=[])[0], rbd.inverse_dynamics(q, qd)[0])
    np.testing.assert_array_equal(rbd.inverse_dynamics(q, qd, f_ext=())[0], rbd.inverse_dynamics(q, qd)[0])
    np.testing.assert_array_equal(rbd.aba(q, qd, tau, f_ext=[]), rbd.aba(q, qd, tau))
    np.testing.assert_array_equal(rbd.forward_dynamics(q, qd, tau, f_ext=[]), rbd.forward_dynamics(q, qd, tau))

    # unbatched qd broadcast against a batched q, and the other way round
    Q = rng.uniform(-1, 1, (4, n))
    QD = rng.uniform(-1, 1, (4, n))
    tau_b = rbd.inverse_dynamics(Q, qd)[0]
    assert tau_b.shape == (4, n)
    for k in range(4):
        np.testing.assert_array_equal(tau_b[k], rbd.inverse_dynamics(Q[k], qd)[0])
    tau_b = rbd.inverse_dynamics(q, QD, qddi)[0]
    for k in range(4):
        np.testing.assert_array_equal(tau_b[k], rbd.inverse_dynamics(q, QD[k], qddi)[0])
    # a batch of one keeps its batch axis
    assert rbd.crba(q[None]).shape == (1, n, n)

    # scalar and option variants
    np.testing.assert_array_equal(rbd.generalized_gravity(q, gravity=-9), rbd.generalized_gravity(q, gravity=-9.0))
    np.testing.assert_array_equal(rbd.generalized_gravity(q, gravity=np.float32(-2.5)),
                                  rbd.generalized_gravity(q, gravity=-2.5))
    np.testing.assert_array_equal(rbd.minv(q, output_dense=np.bool_(False)), rbd.minv(q, output_dense=False))
    assert rbdkit.robots.load("IIWA14").nv == n


def test_unusual_but_valid_floating_base_input(rbd, hyq):
    # an integer configuration (the neutral one) on a floating base
    qi = np.zeros(hyq.nq, dtype=int)
    qi[6] = 1
    np.testing.assert_array_equal(rbd.crba(qi), rbd.crba(hyq.neutral()))
    # a quaternion off unit norm by far less than the 1e-6 tolerance, and a negated one
    q = hyq.neutral()
    q[6] = 1 + 1e-9
    rbd.crba(q)
    q[6] = -1
    np.testing.assert_allclose(rbd.crba(q), rbd.crba(hyq.neutral()), rtol=0, atol=1e-12)
