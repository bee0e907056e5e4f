"""What tests/python/test_jax.py and test_torch.py share: the models of every
robot family, one handle per (model, dtype) of a framework, random states on
the manifold, central differences (in the tangent space for q) and a relative
error."""

import os
import subprocess
import sys

import numpy as np

import rbdkit

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
URDF = os.path.join(ROOT, "tests", "urdf")
SCHEMES = ["euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal", "constant_acceleration"]


# the operations of the configuration alone with a derivative rule, with their parameters
CONFIGURATION_CASES = [("crba", {}), ("minv", {}), ("minv", {"output_dense": False}), ("com", {}),
                       ("frame_placement", {}), ("frame_jacobian", {}),
                       ("frame_jacobian", {"reference_frame": "WORLD"}),
                       ("frame_jacobian", {"reference_frame": "LOCAL_WORLD_ALIGNED"}), ("end_effector_pose", {})]


def registry_cases(dtype):
    """every registered operation on floating HyQ, batched (3) and one sample, with test_handle's
    arguments in `dtype`: (op, call(handle, arguments) -> outputs as a list, arguments, the NumPy
    handle's outputs)"""
    from test_handle import REGISTERED, call, one_sample, values
    m = rbdkit.robots.load("hyq", floating_base=True)
    h = rbdkit.Handle(m, threads=1, dtype=dtype)
    as_list = lambda r: list(r) if isinstance(r, tuple) else [r]  # noqa: E731
    for op in REGISTERED:
        for v in (values(m, 3), one_sample(values(m, 3))):
            v = {k: x.astype(dtype) if isinstance(x, np.ndarray) else x for k, x in v.items()}
            yield op, (lambda hh, vv, op=op: as_list(call(hh, op, vv))), v, as_list(call(h, op, v))


def configuration_call(h, op, kw):
    """f(handle, q) -> op's outputs as a list (a framework's handle or the NumPy one, h.numpy), with a
    frame of the model's where op takes one"""
    if op in ("frame_placement", "frame_jacobian"):
        kw = dict(kw, frame_name=h.model.frame_names[len(h.model.frame_names) // 2])
    return lambda hh, q: (lambda r: list(r) if isinstance(r, tuple) else [r])(getattr(hh, op)(q, **kw))


def elementwise_cases(h, seed=0):
    """(op, (x, a, b), mu) for the quadratic costs and the log barriers of handle h: random states,
    targets and weights; bounds around the state, one of each kind infinite"""
    rng = np.random.default_rng(seed)
    nx = h.nq + h.nv
    cases = [("quadratic_state_cost", (rng.standard_normal(nx), rng.standard_normal(nx), rng.uniform(0.5, 2, nx)),
              None),
             ("quadratic_input_cost", (rng.standard_normal(h.nv), rng.standard_normal(h.nv),
                                       rng.uniform(0.5, 2, h.nv)), None)]
    for op, n in (("joint_position_barrier", h.nq), ("joint_velocity_barrier", h.nv), ("joint_torque_barrier", h.nv)):
        x = rng.standard_normal(n)
        lower, upper = x - rng.uniform(0.3, 1, n), x + rng.uniform(0.3, 1, n)
        lower[0], upper[-1] = -np.inf, np.inf
        cases.append((op, (x, lower, upper), 0.7))
    return cases


def gauss_newton_cases(h, seed=0):
    """(op, arrays {name: value}) for the Gauss–Newton costs of handle h (a framework's): states on the
    manifold, random targets and positive weights"""
    rng = np.random.default_rng(seed)
    (q, q_des), (qd, qd_des) = states(h, 2, seed)[:2]
    return [("quadratic_state_cost_tangent", {"x": np.concatenate([q, qd]), "x_des": np.concatenate([q_des, qd_des]),
                                              "Q": rng.uniform(0.5, 2, 2 * h.nv)}),
            ("com_cost", {"q": q, "p_des": rng.standard_normal(3), "W": rng.uniform(0.5, 2, 3)}),
            ("momentum_cost", {"q": q, "qd": qd, "h_des": rng.standard_normal(6), "W": rng.uniform(0.5, 2, 6)}),
            ("ee_pos_cost", {"q": q, "p_des": rng.standard_normal(3), "W": rng.uniform(0.5, 2, 3)})]


def tangent_difference(h, f, name, x, eps=1e-5):
    """∂f/∂x by central differences in the tangent space where x holds a configuration (q, or the q
    part of a state x or x_des), plainly elsewhere"""
    nq = h.nq
    if name == "q":
        return central_difference(f, x, eps, **on_manifold(h))
    if name in ("x", "x_des"):
        step = lambda x, d: np.concatenate([h.numpy.rbd.integrate(x[:nq], d[:h.nv]), x[nq:] + d[h.nv:]])  # noqa: E731
        return central_difference(f, x, eps, step=step, n=2 * h.nv)
    return central_difference(f, x, eps)


def to_tangent_gradient(h, name, x, g):
    """a gradient on x's coordinates (a framework's) as the tangent-space one tangent_difference gives"""
    g = np.asarray(g.detach() if hasattr(g, "detach") else g)
    if name == "q":
        return np.asarray(h.tangent_gradient(x, g))
    if name in ("x", "x_des"):
        return np.concatenate([np.asarray(h.tangent_gradient(x[:h.nq], g[:h.nq])), g[h.nq:]])
    return g


def load(name, floating):
    if name in rbdkit.robots.names():
        return rbdkit.robots.load(name, floating_base=floating)
    return rbdkit.Model.from_urdf(os.path.join(URDF, name + ".urdf"), floating_base=floating)


class Handles:
    """one framework handle per (model, floating, dtype), made by `make(model, dtype)` on first use"""

    def __init__(self, make):
        self.make, self.cache = make, {}

    def __call__(self, name, floating, dtype="float64"):
        key = (name, floating, dtype)
        if key not in self.cache:
            self.cache[key] = self.make(load(name, floating), dtype)
        return self.cache[key]


def states(h, B, seed=0):
    """B random (q, qd, u): q = neutral ⊕ uniform(-1, 1) tangent steps"""
    rng = np.random.default_rng(seed)
    q = np.stack([h.numpy.rbd.integrate(h.model.neutral(), rng.uniform(-1, 1, h.nv)) for _ in range(B)])
    return q, rng.uniform(-1, 1, (B, h.nv)), rng.uniform(-1, 1, (B, h.nv))


def central_difference(f, x, eps=1e-5, step=None, n=None):
    """∂f/∂x (outputs x inputs) by central differences; step(x, dx) moves x (default x + dx) along
    n directions (default x's size)"""
    step = step or (lambda x, d: x + d)
    n = n or x.shape[-1]
    return np.stack([(f(step(x, eps * e)) - f(step(x, -eps * e))) / (2 * eps) for e in np.eye(n)], -1)


def on_manifold(h):
    """central differences in the tangent space at q: q ⊕ d"""
    return {"step": h.numpy.rbd.integrate, "n": h.nv}


def rel(a, b):
    """max |a - b| relative to max(1, max |b|); a may be a JAX array or a PyTorch tensor"""
    a = a.detach().numpy() if hasattr(a, "detach") else np.asarray(a)
    return np.max(np.abs(a - b)) / max(1.0, np.max(np.abs(b)))


def import_without(framework, module):
    """what `import rbdkit` then `import rbdkit.<module>` print in a process where `framework` cannot be
    imported: "ImportError: <message>" (the test asserts the message)"""
    code = (f"import sys; sys.modules[{framework!r}] = None\n"
            "import rbdkit\n"
            f"try:\n    import rbdkit.{module}\nexcept ImportError as e:\n    print('ImportError:', e)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd="/")
    assert r.returncode == 0, r.stderr
    return r.stdout


def import_example(name):
    """the module examples/<name>.py"""
    sys.path.insert(0, os.path.join(ROOT, "examples"))
    try:
        return __import__(name)
    finally:
        sys.path.pop(0)
