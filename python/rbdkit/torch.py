"""rbdkit.torch: the operations of rbdkit.Handle on PyTorch tensors, as one
`torch.library` custom operator (`rbdkit::call`) with autograd formulas from
rbdkit's analytical derivatives and a fake kernel, so that torch.compile
traces it without graph breaks.

    import rbdkit, rbdkit.torch
    h = rbdkit.torch.Handle(rbdkit.robots.load("iiwa"))
    qdd = h.forward_dynamics(q, qd, u)       # tensors (..., nq), (..., nv), (..., nv)
    qdd.sum().backward()                     # q.grad, qd.grad, u.grad: analytical

Methods are named, ordered and checked as rbdkit.Handle's, and take any
leading batch shape (broadcast on the leading axes). Tensors are in the
handle's dtype (float64 by default; others are converted); parameters are
Python values. Handle(model, backend="cuda") runs on the CUDA backend: CUDA
tensors are read and written in place on PyTorch's current stream (outputs
on their device), CPU tensors are copied to the device and back.

Autograd (first order) for inverse_dynamics (∂τ/∂q, ∂τ/∂qd, M, ∂τ/∂f_ext), forward_dynamics
and aba (∂qdd/∂q, ∂qdd/∂qd, M⁻¹: one forward_dynamics_gradient call; ∂qdd/∂f_ext), each
computed only for the inputs that require grad (a gradient in u alone is one M⁻¹ call), the
integrator and plant_step for every scheme ([A | B], and ∂x⁺/∂f_ext from
integrator_f_ext_gradient), and, with respect to q,
crba and minv (∂M/∂q of idsva_so), com, frame_placement, frame_jacobian and
end_effector_pose, inverse_dynamics_regressor (q, qd, qdd; so
inverse_dynamics_with_parameters differentiates in the inertial parameters
too), the quadratic costs and log barriers with respect to every
array, and the value of the Gauss–Newton costs (quadratic_state_cost_tangent,
com_cost, momentum_cost, ee_pos_cost; rbdkit.jax's module doc lists how). Gradients with respect
to quaternion coordinates follow rbdkit.jax's convention (its module doc): the
tangent-space gradient g becomes E⁺ᵀ g on the coordinates, with no component
along a quaternion; `Handle.tangent_gradient(q, grad_q)` gives g back (in
MuJoCo's coordinates too, where integrator and plant_step differentiate along
mj_integratePos: output_convention="mujoco", as in rbdkit.jax). The
other operations compute values; a backward pass through one raises.

Three routes to the same kernel and formulas. torch.compile traces the
custom operator. An eager call runs the kernel on the tensors' memory, its
layout cached per operation and parameters (bench/frameworks.py: about 10 µs
over the NumPy handle at B = 16); where it needs autograd, that call is
recorded as a plain torch.autograd.Function with the operator's formulas (the
operator's Python dispatch would cost hundreds of µs). Tensors the eager path
cannot take as they are (another dtype, not contiguous, leading shapes to
broadcast) go through the general path, which converts them.
"""

import atexit
import functools
import json
import math

import numpy as np

try:
    import torch
except ImportError as e:  # an optional dependency
    raise ImportError("rbdkit.torch needs PyTorch: pip install torch, then import rbdkit.torch again") from e

from . import _core
from ._frameworks import (CONFIGURATION_RULES, ELEMENTWISE_RULES, GAUSS_NEWTON_RULES, add_operation_methods,
                          call_keywords, configuration_jacobians, elementwise_arguments,
                          elementwise_vjp, gauss_newton_value_vjp, gravity_alias,
                          inverse_dynamics_with_parameters, mujoco_coordinates, mujoco_maps, one_dof_coordinates,
                          quaternion_joints, regressor_jacobians, step_with_forces, transpose_jacobians,
                          with_derivative_algorithms)
from ._handle import Handle as _NumpyHandle

_SIGNATURES = {name: args for name, _, _, _, args in _core.registered_operations()}
_NAMES = [name for name, _, _, _, _ in _core.registered_operations()]  # by operation id
_AUTOGRAD = object()  # Handle._eager: "this call needs autograd"
_PLAIN = (str, int, float, bool, type(None))  # parameter types Handle._eager caches a layout for
_CPU = torch.device("cpu")  # CPU tensors' outputs: on the CPU, whatever torch's default device
_ARGUMENT_NAMES = {op: [a[0] for a in args] for op, args in _SIGNATURES.items()}
_ARRAY_ARGUMENTS = {op: frozenset(a[0] for a in args if a[1] in ("array", "optional"))
                    for op, args in _SIGNATURES.items()}
# a C++ handle's address -> its rbdkit.torch.Handle, for the life of the process: a graph (autograd's,
# torch.compile's) holds the address and may run after the Python handle is gone; handles are few
_HANDLES = {}
atexit.register(_HANDLES.clear)  # released at exit, before the extension's teardown
_core.disable_leak_warnings()  # (those handles are kept on purpose)


# ---------------------------------------------------------------- the custom operator

def _kernel(xs, handle, op, slots, outputs, reals, choices, ee, batch, out_shapes, out_ranks, params=""):
    """operation `op` of the C++ handle at `handle` on xs (arguments `slots`, each (*batch, shape)),
    returning its outputs `outputs` (*batch, shape), the shapes flattened in out_shapes / out_ranks"""
    h = _HANDLES[handle]
    dtype, device = h.dtype, xs[0].device if xs else torch.device("cpu")
    for x in xs:
        if x.dtype != dtype or x.device != device:
            raise TypeError(f"rbdkit::call: expected tensors of the handle's dtype {dtype}, all on one device, got "
                            f"{x.dtype} on {x.device}")
    on_device = h._check_device(device)
    xs = [x.contiguous() for x in xs]
    outs = [torch.empty(tuple(batch) + s, dtype=dtype, device=device) for s in _shapes(out_shapes, out_ranks)]
    B = math.prod(batch) if len(batch) else -1
    _core.run_raw(handle, op, slots, [x.data_ptr() for x in xs], [x.numel() for x in xs], outputs,
                  [o.data_ptr() for o in outs], [o.numel() for o in outs], reals, choices, ee, B,
                  8 if dtype == torch.float64 else 4, on_device)
    return outs


@torch.library.custom_op("rbdkit::call", mutates_args=(), device_types=("cpu", "cuda"))
def _call(xs: list[torch.Tensor], handle: int, op: int, slots: list[int], outputs: list[int], reals: list[float],
          choices: list[int], ee: list[int], batch: list[int], out_shapes: list[int],
          out_ranks: list[int], params: str) -> list[torch.Tensor]:
    """the custom operator: _kernel, with the fake kernel and the autograd formulas below (params: the
    call's parameters as JSON, for the backward formulas)"""
    return _kernel(xs, handle, op, slots, outputs, reals, choices, ee, batch, out_shapes, out_ranks)


@_call.register_fake
def _call_fake(xs, handle, op, slots, outputs, reals, choices, ee, batch, out_shapes, out_ranks, params):
    dtype = xs[0].dtype if xs else torch.float64
    return [xs[0].new_empty(tuple(batch) + s, dtype=dtype) for s in _shapes(out_shapes, out_ranks)]


def _shapes(flat, ranks):
    shapes, i = [], 0
    for r in ranks:
        shapes.append(tuple(flat[i:i + r]))
        i += r
    return shapes


def _setup_context(ctx, inputs, output):
    xs, handle, op, slots = inputs[:4]
    ctx.set_materialize_grads(False)  # an output not used gets None, not zeros (the Gauss–Newton costs' rule)
    ctx.save_for_backward(*xs, *output)
    ctx.n_in = len(xs)
    ctx.call = (op, list(slots), inputs[-1])
    ctx.handle = _HANDLES.get(handle)  # the handle the backward formulas use
    # backward returns the inputs' structure: None for each parameter, [] for an empty list
    ctx.rest = [[] if isinstance(a, (list, tuple)) and len(a) == 0 else None for a in inputs[1:]]


def _backward(ctx, grads):
    saved = ctx.saved_tensors
    xs, outs = list(saved[:ctx.n_in]), list(saved[ctx.n_in:])
    op, slots, params = ctx.call
    h = ctx.handle
    name = _NAMES[op]
    rule = _RULES.get(name)
    if h is None or rule is None:
        raise NotImplementedError(f"rbdkit.torch: {name} computes values only (it has no derivative rule); the "
                                  f"differentiable operations are {', '.join(sorted(_RULES))}")
    if all(g is None for g in grads):  # no output is used
        return ([None] * len(slots), *ctx.rest)
    if torch.is_grad_enabled():  # backward(create_graph=True): a second derivative is asked for
        raise NotImplementedError(f"rbdkit.torch: {name}'s derivative rule is first order; second derivatives "
                                  f"(create_graph=True, double backward) through it are not available")
    sig = [a[0] for a in _SIGNATURES[name]]
    call = {sig[k]: x for k, x in zip(slots, xs)}
    kw = dict(json.loads(params))
    grads_by_name = rule(h, name, call, kw, list(grads), outs)
    return ([grads_by_name.get(sig[k]) for k in slots], *ctx.rest)


_call.register_autograd(_backward, setup_context=_setup_context)


class _EagerCall(torch.autograd.Function):
    """the custom operator's kernel and autograd formulas as a plain autograd.Function, for eager calls
    (a fraction of the operator's dispatch cost); torch.compile traces the operator instead"""

    @staticmethod
    def forward(ctx, rest, *xs):
        outs = _kernel(list(xs), *rest)
        _setup_context(ctx, (list(xs),) + tuple(rest), outs)
        return tuple(outs)

    @staticmethod
    def backward(ctx, *grads):
        return (None, *_backward(ctx, grads)[0])


class _RawCall(_EagerCall):
    """Handle._eager's call (a cached RawCall on the tensors' memory) recorded for autograd: the eager
    path's few µs instead of the general path's argument handling; _EagerCall's context and backward"""

    @staticmethod
    def forward(ctx, meta, *xs):
        h, raw, out_shapes, lead, device, on_device, (op_id, slots, params) = meta
        res = [torch.empty(lead + tuple(s), dtype=h.dtype, device=device or _CPU) for s in out_shapes]
        args = ([x.data_ptr() for x in xs] + [r.data_ptr() for r in res], math.prod(lead) if lead else -1)
        raw(*args) if device is None else raw(*args, on_device)
        _setup_context(ctx, (list(xs), h._address, op_id, slots, params), res)
        return tuple(res)


@torch._dynamo.assume_constant_result
def _plan(address, op, params, arrays, outputs):
    """a call's layout (OpHandle.plan) from its parameters (name, value) and the names of its arrays,
    and the parameters as JSON; constant for torch.compile (parameters are Python values, fixed at
    trace time)"""
    h = _HANDLES[address]
    kw = dict(params)
    kw.update({name: 0 for name in arrays})  # the arrays' places (plan does not read them)
    op_id, planned, reals, choices, ee, outs = h._core.plan(op, (), kw, outputs)
    sig = _SIGNATURES[op]
    return (op_id, tuple((k, sig[k][0], tuple(shape)) for k, _, shape in planned), tuple(reals), tuple(choices),
            tuple(ee), tuple((o, tuple(shape)) for o, shape in outs), _params_json(params))


def _params_json(params):
    """a call's parameters ((name, value), ...) as JSON (cached where they are hashable: json.dumps costs
    µs on every eager call)"""
    try:
        return _cached_params_json(params)
    except TypeError:  # an unhashable value
        return _dumps(params)


def _dumps(params):
    return json.dumps(params, default=lambda v: v.item() if hasattr(v, "item") else str(v))


_cached_params_json = functools.lru_cache(maxsize=1024)(_dumps)


# ---------------------------------------------------------------- the handle

class Handle:
    """A robot's operations on PyTorch tensors (module doc). Attributes: model, numpy (the
    rbdkit.Handle that runs the calls), dtype (a torch dtype), nq, nv, nb."""

    def __init__(self, model, algorithms=None, dtype="float64", threads=None, output_convention="pinocchio",
                 backend="cpu"):
        if isinstance(dtype, torch.dtype):
            dtype = str(dtype).replace("torch.", "")
        self.numpy = _NumpyHandle(model, with_derivative_algorithms(algorithms), backend, dtype, threads,
                                  output_convention)
        self.backend = self.numpy.backend
        self.model = self.numpy.model
        self.dtype = getattr(torch, self.numpy.dtype.name)
        self.nq, self.nv, self.nb = self.model.nq, self.model.nv, self.model.nb
        self.output_convention = self.numpy.output_convention
        self._core = self.numpy._core
        self._address = int(self._core.address)
        self._quats = quaternion_joints(self.model)
        self._vi, self._qi = one_dof_coordinates(self.model)  # lists: constants under torch.compile
        self._identity_map = not self._quats and self.nq == self.nv and self._vi == self._qi == list(range(self.nv))
        # the one-DoF coordinates as two slices where each side is one run (a floating base followed by
        # one-DoF joints: v[6:], q[7:])
        runs = (_run(self._vi), _run(self._qi))
        self._one_dof_slices = runs if all(runs) else None
        self._plans = {}  # (op, parameters, arrays present) -> the call's layout (_eager)
        _HANDLES[self._address] = self

    def available_operations(self):
        return self.numpy.available_operations()

    def has(self, name):
        return self.numpy.has(name)

    def _check_device(self, device):
        """whether tensors on `device` are device arrays for the C++ handle (CUDA tensors of a
        backend="cuda" handle, then on PyTorch's current stream); CPU tensors are host arrays on
        either backend (a backend="cuda" handle copies them to its device)"""
        if device.type == "cpu":
            return False
        if device.type != "cuda" or self.backend != "cuda":
            raise ValueError(f"rbdkit.torch: tensors on {device} need a handle with backend='cuda' (this one's backend "
                             f"is {self.backend!r}); CPU tensors work on either")
        self.numpy.set_stream(torch.cuda.current_stream(device).cuda_stream)
        return True

    def _values(self, op, kwargs, outputs=-1, eager_autograd=False):
        """the results of op (rbdkit.Handle's, or the outputs of mask `outputs`) as a list of tensors
        (eager_autograd: recorded for autograd by _EagerCall, not by the custom operator)"""
        if not eager_autograd and not torch.compiler.is_compiling():
            res = self._eager(op, kwargs, outputs)
            if res is not None and res is not _AUTOGRAD:
                return res
        kinds = {name: kind for name, kind, _ in _SIGNATURES[op]}
        tensors, params = {}, []
        for name, v in kwargs.items():
            if kinds.get(name) in ("array", "optional") and v is not None:
                tensors[name] = v if isinstance(v, torch.Tensor) else torch.as_tensor(np.asarray(v))
            else:
                params.append((name, tuple(v) if isinstance(v, list) else v))
        op_id, arrays, reals, choices, ee, outs, key = _plan(self._address, op, tuple(params), tuple(tensors),
                                                             outputs)
        xs, device = [], None  # the call's device: its tensors' (NumPy inputs follow them)
        for k, name, shape in arrays:
            if isinstance(kwargs[name], torch.Tensor):
                if device is not None and tensors[name].device != device:
                    raise ValueError(f"{name}: expected a tensor on {device}, as the call's others, got one on "
                                     f"{tensors[name].device}")
                device = tensors[name].device
        if device is not None:
            self._check_device(device)
        for k, name, shape in arrays:
            x = tensors[name]
            if x.is_complex() or x.dtype == torch.bool:
                raise TypeError(f"{name}: expected a real tensor, got dtype {x.dtype}")
            x = x.to(device=device, dtype=self.dtype)
            n = len(shape)
            if x.dim() < n or tuple(x.shape[x.dim() - n:]) != tuple(shape):
                raise ValueError(f"{name}: expected shape (..., {', '.join(map(str, shape))}) (any leading batch "
                                 f"axes), got {tuple(x.shape)}")
            xs.append(x)
        leading = [tuple(x.shape[:x.dim() - len(s)]) for x, (_, _, s) in zip(xs, arrays)]
        batch = leading[0] if len(set(leading)) == 1 else tuple(np.broadcast_shapes(*leading)) if xs else ()
        xs = [x if tuple(x.shape[:x.dim() - len(s)]) == batch else x.expand(batch + tuple(s))
              for x, (_, _, s) in zip(xs, arrays)]
        flat = [d for _, s in outs for d in s]
        call = (xs, self._address, op_id, [k for k, _, _ in arrays], [o for o, _ in outs], list(reals),
                list(choices), list(ee), list(batch), flat, [len(s) for _, s in outs], key)
        # the custom operator where torch.compile traces, _EagerCall for eager autograd, the kernel
        # directly otherwise (the operator's Python dispatch costs about 90 µs a call)
        if torch.compiler.is_compiling():
            return list(_call(*call))
        if torch.is_grad_enabled() and any(x.requires_grad for x in xs):
            return list(_EagerCall.apply(call[1:], *xs)) if eager_autograd else list(_call(*call))
        return _kernel(*call)

    def _method_call(self, op, args, kwargs):
        kw = call_keywords(op, _ARGUMENT_NAMES[op], args, kwargs)
        compiling = torch.compiler.is_compiling()
        res = None if compiling else self._eager(op, kw)
        if res is None:  # torch.compile, or a call _eager leaves to the general path
            grad = torch.is_grad_enabled() and any(isinstance(v, torch.Tensor) and v.requires_grad
                                                   for v in kw.values())
            if grad and compiling:  # (the refusals are plain Python: they run at trace time)
                _check_differentiable(self, op, kw)
            res = _AUTOGRAD if grad and not compiling else self._values(op, kw)
        if res is _AUTOGRAD:
            _check_differentiable(self, op, kw)
            res = self._eager(op, kw, autograd=True)  # the eager path, recorded for autograd
            if res is None:  # autograd without the operator's dispatch
                res = self._values(op, kw, eager_autograd=True)
        return res[0] if len(res) == 1 else tuple(res)

    def _eager(self, op, kw, outputs=-1, autograd=False):
        """the outputs of a call outside torch.compile, as a list: the kernel on the tensors' memory,
        the call's layout cached per operation, parameters and arrays present (a few µs on top of the
        engine). None where the general path (_values) must take it: an array that
        is not a contiguous tensor of the handle's dtype, tensors on several devices, leading shapes
        that need broadcasting, a shape other than the planned one (the general path's message), an
        unhashable parameter; _AUTOGRAD where a tensor requires grad and autograd is on, unless `autograd`
        (then the call is recorded for autograd: _RawCall)"""
        arrays, key, xs, grad = _ARRAY_ARGUMENTS[op], [op, outputs], [], torch.is_grad_enabled()
        record = False
        for name, v in kw.items():
            if name in arrays and v is not None:
                if not isinstance(v, torch.Tensor):
                    return None
                if grad and v.requires_grad:
                    if not autograd:
                        return _AUTOGRAD
                    record = True
                xs.append(v)
                key.append(name)
            elif type(v) in _PLAIN:  # (the type too: True, 1 and 1.0 are equal keys, not equal arguments)
                key.append((name, type(v), v))
            elif type(v) in (list, tuple) and all(type(e) in _PLAIN for e in v):
                key.append((name, tuple, tuple(v)))
            else:  # a tensor, an array or another object as a parameter: the general path's checks
                return None
        plan = self._plans.get(tuple(key))
        if plan is None:
            plan = self._eager_plan(op, kw, key, outputs)
            if plan is None:
                return None
        raw, shapes, out_shapes, backward = plan
        dtype, lead, cpu = self.dtype, None, True
        for x, shape in zip(xs, shapes):  # (arguments in the call's order: run_raw takes them so)
            if not (x.dtype is dtype and x.is_contiguous()):
                return None
            cpu = cpu and x.is_cpu
            if lead is None:
                n = x.dim() - len(shape)
                if n < 0 or x.shape[n:] != shape:
                    return None
                lead = tuple(x.shape[:n])
            elif x.shape != lead + shape:
                return None
        lead = lead or ()
        if record:
            device = None if cpu else xs[0].device
            if not cpu and any(x.device != device for x in xs):
                return None
            on_device = None if cpu else self._check_device(device)
            return list(_RawCall.apply((self, raw, out_shapes, lead, device, on_device, backward), *xs))
        if cpu:
            # (varargs: faster than a tuple; a scalar's shape is the empty tuple)
            res = [torch.empty(*lead, *s, dtype=dtype, device=_CPU) if lead or s else
                   torch.empty((), dtype=dtype, device=_CPU) for s in out_shapes]
            raw([x.data_ptr() for x in xs] + [r.data_ptr() for r in res], math.prod(lead) if lead else -1)
            return res
        devices = {x.device for x in xs}
        if len(devices) != 1:
            return None
        device = devices.pop()
        on_device = self._check_device(device)
        res = [torch.empty(lead + tuple(s), dtype=dtype, device=device) for s in out_shapes]
        raw([x.data_ptr() for x in xs] + [r.data_ptr() for r in res], math.prod(lead) if lead else -1, on_device)
        return res

    def _eager_plan(self, op, kw, key, outputs):
        """_eager's layout of a call (_plan's, its arrays in the call's order) as a RawCall, cached under key;
        None for a call the general path must refuse"""
        present = [n for n in key[2:] if isinstance(n, str)]  # (the arrays' names; parameters are tuples)
        params = tuple((n, tuple(v) if isinstance(v, list) else v) for n, v in kw.items() if n not in present)
        try:
            op_id, planned, reals, choices, ee, outs, key_json = _plan(self._address, op, params, tuple(present),
                                                                         outputs)
        except (TypeError, ValueError):
            return None
        slot_shape = {name: (k, shape) for k, name, shape in planned}
        shapes, out_shapes = [slot_shape[n][1] for n in present], [shape for _, shape in outs]
        raw = _core.RawCall(self._address, op_id, [slot_shape[n][0] for n in present], [o for o, _ in outs],
                            list(choices), list(ee), list(reals), [math.prod(s) for s in shapes],
                            [math.prod(s) for s in out_shapes], 8 if self.dtype is torch.float64 else 4)
        # (the backward formulas' view of the call: operation, argument slots, parameters as JSON)
        plan = (raw, shapes, out_shapes, (op_id, [slot_shape[n][0] for n in present], key_json))
        if len(self._plans) < 4096:
            self._plans[tuple(key)] = plan
        return plan

    def inverse_dynamics_with_parameters(self, q, qd, qdd, pi, gravity=None, *, GRAVITY=None):
        """τ = Y(q, qd, qdd) π (..., nv): the inverse dynamics with the inertial parameters pi (..., 10·nb,
        Model.inertial_parameters' layout) as a tensor, differentiable in pi and in q, qd, qdd (rbdkit.jax's
        module doc, "Inertial parameters"); no f_ext"""
        device = q.device if isinstance(q, torch.Tensor) else None
        return inverse_dynamics_with_parameters(torch, self, q, qd, qdd, torch.as_tensor(pi, dtype=self.dtype,
                                                                                         device=device),
                                                gravity_alias("inverse_dynamics_with_parameters", gravity,
                                                              GRAVITY), self.inverse_dynamics_regressor)

    # ---- the coordinates and the tangent space (rbdkit.jax's module doc)
    def tangent_gradient(self, q, grad_q, output_convention=None):
        """Eᵀ(q) grad_q: the tangent-space gradient (..., nv) from a gradient on the coordinates (..., nq)
        (output_convention: None for the handle's; "mujoco": MuJoCo's coordinates and mj_integratePos)"""
        grad_q = torch.as_tensor(grad_q)
        g = _tangent_map(self, torch.as_tensor(q), grad_q, "transpose", mujoco_maps(self, output_convention))
        return g.clone() if g is grad_q else g

    def __repr__(self):
        return f"<rbdkit.torch.Handle of {self.model!r}: dtype={self.dtype}>"


add_operation_methods(Handle, "_method_call")


def _check_differentiable(h, op, kw):
    """refuse, before the call, a derivative no rule gives (kw: the call, some tensor requiring grad)"""
    grad = lambda name: isinstance(kw.get(name), torch.Tensor) and kw[name].requires_grad  # noqa: E731
    if op in GAUSS_NEWTON_RULES and mujoco_coordinates(h, kw):
        raise NotImplementedError(f"rbdkit.torch: {op}'s derivative in MuJoCo's output convention on a model "
                                  f"with free-flyer or spherical joints is not available")
    if op in CONFIGURATION_RULES:
        for name in kw:
            if name != "q" and grad(name):
                raise NotImplementedError(f"rbdkit.torch: {op} is differentiable with respect to q only, not "
                                          f"{name}; pass {name}.detach()")
    if op == "ee_pos_cost" and grad("ee_offset"):
        raise NotImplementedError("rbdkit.torch: ee_pos_cost is not differentiable with respect to ee_offset; "
                                  "pass ee_offset.detach()")


# ---------------------------------------------------------------- the coordinates' maps

def _run(indices):
    """slice(i, i + n) when indices are i, i + 1, ..., i + n - 1 (n > 0), else None"""
    n = len(indices)
    return slice(indices[0], indices[0] + n) if n and list(indices) == list(range(indices[0], indices[0] + n)) else None


def _cross(a, b):
    """a × b over broadcast leading axes (torch.linalg.cross needs equal ranks)"""
    return torch.linalg.cross(*torch.broadcast_tensors(a, b))


def _tangent_map(h, q, x, kind, mujoco=False):
    """"pinv_T": E⁺ᵀ x (nv -> nq), "from_tangent": E x (nv -> nq), "transpose": Eᵀ x (nq -> nv);
    mujoco: MuJoCo's coordinates and ⊕ (rbdkit.jax's _tangent_map). A quaternion joint's blocks are
    applied as quaternion products (a few batched operations each, no matrix formed)"""
    if h._identity_map:  # every joint's coordinates are its tangent
        return x if q.shape[:-1] == x.shape[:-1] else x.expand(torch.broadcast_shapes(q.shape[:-1], x.shape[:-1])
                                                                + x.shape[-1:])
    if kind not in ("pinv_T", "from_tangent", "transpose"):
        raise ValueError(f"_tangent_map: kind: expected 'pinv_T', 'from_tangent' or 'transpose', got {kind!r}")
    to_q = kind in ("pinv_T", "from_tangent")
    batch = torch.broadcast_shapes(q.shape[:-1], x.shape[:-1])
    out = x.new_zeros(tuple(batch) + ((h.nq,) if to_q else (h.nv,)))
    if len(h._vi):
        src, dst = (h._vi, h._qi) if to_q else (h._qi, h._vi)
        if h._one_dof_slices:  # (a slice each side: a view and a copy, not an index tensor per call)
            src, dst = h._one_dof_slices[::1 if to_q else -1]
        out[..., dst] = x[..., src].expand(tuple(batch) + (len(h._vi),))
    for joint, iq, iv in h._quats:
        qq = iq + 3 if joint == "free" else iq
        quat = q[..., qq:qq + 4]
        v, w = (quat[..., 1:], quat[..., :1]) if mujoco else (quat[..., :3], quat[..., 3:])  # vector and scalar parts
        ivr = iv + 3 if joint == "free" else iv
        if joint == "free":  # the position's rows: R(quat) or Rᵀ (R x = x + w t + v × t, t = 2 v × x);
            # MuJoCo's, additive in the world: E = I
            src, dst = (slice(iv, iv + 3), slice(iq, iq + 3)) if to_q else (slice(iq, iq + 3), slice(iv, iv + 3))
            p = x[..., src]
            if not mujoco:
                t = 2 * _cross(v, p)
                p = p + (w if to_q else -w) * t + _cross(v, t)
            out[..., dst] = p
        if to_q:  # Q δ = ½ (w δ + v × δ, -v·δ) (vector part, scalar part), times 4 for E⁺ᵀ
            d = x[..., ivr:ivr + 3]
            scale = 2.0 if kind == "pinv_T" else 0.5
            vec = scale * (w * d + _cross(v, d))
            sca = -scale * (v * d).sum(-1, keepdim=True)
            out[..., qq:qq + 4] = torch.cat([sca, vec] if mujoco else [vec, sca], -1)
        else:  # Qᵀ y = ½ (w y_v - v × y_v - y_w v)
            y = x[..., qq:qq + 4]
            yv, yw = (y[..., 1:], y[..., :1]) if mujoco else (y[..., :3], y[..., 3:])
            out[..., ivr:ivr + 3] = 0.5 * (w * yv - _cross(v, yv) - yw * v)
    return out


# ---------------------------------------------------------------- backward formulas (reverse mode)

def _mtv(A, y):
    """Aᵀ y over leading axes (a matmul: einsum costs tens of µs on small tensors)"""
    return torch.matmul(y.unsqueeze(-2), A).squeeze(-2)


def _dynamics_vjp(h, op, call, kw, grads, outs):
    """the dynamics' cotangents, for the inputs that require a gradient only: q or qd need the
    first-order derivatives (and a free or spherical joint's q the tangent map), the third input alone
    needs only M (inverse dynamics) or M⁻¹ (forward dynamics)"""
    ct = grads[0]
    q, qd = call["q"], call["qd"]
    third = "qdd" if op == "inverse_dynamics" else [n for n in call if n not in ("q", "qd", "f_ext")][0]
    need = {n for n, x in call.items() if x.requires_grad}
    base = {k: v for k, v in kw.items()}
    if "f_ext" in call:
        base["f_ext"] = call["f_ext"].detach()
    Dq = Dqd = D3 = None
    if op == "inverse_dynamics":
        if need & {"q", "qd"}:
            g = {k: v for k, v in base.items() if k in {a[0] for a in _SIGNATURES["inverse_dynamics_gradient"]}}
            D = h._values("inverse_dynamics_gradient", dict(g, q=q, qd=qd, **({"qdd": call["qdd"]} if "qdd" in call
                                                                               else {})))[0]
            Dq, Dqd = D[..., :h.nv], D[..., h.nv:]
        if third in need:
            D3 = h._values("crba", {"q": q})[0]
    elif need & {"q", "qd"}:
        g = {k: v for k, v in base.items() if k in {a[0] for a in _SIGNATURES["forward_dynamics_gradient"]}}
        Dq, Dqd, _, D3 = h._values("forward_dynamics_gradient", dict(g, q=q, qd=qd, u=call[third]), outputs=0b1111)
    elif third in need:  # ∂q̈/∂u = M⁻¹, a fraction of the gradient's cost (MuJoCo's convention, which would
        # change it, is refused for the dynamics on models with quaternions)
        D3 = h._values("minv", {"q": q})[0]
    out = {}
    if "q" in need:
        out["q"] = _tangent_map(h, q, _mtv(Dq, ct), "pinv_T")
    if "qd" in need:
        out["qd"] = _mtv(Dqd, ct)
    if third in need:
        out[third] = _mtv(D3, ct)
    if "f_ext" in need:  # -J_bᵀ or M⁻¹ J_bᵀ per body (f_ext_gradient)
        Df = h._values("f_ext_gradient", {"q": q})[0 if op == "inverse_dynamics" else 1]  # (..., nb, nv, 6)
        out["f_ext"] = torch.einsum("...bvk,...v->...bk", Df, ct)
    return out


def _step_vjp(h, op, call, kw, grads, outs):
    ct = grads[0]
    nq, nv = h.nq, h.nv
    args = dict(kw, **{k: (v.detach() if k == "f_ext" else v) for k, v in call.items()})
    with_f = "f_ext" in call and call["f_ext"].requires_grad
    if with_f:  # x⁺, [A | B] and ∂x⁺/∂f_ext (..., 2nv, nb, 6) in one call
        x_next, AB, Df = h._values("integrator_f_ext_gradient", step_with_forces(op, args, nq), outputs=0b111)
    else:
        grad_op = "integrator_gradient" if op == "integrator" else "plant_step_gradient"
        x_next, AB = h._values(grad_op, args, outputs=0b11)
    mujoco = mujoco_coordinates(h, kw)  # (then [A | B] is along mj_integratePos)
    lam = torch.cat([_tangent_map(h, x_next[..., :nq], ct[..., :nq], "transpose", mujoco), ct[..., nq:]], -1)
    g = _mtv(AB, lam)  # [g_q (tangent); g_qd; g_u]
    q = call["q"] if op == "integrator" else call["x"][..., :nq]
    # the tangent map to q's coordinates only where q (or x) requires a gradient
    need_q = call["q"].requires_grad if op == "integrator" else call["x"].requires_grad
    gq = _tangent_map(h, q, g[..., :nv], "pinv_T", mujoco) if need_q else None
    out = ({"q": gq, "qd": g[..., nv:2 * nv]} if op == "integrator" else
           {"x": torch.cat([gq, g[..., nv:2 * nv]], -1) if need_q else None})
    out["u"] = g[..., 2 * nv:]
    if with_f:
        out["f_ext"] = torch.einsum("...rbk,...r->...bk", Df, lam)
    return out


def _configuration_vjp(h, op, call, kw, grads, outs):
    """crba, minv, com, frame_placement, frame_jacobian, end_effector_pose: functions of q alone, the
    cotangents through their Jacobians (_frameworks.configuration_jacobians)"""
    q = call["q"]
    args = dict(kw, **{k: v.detach() for k, v in call.items()})
    _, jacobians = configuration_jacobians(torch, h, op, args, h._values)
    g = transpose_jacobians(op, jacobians, grads)
    return {"q": None if g is None else _tangent_map(h, q, g, "pinv_T")}


_RULES = {"inverse_dynamics": _dynamics_vjp, "forward_dynamics": _dynamics_vjp, "aba": _dynamics_vjp,
          "integrator": _step_vjp, "plant_step": _step_vjp}
_RULES.update({op: _configuration_vjp for op in CONFIGURATION_RULES})


def _elementwise_vjp(h, op, call, kw, grads, outs):
    """the quadratic costs and the log barriers (_frameworks.elementwise_vjp)"""
    names = elementwise_arguments(op)
    return dict(zip(names, elementwise_vjp(torch, op, kw.get("mu"), *(call[n] for n in names), outs, *grads)))


_RULES.update({op: _elementwise_vjp for op in ELEMENTWISE_RULES})


def _gauss_newton_vjp(h, op, call, kw, grads, outs):
    """the Gauss–Newton costs: through their value (_frameworks.gauss_newton_value_vjp); their grad and H
    are values"""
    if any(g is not None for g in grads[1:]):
        raise NotImplementedError(f"rbdkit.torch: {op}'s grad and H outputs are values (H is the Gauss–Newton "
                                  f"approximation); differentiate its value")
    if grads[0] is None:
        return {}
    args = dict(kw, **{k: v.detach() for k, v in call.items()})
    return gauss_newton_value_vjp(torch, h, op, args, outs, grads[0], h._values,
                                  lambda q, t: _tangent_map(h, q, t, "pinv_T"))


_RULES.update({op: _gauss_newton_vjp for op in GAUSS_NEWTON_RULES})


def _regressor_vjp(h, op, call, kw, grads, outs):
    """inverse_dynamics_regressor: the cotangents through its Jacobians (_frameworks.regressor_jacobians)"""
    ct = grads[0]
    args = dict(kw, **{k: v.detach() for k, v in call.items()})
    J = regressor_jacobians(torch, h, args, h._values, {n for n, v in call.items() if v.requires_grad})
    out = {n: torch.einsum("...ijk,...ij->...k", Jn, ct) for n, Jn in J.items()}
    if "q" in out:
        out["q"] = _tangent_map(h, call["q"], out["q"], "pinv_T")
    return out


_RULES["inverse_dynamics_regressor"] = _regressor_vjp
