"""Energy, Coriolis and centroidal dynamics: against Pinocchio
(computeKineticEnergy, computePotentialEnergy, computeCoriolisMatrix,
centerOfMass, jacobianCenterOfMass, ccrba, computeCentroidalMapTimeVariation,
computeCentroidalMomentumTimeVariation, computeCentroidalDynamicsDerivatives;
1e-9 relative), against central finite differences in the tangent space for
every derivative (1e-6 relative), and against identities (C·qd + g = c,
Ṁ - 2C skew-symmetric, h = A·qd, ḣ = A·qdd + Ȧ·qd, T = ½ qdᵀ M qd,
M_total·ċ = h_linear, ∂V/∂q = g), on the bundled robots and the joint-type
models, fixed and floating base."""

import os

import numpy as np
import pinocchio as pin
import pytest

import rbdkit
from pinref import Reference, all_models, assert_close

CASES = all_models()
FD = 1e-6  # relative tolerance of the finite-difference checks


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def ref(request):
    _, path, fb = request.param
    return Reference(path, fb)


def states(model, n=3, seed=0):
    rng = np.random.default_rng(seed)
    for k in range(n):
        q = model.random_configuration(rng, scale=np.pi)
        vs = 20.0 if k == n - 1 else 2.0
        yield q, rng.uniform(-vs, vs, model.nv), rng.uniform(-3, 3, model.nv)


def fd_tangent(rbd, f, q, eps=1e-5):
    """central differences of f along q <- integrate(q, ±eps e_k): (out..., nv)"""
    cols = []
    for k in range(rbd.nv):
        d = np.zeros(rbd.nv)
        d[k] = eps
        cols.append((f(rbd.integrate(q, d)) - f(rbd.integrate(q, -d))) / (2 * eps))
    return np.stack(cols, axis=-1)


def fd_vector(f, x, eps=1e-4):
    cols = []
    for k in range(x.size):
        d = np.zeros(x.size)
        d[k] = eps
        cols.append((f(x + d) - f(x - d)) / (2 * eps))
    return np.stack(cols, axis=-1)


def total_mass(rbd, q):
    """the robot's mass from rbdkit alone: h_lin = M·ċ along some qd"""
    qd = np.linspace(1.0, 2.0, rbd.nv)
    cdot = rbd.jacobian_com(q) @ qd
    return rbd.centroidal_momentum(q, qd)[:3] @ cdot / (cdot @ cdot)


def fd_time(rbd, f, q, qd, eps=1e-5):
    """d/dt f(q(t)) along q̇ = qd, central differences through integrate"""
    return (f(rbd.integrate(q, eps * qd)) - f(rbd.integrate(q, -eps * qd))) / (2 * eps)


# ------------------------------------------------------------ against Pinocchio


def test_energies_match_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, _ in states(ref.model):
        T = rbd.kinetic_energy(q, qd)
        assert np.ndim(T) == 0
        assert_close(T, ref.kinetic_energy(q, qd), "kinetic energy")
        for g in (-9.81, -3.0, 2.5):
            V = rbd.potential_energy(q, gravity=g)
            assert_close(V, ref.potential_energy(q, g), f"potential energy (gravity {g})")
            assert_close(rbd.mechanical_energy(q, qd, gravity=g), ref.kinetic_energy(q, qd) + V, "mechanical energy")
    # the default gravity is -9.81
    assert_close(rbd.potential_energy(q), ref.potential_energy(q, -9.81), "potential energy (default gravity)")


def test_coriolis_matrix_matches_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, _ in states(ref.model):
        C = rbd.coriolis_matrix(q, qd)
        assert C.shape == (ref.model.nv, ref.model.nv)
        assert_close(C, ref.coriolis(q, qd), "Coriolis matrix")


def test_center_of_mass_matches_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, _, _ in states(ref.model):
        c, J = rbd.com(q), rbd.jacobian_com(q)
        assert c.shape == (3,) and J.shape == (3, ref.model.nv)
        assert_close(c, ref.com(q), "centre of mass")
        assert_close(J, ref.jacobian_com(q), "centre-of-mass Jacobian")


def test_ccrba_matches_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, _ in states(ref.model):
        A, h = rbd.ccrba(q, qd)
        assert A.shape == (6, ref.model.nv) and h.shape == (6,)
        A_ref, h_ref = ref.ccrba(q, qd)
        assert_close(A, A_ref, "A (data.Ag)")
        assert_close(h, h_ref, "h (data.hg)")
        assert_close(rbd.centroidal_momentum(q, qd), h_ref, "centroidal_momentum")


def test_time_variations_match_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, qdd in states(ref.model):
        Adot = rbd.cmm_time_variation(q, qd)
        assert Adot.shape == (6, ref.model.nv)
        assert_close(Adot, ref.cmm_time_variation(q, qd), "Ȧ (data.dAg)")
        hdot = rbd.centroidal_momentum_time_variation(q, qd, qdd)
        assert hdot.shape == (6,)
        assert_close(hdot, ref.centroidal_momentum_time_variation(q, qd, qdd), "ḣ (data.dhg)")


def test_centroidal_dynamics_derivatives_match_pinocchio(ref):
    rbd = rbdkit.RBD(ref.model)
    names = ("dh_dq", "dhdot_dq", "dhdot_dv", "dhdot_da")
    for q, qd, qdd in states(ref.model):
        ours = rbd.centroidal_dynamics_derivatives(q, qd, qdd)
        theirs = ref.centroidal_dynamics_derivatives(q, qd, qdd)
        for name, a, b in zip(names, ours, theirs):
            assert a.shape == (6, ref.model.nv)
            assert_close(a, b, name)


# ------------------------------------------------------------ finite differences


def test_jacobian_com_by_finite_differences(ref):
    rbd = rbdkit.RBD(ref.model)
    q, _, _ = next(states(ref.model, 1, seed=3))
    assert_close(rbd.jacobian_com(q), fd_tangent(rbd, rbd.com, q), "J_com vs FD", FD)


def test_dccrba_by_finite_differences(ref):
    rbd = rbdkit.RBD(ref.model)
    nv = ref.model.nv
    for q, qd, _ in states(ref.model, 2, seed=4):
        dA = rbd.dccrba(q)
        assert dA.shape == (6, nv, nv)
        # independent central differences in Python, and the C++ cross-check
        assert_close(dA, fd_tangent(rbd, lambda x: rbd.ccrba(x, qd)[0], q), "dA vs FD", FD)
        assert_close(dA, rbd.dccrba_fd(q), "dA vs dccrba_fd", FD)
        assert_close(rbd.dccrba_fd(q, eps=1e-4), rbd.dccrba_fd(q), "dccrba_fd step", 1e-5)
        # Ȧ = Σ_k dA[:, :, k] qd_k, and the time derivative of A along qd
        Adot = rbd.cmm_time_variation(q, qd)
        assert_close(Adot, dA @ qd, "Ȧ = dA·qd", 1e-12)
        assert_close(Adot, rbd.cmm_time_variation_fd(q, qd), "Ȧ vs cmm_time_variation_fd", FD)
        assert_close(Adot, fd_time(rbd, lambda x: rbd.ccrba(x, qd)[0], q, qd), "Ȧ vs FD in time", FD)


def test_centroidal_dynamics_derivatives_by_finite_differences(ref):
    rbd = rbdkit.RBD(ref.model)
    q, qd, qdd = next(states(ref.model, 2, seed=5))
    dh_dq, dhdot_dq, dhdot_dv, dhdot_da = rbd.centroidal_dynamics_derivatives(q, qd, qdd)
    hdot = rbd.centroidal_momentum_time_variation
    assert_close(dh_dq, fd_tangent(rbd, lambda x: rbd.ccrba(x, qd)[1], q), "dh/dq vs FD", FD)
    assert_close(dhdot_dq, fd_tangent(rbd, lambda x: hdot(x, qd, qdd), q), "dḣ/dq vs FD", FD)
    assert_close(dhdot_dv, fd_vector(lambda v: hdot(q, v, qdd), qd), "dḣ/dqd vs FD", FD)
    assert_close(dhdot_da, fd_vector(lambda a: hdot(q, qd, a), qdd), "dḣ/dqdd vs FD", FD)
    # dh/dq is also Pinocchio's meaning: the derivative of h at fixed qd, with the moving centre of mass
    assert_close(dh_dq, ref.centroidal_dynamics_derivatives(q, qd, qdd)[0], "dh/dq vs Pinocchio")


def test_potential_energy_gradient_is_generalized_gravity(ref):
    rbd = rbdkit.RBD(ref.model)
    q, _, _ = next(states(ref.model, 1, seed=6))
    for g in (-9.81, 4.0):
        dV = fd_tangent(rbd, lambda x: np.array(rbd.potential_energy(x, gravity=g)), q)
        assert_close(dV, rbd.generalized_gravity(q, gravity=g), "∂V/∂q = g(q)", FD)


# ------------------------------------------------------------ identities


def test_coriolis_identities(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, _ in states(ref.model, 2, seed=7):
        C = rbd.coriolis_matrix(q, qd)
        # C·qd + g = nonlinear effects
        assert_close(C @ qd + rbd.generalized_gravity(q), rbd.nonlinear_effects(q, qd), "C·qd + g = c", 1e-12)
        # Ṁ - 2C is skew-symmetric: Ṁ = C + Cᵀ, Ṁ by central differences of M along qd
        Mdot = fd_time(rbd, rbd.crba, q, qd)
        assert_close(C + C.T, Mdot, "Ṁ = C + Cᵀ", FD)
        N = Mdot - 2 * C
        assert_close(N + N.T, np.zeros_like(N), "Ṁ - 2C skew-symmetric", FD * max(1.0, np.abs(Mdot).max()))


def test_momentum_identities(ref):
    rbd = rbdkit.RBD(ref.model)
    mass = pin.computeTotalMass(ref.pin)
    for q, qd, qdd in states(ref.model, 2, seed=8):
        A, h = rbd.ccrba(q, qd)
        M = rbd.crba(q)
        assert_close(h, A @ qd, "h = A·qd", 1e-12)
        assert_close(rbd.centroidal_dynamics_derivatives(q, qd, qdd)[3], A, "dḣ/dqdd = A", 1e-12)
        assert_close(rbd.kinetic_energy(q, qd), 0.5 * qd @ M @ qd, "T = ½ qdᵀ M qd", 1e-12)
        # linear momentum = total mass x centre-of-mass velocity
        J = rbd.jacobian_com(q)
        assert_close(h[:3], mass * (J @ qd), "M·ċ = h_lin", 1e-12)
        assert_close(A[:3], mass * J, "A_lin = M·J_com", 1e-12)
        # ḣ = A·qdd + Ȧ·qd, and its time derivative by finite differences along (qd, qdd)
        hdot = rbd.centroidal_momentum_time_variation(q, qd, qdd)
        assert_close(hdot, A @ qdd + rbd.cmm_time_variation(q, qd) @ qd, "ḣ = A·qdd + Ȧ·qd", 1e-12)
        eps = 1e-5
        h_at = lambda s: rbd.ccrba(rbd.integrate(q, s * eps * qd), qd + s * eps * qdd)[1]
        assert_close(hdot, (h_at(1) - h_at(-1)) / (2 * eps), "ḣ vs FD in time", FD)


def test_momentum_of_a_free_fall_is_constant_in_rotation():
    # a floating robot in free flight: ḣ = 0 when qdd is forward dynamics without gravity and torques,
    # the linear part is M·g once gravity acts (the weight is the only external force)
    model = rbdkit.robots.load("hyq", floating_base=True)
    rbd = rbdkit.RBD(model)
    rng = np.random.default_rng(9)
    q, qd = model.random_configuration(rng), rng.uniform(-2, 2, model.nv)
    zero = np.zeros(model.nv)
    hdot = rbd.centroidal_momentum_time_variation(q, qd, rbd.aba(q, qd, zero, gravity=0.0))
    assert_close(hdot, np.zeros(6), "ḣ in free flight without gravity", 1e-9)
    hdot = rbd.centroidal_momentum_time_variation(q, qd, rbd.aba(q, qd, zero))
    weight = np.array([0, 0, -9.81 * total_mass(rbd, q), 0, 0, 0])
    assert_close(hdot, weight, "ḣ in free fall = weight", 1e-9)


# ------------------------------------------------------------ batches and bad input


def test_batches_equal_single_samples(ref):
    rbd = rbdkit.RBD(ref.model)
    data = list(states(ref.model, 3, seed=2))
    Q, V, A = (np.stack([d[k] for d in data]) for k in range(3))
    calls = {
        "kinetic_energy": (Q, V), "potential_energy": (Q,), "mechanical_energy": (Q, V),
        "coriolis_matrix": (Q, V), "com": (Q,), "jacobian_com": (Q,), "ccrba": (Q, V),
        "centroidal_momentum": (Q, V), "dccrba": (Q,), "dccrba_fd": (Q,), "cmm_time_variation": (Q, V),
        "cmm_time_variation_fd": (Q, V), "centroidal_momentum_time_variation": (Q, V, A),
        "centroidal_dynamics_derivatives": (Q, V, A),
    }
    for name, args in calls.items():
        batched = getattr(rbd, name)(*args)
        for k in range(3):
            single = getattr(rbd, name)(*(a[k] for a in args))
            if isinstance(single, tuple):
                for x, y in zip(batched, single):
                    np.testing.assert_array_equal(x[k], y, err_msg=name)
            else:
                np.testing.assert_array_equal(batched[k], single, err_msg=name)
    # an unbatched qd broadcasts against a batch of configurations
    h = rbd.centroidal_momentum(Q, V[0])
    for k in range(3):
        np.testing.assert_array_equal(h[k], rbd.centroidal_momentum(Q[k], V[0]))
    assert rbd.kinetic_energy(Q, V).shape == (3,)


def test_massless_robot_has_no_center_of_mass():
    xml = ('<?xml version="1.0"?><robot name="ghost"><link name="a"/><link name="b"/>'
           '<joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint></robot>')
    model = rbdkit.Model.from_urdf_string(xml)
    rbd = rbdkit.RBD(model)
    q, v = np.zeros(1), np.ones(1)
    assert rbd.kinetic_energy(q, v) == 0 and rbd.potential_energy(q) == 0
    np.testing.assert_array_equal(rbd.coriolis_matrix(q, v), np.zeros((1, 1)))
    for name, args in (("com", (q,)), ("jacobian_com", (q,)), ("ccrba", (q, v)), ("centroidal_momentum", (q, v)),
                       ("dccrba", (q,)), ("dccrba_fd", (q,)), ("cmm_time_variation", (q, v)),
                       ("centroidal_momentum_time_variation", (q, v, v)),
                       ("centroidal_dynamics_derivatives", (q, v, v))):
        with pytest.raises(RuntimeError, match=rf"^{name}: the robot has no mass"):
            getattr(rbd, name)(*args)


def test_fixed_base_root_link_is_not_part_of_the_robot():
    # iiwa's base link has mass; fixed to the world it counts neither in the
    # centre of mass nor in the momentum (Pinocchio's convention)
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "robots", "iiwa.urdf")
    ref = Reference(path, False)
    rbd = rbdkit.RBD(ref.model)
    q = ref.model.neutral()
    mass = total_mass(rbd, q)
    assert mass == pytest.approx(pin.computeTotalMass(ref.pin), rel=1e-12)
    assert mass < pin.computeTotalMass(Reference(path, True).pin)
