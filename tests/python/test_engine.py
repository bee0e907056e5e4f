"""The batched CPU engine, rbdkit._core.Engine (threads + SIMD lanes,
float64 and float32):
  * results bit-identical for threads 1, 2, 3 and B in {1, 3, 7, 16, 65};
  * float64 equal to the RBD methods of the same names (the single-sample
    code) to 1e-12 relative (M⁻¹ and ∇FD: 1e-12·cond₁(M)/1e4 where cond₁(M)
    exceeds 1e4: the engine's sin/cos are within an ulp of libm's, and M⁻¹
    amplifies input differences by cond(M));
  * float32 within 1e-4 of float64 (relative to max(1, max |value|) per
    sample); M⁻¹ and what is built on it (∇FD, the step gradients) are
    limited by cond(M)·ε_float32 and get the documented looser bound below;
  * bad input (threads, dtype, array dtype, shapes, batch sizes) raises
    clear errors.
"""

import os

import numpy as np
import pytest

import rbdkit
from rbdkit import _core
from pinref import ROBOTS_DIR, URDF_DIR

CASES = [(f"{n}-{'floating' if fb else 'fixed'}", os.path.join(ROBOTS_DIR, n + ".urdf"), fb)
         for n in ("iiwa", "hyq", "atlas") for fb in (False, True)]
CASES += [(f"{n}-{'floating' if fb else 'fixed'}", os.path.join(URDF_DIR, n + ".urdf"), fb)
          for n in ("spherical", "helical", "mimic") for fb in (False, True)]
OPS = ("inverse_dynamics", "crba", "minv", "forward_dynamics", "inverse_dynamics_gradient",
       "forward_dynamics_gradient", "integrator_rk4", "integrator_gradient_rk4", "integrator_gradient_euler",
       "integrator_constant_acceleration")
# float32 against float64: M⁻¹ carries cond(M)·ε_float32 (atlas: ~6e-4 measured)
F32_TOL = {"minv": 2e-3, "forward_dynamics_gradient": 2e-3, "integrator_gradient_rk4": 2e-3,
           "integrator_gradient_euler": 2e-3}
DT, G = 0.01, -9.81
BMAX = 65


class Case:
    def __init__(self, path, floating):
        self.model = rbdkit.Model.from_urdf(path, floating_base=floating)
        self.rbd = rbdkit.RBD(self.model)
        m = self.model
        rng = np.random.default_rng(5)
        self.q = np.array([m.random_configuration(rng) for _ in range(BMAX)])
        self.qd = rng.uniform(-1, 1, (BMAX, m.nv))
        self.a = rng.uniform(-5, 5, (BMAX, m.nv))


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def case(request):
    return Case(request.param[1], request.param[2])


def run(engine, model, op, q, qd, a):
    """the engine's outputs of op on the batch, as a tuple of arrays"""
    dt = np.float64 if engine.dtype == "float64" else np.float32
    q, qd, a = (np.ascontiguousarray(x, dtype=dt) for x in (q, qd, a))
    B, nq, nv = q.shape[0], model.nq, model.nv
    out = lambda *s: np.full((B,) + s, np.nan, dtype=dt)
    if op == "inverse_dynamics":
        tau = out(nv)
        engine.inverse_dynamics(q, qd, a, G, tau)
        return (tau,)
    if op in ("crba", "minv"):
        M = out(nv, nv)
        getattr(engine, op)(q, M)
        return (M,)
    if op == "forward_dynamics":
        qdd = out(nv)
        engine.forward_dynamics(q, qd, a, G, qdd)
        return (qdd,)
    if op == "inverse_dynamics_gradient":
        d1, d2 = out(nv, nv), out(nv, nv)
        engine.inverse_dynamics_gradient(q, qd, a, G, d1, d2)
        return d1, d2
    if op == "forward_dynamics_gradient":
        d1, d2, Mi = out(nv, nv), out(nv, nv), out(nv, nv)
        engine.forward_dynamics_gradient(q, qd, a, G, d1, d2, Mi)
        return d1, d2, Mi
    scheme = op.split("_", 2)[-1] if op.startswith("integrator_gradient") else op.split("_", 1)[1]
    x = out(nq + nv)
    if op.startswith("integrator_gradient"):
        AB = out(2 * nv, 3 * nv)
        engine.integrator_gradient(q, qd, a, DT, G, scheme, x, AB)
        return x, AB
    engine.integrator(q, qd, a, DT, G, scheme, x)
    return (x,)


def reference(c, op):
    """the same outputs from the RBD methods"""
    r, q, qd, a = c.rbd, c.q, c.qd, c.a
    nv = c.model.nv
    if op == "inverse_dynamics":
        return (r.inverse_dynamics(q, qd, a, gravity=G)[0],)
    if op == "crba":
        return (r.crba(q),)
    if op == "minv":
        return (r.minv(q),)
    if op == "forward_dynamics":
        return (r.aba(q, qd, a, gravity=G),)
    if op == "inverse_dynamics_gradient":
        d = r.inverse_dynamics_gradient(q, qd, a, gravity=G)
        return d[:, :, :nv], d[:, :, nv:]
    if op == "forward_dynamics_gradient":
        return r.forward_dynamics_gradient(q, qd, a, gravity=G) + (r.minv(q),)
    if op.startswith("integrator_gradient"):
        s = op.split("_", 2)[-1]
        return r.integrator(q, qd, a, DT, s, gravity=G), r.integrator_gradient(q, qd, a, DT, s, gravity=G)
    return (r.integrator(q, qd, a, DT, op.split("_", 1)[1], gravity=G),)


def rel_err(a, b):
    """per sample: max |a - b| / max(1, max |b|); the worst sample"""
    a = np.concatenate([x.reshape(x.shape[0], -1) for x in a], axis=1).astype(np.float64)
    b = np.concatenate([x.reshape(x.shape[0], -1) for x in b], axis=1).astype(np.float64)
    scale = np.maximum(1, np.abs(b).max(axis=1))
    return (np.abs(a - b).max(axis=1) / scale).max()


def cond1(M, Minv):
    """the largest 1-norm condition number of a batch of mass matrices"""
    return (np.abs(M).sum(axis=1).max(axis=1) * np.abs(Minv).sum(axis=1).max(axis=1)).max()


@pytest.mark.parametrize("op", OPS)
def test_bit_identical_and_equal_to_single_sample(case, op):
    m = case.model
    engines = [_core.Engine(m._core, t, "float64") for t in (1, 2, 3)]
    full = run(engines[0], m, op, case.q, case.qd, case.a)
    for e in engines:
        for B in (1, 3, 7, 16, 65):
            part = run(e, m, op, case.q[:B], case.qd[:B], case.a[:B])
            for x, y in zip(part, full):
                assert np.array_equal(x.view(np.uint64), y[:B].view(np.uint64)), (e.threads, B)
    # the engine's sin and cos are within an ulp of libm's; M⁻¹ amplifies such
    # differences in its input by up to cond(M) (Atlas floating: ~5e5), and so do the step
    # gradients, which are built from ∇FD and M⁻¹
    tol = 1e-12
    if op in ("minv", "forward_dynamics_gradient") or op.startswith("integrator_gradient"):
        tol *= max(1.0, cond1(case.rbd.crba(case.q), case.rbd.minv(case.q)) / 1e4)
    assert rel_err(full, reference(case, op)) <= tol


@pytest.mark.parametrize("op", OPS)
def test_float32_close_to_float64(case, op):
    m = case.model
    e64, e32 = _core.Engine(m._core, 2, "float64"), _core.Engine(m._core, 2, "float32")
    r64 = run(e64, m, op, case.q, case.qd, case.a)
    r32 = run(e32, m, op, case.q, case.qd, case.a)
    assert all(x.dtype == np.float32 for x in r32)
    assert rel_err(r32, r64) <= F32_TOL.get(op, 1e-4)


def test_properties():
    m = rbdkit.robots.load("iiwa")
    e = _core.Engine(m._core, 2, "float32")
    assert e.threads == 2 and e.dtype == "float32" and e.simd_width >= 1
    d = _core.Engine(m._core)
    assert d.threads >= 1 and d.dtype == "float64"


def test_bad_input():
    m = rbdkit.robots.load("hyq", floating_base=True)  # nq = 19 != nv = 18
    nq, nv = m.nq, m.nv
    for t in (0, -1):
        with pytest.raises(ValueError, match="threads"):
            _core.Engine(m._core, t, "float64")
    with pytest.raises(ValueError, match="dtype"):
        _core.Engine(m._core, 1, "float16")
    e = _core.Engine(m._core, 2, "float64")
    rng = np.random.default_rng(0)
    q = np.array([m.random_configuration(rng) for _ in range(4)])
    v = np.zeros((4, nv))
    tau = np.zeros((4, nv))
    # wrong array dtype (no silent conversion)
    with pytest.raises(TypeError, match="q: expected a float64 array"):
        e.inverse_dynamics(q.astype(np.float32), v, v, G, tau)
    with pytest.raises(TypeError, match="tau: expected a float64 array"):
        e.inverse_dynamics(q, v, v, G, tau.astype(np.float32))
    e32 = _core.Engine(m._core, 1, "float32")
    with pytest.raises(TypeError, match="float32"):
        e32.crba(q, np.zeros((4, nv, nv)))
    # mismatched batch sizes, wrong widths, empty batch, non-contiguous
    with pytest.raises(ValueError, match="qd: batch size 3 does not match q's batch size 4"):
        e.inverse_dynamics(q, v[:3], v, G, tau)
    with pytest.raises(ValueError, match="tau: batch size 5"):
        e.inverse_dynamics(q, v, v, G, np.zeros((5, nv)))
    with pytest.raises(ValueError, match="q: expected 19 values per sample"):
        e.crba(np.ascontiguousarray(q[:, :nv]), np.zeros((4, nv, nv)))
    with pytest.raises(ValueError, match="M: expected 324 values per sample"):
        e.crba(q, np.zeros((4, nv)))
    with pytest.raises(ValueError, match="empty"):
        e.minv(q[:0], np.zeros((0, nv, nv)))
    with pytest.raises(ValueError, match="C-contiguous"):
        e.forward_dynamics(q, np.zeros((4, 2 * nv))[:, ::2], tau, G, tau)
    with pytest.raises(ValueError, match="0-d"):
        e.crba(np.array(1.0), np.zeros((1, nv, nv)))
    # integrator type and dt
    x, AB = np.zeros((4, nq + nv)), np.zeros((4, 2 * nv, 3 * nv))
    with pytest.raises(ValueError, match="integrator_type: unknown integrator 'rk3'"):
        e.integrator(q, v, tau, DT, G, "rk3", x)
    with pytest.raises(ValueError, match="integrator_type"):
        e.integrator_gradient(q, v, tau, DT, G, 7, x, AB)
    with pytest.raises(TypeError, match="integrator_type"):
        e.integrator(q, v, tau, DT, G, 1.5, x)
    with pytest.raises(ValueError, match="dt"):
        e.integrator(q, v, tau, 0.0, G, "euler", x)
    # a valid call after the errors
    e.integrator(q, v, tau, DT, G, 3, x)
    assert np.isfinite(x).all()
