"""What rbdkit.jax and rbdkit.torch share: the algorithms their derivative
rules call, the handle's methods generated from the operation table, and the
matrices of the maps between quaternion coordinates and the tangent space
(rbdkit.jax's module doc), written once for either array module (`xp`:
jax.numpy or torch; both have stack over an axis and the same indexing)."""

from ._handle import ALGORITHMS, OPERATION_ALGORITHM, Handle as NumpyHandle

# the operations with a derivative rule, and the algorithms their rule calls
DERIVATIVE_ALGORITHMS = {
    "inverse_dynamics": ("inverse_dynamics_gradient", "crba"),
    "forward_dynamics": ("forward_dynamics_gradient",),
    "aba": ("forward_dynamics_gradient",),
    "integrator": ("integrator_gradient",),
    "plant_step": ("integrator_gradient",),
}


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
            if not self.numpy.has(op):
                raise ValueError(f"{op}: this handle was not built with it; add '{OPERATION_ALGORITHM[op]}' to "
                                 f"algorithms")
            return getattr(self, call)(op, args, kwargs)

        method.__name__ = method.__qualname__ = op
        method.__signature__ = getattr(ref, "__signature__", None)
        method.__doc__ = ref.__doc__
        return method

    for op in OPERATION_ALGORITHM:
        setattr(cls, op, make(op))


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


def half_q(xp, quat):
    """½ Q(q) (..., 4, 3): ∂(q ⊗ (δ/2, 1))/∂δ for q = (v, w) in x y z w order: [w I + [v]x; -vᵀ] / 2"""
    x, y, z, w = (quat[..., k] for k in range(4))
    return 0.5 * xp.stack([xp.stack([w, -z, y], -1), xp.stack([z, w, -x], -1), xp.stack([-y, x, w], -1),
                           xp.stack([-x, -y, -z], -1)], -2)


def call_keywords(op, names, args, kwargs):
    """a call's positional and keyword arguments as keywords, by the operation's argument names"""
    if len(args) > len(names):
        raise TypeError(f"{op}() takes at most {len(names)} arguments ({len(args)} given)")
    kw = dict(zip(names, args))
    for name, v in kwargs.items():
        if name in kw:
            raise TypeError(f"{op}() got multiple values for argument '{name}'")
        kw[name] = v
    return kw
