"""rbdkit.Handle: a robot, the algorithms it is built with, a backend and a
precision; every operation of rbdkit.RBD on batched arrays.

    h = rbdkit.Handle(model, algorithms=["integrator_gradient", "com_cost"], dtype="float32", threads=2)
    h.available_operations()     # integrator, plant_step, integrator_gradient, ..., com, ccrba, com_cost, ...
    AB = h.plant_step_gradient(X, U, 0.01, "rk4")      # X (B, nq + nv), U (B, nv) -> (B, 2nv, 3nv)
    h.crba(q)                    # ValueError: crba: this handle was not built with it; add 'crba' ...

Algorithms, the operations each provides and their dependencies come from
one table shared with the C++ rbd::Handle (include/rbdkit/handle.hpp,
`Handle.algorithm_table()`); selecting an algorithm brings what it requires
(plant_step_hessian -> fdsva_so, com_cost -> com and ccrba, momentum_cost ->
dccrba, integrator_gradient -> forward_dynamics_gradient, ...).

Every method has the signature, argument checks and results of the RBD
method of the same name (one sample or a batch on axis 0), with one
exception: `inverse_dynamics` returns the joint forces tau only (per-body
velocities, accelerations and forces: `inverse_dynamics_fpass`, or
rbdkit.RBD).

Precision. dtype="float32" returns float32 arrays. The operations of the
batch engine (`Handle.fast_operations()`: inverse dynamics, generalized
gravity, nonlinear effects, crba, dense minv, aba, forward dynamics, both
first-order gradients, the integrator and plant step with their gradients,
without f_ext, in the Pinocchio output convention) compute in float32 when
the engine is in this build; every other operation computes in float64 and
its results are rounded to float32. Without the engine (this build when
`Handle.engine_available()` is False) everything computes in float64 and
`threads` has no effect.
"""

import inspect
import os

import numpy as np

from . import _core
from ._checks import (ANGLE_JOINTS, MAX_ANGLE, MAX_ANGLE_F32, MAX_INPUT, MAX_INPUT_F32, Batch,
                      check_scalar)
from ._integrators import check_dt, integrator_code
from ._model import Model
from ._rbd import RBD

# ---- the algorithm table (C++: rbd::handle_algorithms)
ALGORITHMS = {name: (tuple(ops), tuple(deps)) for name, ops, deps in _core.handle_algorithms()}
OPERATION_ALGORITHM = {op: name for name, (ops, _) in ALGORITHMS.items() for op in ops}
OPERATIONS = tuple(OPERATION_ALGORITHM)  # every operation a handle can have, in table order

DTYPES = ("float64", "float32")
BACKENDS = ("cpu",)
CONVENTIONS = ("pinocchio", "mujoco")

# ---- what the batch engine (_core.Engine) computes, in one place:
# operation -> (engine method, array inputs, scalar inputs, outputs, result)
#   array inputs: (argument, width) with width "nq" / "nv"; "x" is split into
#     q and qd; "0" is a zero array of width nv (qd or qdd the op does not take)
#   scalar inputs: gravity, dt, integrator_type (passed as its code)
#   outputs: shapes per sample; result: index of the output returned, or a
#     tuple of indices (returned as a tuple), or "hstack" of all outputs
#   when: an extra condition on the bound arguments
ENGINE_ROUTES = {
    "inverse_dynamics": ("inverse_dynamics", (("q", "nq"), ("qd", "nv"), ("qdd", "nv")), ("gravity",),
                         (("nv",),), 0),
    "generalized_gravity": ("inverse_dynamics", (("q", "nq"), ("0", "nv"), ("0", "nv")), ("gravity",),
                            (("nv",),), 0),
    "nonlinear_effects": ("inverse_dynamics", (("q", "nq"), ("qd", "nv"), ("0", "nv")), ("gravity",),
                          (("nv",),), 0),
    "crba": ("crba", (("q", "nq"),), (), (("nv", "nv"),), 0),
    "minv": ("minv", (("q", "nq"),), (), (("nv", "nv"),), 0, 
             lambda a: isinstance(a["output_dense"], (bool, np.bool_)) and bool(a["output_dense"])),
    "aba": ("forward_dynamics", (("q", "nq"), ("qd", "nv"), ("tau", "nv")), ("gravity",), (("nv",),), 0),
    "forward_dynamics": ("forward_dynamics", (("q", "nq"), ("qd", "nv"), ("u", "nv")), ("gravity",),
                         (("nv",),), 0),
    "inverse_dynamics_gradient": ("inverse_dynamics_gradient", (("q", "nq"), ("qd", "nv"), ("qdd", "nv")),
                                  ("gravity",), (("nv", "nv"), ("nv", "nv")), "hstack"),
    "forward_dynamics_gradient": ("forward_dynamics_gradient", (("q", "nq"), ("qd", "nv"), ("u", "nv")),
                                  ("gravity",), (("nv", "nv"), ("nv", "nv")), (0, 1)),
    "integrator": ("integrator", (("q", "nq"), ("qd", "nv"), ("u", "nv")), ("dt", "gravity", "integrator_type"),
                   (("nx",),), 0),
    "integrator_gradient": ("integrator_gradient", (("q", "nq"), ("qd", "nv"), ("u", "nv")),
                            ("dt", "gravity", "integrator_type"), (("nx",), ("2nv", "3nv")), 1),
    "plant_step": ("integrator", (("x", "nx"), ("u", "nv")), ("dt", "gravity", "integrator_type"), (("nx",),), 0),
    "plant_step_gradient": ("integrator_gradient", (("x", "nx"), ("u", "nv")), ("dt", "gravity", "integrator_type"),
                            (("nx",), ("2nv", "3nv")), 1),
}

# algorithms whose operations read the same in either output convention
CONVENTION_NEUTRAL = ("mujoco_convention",)

# operations whose handle result differs from the RBD method's
RESULTS = {"inverse_dynamics": lambda r: r[0]}


def _check_threads(threads):
    if threads is None:
        return os.cpu_count() or 1
    if isinstance(threads, (bool, np.bool_)) or not isinstance(threads, (int, np.integer)):
        raise TypeError(f"threads: expected a positive integer or None (all hardware threads), "
                        f"got {type(threads).__name__}")
    if threads <= 0:
        raise ValueError(f"threads: expected a positive integer or None (all hardware threads), got {threads}")
    return int(threads)


def _check_dtype(dtype):
    name = dtype if isinstance(dtype, str) else None
    if name is None and dtype is not None:
        try:
            name = np.dtype(dtype).name
        except TypeError:
            name = None
    if name not in DTYPES:
        raise ValueError(f"dtype: expected 'float64' or 'float32', got {dtype!r}")
    return np.dtype(name)


def _check_backend(backend):
    if backend == "cuda":
        raise ValueError("backend: 'cuda' is not available: this build of rbdkit has no CUDA handle; "
                         "expected 'cpu'")
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise ValueError(f"backend: expected 'cpu', got {backend!r}")
    return backend


def _check_convention(conv):
    if not isinstance(conv, str) or conv not in CONVENTIONS:
        raise ValueError(f"output_convention: expected 'pinocchio' or 'mujoco', got {conv!r}")
    return conv


def _check_algorithms(algorithms):
    """the resolved algorithm list (the requested ones and their dependencies)"""
    if algorithms is None:
        return tuple(ALGORITHMS)
    if isinstance(algorithms, str):
        algorithms = [algorithms]
    if not isinstance(algorithms, (list, tuple, set, frozenset)):
        raise TypeError(f"algorithms: expected a list of algorithm names or None, got {type(algorithms).__name__}")
    if len(algorithms) == 0:
        raise ValueError("algorithms: expected at least one algorithm name (None for every algorithm)")
    for a in algorithms:
        if not isinstance(a, str):
            raise TypeError(f"algorithms: expected algorithm names (str), got an entry of type {type(a).__name__}")
        if a not in ALGORITHMS and a in OPERATION_ALGORITHM:
            raise ValueError(f"algorithms: '{a}' is an operation, not an algorithm; it is provided by algorithm "
                             f"'{OPERATION_ALGORITHM[a]}'")
    return tuple(_core.resolve_algorithms(sorted(algorithms)))


def _to_dtype(r, dtype):
    """results (arrays, numpy scalars, tuples of them) in dtype"""
    if isinstance(r, tuple):
        return tuple(_to_dtype(x, dtype) for x in r)
    if isinstance(r, (np.ndarray, np.floating)) and np.issubdtype(r.dtype, np.floating) and r.dtype != dtype:
        return r.astype(dtype) if isinstance(r, np.ndarray) else dtype.type(r)
    return r


class Handle:
    """Operations of a model on batched arrays (module doc). Attributes:
    model, rbd (the float64 rbdkit.RBD reference path), algorithms (resolved),
    backend, dtype (numpy dtype), threads, output_convention."""

    def __init__(self, model, algorithms=None, backend="cpu", dtype="float64", threads=None,
                 output_convention="pinocchio"):
        if isinstance(model, (str, os.PathLike)):
            model = Model.from_urdf(model)
        if not isinstance(model, Model):
            raise TypeError(f"model: expected an rbdkit.Model or a URDF file path, got {type(model).__name__}")
        self.backend = _check_backend(backend)
        self.dtype = _check_dtype(dtype)
        self.threads = _check_threads(threads)
        self.output_convention = _check_convention(output_convention)
        self.algorithms = _check_algorithms(algorithms)
        self.model = model
        self.rbd = RBD(model)
        self.nq, self.nv, self.nb = model.nq, model.nv, model.nb
        self._ops = frozenset(op for a in self.algorithms for op in ALGORITHMS[a][0])
        # a model without quaternion joints reads the same in both conventions
        self._convention_noop = not any(j["type"] in ("free", "spherical") for j in model.joints)
        self._quats = [(j["name"], j["q_index"] + (3 if j["type"] == "free" else 0))
                       for j in model.joints if j["type"] in ("free", "spherical") and not j["mimic_of"]]
        self._angles = [(j["name"], j["q_index"]) for j in model.joints
                        if j["type"] in ANGLE_JOINTS and not j["mimic_of"]]
        self._angle_columns = np.array([o for _, o in self._angles], dtype=np.intp)
        # the input bounds of the engine path in this dtype (_checks.py)
        f32 = self.dtype == np.float32
        self._max_input, self._max_angle = (MAX_INPUT_F32, MAX_ANGLE_F32) if f32 else (MAX_INPUT, MAX_ANGLE)
        self._engine = _core.Engine(model._core, self.threads, self.dtype.name) if self.engine_available() else None

    # ---- what the handle has
    @staticmethod
    def algorithm_table():
        """{algorithm: (operations, dependencies)}, the table shared with C++"""
        return dict(ALGORITHMS)

    @staticmethod
    def engine_available():
        """whether this build has the batch engine (the fast path)"""
        return hasattr(_core, "Engine")

    def available_operations(self):
        """the operations this handle provides, in table order"""
        return [op for op in OPERATIONS if op in self._ops]

    def has(self, name):
        """whether operation `name` is built into this handle"""
        if not isinstance(name, str):
            raise TypeError(f"name: expected an operation name (str), got {type(name).__name__}")
        return name in self._ops

    def fast_operations(self):
        """the operations that run on the batch engine (in the handle's
        dtype) when called without f_ext; empty without the engine"""
        if self._engine is None or not self._routable():
            return []
        return [op for op in self.available_operations() if op in ENGINE_ROUTES]

    def _routable(self):
        return self.output_convention == "pinocchio" or self._convention_noop

    # ---- dispatch
    def _call(self, op, args, kwargs):
        if op not in self._ops:
            alg = OPERATION_ALGORITHM[op]
            raise ValueError(f"{op}: this handle was not built with it; add '{alg}' to algorithms "
                             f"(Handle(model, algorithms=[..., '{alg}']))")
        method = getattr(self.rbd, op)
        accepts = "output_convention" in inspect.signature(method).parameters
        conv = kwargs.get("output_convention", self.output_convention) if accepts else self.output_convention
        if accepts:
            kwargs = {**kwargs, "output_convention": conv}
        elif (conv != "pinocchio" and not self._convention_noop
              and OPERATION_ALGORITHM[op] not in CONVENTION_NEUTRAL):
            raise ValueError(f"{op}: does not support output_convention='{conv}' on a model with free-flyer or "
                             f"spherical joints; use a handle with output_convention='pinocchio'")
        if self._engine is not None and op in ENGINE_ROUTES and (conv == "pinocchio" or self._convention_noop):
            r = self._engine_call(op, method, args, kwargs)
            if r is not None:
                return r
        r = method(*args, **kwargs)
        r = RESULTS[op](r) if op in RESULTS else r
        return _to_dtype(r, self.dtype)

    def _engine_call(self, op, method, args, kwargs):
        """the op on the batch engine, or None when this call does not fit it"""
        if self.nv == 0:  # no joints: the RBD method's empty results
            return None
        route = ENGINE_ROUTES[op]
        name, inputs, scalars, outputs, result = route[:5]
        sig = inspect.signature(method)
        a = sig.bind(*args, **kwargs)
        a.apply_defaults()
        a = a.arguments
        f = a.get("f_ext")
        if f is not None and not (isinstance(f, (list, tuple)) and len(f) == 0):
            return None
        if len(route) > 5 and not route[5](a):
            return None
        if a.get("output_convention", "pinocchio") != "pinocchio" and not self._convention_noop:
            return None
        # scalars first, then shapes, then values (the RBD order of checks)
        sc = []
        for s in scalars:
            if s == "integrator_type":
                sc.append(integrator_code(a[s]))
            elif s == "dt":
                sc.append(check_dt(a[s]))
            else:
                sc.append(check_scalar(a[s], s, self._max_input))
        dims = {"nq": self.nq, "nv": self.nv, "nx": self.nq + self.nv, "2nv": 2 * self.nv, "3nv": 3 * self.nv}
        b = Batch()
        idx = []
        for arg, w in inputs:
            # None stands for zeros only where the RBD method's default is None (qdd);
            # a required array given as None is checked (and refused) like any other
            if arg == "0" or (a[arg] is None and sig.parameters[arg].default is None):
                idx.append(None)
            elif arg == "q":
                idx.append(self.rbd._q(b, a[arg]))
            elif arg == "x":
                idx.append(b.add(a[arg], "x", (dims["nx"],), ("nq+nv",)))
            else:
                idx.append(self.rbd._v(b, a[arg], arg))
        arrays = []
        for (arg, w), i in zip(inputs, idx):
            if i is None:
                arrays.append(np.zeros((b.size, self.nv), dtype=self.dtype))
                continue
            x = b.get(i)
            if arg == "x":
                self._check_values("q", x[:, :self.nq], config=True)  # the names RBD.plant_step reports
                self._check_values("qd", x[:, self.nq:])
                arrays += [self._engine_array(x[:, :self.nq]), self._engine_array(x[:, self.nq:])]
                continue
            self._check_values(arg, x, config=(arg == "q"))
            arrays.append(self._engine_array(x))
        outs = [np.empty((b.size,) + tuple(dims[d] for d in shape), dtype=self.dtype) for shape in outputs]
        # the engine's argument order: arrays, then gravity / dt, gravity, type, then outputs
        getattr(self._engine, name)(*arrays, *sc, *outs)
        if result == "hstack":
            return b.ret(np.concatenate(outs, axis=-1))
        if isinstance(result, tuple):
            return tuple(b.ret(outs[k]) for k in result)
        return b.ret(outs[result])

    def _engine_array(self, x):
        """C-contiguous, writable (an unbatched argument is a read-only
        broadcast view), in the engine's dtype"""
        return np.require(x, dtype=self.dtype, requirements=["C", "W"])

    def _check_values(self, name, x, config=False):
        """finite values within the dtype's bounds, joint angles within theirs
        and unit quaternions, with the messages of the C++ checks"""
        bad = ~np.isfinite(x) | (np.abs(x) > self._max_input)
        if bad.any():
            s, k = np.argwhere(bad)[0]
            label = f"{name}[{s}]" if config and len(x) > 1 else name
            flat = k if config else s * x.shape[1] + k
            if not np.isfinite(x[s, k]):
                raise ValueError(f"{label}: expected finite values, got {x[s, k]:g} at flat index {flat}")
            raise ValueError(f"{label}: expected values of magnitude at most {self._max_input:g} (larger ones "
                             f"overflow{' in ' + self.dtype.name if self.dtype == np.float32 else ''}), got "
                             f"{x[s, k]:g} at flat index {flat}")
        if not config:
            return
        cols = self._angle_columns
        beyond = np.abs(x[:, cols]) > self._max_angle if len(cols) else None
        if beyond is not None and beyond.any():  # one vectorised test; the joint is found only on failure
            s, c = np.argwhere(beyond)[0]
            jname, o = self._angles[c]
            label = f"{name}[{s}]" if len(x) > 1 else name
            raise ValueError(f"{label}: the angle of joint '{jname}' (q[{o}]) must have magnitude at most "
                             f"{self._max_angle:g} rad (beyond it sin and cos have no precision left), got "
                             f"{x[s, o]:g}")
        for jname, o in self._quats:
            n = np.linalg.norm(x[:, o:o + 4], axis=1)
            off = np.abs(n - 1.0) > 1e-6
            if off.any():
                s = int(np.argmax(off))
                label = f"{name}[{s}]" if len(x) > 1 else name
                raise ValueError(f"{label}: the quaternion of joint '{jname}' (q[{o}:{o + 4}], x y z w) must have "
                                 f"unit norm, got norm {n[s]:g}")

    def __repr__(self):
        return (f"<rbdkit.Handle of {self.model!r}: {len(self.available_operations())} operations, "
                f"backend={self.backend}, dtype={self.dtype.name}, threads={self.threads}, "
                f"output_convention={self.output_convention}>")


def _operation_method(op):
    ref = getattr(RBD, op)

    def method(self, *args, **kwargs):
        return self._call(op, args, kwargs)

    method.__name__ = method.__qualname__ = op
    method.__signature__ = inspect.signature(ref)
    method.__doc__ = ref.__doc__
    return method


# the algorithm table (C++) and the RBD class must name the same operations
_missing = [op for op in OPERATIONS if not hasattr(RBD, op)]
if _missing:
    raise ImportError(f"rbdkit: the algorithm table lists operations RBD lacks: {', '.join(_missing)}")
for _op in OPERATIONS:
    setattr(Handle, _op, _operation_method(_op))
del _op
