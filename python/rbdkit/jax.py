"""rbdkit.jax: the operations of rbdkit.Handle as JAX functions, under jit,
vmap and automatic differentiation, computed by rbdkit's C++ batch engine
through an XLA FFI custom call (no host callback, no copy), or on a GPU by
its CUDA kernels.

    import rbdkit, rbdkit.jax
    h = rbdkit.jax.Handle(rbdkit.robots.load("iiwa"))
    tau = jax.jit(h.inverse_dynamics)(q, qd, qdd)           # q (..., nq), qd, qdd (..., nv)
    g = jax.grad(lambda q: h.forward_dynamics(q, qd, u).sum())(q)   # rbdkit's analytical gradient

Methods are named, ordered and checked as rbdkit.Handle's (one C++ layout of
each call, OpHandle.plan), and accept any leading batch shape: arrays are
broadcast against each other on their leading axes, and every sample is one
knot point of the engine. Parameters (gravity, dt, integrator_type, ...) are
Python values, fixed at trace time; arrays may be traced.

Derivatives. The operations below have a `jax.custom_jvp` rule built on
rbdkit's analytical derivatives, not on tracing or finite differences; JAX
transposes it for reverse mode, so jvp, grad, jacfwd and jacrev all work:

    inverse_dynamics        ∂τ/∂q, ∂τ/∂qd (inverse_dynamics_gradient, where q or qd has a tangent),
                            ∂τ/∂qdd = M (crba),
                            ∂τ/∂f_ext = -J_bᵀ per body (f_ext_gradient; f_ext in body frames)
    forward_dynamics, aba   ∂qdd/∂q, ∂qdd/∂qd and ∂qdd/∂u = M⁻¹ (forward_dynamics_gradient, one
                            call; M⁻¹ alone, minv, when only u has a tangent), ∂qdd/∂f_ext = M⁻¹ J_bᵀ
                            (f_ext_gradient)
    integrator, plant_step  [A | B] = ∂x⁺/∂(x, u) (integrator_gradient / plant_step_gradient), every scheme;
                            ∂x⁺/∂f_ext (integrator_f_ext_gradient)
    crba, minv              ∂M/∂q (idsva_so's dM_dq); ∂M⁻¹ = -M⁻¹ ∂M M⁻¹
    com                     jacobian_com
    frame_placement         ∂R = R [J_ω δ]x, ∂p = R J_v δ from the frame's LOCAL Jacobian
    frame_jacobian          ∂J/∂q from frame_jacobian_dot (dJ/dt along each tangent direction)
    end_effector_pose       end_effector_pose_gradient
(those five with respect to q only; their other arrays are constants),
    inverse_dynamics_regressor
                            ∂Y/∂q, ∂Y/∂qd (inverse_dynamics_regressor_gradient); ∂Y/∂qdd from Y
                            itself (linear in qdd),
    quadratic_state_cost, quadratic_input_cost, joint_position_barrier,
    joint_velocity_barrier, joint_torque_barrier
                            value, grad and H (or Hdiag) with respect to every array: closed forms
                            coordinate by coordinate (the costs' own grad and H, then the rest), and
    quadratic_state_cost_tangent, com_cost, momentum_cost, ee_pos_cost
                            the value with respect to every array (ee_offset excepted), in reverse
                            mode (a jax.custom_vjp): the cost's own gradient for the state, closed
                            forms for the targets and weights; their grad and H (Gauss–Newton) are
                            values, and a gradient through them raises

Every other operation computes values only; differentiating through one
raises an error that names it.

Inertial parameters. A handle's model is fixed, but the inverse dynamics is
linear in the inertial parameters: τ = Y(q, qd, qdd) π, with Y the
regressor and π (10·nb: per body m, m·c, I about the body origin; see
Model.inertial_parameters) the parameters. So
Handle.inverse_dynamics_with_parameters(q, qd, qdd, pi) takes π as an array,
traced and differentiable like any other: ∂τ/∂π = Y, and ∂τ/∂(q, qd, qdd)
through the regressor's rule. Any map onto π (a physically consistent
parametrisation, a log-Cholesky factor of each body's pseudo-inertia) is
differentiated by JAX on top. examples/jax_sysid.py identifies a robot's
parameters this way.

Several devices. Every sample is independent, so a batch sharded over a
mesh on its batch axes is computed shard by shard where it lives, under
plain jit (each call is partitionable over its batch axes: a
custom_partitioning rule keeps the inputs' batch sharding and replicates
the per-sample axes) or under jax.shard_map; values and gradients equal
the unsharded call's:

    qs, qds, us = (jax.device_put(a, NamedSharding(mesh, P("batch"))) for a in (q, qd, u))
    qdd = jax.jit(h.forward_dynamics)(qs, qds, us)          # each device its own samples
    fd = jax.shard_map(h.forward_dynamics, mesh=mesh, in_specs=P("batch"), out_specs=P("batch"))

GPUs. Handle(model, backend="cuda") runs the calls on the CUDA backend. On
JAX's GPU platform (jax with CUDA, arrays on a GPU) the custom call reads and
writes XLA's device buffers in place, on XLA's stream: no copy to the host,
one launch per call. The handle's CUDA engine lives on the device that was
current when it was made (device 0 unless changed); arrays on another GPU
are an error that says so. Arrays on JAX's CPU platform, given to a cuda
handle, are copied to its device and back. backend=None (the default)
chooses "cuda" when JAX's default backend is a GPU and this rbdkit build has
the real kernels, else "cpu". In such a build, a cpu handle (or one in
interpret mode) given GPU arrays raises an error that says what it needs.

Floating bases and spherical joints (quaternion coordinates). rbdkit's
derivatives live in the tangent space: δq is a velocity-like vector of nv
values, q' = q ⊕ δq (rbdkit.RBD.integrate). JAX differentiates with respect
to the nq coordinates. The two are related by E(q) = ∂(q ⊕ δ)/∂δ at δ = 0
(nq x nv): a coordinate tangent dq maps to the tangent-space δ = E⁺ dq (E⁺ =
(EᵀE)⁻¹Eᵀ, the pseudo-inverse), and a tangent-space output change δ to the
coordinates as E δ. For a free joint [p; x y z w] with its twist in the body
frame, E = diag(R, ½ Q(q)) with R the body's rotation and Q(q) the 4 x 3
matrix of q ⊗ (δ/2, 0); for a spherical joint, ½ Q(q). So the gradient JAX
returns for q (a cotangent on the coordinates) is E⁺ᵀ g = E (EᵀE)⁻¹ g for
the tangent-space gradient g: it has no component along q's quaternion (a
change of its norm, which the model ignores), and Eᵀ of it is g again. With
unit quaternions, EᵀE = diag(I, ¼ I), so the quaternion block of the
coordinate gradient is 2 Q(q) g_ω: the tangent gradient is recovered as
g = Eᵀ (JAX's gradient), `Handle.tangent_gradient` below.

MuJoCo's coordinates (output_convention="mujoco": quaternions w x y z, a
free joint's linear velocity in the world). integrator and plant_step
differentiate there too, with [A | B] along MuJoCo's retraction
(mj_integratePos: a free joint's position additive in the world, rotations
r ⊗ exp(δθ)): E is then the identity on a free joint's position and ½ Q(q)
in w x y z order on each quaternion, and to_tangent, from_tangent and
tangent_gradient take output_convention="mujoco" for those maps. The
Gauss–Newton costs' derivatives are Pinocchio-convention only (they raise).
"""

import atexit

import numpy as np

try:
    import jax
    import jax.numpy as jnp
    from jax.custom_batching import custom_vmap
    from jax.experimental.custom_partitioning import custom_partitioning
except ImportError as e:  # an optional dependency
    raise ImportError("rbdkit.jax needs JAX: pip install 'jax[cpu]' (or a CUDA build of jax), then import "
                      "rbdkit.jax again") from e

from . import _core
from ._frameworks import (CONFIGURATION_RULES, ELEMENTWISE_RULES, GAUSS_NEWTON_RULES, add_operation_methods,
                          apply_jacobians, call_keywords, configuration_jacobians,
                          elementwise_arguments, elementwise_jvp, gauss_newton_value_vjp, gravity_alias, half_q,
                          inverse_dynamics_with_parameters, mujoco_coordinates, mujoco_maps, one_dof_coordinates,
                          quaternion_joints, regressor_jacobians, rotation, step_with_forces,
                          with_derivative_algorithms)
from ._handle import Handle as _NumpyHandle, cuda_available

_TARGET = "rbdkit_op"
# every handle made, for the life of the process: a compiled XLA call holds the C++ handle's address,
# and may run after the Python handle is gone (a jitted function traced with it, a call dispatched
# asynchronously); handles are few and long-lived, so none is ever freed
_KEEP = []
atexit.register(_KEEP.clear)  # released at exit, before the extension's teardown
_core.disable_leak_warnings()  # (those handles are kept on purpose)
_SIGNATURES = {name: args for name, _, _, _, args in _core.registered_operations()}
_registered = False


def _register():
    """register the FFI handler with XLA once per process"""
    global _registered
    if _registered:
        return
    handlers = _core.jax_ffi_handlers()
    if handlers is None:
        raise ImportError("rbdkit.jax: this rbdkit build has no XLA FFI handler (JAX was not importable when it "
                          "was built): pip install 'jax[cpu]', then reinstall rbdkit with JAX visible to the build "
                          "(pip install --no-build-isolation ., or ./test.sh)")
    for platform, capsule in handlers.items():
        jax.ffi.register_ffi_target(_TARGET, capsule, platform=platform)  # cpu, and CUDA where built
    _registered = True


def _ffi_call(xs, n_batch, out_shapes, dtype, attributes):
    """the outputs (*batch, shape) of the custom call on xs (each (*batch, its shape)), batch their first
    n_batch axes. Traced with a batch, it is partitionable over the batch axes (custom_partitioning):
    under jit with inputs sharded on their batch axes, each device computes its own samples, the
    trailing axes replicated; on one device or inside jax.shard_map it lowers to the plain call.
    custom_partitioning has no vmap rule, so a custom_vmap gives it one: a vmapped call is the same
    call on a batch with one more axis. Concrete arrays take the plain call (an eager dispatch is
    cached by its attributes)."""
    batch = tuple(xs[0].shape[:n_batch]) if xs else ()
    if n_batch == 0 or not any(isinstance(x, jax.core.Tracer) for x in xs):
        results = [jax.ShapeDtypeStruct(batch + s, dtype) for s in out_shapes]
        return list(jax.ffi.ffi_call(_TARGET, results, vmap_method="broadcast_all")(*xs, **attributes))
    ranks = [x.ndim - n_batch for x in xs]

    def plain(*args):  # on local (per-device) shapes inside partition
        local = tuple(args[0].shape[:n_batch])
        results = [jax.ShapeDtypeStruct(local + s, dtype) for s in out_shapes]
        return tuple(jax.ffi.ffi_call(_TARGET, results, vmap_method="broadcast_all")(*args, **attributes))

    def shardings(mesh, arg_shapes):  # the batch axes' sharding of the first input sharded there, the rest replicated
        spec = (None,) * n_batch  # (none sharded, or shardings without a mesh: replicated)
        for shape in arg_shapes:
            sharding = shape.sharding
            if isinstance(sharding, jax.sharding.NamedSharding) and any(tuple(sharding.spec)[:n_batch]):
                mesh, spec = sharding.mesh, tuple(sharding.spec) + (None,) * n_batch
                break
        P = jax.sharding.PartitionSpec
        named = lambda r: jax.sharding.NamedSharding(mesh, P(*spec[:n_batch], *(None,) * r))  # noqa: E731
        return mesh, tuple(named(r) for r in ranks), tuple(named(len(s)) for s in out_shapes)

    def partition(mesh, arg_shapes, result_shape):
        mesh, args, results = shardings(mesh, arg_shapes)
        return mesh, plain, results, args

    def infer(mesh, arg_shapes, result_shape):
        return shardings(mesh, arg_shapes)[2]

    b = " ".join(f"b{i}" for i in range(n_batch))
    trailing = lambda prefix, r: " ".join(f"{prefix}_{j}" for j in range(r))  # noqa: E731
    rule = ", ".join(f"{b} {trailing(f'i{k}', r)}" for k, r in enumerate(ranks)) + " -> " + \
        ", ".join(f"{b} {trailing(f'o{k}', len(s))}" for k, s in enumerate(out_shapes))
    replicated = tuple(f"i{k}_{j}" for k, r in enumerate(ranks) for j in range(r)) + \
        tuple(f"o{k}_{j}" for k, s in enumerate(out_shapes) for j in range(len(s)))
    partitioned = custom_partitioning(plain)
    partitioned.def_partition(partition, infer_sharding_from_operands=infer, sharding_rule=rule,
                              need_replication_factors=replicated)

    @custom_vmap
    def call(*args):
        return partitioned(*args)

    @call.def_vmap
    def call_vmapped(axis_size, in_batched, *args):
        args = [a if batched else jnp.broadcast_to(a, (axis_size,) + a.shape) for a, batched in zip(args, in_batched)]
        return tuple(_ffi_call(args, n_batch + 1, out_shapes, dtype, attributes)), (True,) * len(out_shapes)

    return list(call(*xs))


def _vary_like(outs, refs):
    """outs, varying over the mesh axes any of refs varies over (inside shard_map: the FFI call does
    not say so itself, and a derivative rule's primal and tangent types must agree)"""
    vma = frozenset().union(*[_varying(r) for r in refs])
    if not vma:
        return list(outs)
    return [jax.lax.pcast(o, tuple(sorted(vma - _varying(o))), to="varying") if vma - _varying(o) else o
            for o in outs]


def _varying(x):
    """the mesh axes x varies over inside shard_map (the attribute's name depends on JAX's version)"""
    t = jax.typeof(x)
    if hasattr(t, "vma"):
        return frozenset(t.vma)
    mat = getattr(t, "manual_axis_type", None)
    return frozenset(getattr(mat, "varying", ()) or ())


def _check_x64(dtype):
    if dtype == np.float64 and not jax.config.jax_enable_x64:
        raise ValueError("dtype: a float64 handle needs JAX's 64-bit mode (jax.config.update('jax_enable_x64', "
                         "True) before creating arrays), or use dtype='float32'")


def _default_backend():
    """"cuda" where JAX computes on a GPU and this build has the real kernels, else "cpu" """
    compiled, devices = cuda_available()
    return "cuda" if compiled and devices > 0 and jax.default_backend() == "gpu" else "cpu"


class Handle:
    """A robot's operations as JAX functions (module doc). Attributes: model,
    numpy (the rbdkit.Handle that runs the calls), dtype, nq, nv, nb, backend
    ("cpu": the batch engine; "cuda": the CUDA kernels, on XLA's GPU buffers
    in place; None chooses, module doc "GPUs")."""

    def __init__(self, model, algorithms=None, dtype="float64", threads=None, output_convention="pinocchio",
                 backend=None):
        _register()
        if backend is None:
            backend = _default_backend()
        self.numpy = _NumpyHandle(model, with_derivative_algorithms(algorithms), backend, dtype, threads,
                                  output_convention)
        self.backend = self.numpy.backend
        _check_x64(self.numpy.dtype)
        self.model = self.numpy.model
        self.dtype = self.numpy.dtype
        self.nq, self.nv, self.nb = self.model.nq, self.model.nv, self.model.nb
        self.output_convention = self.numpy.output_convention
        self._core = self.numpy._core
        self._address = np.int64(self._core.address)
        _KEEP.append(self.numpy)
        self._quats = quaternion_joints(self.model)
        self._vi, self._qi = (np.array(i, int) for i in one_dof_coordinates(self.model))

    # ---- what the handle has
    def available_operations(self):
        return self.numpy.available_operations()

    def has(self, name):
        return self.numpy.has(name)

    # ---- one call of an operation: its values, no derivative rule
    def _values(self, op, args, kwargs, outputs=-1):
        """the results of `op` (rbdkit.Handle's; `outputs`: a mask of the operation's outputs instead)"""
        _check_x64(self.dtype)
        op_id, arrays, reals, choices, ee, outs = self._core.plan(op, tuple(args), dict(kwargs), outputs)
        xs = []
        for k, a, shape in arrays:
            x = jnp.asarray(a)
            name = _signature(op)[k][0]
            if not (jnp.issubdtype(x.dtype, jnp.floating) or jnp.issubdtype(x.dtype, jnp.integer)):
                raise TypeError(f"{name}: expected a real array, got dtype {x.dtype}")
            x = x.astype(self.dtype)
            n = len(shape)
            if x.ndim < n or tuple(x.shape[x.ndim - n:]) != tuple(shape):
                raise ValueError(f"{name}: expected shape (..., {', '.join(map(str, shape))}) (any leading batch "
                                 f"axes), got {tuple(x.shape)}")
            xs.append(x)
        batch = jnp.broadcast_shapes(*[x.shape[:x.ndim - len(s)] for x, (_, _, s) in zip(xs, arrays)]) if xs else ()
        xs = [jnp.broadcast_to(x, batch + tuple(s)) for x, (_, _, s) in zip(xs, arrays)]
        attributes = dict(handle=self._address, op=np.int64(op_id), slots=np.array([k for k, _, _ in arrays], np.int64),
                          outputs=np.array([o for o, _ in outs], np.int64), reals=np.array(reals, np.float64),
                          choices=np.array(choices, np.int64), ee=np.array(ee, np.int64))
        out = _vary_like(_ffi_call(xs, len(batch), [tuple(s) for _, s in outs], self.dtype, attributes), xs)
        return out[0] if len(out) == 1 else tuple(out)

    def _value_list(self, op, kwargs, outputs=-1):
        """_values of a call given as keywords, as a list (the derivative rules' calls)"""
        r = self._values(op, (), kwargs, outputs)
        return list(r) if isinstance(r, tuple) else [r]

    def _call(self, op, args, kwargs):
        if op in GAUSS_NEWTON_RULES:
            return _custom_vjp_call(self, op, args, kwargs)
        return _custom_call(self, op, args, kwargs, _RULES.get(op, _no_derivative))

    # ---- the inertial parameters as an array
    def inverse_dynamics_with_parameters(self, q, qd, qdd, pi, gravity=None, *, GRAVITY=None):
        """τ = Y(q, qd, qdd) π (..., nv): the inverse dynamics with the inertial parameters pi (..., 10·nb,
        Model.inertial_parameters' layout) as an array, differentiable in pi (∂τ/∂π = Y) and in q, qd,
        qdd (the regressor's rule); no f_ext. At pi = model.inertial_parameters() it is
        inverse_dynamics(q, qd, qdd)[0] (module doc, "Inertial parameters")."""
        return inverse_dynamics_with_parameters(jnp, self, q, qd, qdd, jnp.asarray(pi),
                                                gravity_alias("inverse_dynamics_with_parameters", gravity,
                                                              GRAVITY), self.inverse_dynamics_regressor)

    # ---- the coordinates and the tangent space (module doc)
    # (output_convention: None for the handle's; "mujoco": MuJoCo's coordinates and mj_integratePos)
    def to_tangent(self, q, dq, output_convention=None):
        """E⁺(q) dq: a change dq (..., nq) of the coordinates at q as a tangent-space vector (..., nv)"""
        return _tangent_map(self, q, dq, "to_tangent", mujoco_maps(self, output_convention))

    def from_tangent(self, q, dv, output_convention=None):
        """E(q) dv: a tangent-space vector dv (..., nv) at q as a change of the coordinates (..., nq)"""
        return _tangent_map(self, q, dv, "from_tangent", mujoco_maps(self, output_convention))

    def tangent_gradient(self, q, grad_q, output_convention=None):
        """Eᵀ(q) grad_q: the tangent-space gradient (..., nv) from JAX's gradient with respect to the
        coordinates q (..., nq)"""
        return _tangent_map(self, q, grad_q, "transpose", mujoco_maps(self, output_convention))

    def __repr__(self):
        return f"<rbdkit.jax.Handle of {self.model!r}: dtype={self.dtype.name}>"


add_operation_methods(Handle, "_call")


# ---------------------------------------------------------------- a call's arrays
# The arrays of a call are the differentiable inputs of its custom_jvp
# function, by position; the rest of the call (its parameters) is closed over.

def _signature(op):
    """[(argument, kind, default)] of a registered operation"""
    return _SIGNATURES[op]


def _bind(h, op, args, kwargs):
    """the call as keywords, and the names of its array arguments present (argument order)"""
    sig = [a[0] for a in _signature(op)]
    kw = call_keywords(op, sig, args, kwargs)
    _, arrays, _, _, _, _ = h._core.plan(op, (), kw)
    return kw, [sig[k] for k, _, _ in arrays]


def _with(kw, names, arrays):
    kw = dict(kw)
    kw.update(zip(names, arrays))
    return kw


def _custom_call(h, op, args, kwargs, jvp_rule):
    """op's values as a jax.custom_jvp function of the call's arrays (its parameters closed over);
    jvp_rule(h, op, call, names, tangents) -> (out, dout): call is the whole call as keywords at the
    primals, names the arrays' names, tangents theirs (symbolic zeros where not differentiated)"""
    kw, names = _bind(h, op, args, kwargs)

    @jax.custom_jvp
    def f(*arrays):
        return h._values(op, (), _with(kw, names, arrays))

    def rule(primals, tangents):
        out, dout = jvp_rule(h, op, _with(kw, names, primals), names, tangents)
        # the tangents in the outputs' dtype (a float32 handle's inputs may be float64 in 64-bit mode)
        return out, jax.tree.map(lambda d, o: d.astype(o.dtype), dout, out)

    f.defjvp(rule, symbolic_zeros=True)
    return f(*[jnp.asarray(kw[n]) for n in names])


def _custom_vjp_call(h, op, args, kwargs):
    """a Gauss–Newton cost (GAUSS_NEWTON_RULES) as a jax.custom_vjp function of its arrays: reverse mode
    through its value (_gauss_newton_vjp); its grad and H are values, so a cotangent on them raises
    (the symbolic zeros tell which outputs were used)"""
    kw, names = _bind(h, op, args, kwargs)
    perturbed = {}  # which arrays are differentiated (known when fwd is traced)

    @jax.custom_vjp
    def f(*arrays):
        return h._values(op, (), _with(kw, names, arrays))

    def fwd(*primals):  # CustomVJPPrimal: value, and whether it is differentiated
        arrays = tuple(p.value for p in primals)
        perturbed.update({n: p.perturbed for n, p in zip(names, primals)})
        out = h._values(op, (), _with(kw, names, arrays))
        return out, (arrays, out)

    def bwd(res, cotangents):
        arrays, out = res
        return _gauss_newton_vjp(h, op, _with(kw, names, arrays), names, perturbed, arrays, out, cotangents)

    f.defvjp(fwd, bwd, symbolic_zeros=True)
    return f(*[jnp.asarray(kw[n]) for n in names])


def _gauss_newton_vjp(h, op, call, names, perturbed, arrays, out, cotangents):
    """the arrays' cotangents of a Gauss–Newton cost from its value's (_frameworks.gauss_newton_value_vjp)"""
    if not all(_zero(c) for c in cotangents[1:]):
        raise NotImplementedError(f"rbdkit.jax: {op}'s grad and H outputs are values (H is the Gauss–Newton "
                                  f"approximation); differentiate its value")
    _check_convention(h, op, call)
    if perturbed.get("ee_offset"):
        raise NotImplementedError("rbdkit.jax: ee_pos_cost is not differentiable with respect to ee_offset; treat "
                                  "it as a constant (jax.lax.stop_gradient)")
    if _zero(cotangents[0]):
        return (None,) * len(arrays)
    cast = {n: jnp.asarray(a, h.dtype) for n, a in zip(names, arrays)}
    g = gauss_newton_value_vjp(jnp, h, op, dict(call, **cast), list(out), cotangents[0], h._value_list,
                               lambda q, t: _tangent_map(h, q, t, "pinv_t"))
    return tuple(_sum_to(g[n], jnp.shape(a)).astype(jnp.result_type(a)) if n in g and perturbed.get(n) else None
                 for n, a in zip(names, arrays))


def _sum_to(g, shape):
    """g summed over the axes a broadcast added to an array of `shape` (the array's cotangent)"""
    g = g.sum(tuple(range(g.ndim - len(shape)))) if g.ndim > len(shape) else g
    axes = tuple(k for k, (a, b) in enumerate(zip(g.shape, shape)) if b == 1 and a != 1)
    return g.sum(axes, keepdims=True) if axes else g


def _no_derivative(h, op, call, names, tangents):
    """the rule of an operation that computes values only"""
    raise NotImplementedError(f"rbdkit.jax: {op} computes values only (it has no derivative rule); the "
                              f"differentiable operations are {', '.join(sorted(_RULES))}")


# ---------------------------------------------------------------- the coordinates' tangent maps

def _assemble(pieces, n, batch, dtype):
    """the vector (..., n) whose entries `idx` are `values` (..., len(idx)) for each (idx, values) of
    pieces: a concatenation and a fixed permutation (a gather, which JAX can transpose; entries no
    piece names are 0)"""
    idx = [i for ix, _ in pieces for i in ix]
    missing = [i for i in range(n) if i not in set(idx)]
    vals = [jnp.broadcast_to(v, batch + (len(ix),)) for ix, v in pieces]
    if missing:
        vals.append(jnp.zeros(batch + (len(missing),), dtype))
        idx += missing
    if not vals:
        return jnp.zeros(batch + (n,), dtype)
    return jnp.take(jnp.concatenate(vals, -1), np.argsort(np.array(idx)), axis=-1)


def _tangent_map(h, q, x, kind, mujoco=False):
    """the linear maps of the coordinates at q (module doc), applied to x over leading axes:
    "to_tangent" E⁺ x (x: nq -> nv), "from_tangent" E x (nv -> nq), "transpose" Eᵀ x (nq -> nv),
    "pinv_t" E⁺ᵀ x (nv -> nq: a tangent-space cotangent on the coordinates). mujoco: MuJoCo's
    coordinates and ⊕ (a free joint's position block is the identity, quaternions w x y z)"""
    q, x = jnp.asarray(q), jnp.asarray(x)
    batch = jnp.broadcast_shapes(q.shape[:-1], x.shape[:-1])
    dtype = jnp.result_type(q, x)
    to_q = kind in ("from_tangent", "pinv_t")
    vi, qi = h._vi, h._qi
    pieces = [(list(qi if to_q else vi), x[..., vi if to_q else qi])] if len(vi) else []
    T = lambda A, y: jnp.einsum("...ji,...j->...i", A, y)  # Aᵀ y
    N = lambda A, y: jnp.einsum("...ij,...j->...i", A, y)  # A y
    rot_scale = {"to_tangent": 4.0, "from_tangent": 1.0, "transpose": 1.0, "pinv_t": 4.0}[kind]
    for joint, iq, iv in h._quats:
        qq = iq + 3 if joint == "free" else iq  # the quaternion's first coordinate
        Q = half_q(jnp, q[..., qq:qq + 4], w_first=mujoco)
        if joint == "free" and mujoco:  # the position, additive in the world: E = I
            src, dst = (range(iv, iv + 3), range(iq, iq + 3)) if to_q else (range(iq, iq + 3), range(iv, iv + 3))
            pieces.append((list(dst), x[..., src.start:src.stop]))
        elif joint == "free":  # the position: E = R, E⁺ = Eᵀ = Rᵀ
            R = rotation(jnp, q[..., qq:qq + 4])
            if to_q:
                pieces.append((list(range(iq, iq + 3)), N(R, x[..., iv:iv + 3])))
            else:
                pieces.append((list(range(iv, iv + 3)), T(R, x[..., iq:iq + 3])))
        ivr = iv + 3 if joint == "free" else iv  # the rotation's first tangent index
        if to_q:  # E: ½Q; E⁺ᵀ = 4 (½Q) for a unit quaternion
            pieces.append((list(range(qq, qq + 4)), rot_scale * N(Q, x[..., ivr:ivr + 3])))
        else:  # E⁺ = (QᵀQ/4)⁻¹ Qᵀ/2 = 4 (Q/2)ᵀ for a unit quaternion
            pieces.append((list(range(ivr, ivr + 3)), rot_scale * T(Q, x[..., qq:qq + 4])))
    return _assemble(pieces, h.nq if to_q else h.nv, batch, dtype)


def _to_tangent(h, q, dq):
    """E⁺ dq (module doc)"""
    return _tangent_map(h, q, dq, "to_tangent")


# ---------------------------------------------------------------- derivative rules (custom_jvp)

def _mv(A, x):
    """A @ x over leading batch axes: A (..., m, n), x (..., n)"""
    return jnp.einsum("...ij,...j->...i", A, x)


def _zero(t):
    return isinstance(t, jax.custom_derivatives.SymbolicZero)


def _sharded_constant(x):
    """whether x is a concrete array (not a tracer) laid out over several devices"""
    return isinstance(x, jax.Array) and not isinstance(x, jax.core.Tracer) and len(x.sharding.device_set) > 1


def _dense(t, p):
    """a tangent as an array (a symbolic zero for an input JAX does not differentiate)"""
    return jnp.zeros(jnp.shape(p), jnp.result_type(p)) if _zero(t) else t


def _check_convention(h, op, call):
    """the derivative rules work in Pinocchio's coordinates; MuJoCo's differ where a model has
    quaternions (their order, the free joint's velocity frame)"""
    if h._quats and call.get("output_convention", h.output_convention) == "mujoco":
        raise NotImplementedError(f"rbdkit.jax: {op}'s derivative in MuJoCo's output convention on a model with "
                                  f"free-flyer or spherical joints is not available; differentiate in the "
                                  f"Pinocchio convention (output_convention='pinocchio')")


def _only(kw, op):
    """the arguments of the call `kw` that operation `op` takes"""
    names = {a[0] for a in _signature(op)}
    return {k: v for k, v in kw.items() if k in names}


def _dynamics_jvp(h, op, call, names, tangents):
    """inverse_dynamics (q, qd, qdd -> tau) and forward_dynamics / aba (q, qd, u -> qdd), f_ext included
    (f_ext_gradient: ∂τ/∂f_b = -J_bᵀ, ∂qdd/∂f_b = M⁻¹ J_bᵀ); the first-order derivatives only where q or
    qd has a tangent (else M, or M⁻¹, alone for the third input's)"""
    _check_convention(h, op, call)
    third = "qdd" if op == "inverse_dynamics" else names[2]
    q, qd = call["q"], call["qd"]
    t = dict(zip(names, tangents))
    with_third = third in t and not _zero(t[third])
    # a q held constant on several devices (a sharded array closed over) leaves M⁻¹(q) alone without a
    # sharded operand, so XLA would compute it whole on every device: the gradient call (its u sharded)
    # is partitioned instead. (A replicated q passed to jit with a sharded u still takes M⁻¹ alone, each
    # device then computing it for the whole batch: still less work than the gradient call's share.)
    moving = not (_zero(t["q"]) and _zero(t["qd"])) or (op != "inverse_dynamics" and with_third and
                                                        _sharded_constant(q))
    Dq = Dqd = D3 = None
    if op == "inverse_dynamics":
        out = h._values(op, (), call)
        if moving:
            D = h._values("inverse_dynamics_gradient", (), _only(call, "inverse_dynamics_gradient"))
            Dq, Dqd = D[..., :h.nv], D[..., h.nv:]
        if with_third:
            D3 = h._values("crba", (), {"q": q})  # ∂τ/∂qdd = M
    elif moving:  # one call: ∂qdd/∂q, ∂qdd/∂qd, qdd and ∂qdd/∂u = M⁻¹
        g = _only(call, "forward_dynamics_gradient")
        g["u"] = call[third]
        Dq, Dqd, out, D3 = h._values("forward_dynamics_gradient", (), g, outputs=0b1111)
    else:  # ∂qdd/∂u = M⁻¹ alone
        out = h._values(op, (), call)
        if with_third:
            D3 = h._values("minv", (), {"q": q})
    dout = jnp.zeros_like(out)
    if moving:
        dout = _mv(Dq, _to_tangent(h, q, _dense(t["q"], q))) + _mv(Dqd, _dense(t["qd"], qd))
    if with_third:
        dout = dout + _mv(D3, t[third])
    if "f_ext" in t and not _zero(t["f_ext"]):
        Df = h._values("f_ext_gradient", (), {"q": q})[0 if op == "inverse_dynamics" else 1]  # (..., nb, nv, 6)
        dout = dout + jnp.einsum("...bvk,...bk->...v", Df, t["f_ext"])
    out, dout = _vary_like([out, dout], [out, dout])
    return out, dout


def _step_jvp(h, op, call, names, tangents):
    """integrator (q, qd, u -> x⁺) and plant_step (x, u -> x⁺): [A | B] in the tangent space (MuJoCo's
    under its convention: [A | B] is then along mj_integratePos), and ∂x⁺/∂f_ext when f_ext has a
    tangent (integrator_f_ext_gradient, one call for the three)"""
    tf = dict(zip(names, tangents)).get("f_ext")
    with_f = tf is not None and not _zero(tf)
    mujoco = mujoco_coordinates(h, call)
    if with_f:
        x_next, AB, Df = h._values("integrator_f_ext_gradient", (), step_with_forces(op, call, h.nq),
                                   outputs=0b111)
    else:
        grad_op = "integrator_gradient" if op == "integrator" else "plant_step_gradient"
        x_next, AB = h._values(grad_op, (), call, outputs=0b11)
    nq, nv = h.nq, h.nv
    batch = AB.shape[:-2]  # the call's batch shape: every tangent broadcast to it
    t = {n: jnp.broadcast_to(_dense(tn, call[n]), batch + jnp.shape(call[n])[-1:]) for n, tn in zip(names, tangents)
         if n != "f_ext"}
    if op == "integrator":
        q, tq, tqd = call["q"], t["q"], t["qd"]
    else:
        q, tq, tqd = call["x"][..., :nq], t["x"][..., :nq], t["x"][..., nq:]
    dx = jnp.concatenate([_tangent_map(h, q, tq, "to_tangent", mujoco), tqd, t["u"]], -1)
    d = _mv(AB, dx)  # [δq⁺ in the tangent space; δqd⁺]
    if with_f:  # Df (..., 2nv, nb, 6)
        d = d + jnp.einsum("...rbk,...bk->...r", Df, tf)
    dnext = jnp.concatenate([_tangent_map(h, x_next[..., :nq], d[..., :nv], "from_tangent", mujoco), d[..., nv:]],
                            -1)
    x_next, dnext = _vary_like([x_next, dnext], [x_next, dnext])
    return x_next, dnext


def _configuration_jvp(h, op, call, names, tangents):
    """crba, minv, com, frame_placement, frame_jacobian, end_effector_pose: functions of q alone, their
    Jacobians (_frameworks.configuration_jacobians) applied to q's tangent"""
    for n, t in zip(names, tangents):
        if n != "q" and not _zero(t):
            raise NotImplementedError(f"rbdkit.jax: {op} is differentiable with respect to q only, not {n}; "
                                      f"treat {n} as a constant (jax.lax.stop_gradient)")
    outs, jacobians = configuration_jacobians(jnp, h, op, call, h._value_list)
    q = call["q"]
    dq = _to_tangent(h, q, _dense(dict(zip(names, tangents))["q"], q))
    douts = apply_jacobians(op, jacobians, dq)
    both = _vary_like(outs + douts, outs + douts)
    outs, douts = both[:len(outs)], both[len(outs):]
    return (outs[0], douts[0]) if len(outs) == 1 else (tuple(outs), tuple(douts))


def _elementwise_jvp(h, op, call, names, tangents):
    """the quadratic costs and the log barriers: closed forms coordinate by coordinate, every output
    with respect to every array (_frameworks.elementwise_jvp)"""
    outs = list(h._values(op, (), call))
    t = dict(zip(names, tangents))
    arrays = [jnp.asarray(call[n], h.dtype) for n in elementwise_arguments(op)]
    d = [_dense(t[n], a) for n, a in zip(elementwise_arguments(op), arrays)]
    douts = [jnp.broadcast_to(dd, o.shape) for dd, o in zip(elementwise_jvp(jnp, op, call.get("mu"), *arrays, outs,
                                                                            *d), outs)]
    both = _vary_like(outs + douts, outs + douts)
    return tuple(both[:3]), tuple(both[3:])


def _regressor_jvp(h, op, call, names, tangents):
    """inverse_dynamics_regressor (q, qd, qdd -> Y): its Jacobians (_frameworks.regressor_jacobians)
    applied to the tangents"""
    t = {n: tn for n, tn in zip(names, tangents) if not _zero(tn)}
    Y = h._values(op, (), call)
    J = regressor_jacobians(jnp, h, call, h._value_list, set(t))
    dY = jnp.zeros_like(Y)
    for n, tn in t.items():
        d = _to_tangent(h, call["q"], tn) if n == "q" else tn
        dY = dY + jnp.einsum("...ijk,...k->...ij", J[n], d)
    Y, dY = _vary_like([Y, dY], [Y, dY])
    return Y, dY


_RULES = {"inverse_dynamics": _dynamics_jvp, "forward_dynamics": _dynamics_jvp, "aba": _dynamics_jvp,
          "integrator": _step_jvp, "plant_step": _step_jvp, "inverse_dynamics_regressor": _regressor_jvp}
_RULES.update({op: _configuration_jvp for op in CONFIGURATION_RULES})
_RULES.update({op: _elementwise_jvp for op in ELEMENTWISE_RULES})
