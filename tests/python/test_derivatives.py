"""First-order dynamics derivatives: against Pinocchio's computeRNEADerivatives
and computeABADerivatives (1e-9 relative) and against central finite
differences in the tangent space (1e-6 relative), on the bundled robots and
the joint-type models, fixed and floating base; plus the per-pass helpers."""

import numpy as np
import pytest

import rbdkit
from pinref import Reference, all_models, assert_close

CASES = all_models()


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def ref(request):
    _, path, fb = request.param
    return Reference(path, fb)


def states(model, n=3, seed=0):
    rng = np.random.default_rng(seed)
    for k in range(n):
        q = model.random_configuration(rng, scale=np.pi)
        vs = 20.0 if k == n - 1 else 2.0
        yield (q, rng.uniform(-vs, vs, model.nv), rng.uniform(-3, 3, model.nv), rng.uniform(-30, 30, model.nv),
               rng.uniform(-5, 5, (model.nb, 6)))


def fd_tangent(rbd, f, q, eps=1e-5):
    """central differences of f along q <- integrate(q, ±eps e_k): (out..., nv)"""
    cols = []
    for k in range(rbd.nv):
        d = np.zeros(rbd.nv)
        d[k] = eps
        cols.append((f(rbd.integrate(q, d)) - f(rbd.integrate(q, -d))) / (2 * eps))
    return np.stack(cols, axis=-1)


def fd_vector(f, x, eps=1e-6):
    cols = []
    for k in range(x.size):
        d = np.zeros(x.size)
        d[k] = eps
        cols.append((f(x + d) - f(x - d)) / (2 * eps))
    return np.stack(cols, axis=-1)


def test_inverse_dynamics_gradient_matches_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    nv = ref.model.nv
    for q, qd, qdd, _, fext in states(ref.model):
        for fx, g in ((None, -9.81), (fext, -4.0)):
            D = rbd.inverse_dynamics_gradient(q, qd, qdd, gravity=g, f_ext=fx)
            assert D.shape == (nv, 2 * nv)
            dq, dv = ref.rnea_derivatives(q, qd, qdd, g, fx)
            assert_close(D[:, :nv], dq, "dtau/dq")
            assert_close(D[:, nv:], dv, "dtau/dqd")
        # qdd=None means zero acceleration
        dq0, _ = ref.rnea_derivatives(q, qd, np.zeros(nv))
        assert_close(rbd.inverse_dynamics_gradient(q, qd)[:, :nv], dq0, "dtau/dq at qdd=0")


def test_forward_dynamics_gradient_matches_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, _, tau, fext in states(ref.model):
        for fx in (None, fext):
            dq, dv = rbd.forward_dynamics_gradient(q, qd, tau, f_ext=fx)
            rq, rv = ref.aba_derivatives(q, qd, tau, -9.81, fx)
            assert_close(dq, rq, "dqdd/dq")
            assert_close(dv, rv, "dqdd/dqd")


def test_gradients_by_finite_differences(ref):
    rbd = rbdkit.RBD(ref.model)
    nv = ref.model.nv
    # a moderate-velocity state; qd steps of 1e-4 are exact up to rounding (ID
    # and FD are quadratic in qd), tangent steps of 1e-5 balance truncation and rounding
    q, qd, qdd, tau, fext = next(states(ref.model, 2, seed=4))
    D = rbd.inverse_dynamics_gradient(q, qd, qdd, f_ext=fext)
    tau_of = lambda qq: rbd.inverse_dynamics(qq, qd, qdd, f_ext=fext)[0]
    assert_close(D[:, :nv], fd_tangent(rbd, tau_of, q), "dtau/dq vs FD", 1e-6)
    assert_close(D[:, nv:], fd_vector(lambda v: rbd.inverse_dynamics(q, v, qdd, f_ext=fext)[0], qd, 1e-4),
                 "dtau/dqd vs FD", 1e-6)
    dq, dv = rbd.forward_dynamics_gradient(q, qd, tau, f_ext=fext)
    assert_close(dq, fd_tangent(rbd, lambda qq: rbd.aba(qq, qd, tau, f_ext=fext), q), "dqdd/dq vs FD", 1e-6)
    assert_close(dv, fd_vector(lambda v: rbd.aba(q, v, tau, f_ext=fext), qd, 1e-4), "dqdd/dqd vs FD", 1e-6)


def test_f_ext_gradient(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    q, qd, qdd, tau, fext = next(states(m, 2, seed=7))
    dtau, dqdd = rbd.f_ext_gradient(q)
    assert dtau.shape == (m.nb, m.nv, 6) and dqdd.shape == (m.nb, m.nv, 6)
    for b in range(m.nb):
        assert_close(dtau[b], -ref.body_jacobian(q, b).T, f"dtau/dfext of body {b} = -J^T")
    # finite differences (the maps are linear in f_ext)
    flat = fext.reshape(-1)
    fd_tau = fd_vector(lambda f: rbd.inverse_dynamics(q, qd, qdd, f_ext=f.reshape(m.nb, 6))[0], flat, 1e-3)
    fd_acc = fd_vector(lambda f: rbd.aba(q, qd, tau, f_ext=f.reshape(m.nb, 6)), flat, 1e-3)
    assert_close(dtau.transpose(1, 0, 2).reshape(m.nv, -1), fd_tau, "dtau/dfext vs FD", 1e-6)
    assert_close(dqdd.transpose(1, 0, 2).reshape(m.nv, -1), fd_acc, "dqdd/dfext vs FD", 1e-6)
    assert_close(dqdd, np.einsum("ij,bjk->bik", rbd.minv(q), -dtau), "M^-1 J^T")


def test_gradient_batches_equal_single_samples(ref):
    rbd = rbdkit.RBD(ref.model)
    data = list(states(ref.model, 3, seed=2))
    Q, V, A, T = (np.stack([d[k] for d in data]) for k in range(4))
    D = rbd.inverse_dynamics_gradient(Q, V, A)
    dq, dv = rbd.forward_dynamics_gradient(Q, V, T)
    for k in range(3):
        np.testing.assert_array_equal(D[k], rbd.inverse_dynamics_gradient(Q[k], V[k], A[k]))
        np.testing.assert_array_equal(dq[k], rbd.forward_dynamics_gradient(Q[k], V[k], T[k])[0])
        np.testing.assert_array_equal(dv[k], rbd.forward_dynamics_gradient(Q[k], V[k], T[k])[1])


def test_per_pass_helpers_compose(ref):
    rbd = rbdkit.RBD(ref.model)
    nv = ref.model.nv
    for q, qd, qdd, _, fext in states(ref.model, 2, seed=9):
        # RNEA passes
        v, a, f = rbd.inverse_dynamics_fpass(q, qd, qdd, f_ext=fext)
        tau, fj = rbd.inverse_dynamics_bpass(q, f)
        tau_ref, v_ref, _, f_ref = rbd.inverse_dynamics(q, qd, qdd, f_ext=fext)
        assert_close(tau, tau_ref, "bpass(fpass) = inverse_dynamics", 1e-12)
        assert_close(v, v_ref, "fpass velocities", 1e-12)
        assert_close(fj, f_ref, "bpass joint forces", 1e-12)
        # gradient passes
        dV, dA = rbd.inverse_dynamics_gradient_fpass_dq(q, qd, qdd)
        S, dAv = rbd.inverse_dynamics_gradient_fpass_dqd(q, qd, qdd)
        D = rbd.inverse_dynamics_gradient(q, qd, qdd)
        assert_close(rbd.inverse_dynamics_gradient_bpass_dq(q, qd, qdd, dV, dA), D[:, :nv], "bpass_dq", 1e-12)
        assert_close(rbd.inverse_dynamics_gradient_bpass_dqd(q, qd, qdd, S, dAv), D[:, nv:], "bpass_dqd", 1e-12)
        # Minv passes (direct inverse: models without mimic joints): M Z = 1 to n² u max|M| max|Z|, and the
        # minv operation's M⁻¹ (by M's factorisation on small trees: the same to rounding)
        if not ref.model.has_mimic:
            Mb = rbd.minv_bpass(q)
            Zu = rbd.minv_fpass(q, Mb)
            Z = np.triu(Zu) + np.triu(Zu, 1).T
            M = rbd.crba(q)
            resid = np.abs(M @ Z - np.eye(nv)).max()
            bound = 1.1e-16 * nv * nv * np.abs(M).max() * np.abs(Z).max()
            assert resid < bound, f"minv_fpass(minv_bpass): M Z - 1 = {resid:.3e} > {bound:.3e}"
            assert_close(Zu, rbd.minv(q, output_dense=False), "minv_fpass(minv_bpass)", 1e-10)


def test_fpass_accelerations_include_gravity(ref):
    # the forward pass keeps the fictitious base acceleration -g; inverse_dynamics reports it removed
    rbd = rbdkit.RBD(ref.model)
    q, qd, qdd, _, _ = next(states(ref.model, 1))
    _, a_gf, _ = rbd.inverse_dynamics_fpass(q, qd, qdd)
    _, per_body = ref.rnea(q, qd, qdd)
    pin_a_gf = {b: ref.data.a_gf[j].vector for j, b in ref.body_of_joint.items()}
    for b in range(ref.model.nb):
        assert_close(a_gf[b], pin_a_gf[b], f"a_gf of body {b}")


def test_world_subspace_columns_are_the_world_jacobian(ref):
    # S from the dqd forward pass, gathered per velocity column, is Pinocchio's WORLD Jacobian of the whole tree
    import pinocchio as pin
    rbd = rbdkit.RBD(ref.model)
    q, qd, qdd, _, _ = next(states(ref.model, 1))
    S, _ = rbd.inverse_dynamics_gradient_fpass_dqd(q, qd, qdd)
    J = np.zeros((6, ref.model.nv))
    for j in ref.model.joints:
        b, nvj = j["body"], max(j["nv"], 1)
        J[:, j["v_index"]:j["v_index"] + nvj] += S[b][:, :nvj]
    Jp = pin.computeJointJacobians(ref.pin, ref.data, ref.q(q))
    # mimic bodies add multiplier-scaled columns: compare through G
    assert_close(J, Jp @ ref.G, "world subspace columns")


def test_minv_passes_reject_mimic_models():
    import os
    from pinref import URDF_DIR
    m = rbdkit.Model.from_urdf(os.path.join(URDF_DIR, "mimic.urdf"))
    rbd = rbdkit.RBD(m)
    q = m.neutral()
    with pytest.raises(ValueError, match="^minv_bpass: .*mimic joints"):
        rbd.minv_bpass(q)
    with pytest.raises(ValueError, match="^minv_fpass: .*mimic joints"):
        rbd.minv_fpass(q, np.zeros((m.nv, m.nv)))
