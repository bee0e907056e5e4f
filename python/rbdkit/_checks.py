"""Argument checks shared by the Python API: shapes and dtypes are checked
before any work, and errors name the argument and the expected form."""

import numpy as np

from . import _core

# Input bounds (C++: rbd::kMaxInput, kMaxAngle, kMaxTimeStep in
# include/rbdkit/batch/dynamics.hpp): beyond MAX_INPUT the dynamics overflow
# float64, beyond MAX_ANGLE (rad, revolute and helical joints) sin and cos
# keep no precision; dt is at most MAX_TIME_STEP (s). (The float32 bounds,
# rbd::kMaxInputF32 and kMaxAngleF32, are checked in C++.)
MAX_INPUT = float(_core.MAX_INPUT)
MAX_ANGLE = float(_core.MAX_ANGLE)
MAX_TIME_STEP = float(_core.MAX_TIME_STEP)


def as_real_array(x, name):
    """x as a float64 ndarray; TypeError for non-numeric input."""
    if x is None or isinstance(x, (str, bytes, dict, set)):
        raise TypeError(f"{name}: expected a real numeric array, got {type(x).__name__}")
    try:
        a = np.asarray(x)
    except Exception as e:  # ragged lists and the like
        raise TypeError(f"{name}: expected a real numeric array ({e})") from None
    if a.dtype == np.bool_ or not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
        raise TypeError(f"{name}: expected a real numeric array (float or int), got dtype {a.dtype}")
    return a.astype(np.float64, copy=False)


class Batch:
    """Collects arguments of one call, each (*shape) or (B, *shape), checks
    that their batch sizes agree, and broadcasts unbatched ones."""

    def __init__(self):
        self.B = None          # batch size of the batched arguments, None if none is batched
        self.source = None     # the argument that set B
        self._args = []

    def add(self, x, name, shape, dims):
        """shape: expected trailing shape (ints); dims: their names, e.g. ('nq',)"""
        a = as_real_array(x, name)
        shape = tuple(int(s) for s in shape)
        k = len(shape)
        desc = ", ".join(f"{d}={s}" for d, s in zip(dims, shape))
        expect = f"{shape if k != 1 else '(' + str(shape[0]) + ',)'} or (B, {', '.join(map(str, shape))})"
        if a.ndim == k and a.shape == shape:
            batched = False
        elif a.ndim == k + 1 and a.shape[1:] == shape:
            batched = True
            if a.shape[0] == 0:
                raise ValueError(f"{name}: the batch is empty (shape {a.shape})")
            if self.B is not None and a.shape[0] != self.B:
                raise ValueError(f"{name}: batch size {a.shape[0]} does not match {self.source}'s batch size {self.B}")
            self.B, self.source = a.shape[0], name
        else:
            raise ValueError(f"{name}: expected shape {expect} with {desc}, got shape {a.shape}")
        self._args.append((a, batched, shape))
        return len(self._args) - 1

    @property
    def batched(self):
        return self.B is not None

    @property
    def size(self):
        return self.B if self.B is not None else 1

    def get(self, i):
        """argument i as a C-contiguous (B, *shape) float64 array"""
        a, batched, shape = self._args[i]
        if not batched:
            a = np.broadcast_to(a, (self.size,) + shape)
        return np.ascontiguousarray(a, dtype=np.float64)

    def out(self, *shape):
        return np.empty((self.size,) + tuple(shape), dtype=np.float64)

    def ret(self, a):
        """drop the batch axis again for an unbatched call"""
        return a if self.batched else a[0]


def check_values(a, name, batched=False):
    """finite values of magnitude at most MAX_INPUT (the C++ check_finite);
    batched: a (B, ...) array whose failing sample is named as name[s]"""
    a = np.asarray(a)
    bad = ~np.isfinite(a) | (np.abs(a) > MAX_INPUT)
    if not bad.any():
        return a
    s = int(np.argmax(bad.reshape(len(a), -1).any(axis=1))) if batched else None
    label = f"{name}[{s}]" if batched else name
    v = a[bad][0]
    if not np.isfinite(v):
        raise ValueError(f"{label}: expected finite values, got {v:g}")
    raise ValueError(f"{label}: expected values of magnitude at most {MAX_INPUT:g} (larger ones overflow), got {v:g}")


def check_scalar(x, name, bound=None):
    """a real number, finite; |x| <= bound when given"""
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name}: expected a real number, got {type(x).__name__}")
    x = float(x)
    if not np.isfinite(x):
        raise ValueError(f"{name}: expected a finite number, got {x}")
    if bound is not None and abs(x) > bound:
        raise ValueError(f"{name}: expected a magnitude of at most {bound:g} (larger ones overflow), got {x:g}")
    return x


def check_choice(x, name, choices):
    if not isinstance(x, str) or x not in choices:
        raise ValueError(f"{name}: expected one of {', '.join(repr(c) for c in choices)}, got {x!r}")
    return choices.index(x)
