"""Inertial-parameter regressors and run-time inertial parameters: against
Pinocchio's computeJointTorqueRegressor / computeKineticEnergyRegressor /
computePotentialEnergyRegressor (1e-9 relative), against rbdkit's own dynamics
through the identities tau = Y·π, E = y·π, dY_dx·π = ∂tau/∂x and
∂qdd/∂π = -M⁻¹Y, and against central finite differences (in the tangent
space for dY_dx, in π through with_inertial_parameters for ∂qdd/∂π), on the
bundled robots and the joint-type models, fixed and floating base."""

import os
import warnings

import numpy as np
import pytest

import rbdkit
from pinref import ROBOTS_DIR, URDF_DIR, Reference, all_models, assert_close

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
        yield q, rng.uniform(-vs, vs, model.nv), rng.uniform(-3, 3, model.nv), rng.uniform(-30, 30, model.nv)


def random_consistent_parameters(nb, rng):
    """π (10·nb,) of random rigid bodies strictly inside the consistent set:
    m > 0, principal moments about the CoM with a margin in the triangle inequalities"""
    pi = []
    for _ in range(nb):
        m = rng.uniform(0.5, 3.0)
        c = rng.uniform(-0.2, 0.2, 3)
        a, b = rng.uniform(0.02, 0.1, 2)
        lo, hi = abs(a - b), a + b
        moments = np.array([a, b, lo + rng.uniform(0.2, 0.8) * (hi - lo)])
        R, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        I = R @ np.diag(moments) @ R.T + m * (c @ c * np.eye(3) - np.outer(c, c))
        pi.append([m, *(m * c), I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])
    return np.array(pi).reshape(-1)


def fd_tangent(rbd, f, q, eps=1e-5):
    """central differences of f along q <- integrate(q, ±eps e_k): (nv, out...)"""
    cols = []
    for k in range(rbd.nv):
        d = np.zeros(rbd.nv)
        d[k] = eps
        cols.append((f(rbd.integrate(q, d)) - f(rbd.integrate(q, -d))) / (2 * eps))
    return np.stack(cols)


def fd_vector(f, x, eps):
    """central differences of f along each coordinate of x: (x.size, out...)"""
    cols = []
    for k in range(x.size):
        d = np.zeros(x.size)
        d[k] = eps
        cols.append((f(x + d) - f(x - d)) / (2 * eps))
    return np.stack(cols)


# ------------------------------------------------------------ inertial parameters


def test_inertial_parameters_are_pinocchios_dynamic_parameters(ref):
    pi = ref.model.inertial_parameters()
    assert pi.shape == (10 * ref.model.nb,)
    assert_close(pi, ref.dynamic_parameters(), "model.inertial_parameters() vs Inertia.toDynamicParameters()")


def test_round_trip_reproduces_the_dynamics_exactly(ref):
    m = ref.model
    m2 = m.with_inertial_parameters(m.inertial_parameters())
    assert isinstance(m2, rbdkit.Model) and m2 is not m
    np.testing.assert_array_equal(m2.inertial_parameters(), m.inertial_parameters())
    a, b = rbdkit.RBD(m), rbdkit.RBD(m2)
    for q, qd, qdd, tau in states(m, 2, seed=5):
        for x, y in zip(a.inverse_dynamics(q, qd, qdd), b.inverse_dynamics(q, qd, qdd)):
            np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(a.crba(q), b.crba(q))
        np.testing.assert_array_equal(a.minv(q), b.minv(q))
        np.testing.assert_array_equal(a.aba(q, qd, tau), b.aba(q, qd, tau))
        np.testing.assert_array_equal(a.forward_dynamics(q, qd, tau), b.forward_dynamics(q, qd, tau))
        np.testing.assert_array_equal(a.inverse_dynamics_gradient(q, qd, qdd), b.inverse_dynamics_gradient(q, qd, qdd))
        for x, y in zip(a.forward_dynamics_gradient(q, qd, tau), b.forward_dynamics_gradient(q, qd, tau)):
            np.testing.assert_array_equal(x, y)


def test_new_parameters_match_pinocchio_with_the_same_inertias(ref):
    m = ref.model
    rng = np.random.default_rng(11)
    pi = random_consistent_parameters(m.nb, rng)
    before = m.inertial_parameters()
    m2 = m.with_inertial_parameters(pi)
    np.testing.assert_array_equal(m2.inertial_parameters(), pi)
    # the original model is unchanged (models are immutable)
    np.testing.assert_array_equal(m.inertial_parameters(), before)
    rbd = rbdkit.RBD(m2)
    for q, qd, qdd, _ in states(m, 2, seed=6):
        for g in (-9.81, -4.0):
            tau = rbd.inverse_dynamics(q, qd, qdd, gravity=g)[0]
            assert_close(tau, ref.rnea_with_parameters(pi, q, qd, qdd, g), "tau with new parameters vs Pinocchio")
            assert_close(rbd.inverse_dynamics_regressor(q, qd, qdd, gravity=g) @ pi, tau, "Y·π_new = tau")


# ------------------------------------------------------------ regressor


def test_regressor_matches_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    for q, qd, qdd, _ in states(m):
        for g in (-9.81, -4.0):
            Y = rbd.inverse_dynamics_regressor(q, qd, qdd, gravity=g)
            assert Y.shape == (m.nv, 10 * m.nb)
            assert_close(Y, ref.joint_torque_regressor(q, qd, qdd, g), "Y vs computeJointTorqueRegressor")
        # qdd=None means zero acceleration
        assert_close(rbd.inverse_dynamics_regressor(q, qd), ref.joint_torque_regressor(q, qd, np.zeros(m.nv)),
                     "Y at qdd=0")


def test_regressor_times_parameters_is_inverse_dynamics(ref):
    rbd = rbdkit.RBD(ref.model)
    pi = ref.model.inertial_parameters()
    for q, qd, qdd, _ in states(ref.model):
        for g in (-9.81, 0.0, 3.5):
            tau = rbd.inverse_dynamics(q, qd, qdd, gravity=g)[0]
            assert_close(rbd.inverse_dynamics_regressor(q, qd, qdd, gravity=g) @ pi, tau, "Y·π = tau")
        assert_close(rbd.inverse_dynamics_regressor(q, qd) @ pi, rbd.nonlinear_effects(q, qd), "Y(qdd=0)·π = c")
        assert_close(rbd.inverse_dynamics_regressor(q, 0 * qd) @ pi, rbd.generalized_gravity(q), "Y(0, 0)·π = g")


# ------------------------------------------------------------ energy regressors


def test_energy_regressors_match_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    for q, qd, _, _ in states(m):
        yk = rbd.kinetic_energy_regressor(q, qd)
        assert yk.shape == (10 * m.nb,)
        assert_close(yk, ref.kinetic_energy_regressor(q, qd), "kinetic energy regressor vs Pinocchio")
        for g in (-9.81, -4.0):
            yp = rbd.potential_energy_regressor(q, gravity=g)
            assert yp.shape == (10 * m.nb,)
            assert_close(yp, ref.potential_energy_regressor(q, g), "potential energy regressor vs Pinocchio")


def test_energy_regressors_times_parameters_are_the_energies(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    pi = m.inertial_parameters()
    for q, qd, _, _ in states(m):
        for g in (-9.81, 2.0):
            assert_close(rbd.potential_energy_regressor(q, gravity=g) @ pi, ref.potential_energy(q, g),
                         "y_V·π = Pinocchio's computePotentialEnergy")
    for pi in (pi, random_consistent_parameters(m.nb, np.random.default_rng(2))):
        r = rbdkit.RBD(m.with_inertial_parameters(pi))
        for q, qd, _, _ in states(m):
            T = 0.5 * qd @ r.crba(q) @ qd
            assert_close(rbd.kinetic_energy_regressor(q, qd) @ pi, T, "y_T·π = ½ qdᵀ M qd")
            # V is the potential of generalized gravity: ∂V/∂q (tangent) = g(q)
            dV = fd_tangent(rbd, lambda x: rbd.potential_energy_regressor(x) @ pi, q)
            assert_close(dV, r.generalized_gravity(q), "∂(y_V·π)/∂q = g(q)", 1e-6)


# ------------------------------------------------------------ regressor gradient


def test_regressor_gradient_times_parameters_is_the_inverse_dynamics_gradient(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    nv = m.nv
    for pi in (m.inertial_parameters(), random_consistent_parameters(m.nb, np.random.default_rng(3))):
        r = rbdkit.RBD(m.with_inertial_parameters(pi))
        for q, qd, qdd, _ in states(m):
            for g in (-9.81, -4.0):
                dY = rbd.inverse_dynamics_regressor_gradient(q, qd, qdd, gravity=g)
                assert dY.shape == (2 * nv, nv, 10 * m.nb)
                D = r.inverse_dynamics_gradient(q, qd, qdd, gravity=g)
                assert_close(np.einsum("crp,p->rc", dY, pi), D, "dY_dx·π = [∂tau/∂q | ∂tau/∂qd]")
    # against Pinocchio's RNEA derivatives of the model's own parameters
    q, qd, qdd, _ = next(states(m, 1, seed=8))
    dY = rbd.inverse_dynamics_regressor_gradient(q, qd, qdd)
    dq, dv = ref.rnea_derivatives(q, qd, qdd)
    pi = m.inertial_parameters()
    assert_close(np.einsum("crp,p->rc", dY[:nv], pi), dq, "dY_dq·π vs computeRNEADerivatives")
    assert_close(np.einsum("crp,p->rc", dY[nv:], pi), dv, "dY_dqd·π vs computeRNEADerivatives")
    # qdd=None means zero acceleration
    np.testing.assert_array_equal(rbd.inverse_dynamics_regressor_gradient(q, qd),
                                  rbd.inverse_dynamics_regressor_gradient(q, qd, np.zeros(nv)))


def test_regressor_gradient_by_finite_differences(ref):
    rbd = rbdkit.RBD(ref.model)
    nv = ref.model.nv
    q, qd, qdd, _ = next(states(ref.model, 2, seed=4))
    dY = rbd.inverse_dynamics_regressor_gradient(q, qd, qdd)
    Y_of_q = lambda x: rbd.inverse_dynamics_regressor(x, qd, qdd)
    Y_of_qd = lambda v: rbd.inverse_dynamics_regressor(q, v, qdd)
    # Y is quadratic in qd: steps of 1e-4 are exact up to rounding
    assert_close(dY[:nv], fd_tangent(rbd, Y_of_q, q), "dY/dq vs central differences (tangent)", 1e-6)
    assert_close(dY[nv:], fd_vector(Y_of_qd, qd, 1e-4), "dY/dqd vs central differences", 1e-6)


# ------------------------------------------------------------ forward-dynamics parameter gradient


def test_forward_dynamics_parameter_gradient_is_minus_minv_y(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    for q, qd, _, u in states(m):
        for g in (-9.81, -4.0):
            G = rbd.forward_dynamics_parameter_gradient(q, qd, u, gravity=g)
            assert G.shape == (m.nv, 10 * m.nb)
            qdd = rbd.forward_dynamics(q, qd, u, gravity=g)
            Y = rbd.inverse_dynamics_regressor(q, qd, qdd, gravity=g)
            assert_close(G, -np.linalg.solve(rbd.crba(q), Y), "dqdd/dπ = -M⁻¹ Y (solve)")
            assert_close(G, -rbd.minv(q) @ Y, "dqdd/dπ = -M⁻¹ Y (minv)")
            # and at the model's own π: M·G·π = -Y·π = -(u) since Y(FD)·π = u
            pi = m.inertial_parameters()
            assert_close(rbd.crba(q) @ G @ pi, -u, "M·(dqdd/dπ)·π = -u")


def test_forward_dynamics_parameter_gradient_by_finite_differences(ref):
    m = ref.model
    rng = np.random.default_rng(13)
    pi = random_consistent_parameters(m.nb, rng)
    rbd = rbdkit.RBD(m.with_inertial_parameters(pi))
    q, qd, _, u = next(states(m, 1, seed=12))
    G = rbd.forward_dynamics_parameter_gradient(q, qd, u)

    def qdd_of(p):
        return rbdkit.RBD(m.with_inertial_parameters(p)).forward_dynamics(q, qd, u)

    fd = fd_vector(qdd_of, pi, 1e-6).T
    assert_close(G, fd, "dqdd/dπ vs central differences in π", 1e-6)


# ------------------------------------------------------------ batches


def test_regressor_batches_equal_single_samples(ref):
    rbd = rbdkit.RBD(ref.model)
    data = list(states(ref.model, 3, seed=2))
    Q, V, A, U = (np.stack([d[k] for d in data]) for k in range(4))
    Y = rbd.inverse_dynamics_regressor(Q, V, A)
    dY = rbd.inverse_dynamics_regressor_gradient(Q, V, A)
    G = rbd.forward_dynamics_parameter_gradient(Q, V, U)
    yk = rbd.kinetic_energy_regressor(Q, V)
    yp = rbd.potential_energy_regressor(Q)
    assert Y.shape[0] == dY.shape[0] == G.shape[0] == yk.shape[0] == yp.shape[0] == 3
    for k in range(3):
        np.testing.assert_array_equal(Y[k], rbd.inverse_dynamics_regressor(Q[k], V[k], A[k]))
        np.testing.assert_array_equal(dY[k], rbd.inverse_dynamics_regressor_gradient(Q[k], V[k], A[k]))
        np.testing.assert_array_equal(G[k], rbd.forward_dynamics_parameter_gradient(Q[k], V[k], U[k]))
        np.testing.assert_array_equal(yk[k], rbd.kinetic_energy_regressor(Q[k], V[k]))
        np.testing.assert_array_equal(yp[k], rbd.potential_energy_regressor(Q[k]))
    # an unbatched qd broadcast against a batched q
    Yb = rbd.inverse_dynamics_regressor(Q, V[0])
    np.testing.assert_array_equal(Yb[1], rbd.inverse_dynamics_regressor(Q[1], V[0]))


# ------------------------------------------------------------ checks of new parameters


IIWA = os.path.join(ROBOTS_DIR, "iiwa.urdf")
ATLAS = os.path.join(ROBOTS_DIR, "atlas.urdf")


@pytest.fixture(scope="module")
def iiwa():
    return rbdkit.Model.from_urdf(IIWA)


def with_block(model, body, block):
    pi = model.inertial_parameters()
    pi[10 * body:10 * body + 10] = block
    return pi


def block(m, c, Ic):
    c = np.asarray(c, float)
    I = np.asarray(Ic, float) + m * (c @ c * np.eye(3) - np.outer(c, c))
    return [m, *(m * c), I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]]


def test_consistent_edge_cases_are_accepted(iiwa):
    # a massless body, a point mass, a thin rod (the triangle inequality with equality)
    for blk in ([0.0] * 10, block(2.0, [0.1, 0, 0], np.zeros((3, 3))), block(1.0, [0, 0, 0.3], np.diag([0.1, 0.1, 0]))):
        m2 = iiwa.with_inertial_parameters(with_block(iiwa, 3, blk))
        np.testing.assert_array_equal(m2.inertial_parameters()[30:40], blk)


@pytest.mark.parametrize("case,blk,pattern", [
    ("negative-mass", block(-1.0, [0, 0, 0], np.eye(3)), r"negative mass m = -1"),
    ("zero-mass-with-first-moment", [0.0, 0.1, 0, 0, 0, 0, 0, 0, 0, 0],
     r"zero mass with a non-zero first moment m\*c = \(0\.1, 0, 0\)"),
    ("not-psd", block(2.0, [0.1, 0, 0], [[0.1, 0.5, 0], [0.5, 0.1, 0], [0, 0, 0.1]]),
     r"the rotational inertia about the centre of mass is not positive semi-definite"),
    ("not-psd-negative-moment", block(2.0, [0, 0.2, 0], np.diag([0.1, 0.1, -0.05])),
     r"the rotational inertia about the centre of mass is not positive semi-definite"),
    ("massless-not-psd", [0, 0, 0, 0, 0.1, 0.5, 0.1, 0, 0, 0.1],
     r"the rotational inertia about the centre of mass is not positive semi-definite"),
    ("triangle-inequality", block(2.0, [0.1, 0.2, 0], np.diag([0.1, 0.1, 0.3])),
     r"the rotational inertia about the centre of mass violates the triangle inequality"),
    # about the origin the inertia is fine; about the CoM it is not
    ("psd-about-origin-only", [1.0, 0.5, 0, 0, 0.1, 0, 0.1, 0, 0, 0.1],
     r"the rotational inertia about the centre of mass is not positive semi-definite"),
])
def test_inconsistent_parameters_are_rejected(iiwa, case, blk, pattern):
    link = iiwa.body_names[3]
    with pytest.raises(ValueError, match=rf"^pi: link '{link}' \(body 3, pi\[30:40\]\): {pattern}"):
        iiwa.with_inertial_parameters(with_block(iiwa, 3, blk))


def test_bad_parameter_arrays_are_rejected(iiwa):
    n = 10 * iiwa.nb
    pi = iiwa.inertial_parameters()
    for shape in ((n - 1,), (n + 1,), (iiwa.nb, 10), (), (1, n)):
        with pytest.raises(ValueError, match=rf"^pi: expected shape \({n},\) with 10\*nb={n}, got shape"):
            iiwa.with_inertial_parameters(np.zeros(shape))
    for bad in (None, "abc", np.zeros(n, dtype=complex), np.ones(n, dtype=bool), {"a": 1}):
        with pytest.raises(TypeError, match=r"^pi: expected a real numeric array"):
            iiwa.with_inertial_parameters(bad)
    for bad in (np.nan, np.inf, -np.inf):
        for k in (0, 17, n - 1):
            x = pi.copy()
            x[k] = bad
            link = iiwa.body_names[k // 10]
            with pytest.raises(ValueError, match=rf"^pi: expected finite values, got .* at index {k} \(.* of link '{link}'\)"):
                iiwa.with_inertial_parameters(x)
    # the core checks the length itself too
    with pytest.raises(ValueError, match=rf"^pi: expected 10\*nb = {n} inertial parameters"):
        iiwa._core.with_inertial_parameters([1.0] * (n - 1))
    # lists and integer arrays are fine
    np.testing.assert_array_equal(iiwa.with_inertial_parameters(list(pi)).inertial_parameters(), pi)


def test_atlas_published_inertias_pass_unchanged_but_not_when_changed():
    # Atlas's published data has inconsistent inertias: utorso, l_foot, r_foot
    # are not positive semi-definite (the reader warns), l_lglut breaks the
    # triangle inequality. The checks apply to changed bodies only, so the
    # round trip works, and changing one of those bodies without fixing it fails.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        atlas = rbdkit.Model.from_urdf(ATLAS, floating_base=True)
    pi = atlas.inertial_parameters()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no second round of the reader's warnings
        same = atlas.with_inertial_parameters(pi)
    rbd, rbd2 = rbdkit.RBD(atlas), rbdkit.RBD(same)
    q, qd, qdd, _ = next(states(atlas, 1))
    np.testing.assert_array_equal(rbd.inverse_dynamics(q, qd, qdd)[0], rbd2.inverse_dynamics(q, qd, qdd)[0])
    for link, why in (("utorso", "not positive semi-definite"), ("l_foot", "not positive semi-definite"),
                      ("r_foot", "not positive semi-definite"), ("l_lglut", "violates the triangle inequality")):
        b = atlas.body_names.index(link)
        x = pi.copy()
        x[10 * b] *= 1.01  # 1% more mass, same first moment and inertia
        with pytest.raises(ValueError, match=rf"^pi: link '{link}' \(body {b}, .*\): .*{why}"):
            atlas.with_inertial_parameters(x)
        # a consistent replacement is accepted
        x[10 * b:10 * b + 10] = block(5.0, [0, 0, 0.1], np.diag([0.1, 0.2, 0.25]))
        m2 = atlas.with_inertial_parameters(x)
        tau = rbdkit.RBD(m2).inverse_dynamics(q, qd, qdd)[0]
        assert_close(rbd.inverse_dynamics_regressor(q, qd, qdd) @ x, tau, f"Y·π with a new {link}")
