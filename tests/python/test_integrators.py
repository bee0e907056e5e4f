"""Time integrators: step values against references built from Pinocchio
(pin.aba + pin.integrate, the same schemes written out in NumPy), Jacobians
[A | B] against central finite differences in the tangent space, and the
convergence orders of the schemes (halving dt)."""

import os

import numpy as np
import pinocchio as pin
import pytest

import rbdkit
from pinref import ROBOTS_DIR, URDF_DIR, Reference, assert_close

SCHEMES = ("euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal", "constant_acceleration")
CASES = [(f"{n}-{'floating' if fb else 'fixed'}", os.path.join(ROBOTS_DIR, n + ".urdf"), fb)
         for n in ("iiwa", "hyq", "atlas") for fb in (False, True)]
CASES += [(f"{n}-{'floating' if fb else 'fixed'}", os.path.join(URDF_DIR, n + ".urdf"), fb)
          for n in ("spherical", "helical", "mimic") for fb in (False, True)]


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def ref(request):
    return Reference(request.param[1], request.param[2])


def state(model, seed=0):
    rng = np.random.default_rng(seed)
    return (model.random_configuration(rng), rng.uniform(-2, 2, model.nv), rng.uniform(-10, 10, model.nv),
            rng.uniform(-3, 3, (model.nb, 6)))


def reference_step(ref, q, v, u, dt, scheme, fext=None):
    """the step in Pinocchio's coordinates, from Pinocchio's aba and integrate"""
    return reference_step_pin(ref, ref.q(q), ref.G @ v, u, dt, scheme, fext)


def reference_step_pin(ref, qp, vp, u, dt, scheme, fext=None):
    """the same from a state in Pinocchio's coordinates"""
    G = ref.G

    def acc(qq_pin, vv_pin):
        # reduced forward dynamics at a Pinocchio state: the state is G-mapped from a reduced one
        vr = np.linalg.lstsq(G, vv_pin, rcond=None)[0]
        return G @ ref_forward(ref, qq_pin, vr, u, fext)

    def integ(qq, w):
        return pin.integrate(ref.pin, qq, w)

    if scheme in ("euler", "semi_implicit_euler", "constant_acceleration"):
        a = acc(qp, vp)
        vn = vp + dt * a
        w = {"euler": dt * vp, "semi_implicit_euler": dt * vn, "constant_acceleration": dt * vp + 0.5 * dt * dt * a}
        return integ(qp, w[scheme]), vn
    c, bw = {"midpoint": ([0, 0.5], [0, 1]), "trapezoidal": ([0, 1], [0.5, 0.5]),
             "rk4": ([0, 0.5, 0.5, 1], [1 / 6, 1 / 3, 1 / 3, 1 / 6])}[scheme]
    vs, a_s = vp, acc(qp, vp)
    vsum, asum = bw[0] * vs, bw[0] * a_s
    for s in range(1, len(c)):
        qs = integ(qp, c[s] * dt * vs)
        vs = vp + c[s] * dt * a_s
        a_s = acc(qs, vs)
        vsum, asum = vsum + bw[s] * vs, asum + bw[s] * a_s
    return integ(qp, dt * vsum), vp + dt * asum


def ref_forward(ref, q_pin, v_red, u, fext):
    """reduced forward dynamics at a Pinocchio configuration (mimic: through G)"""
    ref.set_gravity(-9.81)
    G = ref.G
    args = (ref.pin, ref.data, q_pin, G @ v_red, np.zeros(ref.pin.nv))
    fx = ref.fext(fext) if fext is not None else None
    c = G.T @ (pin.rnea(*args, fx) if fx is not None else pin.rnea(*args))
    M = pin.crba(ref.pin, ref.data, q_pin)
    M = np.triu(M) + np.triu(M, 1).T
    return np.linalg.solve(G.T @ M @ G, u - c)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_step_matches_pinocchio_reference(ref, scheme):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    for seed, fx in ((0, False), (1, True)):
        q, v, u, fext = state(m, seed)
        fext = fext if fx else None
        x = rbd.integrator(q, v, u, 0.01, scheme, f_ext=fext)
        qn, vn = reference_step(ref, q, v, u, 0.01, scheme, fext)
        assert_close(ref.q(x[:m.nq]), qn, f"{scheme} q+")
        assert_close(ref.G @ x[m.nq:], vn, f"{scheme} v+")
        # plant_step is the same step on x = [q; qd]
        np.testing.assert_array_equal(rbd.plant_step(np.concatenate([q, v]), u, 0.01, scheme, f_ext=fext), x)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_gradient_by_finite_differences(ref, scheme):
    rbd = rbdkit.RBD(ref.model)
    m, nv = ref.model, ref.model.nv
    q, v, u, fext = state(m, 3)
    dt = 0.02
    AB = rbd.integrator_gradient(q, v, u, dt, scheme, f_ext=fext)
    assert AB.shape == (2 * nv, 3 * nv)
    x0 = rbd.integrator(q, v, u, dt, scheme, f_ext=fext)

    def step(d):
        return rbd.integrator(rbd.integrate(q, d[:nv]), v + d[nv:2 * nv], u + d[2 * nv:], dt, scheme, f_ext=fext)

    def tangent(x):  # x relative to x0, in the tangent space at x0
        return np.concatenate([rbd.difference(x0[:m.nq], x[:m.nq]), x[m.nq:] - x0[m.nq:]])

    F = np.zeros_like(AB)
    eps = 1e-5
    for k in range(3 * nv):
        d = np.zeros(3 * nv)
        d[k] = eps
        F[:, k] = (tangent(step(d)) - tangent(step(-d))) / (2 * eps)
    assert_close(AB, F, f"{scheme} [A|B] vs FD", 1e-6)
    np.testing.assert_array_equal(rbd.plant_step_gradient(np.concatenate([q, v]), u, dt, scheme, f_ext=fext), AB)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_external_force_gradient_by_finite_differences(ref, scheme):
    # ∂x⁺/∂f_ext (2nv, nb, 6) against central differences in f (Euclidean), in the tangent space at x⁺
    rbd = rbdkit.RBD(ref.model)
    m, nv, nb = ref.model, ref.model.nv, ref.model.nb
    q, v, u, fext = state(m, 4)
    dt = 0.02
    D = rbd.integrator_f_ext_gradient(q, v, u, dt, scheme, f_ext=fext)
    assert D.shape == (2 * nv, nb, 6)
    x0 = rbd.integrator(q, v, u, dt, scheme, f_ext=fext)

    def tangent(x):
        return np.concatenate([rbd.difference(x0[:m.nq], x[:m.nq]), x[m.nq:] - x0[m.nq:]])

    eps = 1e-5
    F = np.stack([(tangent(rbd.integrator(q, v, u, dt, scheme, f_ext=fext + eps * e.reshape(nb, 6)))
                   - tangent(rbd.integrator(q, v, u, dt, scheme, f_ext=fext - eps * e.reshape(nb, 6)))) / (2 * eps)
                  for e in np.eye(6 * nb)], -1)
    assert_close(D.reshape(2 * nv, -1), F, f"{scheme} ∂x⁺/∂f_ext vs FD", 1e-6)
    # without f_ext: the derivative at zero forces (the first two bodies' columns)
    D0 = rbd.integrator_f_ext_gradient(q, v, u, dt, scheme)
    x0 = rbd.integrator(q, v, u, dt, scheme)
    F0 = np.stack([(tangent(rbd.integrator(q, v, u, dt, scheme, f_ext=eps * e.reshape(nb, 6)))
                    - tangent(rbd.integrator(q, v, u, dt, scheme, f_ext=-eps * e.reshape(nb, 6)))) / (2 * eps)
                   for e in np.eye(6 * nb)[:12]], -1)
    assert_close(D0.reshape(2 * nv, -1)[:, :12], F0, f"{scheme} ∂x⁺/∂f_ext at f = 0 vs FD", 1e-6)


@pytest.mark.parametrize("scheme", ("euler", "rk4"))
@pytest.mark.parametrize("name", ("hyq", "spherical"))
def test_external_force_gradient_in_mujoco_coordinates(name, scheme):
    # output_convention="mujoco": x, u in MuJoCo's qpos/qvel layout and frames, rows along
    # mj_integratePos's tangent; f_ext stays body-local
    path = os.path.join(ROBOTS_DIR if name == "hyq" else URDF_DIR, name + ".urdf")
    m = rbdkit.Model.from_urdf(path, floating_base=name == "hyq")
    rbd = rbdkit.RBD(m)
    q, v, u, fext = state(m, 5)
    x = rbd.state_to_mujoco(np.concatenate([q, v]))
    qm, vm = x[:m.nq], x[m.nq:]
    dt, nv, nb = 0.02, m.nv, m.nb
    D = rbd.integrator_f_ext_gradient(qm, vm, u, dt, scheme, f_ext=fext, output_convention="mujoco")
    x0 = rbd.integrator(qm, vm, u, dt, scheme, f_ext=fext, output_convention="mujoco")

    def tangent(x):
        return np.concatenate([rbd.mujoco_difference(x0[:m.nq], x[:m.nq]), x[m.nq:] - x0[m.nq:]])

    eps = 1e-5
    F = np.stack([(tangent(rbd.integrator(qm, vm, u, dt, scheme, f_ext=fext + eps * e.reshape(nb, 6),
                                          output_convention="mujoco"))
                   - tangent(rbd.integrator(qm, vm, u, dt, scheme, f_ext=fext - eps * e.reshape(nb, 6),
                                            output_convention="mujoco"))) / (2 * eps)
                  for e in np.eye(6 * nb)], -1)
    assert_close(D.reshape(2 * nv, -1), F, f"{scheme} mujoco ∂x⁺/∂f_ext vs FD", 1e-6)


def global_error(rbd, q, v, u, T, n, scheme, q_ref, v_ref):
    dt = T / n
    for _ in range(n):
        x = rbd.integrator(q, v, u, dt, scheme)
        q, v = x[:rbd.nq], x[rbd.nq:]
    return max(np.abs(rbd.difference(q_ref, q)).max(), np.abs(v - v_ref).max())


@pytest.mark.parametrize("robot,floating,orders", [
    ("iiwa", False, {"euler": 1, "semi_implicit_euler": 1, "constant_acceleration": 1, "midpoint": 2,
                     "trapezoidal": 2, "rk4": 4}),
    ("hyq", True, {"euler": 1, "midpoint": 2, "trapezoidal": 2, "rk4": 2}),
])
def test_convergence_orders(robot, floating, orders):
    # global error over 0.2 s against a fine RK4 solution; halving dt divides it by about 2^p.
    # On the floating base the base-point retractions limit RK4 to order 2 (no Munthe-Kaas correction).
    model = rbdkit.robots.load(robot, floating_base=floating)
    rbd = rbdkit.RBD(model)
    rng = np.random.default_rng(0)
    q, v = model.random_configuration(rng, 0.5), rng.uniform(-1, 1, model.nv)
    if floating:
        v[3:6] = [4.0, -3.0, 5.0]  # a spinning base makes the rotational error term dominate
    u = rbd.generalized_gravity(q) + rng.uniform(-2, 2, model.nv)
    T = 0.2
    qr, vr = q, v
    n_ref = 4000
    for _ in range(n_ref):
        x = rbd.integrator(qr, vr, u, T / n_ref, "rk4")
        qr, vr = x[:model.nq], x[model.nq:]
    for scheme, p in orders.items():
        e1 = global_error(rbd, q, v, u, T, 20, scheme, qr, vr)
        e2 = global_error(rbd, q, v, u, T, 40, scheme, qr, vr)
        rate = np.log2(e1 / e2)
        assert abs(rate - p) < 0.35, f"{scheme}: observed order {rate:.2f}, expected {p}"


def test_bad_integrator_arguments():
    model = rbdkit.robots.load("iiwa")
    rbd = rbdkit.RBD(model)
    q, v, u = model.neutral(), np.zeros(model.nv), np.zeros(model.nv)
    for name in ("rk3", "si_euler", "RK4", "implicit"):
        with pytest.raises(ValueError, match=r"^integrator_type: unknown integrator .*expected one of euler"):
            rbd.integrator(q, v, u, 0.01, name)
    with pytest.raises(TypeError, match="^integrator_type"):
        rbd.integrator(q, v, u, 0.01, 4)
    for dt in (0.0, -0.01, np.nan, np.inf):
        with pytest.raises(ValueError, match="^dt: "):
            rbd.integrator_gradient(q, v, u, dt)
    with pytest.raises(ValueError, match=r"^x: expected shape"):
        rbd.plant_step(q, u, 0.01)
    with pytest.raises(ValueError, match=r"^u: expected shape"):
        rbd.integrator(q, v, np.zeros(3), 0.01)
    with pytest.raises(ValueError, match="^qd: expected finite"):
        rbd.integrator(q, np.full(model.nv, np.nan), u, 0.01)


def test_batched_steps_equal_single_steps():
    model = rbdkit.robots.load("hyq", floating_base=True)
    rbd = rbdkit.RBD(model)
    rng = np.random.default_rng(4)
    Q = np.stack([model.random_configuration(rng) for _ in range(5)])
    V, U = rng.normal(size=(5, model.nv)), rng.normal(size=(5, model.nv))
    for scheme in SCHEMES:
        X = rbd.integrator(Q, V, U, 0.01, scheme)
        AB = rbd.integrator_gradient(Q, V, U, 0.01, scheme)
        for k in range(5):
            np.testing.assert_array_equal(X[k], rbd.integrator(Q[k], V[k], U[k], 0.01, scheme))
            np.testing.assert_array_equal(AB[k], rbd.integrator_gradient(Q[k], V[k], U[k], 0.01, scheme))


# ---- a spherical joint inside a floating robot against Pinocchio's JointModelSpherical: the step
# gradient and the step Hessian of every scheme, from steps built by Pinocchio (pin.aba's dynamics,
# pin.integrate, pin.difference), both derivatives by central differences of those steps

@pytest.fixture(scope="module")
def spherical_floating():
    return Reference(os.path.join(URDF_DIR, "spherical.urdf"), True)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_spherical_in_floating_step_derivatives_match_pinocchio(spherical_floating, scheme):
    ref = spherical_floating
    m, nv = ref.model, ref.model.nv
    assert ref.pin.joints[1].shortname() == "JointModelFreeFlyer"
    assert any(j.shortname() == "JointModelSpherical" for j in ref.pin.joints)
    rbd = rbdkit.RBD(m)
    rng = np.random.default_rng(7)
    q, v, u = m.random_configuration(rng), rng.uniform(-2, 2, nv), rng.uniform(-5, 5, nv)
    v[3:6] = [3.0, -2.0, 2.5]  # the base turning: its brackets matter
    dt = 0.02
    x = np.concatenate([q, v])
    G = ref.G  # rbdkit's tangent coordinates -> Pinocchio's (a permutation: the joint orders differ)
    np.testing.assert_array_equal(G @ G.T, np.eye(nv))
    AB, H = rbd.plant_step_gradient(x, u, dt, scheme), rbd.plant_step_hessian(x, u, dt, scheme)
    qp0, vp0 = reference_step(ref, q, v, u, dt, scheme)

    def psi(z):  # the Pinocchio-built step at (q ⊕ δq, v + δv, u + δu), in the tangent at the nominal one
        qz = pin.integrate(ref.pin, ref.q(q), G @ z[:nv])
        qn, vn = reference_step_pin(ref, qz, G @ (v + z[nv:2 * nv]), u + z[2 * nv:], dt, scheme)
        return np.concatenate([G.T @ pin.difference(ref.pin, qp0, qn), G.T @ (vn - vp0)])

    n = 3 * nv
    E = np.eye(n)
    h = 1e-5
    F = np.stack([(psi(h * E[k]) - psi(-h * E[k])) / (2 * h) for k in range(n)], axis=1)
    assert_close(AB, F, f"{scheme} plant_step_gradient vs Pinocchio's steps", 1e-6)
    # the Hessian on the directions where the two joints' manifolds act: the free flyer's six, the
    # ball's three, and one velocity and one torque coordinate of each (every pair of them)
    ball = next(j["v_index"] for j in m.joints if j["type"] == "spherical")
    dirs = list(range(6)) + [ball, ball + 1, ball + 2, nv + 3, nv + ball + 1, 2 * nv + 4, 2 * nv + ball]
    h2 = 2e-3  # second differences, Richardson-extrapolated (h, h/2)
    err, scale = 0.0, max(1.0, np.max(np.abs(H)))
    for a, j in enumerate(dirs):
        for k in dirs[a:]:
            def d2(s):
                x, y = s * E[j], s * E[k]
                return (psi(x + y) - psi(x - y) - psi(y - x) + psi(-x - y)) / (4 * s * s)
            err = max(err, np.max(np.abs(H[:, j, k] - (4 * d2(h2 / 2) - d2(h2)) / 3)) / scale)
    assert err < 1e-5, f"{scheme} plant_step_hessian vs Pinocchio's steps: relative error {err:.1e}"
