"""rbdkit's core dynamics against Pinocchio on the bundled robots and the
joint-type test models, fixed and floating base, random states including
high velocities. Agreement: max|err| <= 1e-9 · max(1, max|reference|)."""

import numpy as np
import pytest

import rbdkit
from pinref import Reference, all_models, assert_close

CASES = all_models()


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def ref(request):
    _, path, fb = request.param
    return Reference(path, fb)


def states(model, n=4, seed=0):
    """random states; the last one with high velocities"""
    rng = np.random.default_rng(seed)
    for k in range(n):
        q = model.random_configuration(rng, scale=np.pi)
        vscale = 30.0 if k == n - 1 else 3.0
        yield (q, rng.uniform(-vscale, vscale, model.nv), rng.uniform(-5, 5, model.nv),
               rng.uniform(-50, 50, model.nv), rng.uniform(-10, 10, (model.nb, 6)))


def test_coordinates_match_by_name(ref):
    # every Pinocchio joint maps to an rbdkit body and every rbdkit coordinate is used
    assert sorted(ref.bodies) == list(range(ref.model.nb))
    assert np.linalg.matrix_rank(ref.G) == ref.model.nv


def test_inverse_dynamics(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, qdd, _, fext in states(ref.model):
        for g in (-9.81, -3.7):
            tau, v, a, f = rbd.inverse_dynamics(q, qd, qdd, gravity=g)
            tau_ref, per_body = ref.rnea(q, qd, qdd, g)
            assert_close(tau, tau_ref, f"tau (g={g})")
            for b, (vr, ar, fr) in per_body.items():
                assert_close(v[b], vr, f"v of body {b}")
                assert_close(a[b], ar, f"a of body {b}")
                assert_close(f[b], fr, f"f of body {b}")


def test_inverse_dynamics_external_forces(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, qdd, _, fext in states(ref.model, 2, seed=1):
        tau, _, _, f = rbd.inverse_dynamics(q, qd, qdd, f_ext=fext)
        tau_ref, per_body = ref.rnea(q, qd, qdd, -9.81, fext)
        assert_close(tau, tau_ref, "tau with f_ext")
        for b, (_, _, fr) in per_body.items():
            assert_close(f[b], fr, f"f of body {b} with f_ext")


def test_mass_matrix(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, *_ in states(ref.model):
        M = rbd.crba(q)
        assert_close(M, ref.crba(q), "M")
        assert_close(M, M.T, "M symmetric", 1e-14)


def test_minv(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, *_ in states(ref.model):
        Mi = rbd.minv(q)
        assert_close(Mi, ref.minv(q), "Minv")
        assert_close(rbd.crba(q) @ Mi, np.eye(ref.model.nv), "M Minv = I")
        upper = rbd.minv(q, output_dense=False)
        assert_close(upper, np.triu(Mi), "Minv upper triangle", 1e-14)


def test_forward_dynamics(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, _, tau, fext in states(ref.model):
        for fx in (None, fext):
            qdd_ref = ref.forward(q, qd, tau, -9.81, fx)
            qdd_aba = rbd.aba(q, qd, tau, f_ext=fx)
            qdd_fd = rbd.forward_dynamics(q, qd, tau, f_ext=fx)
            assert_close(qdd_aba, qdd_ref, "aba")
            assert_close(qdd_fd, qdd_ref, "forward_dynamics")
            # identity: solve(M, tau - c)
            c = rbd.nonlinear_effects(q, qd) if fx is None else rbd.inverse_dynamics(q, qd, f_ext=fx)[0]
            assert_close(qdd_aba, np.linalg.solve(rbd.crba(q), tau - c), "aba = solve(M, tau - c)")


def test_gravity_and_nonlinear_effects(ref):
    rbd = rbdkit.RBD(ref.model)
    for q, qd, *_ in states(ref.model, 2):
        assert_close(rbd.generalized_gravity(q), ref.nle(q, np.zeros_like(qd)), "g(q)")
        assert_close(rbd.generalized_gravity(q, gravity=-1.62), ref.nle(q, np.zeros_like(qd), -1.62), "g(q) moon")
        assert_close(rbd.nonlinear_effects(q, qd), ref.nle(q, qd), "c(q, qd)")


BUNDLED = [c for c in CASES if c[0].split("-")[0] in ("iiwa", "hyq", "atlas")]


@pytest.mark.parametrize("case", BUNDLED, ids=[c[0] for c in BUNDLED])
def test_bundled_robots_directly_against_pinocchio_calls(case):
    # the bundled robots need no coordinate mapping: compare straight to Pinocchio's own calls
    import pinocchio as pin
    ref = Reference(case[1], case[2])
    assert np.array_equal(ref.G, np.eye(ref.model.nv)) and ref.pin.nq == ref.model.nq
    rbd = rbdkit.RBD(ref.model)
    for q, qd, qdd, tau, _ in states(ref.model, 2):
        assert_close(rbd.inverse_dynamics(q, qd, qdd)[0], pin.rnea(ref.pin, ref.data, q, qd, qdd), "rnea")
        assert_close(rbd.aba(q, qd, tau), pin.aba(ref.pin, ref.data, q, qd, tau), "aba")
        assert_close(rbd.nonlinear_effects(q, qd), pin.nonLinearEffects(ref.pin, ref.data, q, qd), "nle")
        assert_close(rbd.generalized_gravity(q), pin.computeGeneralizedGravity(ref.pin, ref.data, q), "g")


def test_batch_equals_single(ref):
    rbd = rbdkit.RBD(ref.model)
    data = list(states(ref.model, 3, seed=5))
    Q = np.stack([d[0] for d in data])
    V = np.stack([d[1] for d in data])
    A = np.stack([d[2] for d in data])
    T = np.stack([d[3] for d in data])
    tau_b = rbd.inverse_dynamics(Q, V, A)[0]
    M_b = rbd.crba(Q)
    qdd_b = rbd.aba(Q, V, T)
    assert tau_b.shape == (3, ref.model.nv) and M_b.shape == (3, ref.model.nv, ref.model.nv)
    for k in range(3):
        np.testing.assert_array_equal(tau_b[k], rbd.inverse_dynamics(Q[k], V[k], A[k])[0])
        np.testing.assert_array_equal(M_b[k], rbd.crba(Q[k]))
        np.testing.assert_array_equal(qdd_b[k], rbd.aba(Q[k], V[k], T[k]))


def test_apply_external_forces_gives_the_net_force_on_leaf_bodies(ref):
    # a leaf body's transmitted force is its net body force; with f_ext it is
    # exactly the force without f_ext, minus f_ext (body frame)
    rbd = rbdkit.RBD(ref.model)
    parents = ref.model.body_parents
    leaves = [b for b in range(ref.model.nb) if b not in parents]
    for q, qd, qdd, _, fext in states(ref.model, 2, seed=3):
        f_free = rbd.inverse_dynamics(q, qd, qdd)[3]
        f_with = rbd.inverse_dynamics(q, qd, qdd, f_ext=fext)[3]
        applied = rbd.apply_external_forces(f_free, fext)
        assert_close(applied[leaves], f_with[leaves], "leaf forces with f_ext")
        np.testing.assert_array_equal(applied, f_free - fext)
