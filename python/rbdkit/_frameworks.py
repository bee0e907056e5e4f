"""What rbdkit.jax and rbdkit.torch share: the algorithms their derivative
rules call, the handle's methods generated from the operation table, and the
matrices of the maps between quaternion coordinates and the tangent space
(rbdkit.jax's module doc), written once for either array module (`xp`:
jax.numpy or torch; both have stack over an axis and the same indexing)."""

import numpy as np

from ._handle import ALGORITHMS, OPERATION_ALGORITHM, Handle as NumpyHandle

# the operations with a derivative rule, and the algorithms their rule calls
DERIVATIVE_ALGORITHMS = {
    "inverse_dynamics": ("inverse_dynamics_gradient", "crba", "f_ext_gradient"),
    "forward_dynamics": ("forward_dynamics_gradient", "f_ext_gradient"),
    "aba": ("forward_dynamics_gradient", "f_ext_gradient"),
    "integrator": ("integrator_gradient",),
    "plant_step": ("integrator_gradient",),
    "crba": ("idsva_so",),
    "minv": ("idsva_so",),
    "com": (),
    "frame_placement": (),
    "frame_jacobian": (),
    "end_effector_pose": (),
    "quadratic_state_cost_tangent": ("configuration",),
    "com_cost": ("com",),
    "momentum_cost": ("ccrba",),
    "ee_pos_cost": ("kinematics",),
    "inverse_dynamics_regressor": ("regressor_gradient",),
}
# the operations of the configuration alone whose rule is configuration_jacobians' (q's tangent only)
CONFIGURATION_RULES = ("crba", "minv", "com", "frame_placement", "frame_jacobian", "end_effector_pose")


def with_derivative_algorithms(algorithms):
    """a handle's algorithm list with those the derivative rules of its operations call (None: all)"""
    if algorithms is None:
        return None
    if isinstance(algorithms, str):
        algorithms = [algorithms]
    extra = [a for alg in list(algorithms) if isinstance(alg, str) and alg in ALGORITHMS
             for op in ALGORITHMS[alg][0] for a in DERIVATIVE_ALGORITHMS.get(op, ())]
    return list(algorithms) + [a for a in extra if a not in algorithms]


def add_operation_methods(cls, call):
    """a method on cls for every operation, named, signed and documented as rbdkit.Handle's; it raises
    for an operation the handle was not built with, else returns getattr(self, call)(op, args, kwargs)"""
    def make(op):
        ref = getattr(NumpyHandle, op)

        def method(self, *args, **kwargs):
            if op not in self.numpy._ops:
                raise ValueError(f"{op}: this handle was not built with it; add '{OPERATION_ALGORITHM[op]}' to "
                                 f"algorithms")
            return getattr(self, call)(op, args, kwargs)

        method.__name__ = method.__qualname__ = op
        method.__signature__ = getattr(ref, "__signature__", None)
        method.__doc__ = ref.__doc__
        return method

    for op in OPERATION_ALGORITHM:
        setattr(cls, op, make(op))


def step_with_forces(op, call, nq):
    """the call of integrator_f_ext_gradient (x⁺, [A | B] and ∂x⁺/∂f_ext) for a call of integrator or
    plant_step (x = [q; qd])"""
    if op == "integrator":
        return call
    c = {k: v for k, v in call.items() if k != "x"}
    c["q"], c["qd"] = call["x"][..., :nq], call["x"][..., nq:]
    return c


def mujoco_coordinates(h, call):
    """whether a call's q, x and tangents are MuJoCo's (output_convention="mujoco" on a model with
    quaternions): quaternions w x y z, ⊕ is mj_integratePos (a free joint's position additive in the
    world, the rotation r ⊗ exp(δθ)); elsewhere both conventions have the same coordinates"""
    return bool(h._quats) and call.get("output_convention", h.output_convention) == "mujoco"


def mujoco_maps(h, output_convention):
    """whether a handle's public tangent maps (to_tangent, from_tangent, tangent_gradient) use MuJoCo's
    coordinates for `output_convention` (None: the handle's)"""
    conv = h.output_convention if output_convention is None else output_convention
    if conv not in ("pinocchio", "mujoco"):
        raise ValueError(f"output_convention: expected 'pinocchio' or 'mujoco', got {conv!r}")
    return mujoco_coordinates(h, {"output_convention": conv})


def quaternion_joints(model):
    """[(kind, q_index, v_index)] of the joints whose coordinates are not their tangent space: free
    joints ("free": position, then a quaternion x y z w) and spherical ones ("spherical")"""
    return [(j["type"], j["q_index"], j["v_index"]) for j in model.joints if j["type"] in ("free", "spherical")]


def one_dof_coordinates(model):
    """(v indices, q indices) of the one-coordinate joints (their coordinate is their tangent)"""
    one = [(j["v_index"], j["q_index"]) for j in model.joints
           if j["type"] not in ("free", "spherical") and j["nv"] == 1]
    return [v for v, _ in one], [q for _, q in one]


def rotation(xp, quat):
    """R (..., 3, 3) of unit quaternions (..., 4) in x y z w order"""
    x, y, z, w = (quat[..., k] for k in range(4))
    return xp.stack([
        xp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        xp.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        xp.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def half_q(xp, quat, w_first=False):
    """½ Q(q) (..., 4, 3): ∂(q ⊗ (δ/2, 1))/∂δ for q = (v, w) in x y z w order: [w I + [v]x; -vᵀ] / 2;
    w_first: q and the rows in MuJoCo's w x y z order ([-vᵀ; w I + [v]x] / 2)"""
    if w_first:
        w, x, y, z = (quat[..., k] for k in range(4))
    else:
        x, y, z, w = (quat[..., k] for k in range(4))
    rows = [xp.stack([w, -z, y], -1), xp.stack([z, w, -x], -1), xp.stack([-y, x, w], -1), xp.stack([-x, -y, -z], -1)]
    return 0.5 * xp.stack(rows[3:] + rows[:3] if w_first else rows, -2)


def on_device_of(a, ref):
    """a on ref's device where ref is a CUDA tensor (a rule's constants, made on the CPU); JAX places its
    arrays itself"""
    return a.to(ref.device) if getattr(ref, "is_cuda", False) else a


def call_keywords(op, names, args, kwargs):
    """a call's positional and keyword arguments as keywords, by the operation's argument names
    (GRAVITY, the reference implementation's spelling, is gravity's alias)"""
    if len(args) > len(names):
        raise TypeError(f"{op}() takes at most {len(names)} arguments ({len(args)} given)")
    kw = dict(zip(names, args))
    if "GRAVITY" in kwargs and "gravity" in names and ("gravity" in kw or "gravity" in kwargs):
        raise TypeError(f"{op}() got both gravity and GRAVITY (its alias); pass one")
    for name, v in kwargs.items():
        if name == "GRAVITY" and "gravity" in names:
            name = "gravity"
        elif name in kw:
            raise TypeError(f"{op}() got multiple values for argument '{name}'")
        kw[name] = v
    return kw


def gravity_alias(op, gravity, GRAVITY, default=-9.81):
    """gravity from a method that takes both spellings (None: not given)"""
    if GRAVITY is None:
        return default if gravity is None else gravity
    if gravity is not None:
        raise TypeError(f"{op}() got both gravity and GRAVITY (its alias); pass one")
    return GRAVITY


# ε_ijk: [w]x = -ε·w, i.e. ([w]x)_ij = -ε_ijk w_k
_LEVI_CIVITA = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _LEVI_CIVITA[_i, _j, _k], _LEVI_CIVITA[_j, _i, _k] = 1.0, -1.0


def configuration_jacobians(xp, h, op, call, values):
    """(outputs, jacobians) of an operation of the configuration alone (CONFIGURATION_RULES) at `call`
    (its keywords): jacobians[o] (..., *shape of output o, nv) = ∂output_o/∂δ along tangent steps
    q ⊕ δ, from rbdkit's analytical derivatives. A rule applies them to a tangent (JVP,
    apply_jacobians) or a cotangent (VJP). values(op, keywords, outputs=-1) -> list of arrays is the
    framework's call.
      crba               ∂M/∂δ: dM_dq of the second-order inverse dynamics (idsva_so)
      minv               -M⁻¹ (∂M/∂δ) M⁻¹ (the upper triangle where the call asks for it)
      com                jacobian_com
      frame_placement    ∂R = R [J_ω δ]x, ∂p = R J_v δ, with J the frame's LOCAL Jacobian
      frame_jacobian     ∂J/∂δ_k = frame_jacobian_dot(q, e_k): one batched call over the nv directions
      end_effector_pose  end_effector_pose_gradient"""
    q = call["q"]
    nv = h.nv
    if op in ("crba", "minv"):
        zero = on_device_of(xp.zeros(tuple(q.shape[:-1]) + (nv,), dtype=q.dtype), q)
        dM = values("idsva_so", {"q": q, "qd": zero, "qdd": zero})[3]  # (..., nv, nv, nv): ∂M_ij/∂δ_k
        if op == "crba":
            return values("crba", {"q": q}), [dM]
        out = values("minv", call)
        Minv = out[0] if call.get("output_dense", True) else values("minv", {"q": q})[0]
        D = -xp.einsum("...ia,...abk,...bj->...ijk", Minv, dM, Minv)
        if not call.get("output_dense", True):  # the output is the upper triangle
            D = D * on_device_of(xp.triu(xp.ones((nv, nv), dtype=q.dtype)), q)[..., None]
        return out, [D]
    if op == "com":
        return values("com", call), values("jacobian_com", {"q": q})
    if op == "frame_placement":
        R, p = values("frame_placement", call)
        J = values("frame_jacobian", dict(call, reference_frame="LOCAL"))[0]
        eps = on_device_of(xp.asarray(_LEVI_CIVITA, dtype=R.dtype), R)
        dR = -xp.einsum("...ia,ajk,...kn->...ijn", R, eps, J[..., 3:, :])
        dp = xp.einsum("...ia,...an->...in", R, J[..., :3, :])
        return [R, p], [dR, dp]
    if op == "frame_jacobian":
        directions = on_device_of(xp.eye(nv, dtype=q.dtype), q)  # (nv, nv): the k-th is e_k
        dJ = values("frame_jacobian_dot", dict(call, q=q[..., None, :], qd=directions))[0]  # (..., k, 6, nv)
        return values("frame_jacobian", call), [xp.moveaxis(dJ, -3, -1)]
    if op == "end_effector_pose":
        return values("end_effector_pose", call), values("end_effector_pose_gradient", call)
    raise KeyError(op)


# the ranks of those operations' outputs (their shapes without the batch axes)
OUTPUT_RANKS = {"crba": (2,), "minv": (2,), "com": (1,), "frame_placement": (2, 1), "frame_jacobian": (2,),
                "end_effector_pose": (2,)}


def apply_jacobians(op, jacobians, dq):
    """[J·dq]: the changes (..., *shape) of op's outputs along the tangent dq (..., nv), for the
    jacobians (..., *shape, nv) of configuration_jacobians (leading axes broadcast)"""
    lead = tuple(dq.shape[:-1])
    return [(J * dq.reshape(lead + (1,) * rank + (dq.shape[-1],))).sum(-1)
            for J, rank in zip(jacobians, OUTPUT_RANKS[op])]


def transpose_jacobians(op, jacobians, cotangents):
    """Σ_o ⟨cotangent_o, J_o⟩ over each output's own axes: the tangent-space cotangent (..., nv) of
    the configuration (None cotangents: outputs not used)"""
    total = None
    for J, ct, rank in zip(jacobians, cotangents, OUTPUT_RANKS[op]):
        if ct is None:
            continue
        g = (J * ct[(...,) + (None,)]).sum(tuple(range(-rank - 1, -1)))
        total = g if total is None else total + g
    return total


# ---- the costs and barriers whose every derivative is a closed form, coordinate by coordinate:
# the quadratics ½ Σ w (x - x_des)² (value, grad, H = diag(w)) and the log barriers
# -mu Σ [log(x - lower) + log(upper - x)] (value, grad, Hdiag), in the coordinates given (ambient)
ELEMENTWISE_RULES = ("quadratic_state_cost", "quadratic_input_cost", "joint_position_barrier",
                     "joint_velocity_barrier", "joint_torque_barrier")


def elementwise_arguments(op):
    """the names of the three arrays of an ELEMENTWISE_RULES operation: (x, x_des, weights) or
    (x, lower, upper)"""
    if op == "quadratic_state_cost":
        return "x", "x_des", "Q"
    if op == "quadratic_input_cost":
        return "u", "u_des", "R"
    return {"joint_position_barrier": "q", "joint_velocity_barrier": "qd", "joint_torque_barrier": "u"}[op], \
        "lower", "upper"


def _barrier_terms(x, lower, upper):
    """a = 1/(x - lower), b = 1/(upper - x): 0 for an infinite bound"""
    return 1 / (x - lower), 1 / (upper - x)


def elementwise_jvp(xp, op, mu, x, a, b, outs, dx, da, db):
    """the changes of (value, grad, H or Hdiag) of an ELEMENTWISE_RULES operation at (x, a, b) (its
    arrays, elementwise_arguments), outs its outputs, along (dx, da, db)"""
    v, g, H = outs
    if op.startswith("quadratic"):
        r, dr = x - a, dx - da
        return ((g * dr).sum(-1) + 0.5 * (r * r * db).sum(-1), b * dr + r * db,
                db[..., :, None] * xp.eye(x.shape[-1], dtype=x.dtype))
    ia, ib = _barrier_terms(x, a, b)
    dv = (g * dx).sum(-1) + mu * (ia * da).sum(-1) - mu * (ib * db).sum(-1)
    dg = H * dx - mu * ia * ia * da - mu * ib * ib * db
    dh = 2 * mu * ((ib ** 3 - ia ** 3) * dx + ia ** 3 * da - ib ** 3 * db)
    return dv, dg, dh


def elementwise_vjp(xp, op, mu, x, a, b, outs, cv, cg, ch):
    """the cotangents of (x, a, b) of an ELEMENTWISE_RULES operation from those of its outputs
    (value, grad, H or Hdiag; None: not used): elementwise_jvp transposed"""
    v, g, H = outs
    zero = xp.zeros_like(x)
    cv = zero[..., 0] if cv is None else cv
    cg = zero if cg is None else cg
    if op.startswith("quadratic"):
        r = x - a
        gx = cv[..., None] * g + b * cg
        gb = 0.5 * cv[..., None] * r * r + r * cg
        if ch is not None:
            gb = gb + xp.diagonal(ch, 0, -2, -1)
        return gx, -gx, gb
    ch = zero if ch is None else ch
    ia, ib = _barrier_terms(x, a, b)
    c = cv[..., None]
    gx = c * g + cg * H + 2 * mu * (ib ** 3 - ia ** 3) * ch
    ga = mu * (c * ia - cg * ia * ia + 2 * ch * ia ** 3)
    gb = -mu * (c * ib + cg * ib * ib + 2 * ch * ib ** 3)
    return gx, ga, gb


# ---- the Gauss–Newton costs: their value is differentiable with respect to every array (its own grad
# for the state, closed forms for the targets and weights); their grad and H are values (H drops the
# residual's curvature, so H·δ is not the change of grad)
GAUSS_NEWTON_RULES = ("quadratic_state_cost_tangent", "com_cost", "momentum_cost", "ee_pos_cost")


def gauss_newton_value_vjp(xp, h, op, call, outs, cv, values, pinv_t):
    """{array name: cotangent} of a GAUSS_NEWTON_RULES cost's arrays from its value's cotangent cv (...,),
    outs its outputs (value, grad, H). values(op, keywords) -> list of arrays is the framework's call;
    pinv_t(q, g) maps a tangent-space cotangent at q to the coordinates (E⁺ᵀ g)."""
    _, g, _ = outs
    c = cv[..., None]
    nq, nv = h.nq, h.nv
    if op == "quadratic_state_cost_tangent":  # ½ eᵀ diag(Q) e, e = [q ⊖ q_des; qd - qd_des]
        x, x_des, Q = call["x"], call["x_des"], call["Q"]
        q, q_des = x[..., :nq], x_des[..., :nq]
        e = xp.concatenate([values("difference", {"q0": q_des, "q1": q})[0], x[..., nq:] - x_des[..., nq:]], -1)
        Qe = Q * e
        D_from = values("dDifference", {"q0": q_des, "q1": q, "with_respect_to": "from"})[0]
        g_des = xp.einsum("...ji,...j->...i", D_from, Qe[..., :nv])  # ∂value/∂δq_des
        return {"x": xp.concatenate([pinv_t(q, c * g[..., :nv]), c * g[..., nv:]], -1),
                "x_des": xp.concatenate([pinv_t(q_des, c * g_des), -c * Qe[..., nv:]], -1),
                "Q": 0.5 * c * e * e}
    q, W = call["q"], call["W"]
    if op == "momentum_cost":  # ½ Σ W r², r = A(q) qd - h_des
        r = values("centroidal_momentum", {"q": q, "qd": call["qd"]})[0] - call["h_des"]
        return {"q": pinv_t(q, c * g[..., :nv]), "qd": c * g[..., nv:], "h_des": -c * W * r, "W": 0.5 * c * r * r}
    if op == "com_cost":  # ½ Σ W r², r = com(q) - p_des
        r = values("com", {"q": q})[0] - call["p_des"]
    else:  # ee_pos_cost: r = p_ee(q) - p_des, p_ee the end effector's tool point
        name, offset = call.get("ee_joint_name"), call.get("ee_offset")
        if name is None:  # the first of the default end effectors (every leaf): the offset given to each
            n_ee = values("end_effector_pose", {"q": q})[0].shape[-2]
            ee = {"ee_offsets": None if offset is None else
                  offset[..., None, :] * on_device_of(xp.ones((n_ee, 1), dtype=q.dtype), q)}
        else:
            ee = {"ee_joint_names": [name], "ee_offsets": None if offset is None else offset[..., None, :]}
        r = values("end_effector_pose", dict(ee, q=q))[0][..., 0, :3] - call["p_des"]
    return {"q": pinv_t(q, c * g[..., :nv]), "p_des": -c * W * r, "W": 0.5 * c * r * r}


# ---- the inverse-dynamics regressor Y (nv, 10·nb), τ = Y(q, qd, qdd) π: its derivatives, and the
# inverse dynamics with the inertial parameters π as an array (a differentiable input)

def regressor_jacobians(xp, h, call, values, wanted):
    """{name: J (..., nv, 10·nb, n)} for the arrays `wanted` of inverse_dynamics_regressor at `call`
    (keywords): J_q along tangent steps q ⊕ δ and J_qd, slices of inverse_dynamics_regressor_gradient
    (dY[c] = ∂Y/∂x_c, x = [δ; qd]); J_qdd[..., k] = Y(q, 0, e_k, gravity=0), as Y is linear in qdd
    (one batched call over the nv directions). values(op, keywords) -> list of arrays is the
    framework's call."""
    q, nv = call["q"], h.nv
    J = {}
    if wanted & {"q", "qd"}:
        dY = xp.moveaxis(values("inverse_dynamics_regressor_gradient", call)[0], -3, -1)  # (..., nv, 10nb, 2nv)
        J["q"], J["qd"] = dY[..., :nv], dY[..., nv:]
    if "qdd" in wanted:
        directions = on_device_of(xp.eye(nv, dtype=q.dtype), q)
        zero = on_device_of(xp.zeros((nv,), dtype=q.dtype), q)
        Ya = values("inverse_dynamics_regressor", {"q": q[..., None, :], "qd": zero, "qdd": directions,
                                                   "gravity": 0.0})[0]  # (..., k, nv, 10nb)
        J["qdd"] = xp.moveaxis(Ya, -3, -1)
    return J


def inverse_dynamics_with_parameters(xp, h, q, qd, qdd, pi, gravity, regressor):
    """τ = Y(q, qd, qdd) π (..., nv) for inertial parameters pi (..., 10·nb) in
    Model.inertial_parameters' layout; regressor(q, qd, qdd, gravity) is the framework handle's
    inverse_dynamics_regressor (differentiable in q, qd, qdd)"""
    n = 10 * h.nb
    if tuple(pi.shape[-1:]) != (n,):
        raise ValueError(f"pi: expected shape (..., {n}) with 10*nb={n} (Model.inertial_parameters' layout), got "
                         f"{tuple(pi.shape)}")
    return xp.einsum("...ij,...j->...i", regressor(q, qd, qdd, gravity), pi)
