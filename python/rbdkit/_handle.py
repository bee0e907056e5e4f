"""rbdkit.Handle: a robot, the algorithms it is built with, a backend and a
precision; every operation of rbdkit.RBD on batched arrays.

    h = rbdkit.Handle(model, algorithms=["integrator_gradient", "com_cost"], dtype="float32", threads=2)
    h.available_operations()     # integrator, plant_step, integrator_gradient, ..., com, ccrba, com_cost, ...
    AB = h.plant_step_gradient(X, U, 0.01, "rk4")      # X (B, nq + nv), U (B, nv) -> (B, 2nv, 3nv)
    h.crba(q)                    # ValueError: crba: this handle was not built with it; add 'crba' ...

Algorithms, the operations each provides and their dependencies come from
one table shared with the C++ rbd::Handle (include/rbdkit/handle/handle.hpp,
`Handle.algorithm_table()`); selecting an algorithm brings what it requires
(plant_step_hessian -> fdsva_so, com_cost -> com and ccrba, momentum_cost ->
dccrba, integrator_gradient -> forward_dynamics_gradient, ...).

Every method has the signature, argument checks and results of the RBD
method of the same name (one sample or a batch on axis 0), with one
exception: `inverse_dynamics` returns the joint forces tau only (per-body
velocities, accelerations and forces: `inverse_dynamics_fpass`, or
rbdkit.RBD).

Precision, threads and the output convention. Every operation is a
compiled callable of the C++ rbd::Handle (include/rbdkit/handle/handle.hpp,
generated from the registry include/rbdkit/ops/registry.hpp): it checks its
arguments and computes in the handle's dtype (dtype="float32": float32
arithmetic and arrays) on the batch engine with `threads` threads, f_ext
included. The handle's output_convention is the default of every operation
that takes one (the integrators, the plant step, the costs); on a model with
free-flyer or spherical joints a MuJoCo handle refuses the operations that
take none, but for the conversions between the conventions. Those
decisions are the C++ handle's.

Specialised code. Handle(model, specialize=True) generates the robot's
header (rbdkit.generate), compiles it with the system's C++ compiler ($CXX,
else c++) into a shared library cached per model, compiler, flags and
rbdkit's headers ($RBDKIT_CACHE_DIR, else ~/.cache/rbdkit: the first handle
of a robot takes seconds, later ones load the library) and loads it: float64
single-sample calls of the dynamics, M, M⁻¹, their first derivatives and the
step then run its per-robot kernels, with the same results to rounding
(batches stay on the batch engine). On backend="cuda" it compiles the CUDA
backend's kernels on the robot's constants instead (nvcc, or the C++ compiler
in interpret mode) for ID, M⁻¹, FD, ∇ID, ∇FD and the step gradient, every
batch size, both dtypes. Without a compiler it warns once and keeps the
generic kernels (so does a CPU float32 handle, which computes on the engine);
`specialized` says which is in use (docs/generated-code.md).
"""

import inspect
import os
import warnings

import numpy as np

from . import _core
from ._model import Model
from ._rbd import RBD

# ---- the algorithm table (C++: rbd::handle_algorithms)
ALGORITHMS = {name: (tuple(ops), tuple(deps)) for name, ops, deps in _core.handle_algorithms()}
OPERATION_ALGORITHM = {op: name for name, (ops, _) in ALGORITHMS.items() for op in ops}
OPERATIONS = tuple(OPERATION_ALGORITHM)  # every operation a handle can have, in table order

DTYPES = ("float64", "float32")
BACKENDS = ("cpu", "cuda")
CONVENTIONS = ("pinocchio", "mujoco")



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
    if not isinstance(backend, str) or backend not in BACKENDS:
        raise ValueError(f"backend: expected 'cpu' or 'cuda', got {backend!r}")
    return backend


def cuda_available():
    """(whether this build has the real CUDA kernels, the CUDA devices this process sees);
    backend='cuda' needs both, or RBDKIT_CUDA_INTERPRET=1 (the kernels' source on the CPU)"""
    compiled, devices = _core.cuda_info()
    return bool(compiled), int(devices)


def device_empty(proto, shape, dtype):
    """a new device array of `shape` and `dtype` on the device of `proto` (a
    device array passed to a backend='cuda' handle), made by proto's framework:
    the outputs of a call on device arrays. PyTorch and CuPy arrays are
    recognised; another type may offer a classmethod `_rbdkit_empty(shape,
    dtype, like)` (the tests' NumPy stand-ins do)."""
    make = getattr(type(proto), "_rbdkit_empty", None)
    if make is not None:
        return make(shape, dtype, proto)
    module = type(proto).__module__.split(".")[0]
    if module == "torch":
        import torch
        return torch.empty(shape, dtype=getattr(torch, dtype), device=proto.device)
    if module == "cupy":
        import cupy
        with proto.device:
            return cupy.empty(shape, dtype=dtype)
    raise TypeError(f"device arrays of type {type(proto).__module__}.{type(proto).__name__}: rbdkit cannot make "
                    f"the outputs on their device (PyTorch and CuPy arrays are supported)")


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


_SPECIALIZE_WARNED = set()


def _specialize(core):
    """loads the handle's compiled instance (compiling it first if not cached): whether it is in
    use; if not, warns once per reason and the generic kernels stay"""
    from ._codegen import include_dir
    ok, detail = core.specialize("", "", include_dir())
    if not ok and detail not in _SPECIALIZE_WARNED:
        _SPECIALIZE_WARNED.add(detail)
        warnings.warn(f"rbdkit: specialize=True fell back to the generic kernels: {detail}", RuntimeWarning,
                      stacklevel=3)
    return ok


class Handle:
    """Operations of a model on batched arrays (module doc). Attributes:
    model, rbd (the float64 rbdkit.RBD reference path), algorithms (resolved),
    backend, dtype (numpy dtype), threads, output_convention, specialized
    (whether the compiled per-robot kernels are in use: module doc)."""

    def __init__(self, model, algorithms=None, backend="cpu", dtype="float64", threads=None,
                 output_convention="pinocchio", stream=None, specialize=False):
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
        # the C++ handle (rbd::Handle): the operations in this dtype, on the
        # engine with these threads, in this output convention, as compiled
        # callables (instance attributes, shadowing the generic methods of the class)
        self._core = _core.OpHandle(model._core, list(self.algorithms), self.threads, self.dtype.name,
                                    self.output_convention, self.backend)
        if stream is not None:
            self.set_stream(stream)
        if not isinstance(specialize, (bool, np.bool_)):
            raise TypeError(f"specialize: expected True or False, got {type(specialize).__name__}")
        self.specialized = bool(specialize) and _specialize(self._core)
        for op in self._core.operations():
            self.__dict__[op] = self._core.op(op, True)

    # ---- the CUDA backend
    @property
    def device(self):
        """the device a backend='cuda' handle computes on ("interpret (CPU)" in
        interpret mode); None on the CPU backend"""
        return self._core.device

    def set_stream(self, stream):
        """the CUDA stream a backend='cuda' handle launches on: a cudaStream_t
        as an int (0: the default stream), an object with a `cuda_stream` or
        `ptr` attribute (PyTorch, CuPy), or None for the handle's own stream
        (the default; it waits for the default stream, where PyTorch and CuPy
        work unless told otherwise)"""
        if stream is None:
            self._core.set_stream(None)
            return
        for attr in ("cuda_stream", "ptr"):
            if not isinstance(stream, (int, np.integer)) and hasattr(stream, attr):
                stream = getattr(stream, attr)
        if isinstance(stream, (bool, np.bool_)) or not isinstance(stream, (int, np.integer)) or stream < 0:
            raise TypeError(f"stream: expected a CUDA stream (an int handle, or an object with cuda_stream or "
                            f"ptr), got {type(stream).__name__}")
        self._core.set_stream(int(stream))

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
        """the operations this handle computes in C++, in its dtype, on the
        engine with its threads: all of them (every operation is registered,
        include/rbdkit/ops/registry.hpp)"""
        return self._core.operations()

    # ---- an operation this handle was not built with (the others are compiled callables)
    def _call(self, op, args, kwargs):
        alg = OPERATION_ALGORITHM[op]
        raise ValueError(f"{op}: this handle was not built with it; add '{alg}' to algorithms "
                         f"(Handle(model, algorithms=[..., '{alg}']))")

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
