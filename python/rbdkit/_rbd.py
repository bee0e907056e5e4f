"""rbdkit.RBD: the dynamics of one model, single samples or batches.

Shapes: q (nq,), qd/qdd/tau/u (nv,), per-body 6D quantities (nb, 6) in the
body frame as [linear; angular]; each may carry a leading batch axis B, and
unbatched arguments are broadcast against batched ones. Results carry the
batch axis when any argument did.

The registered operations (include/rbdkit/ops/registry.hpp: inverse and
forward dynamics, M, M⁻¹, their first- and second-order derivatives, the
Lie-group operations, the integrators, the plant step with its gradient and
Hessian, kinematics, energies, centroidal quantities, the regressors, the
costs and barriers: every operation) are generated from the C++ registry: each
instance holds one compiled callable per operation, which parses, checks
and allocates in C++ (python/src/bind_ops.cpp). The class attributes of the
same names carry their signatures and documentation.
"""

import inspect

import numpy as np

from . import _core
from ._checks import Batch, check_choice, check_values
from ._model import Model

GRAVITY = -9.81


class RBD:
    """Rigid-body dynamics of a Model (see the module doc for shapes)."""

    def __init__(self, model):
        if not isinstance(model, Model):
            raise TypeError(f"model: expected an rbdkit.Model, got {type(model).__name__}")
        self.model = model
        self._m = model._core
        self.nq, self.nv, self.nb = model.nq, model.nv, model.nb
        # the registered operations: compiled callables (instance attributes
        # shadow the class's generic methods, not a subclass's override)
        self._ops = _core.OpHandle(model._core, [], 0, "float64")
        self._compiled = {name: self._ops.op(name, False) for name in _GENERIC}
        cls = type(self)
        for name, generic in _GENERIC.items():
            if getattr(cls, name) is generic:
                self.__dict__[name] = self._compiled[name]

    # ---- argument helpers
    def _q(self, b, q, name="q"):
        return b.add(q, name, (self.nq,), ("nq",))

    def _v(self, b, v, name):
        return b.add(v, name, (self.nv,), ("nv",))

    # ---- timing (for reports; benchmarks live in bench/)
    def time_per_call(self, op, q, qd, tau, iters=2000):
        """seconds per call of a core algorithm in C++ (best of 5 runs of
        `iters` calls); op: inverse_dynamics, crba, minv, aba, forward_dynamics"""
        ops = ("inverse_dynamics", "crba", "minv", "aba", "forward_dynamics")
        check_choice(op, "op", ops)
        if isinstance(iters, (bool, np.bool_)) or not isinstance(iters, (int, np.integer)) or iters < 1:
            raise ValueError(f"iters: expected a positive integer, got {iters!r}")
        b = Batch()
        iq, iv, it = self._q(b, q), self._v(b, qd, "qd"), self._v(b, tau, "tau")
        if b.batched:
            raise ValueError("time_per_call: expected one sample, not a batch")
        self.integrate(q, np.zeros(self.nv))  # checks q (finite, unit quaternions)
        for name, i in (("qd", iv), ("tau", it)):
            check_values(b.get(i), name)
        return _core.time_per_call(self._m, op, b.get(iq)[0], b.get(iv)[0], b.get(it)[0], int(iters))

    def __repr__(self):
        return f"<rbdkit.RBD of {self.model!r}>"


# ---- the registered operations' class attributes: signature and doc from
# the registry; a call goes to the instance's compiled callable
REGISTERED = tuple(op[0] for op in _core.registered_operations())
_NO_DEFAULT = ("array", "dt", "frame")


def _registered_method(name, doc, args):
    def method(self, *a, **k):
        return self._compiled[name](*a, **k)

    P = inspect.Parameter
    # an optional array before a required one (the per-pass helpers' qdd) is
    # shown without its default: a signature cannot have one there, and the
    # call still takes None for it
    required = [kind in _NO_DEFAULT or (kind in ("real", "positive") and default is None) for _, kind, default in args]
    last_required = max((k for k, r in enumerate(required) if r), default=-1)
    params = [P("self", P.POSITIONAL_OR_KEYWORD)]
    params += [P(arg, P.POSITIONAL_OR_KEYWORD, default=P.empty if required[k] or k < last_required else default)
               for k, (arg, kind, default) in enumerate(args)]
    method.__name__ = name
    method.__qualname__ = f"RBD.{name}"
    method.__doc__ = doc.split("\n\n", 1)[-1]
    method.__signature__ = inspect.Signature(params)
    return method


_GENERIC = {}  # name -> the class attribute
for _name, _alg, _family, _doc, _args in _core.registered_operations():
    _GENERIC[_name] = _registered_method(_name, _doc, _args)
    setattr(RBD, _name, _GENERIC[_name])
del _name, _alg, _family, _doc, _args
