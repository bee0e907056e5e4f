"""plant_step_hessian: the second-order sensitivity of one integrator step,
H[i, j, k] = ∂²ψ_i/∂z_j∂z_k with z = [δq; δqd; δu] and
ψ(z) = [difference(q⁺(0), q⁺(z)); qd⁺(z) - qd⁺(0)], against central second
differences of ψ (every perturbed step in one batched plant_step call), its
symmetry, and its consistency with plant_step_gradient; the same in
MuJoCo's convention (output_convention="mujoco": ⊕ / ⊖ = mj_integratePos /
mj_differentiatePos, MuJoCo's qpos/qvel), which is bit-identical to ours
without free or ball joints. Exact (nested dual number) checks:
tests/cpp/test_integrator_hessian.cpp; against the mujoco package's
transition Jacobians: tests/python/test_mujoco.py."""

import os

import numpy as np
import pytest

import rbdkit
from pinref import ROBOTS_DIR, URDF_DIR

SCHEMES = ("euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal", "constant_acceleration")


def load(name, floating):
    d = ROBOTS_DIR if name in ("iiwa", "hyq", "atlas") else URDF_DIR
    return rbdkit.Model.from_urdf(os.path.join(d, name + ".urdf"), floating_base=floating)


def state(model, seed=0, spin=False):
    rng = np.random.default_rng(seed)
    q, v, u = model.random_configuration(rng), rng.uniform(-2, 2, model.nv), rng.uniform(-10, 10, model.nv)
    if spin:  # the floating base turning fast: the curvature of the retraction matters
        v[3:6] = [6.0, -4.0, 5.0]
    return np.concatenate([q, v]), u


def psi_fn(rbd, x, u, dt, scheme, gravity=-9.81, convention="pinocchio"):
    """ψ(Z) for perturbations Z (P, 3nv), all steps in one batched call, with
    the convention's ⊕ / ⊖ and coordinates"""
    nq, nv = rbd.nq, rbd.nv
    plus, minus = {"pinocchio": (rbd.integrate, rbd.difference),
                   "mujoco": (rbd.mujoco_integrate, rbd.mujoco_difference)}[convention]
    x0 = rbd.plant_step(x, u, dt, scheme, gravity=gravity, output_convention=convention)

    def psi(Z):
        P = Z.shape[0]
        q = plus(np.tile(x[:nq], (P, 1)), Z[:, :nv])
        X = np.concatenate([q, x[nq:] + Z[:, nv:2 * nv]], axis=1)
        xn = rbd.plant_step(X, u + Z[:, 2 * nv:], dt, scheme, gravity=gravity, output_convention=convention)
        return np.concatenate([minus(np.tile(x0[:nq], (P, 1)), xn[:, :nq]), xn[:, nq:] - x0[nq:]], axis=1)

    return psi


def fd_hessian(psi, n, h=2e-3):
    """central second differences, H[:, j, k] ≈ Σ± ψ(±h e_j ± h e_k) / 4h² (j <= k),
    at steps h and h/2 with Richardson extrapolation (error O(h⁴))"""
    J, K = np.triu_indices(n)
    E = np.eye(n)
    P = np.concatenate([E[J] + E[K], E[J] - E[K], E[K] - E[J], -(E[J] + E[K])])
    Y = psi(np.concatenate([h * P, 0.5 * h * P])).reshape(2, 4, len(J), -1)
    D1, D2 = ((Y[s, 0] - Y[s, 1] - Y[s, 2] + Y[s, 3]) / (4 * (h / 2 ** s) ** 2) for s in (0, 1))
    D = (4 * D2 - D1) / 3  # (pairs, 2nv)
    H = np.zeros((D.shape[1], n, n))
    H[:, J, K] = D.T
    H[:, K, J] = D.T
    return H


def check_against_fd(model, scheme, seed=0, spin=False, dt=0.02, tol=1e-5, convention="pinocchio"):
    rbd = rbdkit.RBD(model)
    nv = model.nv
    x, u = state(model, seed, spin)
    if convention == "mujoco":  # the same motion in MuJoCo's qpos/qvel (ω stays in the body frame)
        x = rbd.state_to_mujoco(x)
    H = rbd.plant_step_hessian(x, u, dt, scheme, output_convention=convention)
    assert H.shape == (2 * nv, 3 * nv, 3 * nv)
    F = fd_hessian(psi_fn(rbd, x, u, dt, scheme, convention=convention), 3 * nv)
    err = np.max(np.abs(H - F)) / max(1.0, np.max(np.abs(F)))
    assert err < tol, f"{scheme}: H vs central second differences, relative error {err:.2e}"
    np.testing.assert_array_equal(H, np.swapaxes(H, 1, 2))
    return rbd, x, u, H


SMALL = [(n, fb) for n in ("iiwa", "hyq", "spherical", "helical", "planar", "mimic") for fb in (False, True)]


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("name,floating", SMALL, ids=[f"{n}-{'floating' if f else 'fixed'}" for n, f in SMALL])
def test_hessian_by_second_differences(name, floating, scheme):
    check_against_fd(load(name, floating), scheme, seed=1)


ATLAS = [(False, "rk4"), (False, "semi_implicit_euler"), (True, "euler"), (True, "rk4")]


@pytest.mark.parametrize("floating,scheme", ATLAS, ids=[f"{'floating' if f else 'fixed'}-{s}" for f, s in ATLAS])
def test_hessian_atlas(floating, scheme):
    check_against_fd(load("atlas", floating), scheme, seed=2)


SPIN = [(n, s) for n in ("hyq", "spherical") for s in ("euler", "semi_implicit_euler", "constant_acceleration", "rk4")]


@pytest.mark.parametrize("name,scheme", SPIN, ids=[f"{n}-{s}" for n, s in SPIN])
def test_hessian_with_a_spinning_floating_base(name, scheme):
    # a large body rate and a long step: the exponential map's second derivatives are far from zero
    check_against_fd(load(name, True), scheme, seed=3, spin=True, dt=0.05)


@pytest.mark.parametrize("convention", ("pinocchio", "mujoco"))
@pytest.mark.parametrize("scheme", SCHEMES)
def test_hessian_is_the_derivative_of_the_gradient(scheme, convention):
    # along a direction d in (δqd, δu) the input and the qd⁺ rows need no chart change:
    # ∂AB[qd⁺ rows]/∂d = H[qd⁺ rows] · d
    model = load("hyq", True)
    rbd = rbdkit.RBD(model)
    nq, nv = model.nq, model.nv
    x, u = state(model, 4, spin=True)
    if convention == "mujoco":
        x = rbd.state_to_mujoco(x)
    dt = 0.02
    kw = dict(output_convention=convention)
    H = rbd.plant_step_hessian(x, u, dt, scheme, **kw)
    rng = np.random.default_rng(5)
    d = np.concatenate([np.zeros(nv), rng.uniform(-1, 1, 2 * nv)])
    t = 1e-4
    ABp = rbd.plant_step_gradient(x + np.concatenate([np.zeros(nq), t * d[nv:2 * nv]]), u + t * d[2 * nv:], dt, scheme,
                                  **kw)
    ABm = rbd.plant_step_gradient(x - np.concatenate([np.zeros(nq), t * d[nv:2 * nv]]), u - t * d[2 * nv:], dt, scheme,
                                  **kw)
    dAB = (ABp - ABm)[nv:] / (2 * t)
    Hd = H[nv:] @ d
    assert np.max(np.abs(dAB - Hd)) / max(1.0, np.max(np.abs(Hd))) < 1e-7


MJ = [(n, s) for n in ("hyq", "spherical") for s in SCHEMES]


@pytest.mark.parametrize("name,scheme", MJ, ids=[f"{n}-{s}" for n, s in MJ])
def test_mujoco_hessian_by_second_differences(name, scheme):
    # MuJoCo's ⊕ / ⊖ on input and output, qvel = [ṗ world; ω body], u in the same
    # frames; a floating base (free joint; ball joints in the spherical model) spinning fast
    check_against_fd(load(name, True), scheme, seed=3, spin=True, dt=0.05, convention="mujoco")


@pytest.mark.parametrize("name", ("spherical", "mimic"))
def test_mujoco_hessian_fixed_base_by_second_differences(name):
    # ball joints only (spherical): the same maps with the quaternions reordered
    check_against_fd(load(name, False), "rk4", seed=6, convention="mujoco")


@pytest.mark.parametrize("name", ("iiwa", "hyq", "helical", "planar", "mixed", "mimic"))
def test_mujoco_convention_is_bit_identical_without_free_or_ball_joints(name):
    # fixed bases, no ball joints: the two conventions are the same coordinates
    model = load(name, False)
    rbd = rbdkit.RBD(model)
    x, u = state(model, 7)
    for scheme in SCHEMES:
        np.testing.assert_array_equal(rbd.plant_step_hessian(x, u, 0.02, scheme, output_convention="mujoco"),
                                      rbd.plant_step_hessian(x, u, 0.02, scheme))


def test_batch_and_gravity():
    model = load("iiwa", False)
    rbd = rbdkit.RBD(model)
    X, U = zip(*(state(model, s) for s in range(3)))
    X, U = np.stack(X), np.stack(U)
    Hb = rbd.plant_step_hessian(X, U, 0.01, "midpoint", gravity=-3.0)
    assert Hb.shape == (3, 2 * model.nv, 3 * model.nv, 3 * model.nv)
    for s in range(3):
        np.testing.assert_array_equal(Hb[s], rbd.plant_step_hessian(X[s], U[s], 0.01, "midpoint", gravity=-3.0))
    # gravity enters: the q-q block of the qd⁺ rows changes with it
    assert not np.allclose(Hb[0], rbd.plant_step_hessian(X[0], U[0], 0.01, "midpoint"))
    # MuJoCo's convention, batched
    model = load("hyq", True)
    rbd = rbdkit.RBD(model)
    X, U = zip(*(state(model, s, spin=True) for s in range(2)))
    X, U = rbd.state_to_mujoco(np.stack(X)), np.stack(U)
    Hb = rbd.plant_step_hessian(X, U, 0.01, "rk4", output_convention="mujoco")
    for s in range(2):
        np.testing.assert_array_equal(Hb[s], rbd.plant_step_hessian(X[s], U[s], 0.01, "rk4",
                                                                    output_convention="mujoco"))


def test_bad_scheme_and_dt():
    model = load("iiwa", False)
    rbd = rbdkit.RBD(model)
    x, u = state(model)
    with pytest.raises(ValueError, match="^integrator_type: unknown integrator"):
        rbd.plant_step_hessian(x, u, 0.01, "rk3")
    for dt in (0.0, -0.01, np.nan):
        with pytest.raises(ValueError, match="^dt: "):
            rbd.plant_step_hessian(x, u, dt)
    with pytest.raises(TypeError):
        rbd.plant_step_hessian(x, u, 0.01, f_ext=np.zeros((model.nb, 6)))
