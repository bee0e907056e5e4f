"""Second-order dynamics derivatives (IDSVA-SO, FDSVA-SO): the body- and
world-frame recursions agree (1e-10 relative); every tensor against central
finite differences of the first-order derivatives in the tangent space
(through integrate) and of crba (1e-6 relative); symmetries, the Lie-bracket
asymmetry inside free-flyer and spherical joints, the Christoffel identity on
Euclidean models; batches. On the bundled robots and the joint-type models,
fixed and floating base. Pinocchio's ComputeRNEASecondOrderDerivatives is
C++ only in Pinocchio 4: that comparison is tests/pinocchio_so/."""

import numpy as np
import pytest

import rbdkit
from pinref import all_models, assert_close

CASES = all_models()


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def model(request):
    _, path, fb = request.param
    return rbdkit.Model.from_urdf(path, floating_base=fb)


def state(model, seed=4, vscale=2.0):
    rng = np.random.default_rng(seed)
    q = model.random_configuration(rng, scale=np.pi)
    return (q, rng.uniform(-vscale, vscale, model.nv), rng.uniform(-3, 3, model.nv),
            rng.uniform(-30, 30, model.nv))


def fd_tangent(rbd, f, q, eps=1e-3):
    """five-point central differences (error O(eps⁴)) of f along q <- integrate(q, t e_k),
    t = ±eps, ±2 eps, stacked on a last axis k. The fourth-order stencil lets the step
    stay large, which keeps the rounding of the first-order results (amplified by
    M⁻¹ in forward dynamics) well below the 1e-6 tolerance."""
    cols = []
    for k in range(rbd.nv):
        d = np.zeros(rbd.nv)
        d[k] = eps
        f1 = f(rbd.integrate(q, d)) - f(rbd.integrate(q, -d))
        f2 = f(rbd.integrate(q, 2 * d)) - f(rbd.integrate(q, -2 * d))
        cols.append((8 * f1 - f2) / (12 * eps))
    return np.stack(cols, axis=-1)


def fd_vector(f, x, eps):
    cols = []
    for k in range(x.size):
        d = np.zeros(x.size)
        d[k] = eps
        cols.append((f(x + d) - f(x - d)) / (2 * eps))
    return np.stack(cols, axis=-1)


def lie_blocks(model):
    """(tangent offset, kind) of every free-flyer and spherical joint"""
    return [(j["v_index"], j["type"]) for j in model.joints if j["type"] in ("free", "spherical") and not j["mimic_of"]]


def bracket(kind, a, b):
    """[e_a, e_b] in a free-flyer ([v; ω], se(3)) or spherical (ω, so(3)) joint's tangent coordinates"""
    n = 6 if kind == "free" else 3
    ea, eb = np.eye(n)[a], np.eye(n)[b]
    if kind == "spherical":
        return np.cross(ea, eb)
    va, wa, vb, wb = ea[:3], ea[3:], eb[:3], eb[3:]
    return np.concatenate([np.cross(wa, vb) + np.cross(va, wb), np.cross(wa, wb)])


def test_shapes_and_dispatch(model):
    rbd = rbdkit.RBD(model)
    q, qd, qdd, _ = state(model)
    n = model.nv
    body = rbd.idsva_so_body_frame(q, qd, qdd)
    world = rbd.idsva_so_world_frame(q, qd, qdd)
    auto = rbd.idsva_so(q, qd, qdd)
    assert len(body) == len(world) == len(auto) == 4
    for t in body + world + auto:
        assert t.shape == (n, n, n) and t.dtype == np.float64
    chosen = world if model.floating_base else body
    for a, c in zip(auto, chosen):
        np.testing.assert_array_equal(a, c)
    fd = rbd.fdsva_so(q, qd, qdd)
    assert len(fd) == 4 and all(t.shape == (n, n, n) for t in fd)


@pytest.mark.parametrize("vscale", [2.0, 20.0])
def test_body_and_world_frame_variants_agree(model, vscale):
    rbd = rbdkit.RBD(model)
    for seed in (1, 2):
        q, qd, qdd, _ = state(model, seed, vscale)
        for g in (-9.81, 3.0):
            body = rbd.idsva_so_body_frame(q, qd, qdd, gravity=g)
            world = rbd.idsva_so_world_frame(q, qd, qdd, gravity=g)
            for name, b, w in zip(("d2tau_dq2", "d2tau_dqd2", "d2tau_dqdqd", "dM_dq"), body, world):
                assert_close(b, w, f"{name}: body vs world frame", 1e-10)


def test_idsva_so_by_finite_differences(model):
    rbd = rbdkit.RBD(model)
    nv = model.nv
    q, qd, qdd, _ = state(model)
    g = -4.0
    d2q, d2v, d2qv, dM = rbd.idsva_so(q, qd, qdd, gravity=g)
    grad = lambda qq, vv, aa: rbd.inverse_dynamics_gradient(qq, vv, aa, gravity=g)
    # ∂/∂q_k of ∂tau/∂q (tangent steps through integrate)
    assert_close(d2q, fd_tangent(rbd, lambda qq: grad(qq, qd, qdd)[:, :nv], q), "d2tau_dq2 vs FD", 1e-6)
    # qd: tau is quadratic in qd, so qd differences are exact up to rounding at any step
    assert_close(d2v, fd_vector(lambda v: grad(q, v, qdd)[:, nv:], qd, 0.1), "d2tau_dqd2 vs FD", 1e-6)
    # the cross term both ways: ∂/∂qd_k of ∂tau/∂q_j and ∂/∂q_j of ∂tau/∂qd_k
    assert_close(d2qv, fd_vector(lambda v: grad(q, v, qdd)[:, :nv], qd, 0.1), "d2tau_dqdqd vs FD in qd", 1e-6)
    assert_close(d2qv, fd_tangent(rbd, lambda qq: grad(qq, qd, qdd)[:, nv:], q).transpose(0, 2, 1),
                 "d2tau_dqdqd vs FD in q", 1e-6)
    # ∂M/∂q from crba, and as ∂/∂qdd_j of ∂tau/∂q_k
    assert_close(dM, fd_tangent(rbd, rbd.crba, q), "dM_dq vs FD of crba", 1e-6)
    assert_close(dM, fd_vector(lambda a: grad(q, qd, a)[:, :nv], qdd, 1e-3).transpose(0, 2, 1),
                 "dM_dq vs FD of dtau/dq in qdd", 1e-6)


def test_fdsva_so_by_finite_differences(model):
    rbd = rbdkit.RBD(model)
    q, qd, _, u = state(model, seed=6)
    g = -4.0
    d2q, d2v, d2qv, d2qu = rbd.fdsva_so(q, qd, u, gravity=g)
    grad = lambda qq, vv, uu: rbd.forward_dynamics_gradient(qq, vv, uu, gravity=g)
    # qd and u steps are exact up to rounding (qdd is quadratic in qd, linear in u)
    assert_close(d2q, fd_tangent(rbd, lambda qq: grad(qq, qd, u)[0], q), "d2qdd_dq2 vs FD", 1e-6)
    assert_close(d2v, fd_vector(lambda v: grad(q, v, u)[1], qd, 0.1), "d2qdd_dqd2 vs FD", 1e-6)
    assert_close(d2qv, fd_vector(lambda v: grad(q, v, u)[0], qd, 0.1), "d2qdd_dqdqd vs FD in qd", 1e-6)
    assert_close(d2qv, fd_tangent(rbd, lambda qq: grad(qq, qd, u)[1], q).transpose(0, 2, 1),
                 "d2qdd_dqdqd vs FD in q", 1e-6)
    assert_close(d2qu, fd_vector(lambda uu: grad(q, qd, uu)[0], u, 1.0), "d2qdd_dqdu vs FD", 1e-6)
    # ∂qdd/∂u = M⁻¹ does not depend on qd or u: ∂²qdd/∂q∂u is also ∂M⁻¹/∂q
    assert_close(d2qu, fd_tangent(rbd, rbd.minv, q).transpose(0, 2, 1), "d2qdd_dqdu vs FD of minv", 1e-6)


def test_symmetries(model):
    rbd = rbdkit.RBD(model)
    nv = model.nv
    q, qd, qdd, u = state(model, seed=8)
    d2q, d2v, d2qv, dM = rbd.idsva_so(q, qd, qdd)
    fq, fv, _, fqu = rbd.fdsva_so(q, qd, u)
    # always symmetric: the qd Hessians (qd is a vector space) and ∂M/∂q in (i, j)
    assert_close(d2v, d2v.transpose(0, 2, 1), "d2tau_dqd2 symmetric in (j, k)", 1e-12)
    assert_close(fv, fv.transpose(0, 2, 1), "d2qdd_dqd2 symmetric in (j, k)", 1e-11)
    assert_close(dM, dM.transpose(1, 0, 2), "dM_dq symmetric in (i, j)", 1e-12)
    # d2tau_dq2 is symmetric in (j, k) except inside a free-flyer / spherical joint
    mask = np.ones((nv, nv), dtype=bool)
    blocks = lie_blocks(model)
    for o, kind in blocks:
        n = 6 if kind == "free" else 3
        mask[o:o + n, o:o + n] = False
    asym = d2q - d2q.transpose(0, 2, 1)
    assert_close(asym[:, mask], np.zeros_like(asym[:, mask]), "d2tau_dq2 symmetric outside Lie-group blocks", 1e-12)
    asym_f = fq - fq.transpose(0, 2, 1)
    assert_close(asym_f[:, mask], np.zeros_like(asym_f[:, mask]), "d2qdd_dq2 symmetric outside Lie-group blocks",
                 1e-11)
    # inside them: d2[:, j, k] - d2[:, k, j] = (∂/∂q)·[e_k, e_j], the first derivative along the bracket
    dtau_dq = rbd.inverse_dynamics_gradient(q, qd, qdd)[:, :nv]
    dqdd_dq = rbd.forward_dynamics_gradient(q, qd, u)[0]
    for o, kind in blocks:
        n = 6 if kind == "free" else 3
        for a in range(n):
            for b in range(n):
                c = bracket(kind, b, a)  # [e_k, e_j] with j = o + a (inner), k = o + b (outer)
                assert_close(asym[:, o + a, o + b], dtau_dq[:, o:o + n] @ c, f"ID bracket {kind} ({a}, {b})", 1e-10)
                assert_close(asym_f[:, o + a, o + b], dqdd_dq[:, o:o + n] @ c, f"FD bracket {kind} ({a}, {b})",
                             1e-9)
    if blocks and np.abs(dtau_dq).max() > 0:
        assert np.abs(asym).max() > 1e-6  # the asymmetry is there, not only allowed
    # Euclidean configuration spaces: 2 Γ_ijk from ∂M/∂q (Christoffel symbols of the first kind)
    if not blocks:
        christoffel = dM + dM.transpose(0, 2, 1) - np.einsum("jki->ijk", dM)
        assert_close(d2v, christoffel, "d2tau_dqd2 = dM_ij/dq_k + dM_ik/dq_j - dM_jk/dq_i", 1e-11)
        # and ∂M⁻¹/∂q = -M⁻¹ ∂M/∂q M⁻¹
        Mi = rbd.minv(q)
        assert_close(fqu, -np.einsum("ia,abj,bk->ijk", Mi, dM, Mi), "d2qdd_dqdu = -M⁻¹ dM M⁻¹", 1e-10)


def test_batches_equal_single_samples(model):
    rbd = rbdkit.RBD(model)
    data = [state(model, seed) for seed in (1, 2, 3)]
    Q, V, A, U = (np.stack([d[k] for d in data]) for k in range(4))
    for method, third in (("idsva_so_body_frame", A), ("idsva_so_world_frame", A), ("idsva_so", A),
                          ("fdsva_so", U)):
        f = getattr(rbd, method)
        out = f(Q, V, third)
        assert all(t.shape == (3, model.nv, model.nv, model.nv) for t in out)
        for s in range(3):
            single = f(Q[s], V[s], third[s])
            for t, t1 in zip(out, single):
                np.testing.assert_array_equal(t[s], t1)
    # an unbatched argument is broadcast
    out = rbd.idsva_so(Q, V[0], A[0])
    np.testing.assert_array_equal(out[0][2], rbd.idsva_so(Q[2], V[0], A[0])[0])


def test_second_order_with_zero_velocity_is_gravity_and_inertia_only():
    # at qd = 0 the qd-q cross term is zero on a fixed base (no velocity products) and
    # d2tau_dqd2 does not depend on the state's velocity or acceleration
    m = rbdkit.robots.load("iiwa")
    rbd = rbdkit.RBD(m)
    q, qd, qdd, _ = state(m)
    _, d2v_a, d2qv0, _ = rbd.idsva_so(q, np.zeros(m.nv), qdd)
    _, d2v_b, _, _ = rbd.idsva_so(q, qd, np.zeros(m.nv))
    assert_close(d2qv0, np.zeros_like(d2qv0), "d2tau_dqdqd at qd = 0", 1e-13)
    assert_close(d2v_a, d2v_b, "d2tau_dqd2 independent of qd, qdd", 1e-13)
