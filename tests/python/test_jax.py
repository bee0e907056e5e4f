"""rbdkit.jax: the XLA FFI calls against the NumPy handle (the same engine:
bit for bit), leading batch shapes, jit and vmap, the derivative rules against
central differences of the NumPy path (in the tangent space for q), the
coordinate / tangent maps of quaternion joints, and the errors."""

import os
import subprocess
import sys

import numpy as np
import pytest

jax = pytest.importorskip("jax") if os.environ.get("CI") != "true" else __import__("jax")
import jax.numpy as jnp  # noqa: E402

import rbdkit  # noqa: E402
import rbdkit.jax as rj  # noqa: E402

jax.config.update("jax_enable_x64", True)

from framework_cases import (CONFIGURATION_CASES, SCHEMES, central_difference, configuration_call,  # noqa: E402
                             elementwise_cases, gauss_newton_cases, Handles, import_example,
                             import_without, on_manifold, registry_cases, rel, states, tangent_difference,
                             to_tangent_gradient)

# every robot family: serial arm, quadruped and humanoid with free flyers,
# spherical, helical, planar (prismatic and continuous) and mimic joints
MODELS = [("iiwa", False), ("hyq", True), ("atlas", True), ("spherical", False), ("helical", True),
          ("planar", False), ("mimic", False)]
handle = Handles(lambda model, dtype: rj.Handle(model, dtype=dtype, threads=1))


# a representative call of every kind of argument: optional arrays (qdd,
# f_ext), reals, choices, integrators, frames, end effectors, several outputs,
# third-order tensors
def calls(h, q, qd, u):
    x = np.concatenate([q, qd], -1)
    frame = h.model.frame_names[len(h.model.frame_names) // 2]
    f_ext = 0.3 * np.ones(q.shape[:-1] + (h.nb, 6))
    return [
        ("inverse_dynamics", (q, qd, u), {}),
        ("inverse_dynamics", (q, qd), {"gravity": -3.0, "f_ext": f_ext}),
        ("crba", (q,), {}),
        ("minv", (q,), {}),
        ("forward_dynamics_gradient", (q, qd, u), {}),
        ("integrator", (q, qd, u, 0.01, "rk4"), {}),
        ("plant_step_gradient", (x, u, 0.01, "midpoint"), {}),
        ("dDifference", (q, q), {"with_respect_to": "from"}),
        ("frame_jacobian", (q, frame), {}),
        ("end_effector_pose", (q,), {}),
        ("idsva_so", (q, qd, u), {}),
        ("com", (q,), {}),
    ]


def as_list(r):
    return list(r) if isinstance(r, tuple) else [r]


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_every_registered_operation_equals_the_numpy_handle(dtype):
    # the whole registry on a floating base, batched and one sample (test_handle's arguments for each
    # operation), eager and under jax.jit: the same outputs bit for bit, shapes and dtypes included
    from test_handle import CALLS
    hj = rj.Handle(rbdkit.robots.load("hyq", floating_base=True), threads=1, dtype=dtype)
    for op, call, v, want in registry_cases(dtype):
        jv = {k: jnp.asarray(x) if isinstance(x, np.ndarray) else x for k, x in v.items()}
        arrays = [n for n in CALLS[op][0] if isinstance(v[n], np.ndarray)]  # (the jitted function's arguments)
        jitted = jax.jit(lambda *a: call(hj, dict(jv, **dict(zip(arrays, a)))))  # noqa: B023
        for got in (call(hj, jv), jitted(*[jv[n] for n in arrays])):
            assert len(got) == len(want), op
            for g, w in zip(got, want):
                assert g.dtype == np.dtype(dtype) and g.shape == w.shape, op
                np.testing.assert_array_equal(np.asarray(g), w, err_msg=op)


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True), ("atlas", True)])
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_values_equal_the_numpy_handle(name, floating, dtype):
    h = handle(name, floating, dtype)
    q, qd, u = (a.astype(dtype) for a in states(h, 4))
    for op, args, kw in calls(h, q, qd, u):
        want = as_list(getattr(h.numpy, op)(*args, **kw))
        eager = as_list(getattr(h, op)(*args, **kw))
        jitted = as_list(jax.jit(lambda *a: getattr(h, op)(*a, **kw), static_argnums=tuple(
            i for i, a in enumerate(args) if not isinstance(a, np.ndarray)))(*args))
        assert len(want) == len(eager) == len(jitted), op
        for w, e, j in zip(want, eager, jitted):
            assert e.dtype == np.dtype(dtype) and e.shape == w.shape, op
            np.testing.assert_array_equal(np.asarray(e), w, err_msg=op)  # the same engine: bit for bit
            np.testing.assert_array_equal(np.asarray(j), w, err_msg=op)


def test_leading_batch_shapes_and_broadcasting():
    h = handle("hyq", True)
    q, qd, u = states(h, 6)
    flat = h.numpy.forward_dynamics(q, qd, u)
    out = h.forward_dynamics(q.reshape(2, 3, -1), qd.reshape(2, 3, -1), u.reshape(2, 3, -1))
    assert out.shape == (2, 3, h.nv)
    np.testing.assert_array_equal(np.asarray(out).reshape(6, -1), flat)
    # one sample against a batch: broadcast on the leading axes
    out = h.forward_dynamics(q[0], qd, u)
    np.testing.assert_array_equal(np.asarray(out), h.numpy.forward_dynamics(np.tile(q[0], (6, 1)), qd, u))
    # one sample: no batch axis
    assert h.crba(q[0]).shape == (h.nv, h.nv)
    assert h.integrator(q[0], qd[0], u[0], 0.01).shape == (h.nq + h.nv,)


def test_gradients_with_mixed_batch_shapes():
    # a batch of q against one qd and u: the rules broadcast the tangents to the call's batch
    h = handle("hyq", True)
    q, qd, u = states(h, 3)
    for f in (lambda q, qd, u: h.integrator(q, qd, u, 0.01, "rk4"), h.forward_dynamics, h.inverse_dynamics):
        for argnum in range(3):
            g = jax.grad(lambda *a: jnp.sum(f(*a)), argnums=argnum)(q, qd[0], u[0])
            g_tiled = jax.grad(lambda *a: jnp.sum(f(*a)), argnums=argnum)(q, np.tile(qd[0], (3, 1)),
                                                                          np.tile(u[0], (3, 1)))
            want = g_tiled if argnum == 0 else g_tiled.sum(0)
            np.testing.assert_allclose(np.asarray(g), np.asarray(want), rtol=1e-12, atol=1e-12)
    x = np.concatenate([q, qd], -1)
    g = jax.grad(lambda u: jnp.sum(h.plant_step(x, u, 0.01)))(u[0])
    assert g.shape == (h.nv,)


def test_vmap_equals_the_batched_call():
    h = handle("atlas", True)
    q, qd, u = states(h, 6)
    want = h.numpy.inverse_dynamics(q, qd, u)
    np.testing.assert_array_equal(np.asarray(jax.vmap(h.inverse_dynamics)(q, qd, u)), want)
    np.testing.assert_array_equal(np.asarray(jax.jit(jax.vmap(h.inverse_dynamics))(q, qd, u)), want)
    nested = jax.vmap(jax.vmap(h.inverse_dynamics))(q.reshape(2, 3, -1), qd.reshape(2, 3, -1), u.reshape(2, 3, -1))
    np.testing.assert_array_equal(np.asarray(nested).reshape(6, -1), want)
    # an unbatched argument (in_axes None)
    got = jax.vmap(h.inverse_dynamics, in_axes=(0, None, 0))(q, qd[0], u)
    np.testing.assert_array_equal(np.asarray(got), h.numpy.inverse_dynamics(q, np.tile(qd[0], (6, 1)), u))
    # a vmapped gradient
    g = jax.vmap(jax.grad(lambda u: jnp.sum(h.aba(q[0], qd[0], u) ** 2)))(u)
    assert g.shape == u.shape


@pytest.mark.parametrize("name,floating", MODELS)
def test_dynamics_gradients_against_central_differences(name, floating):
    h = handle(name, floating)
    q, qd, u = (a[0] for a in states(h, 1, seed=3))
    w = np.random.default_rng(4).standard_normal(h.nv)
    for op in ("inverse_dynamics", "forward_dynamics", "aba"):
        f_np = getattr(h.numpy, op)
        # reverse mode: the gradient of w·f, each input; q's through the tangent space (module doc)
        gq, gqd, gu = jax.grad(lambda q, qd, u: jnp.dot(w, getattr(h, op)(q, qd, u)), argnums=(0, 1, 2))(q, qd, u)
        Jq = central_difference(lambda x: f_np(x, qd, u), q, **on_manifold(h))
        Jqd = central_difference(lambda x: f_np(q, x, u), qd)
        Ju = central_difference(lambda x: f_np(q, qd, x), u)
        assert rel(h.tangent_gradient(q, gq), w @ Jq) < 1e-6, op
        assert rel(gqd, w @ Jqd) < 1e-6, op
        assert rel(gu, w @ Ju) < 1e-6, op
        # forward mode: the Jacobian with respect to qd and u
        Jf = jax.jacfwd(lambda qd, u: getattr(h, op)(q, qd, u), argnums=(0, 1))(qd, u)
        assert rel(Jf[0], Jqd) < 1e-6 and rel(Jf[1], Ju) < 1e-6, op


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True), ("mimic", False)])
def test_gradients_of_some_inputs_only(name, floating):
    # the rule computes what the differentiated inputs need (M or M⁻¹ alone when only the third input
    # has a tangent): each subset's gradients, reverse and forward mode, equal those of the call where
    # every input is differentiated (checked against central differences above)
    h = handle(name, floating)
    q, qd, u = states(h, 3, seed=5)
    w = np.random.default_rng(7).standard_normal((3, h.nv))
    for op in ("inverse_dynamics", "forward_dynamics", "aba"):
        f = lambda q, qd, u: jnp.sum(w * getattr(h, op)(q, qd, u))  # noqa: E731
        full = jax.grad(f, argnums=(0, 1, 2))(q, qd, u)
        for argnums in ((2,), (0,), (1,), (0, 2), (1, 2)):
            got = jax.jit(jax.grad(f, argnums=argnums))(q, qd, u)
            for k, g in zip(argnums, got):
                np.testing.assert_allclose(g, full[k], rtol=1e-10, atol=1e-10, err_msg=f"{op} {argnums} {k}")
        du = np.random.default_rng(8).standard_normal(u.shape)
        _, jv = jax.jvp(lambda u: getattr(h, op)(q, qd, u), (u,), (du,))
        _, jv_full = jax.jvp(lambda q, qd, u: getattr(h, op)(q, qd, u), (q, qd, u),
                             (jnp.zeros_like(q), jnp.zeros_like(qd), du))
        np.testing.assert_allclose(jv, jv_full, rtol=1e-10, atol=1e-10, err_msg=op)


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True)])
def test_external_force_gradients_against_central_differences(name, floating):
    # f_ext (nb, 6), body frames: ∂τ/∂f_ext = -J_bᵀ, ∂qdd/∂f_ext = M⁻¹ J_bᵀ, and ∂/∂q with the forces on
    h = handle(name, floating)
    q, qd, u = (a[0] for a in states(h, 1, seed=5))
    f = np.random.default_rng(6).standard_normal((h.nb, 6))
    w = np.random.default_rng(7).standard_normal(h.nv)
    for op in ("inverse_dynamics", "forward_dynamics", "aba"):
        f_np = lambda q, f: getattr(h.numpy, op)(q, qd, u, f_ext=f.reshape(h.nb, 6))  # noqa: E731
        gq, gf = jax.jit(jax.grad(lambda q, f: jnp.dot(w, getattr(h, op)(q, qd, u, f_ext=f)), argnums=(0, 1)))(q, f)
        Jq = central_difference(lambda x: f_np(x, f), q, **on_manifold(h))
        Jf = central_difference(lambda x: f_np(q, x), f.ravel())
        assert rel(h.tangent_gradient(q, gq), w @ Jq) < 1e-6, op
        assert rel(np.asarray(gf).ravel(), w @ Jf) < 1e-6, op
        # forward mode, a batch of forces against one state
        fb = np.stack([f, 2 * f])
        J = jax.jacfwd(lambda f: getattr(h, op)(q, qd, u, f_ext=f))(fb)  # (2, nv, 2, nb, 6)
        assert rel(np.asarray(J[1, :, 1]).reshape(h.nv, -1), central_difference(lambda x: f_np(q, x), 2 * f.ravel())) \
            < 1e-6, op


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True)])
def test_step_external_force_gradients_against_central_differences(name, floating):
    # ∂x⁺/∂f_ext (integrator_f_ext_gradient), every scheme: reverse mode in (u, f) together, forward mode
    # over a batch of forces, against central differences of the NumPy handle's x⁺ (coordinates); and in
    # MuJoCo's coordinates
    h = handle(name, floating)
    q, qd, u = (a[0] for a in states(h, 1, seed=8))
    f = np.random.default_rng(9).standard_normal((h.nb, 6))
    w = np.random.default_rng(10).standard_normal(h.nq + h.nv)
    x = np.concatenate([q, qd])
    xm = h.numpy.state_to_mujoco(x)
    for scheme, op, conv in [(s, "integrator", "pinocchio") for s in SCHEMES] + [
            ("semi_implicit_euler", "plant_step", "pinocchio"), ("rk4", "plant_step", "mujoco")]:
        state = (q, qd) if op == "integrator" else (xm if conv == "mujoco" else x,)
        kw = {"output_convention": conv}
        step = lambda u, f: getattr(h, op)(*state, u, 0.01, scheme, f_ext=f, **kw)  # noqa: E731
        step_np = lambda u, f: getattr(h.numpy, op)(*state, u, 0.01, scheme, f_ext=f.reshape(h.nb, 6),  # noqa: E731
                                                    **kw)
        gu, gf = jax.jit(jax.grad(lambda u, f: jnp.dot(w, step(u, f)), argnums=(0, 1)))(u, f)
        assert rel(gu, w @ central_difference(lambda z: step_np(z, f), u)) < 1e-6, (scheme, op, conv)
        assert rel(np.asarray(gf).ravel(), w @ central_difference(lambda z: step_np(u, z), f.ravel())) < 1e-6, \
            (scheme, op, conv)
        J = jax.jacfwd(lambda f: step(u, f))(np.stack([f, -f]))  # (2, nx, 2, nb, 6)
        assert rel(np.asarray(J[1, :, 1]).reshape(h.nq + h.nv, -1),
                   central_difference(lambda z: step_np(u, z), -f.ravel())) < 1e-6, (scheme, op, conv)
        assert not np.any(np.asarray(J[0, :, 1])), (scheme, op, conv)  # sample 0 does not see sample 1's forces
    # the rule's x⁺ and [A | B] (integrator_f_ext_gradient's first outputs) are the step's and its gradient's,
    # bit for bit, in either convention and over a batch: the force columns leave the others as they were
    Q, QD, U = states(h, 3, seed=11)
    for scheme in SCHEMES:
        for conv, q0 in (("pinocchio", Q), ("mujoco", h.numpy.state_to_mujoco(np.concatenate([Q, QD], -1))[:, :h.nq])):
            kw = dict(q=q0, qd=QD, u=U, dt=0.01, integrator_type=scheme, f_ext=f, output_convention=conv)
            x1, AB1, _ = h._values("integrator_f_ext_gradient", (), kw, outputs=0b111)
            x2, AB2 = h._values("integrator_gradient", (), kw, outputs=0b11)
            np.testing.assert_array_equal(np.asarray(x1), np.asarray(x2))
            np.testing.assert_array_equal(np.asarray(AB1), np.asarray(AB2))


@pytest.mark.parametrize("name,floating", [("hyq", True), ("spherical", False)])
def test_step_gradients_in_mujoco_coordinates(name, floating):
    # output_convention="mujoco" on models with quaternions: x in MuJoCo's qpos/qvel, [A | B] along
    # mj_integratePos; reverse mode against central differences along that retraction, forward mode
    # (a coordinate tangent E(x) d) against the coordinates' central differences
    h = handle(name, floating)
    nq, nv = h.nq, h.nv
    q, qd, u = (a[0] for a in states(h, 1, seed=11))
    x = h.numpy.state_to_mujoco(np.concatenate([q, qd]))
    step = lambda x, d: np.concatenate([h.numpy.mujoco_integrate(x[:nq], d[:nv]), x[nq:] + d[nv:]])  # noqa: E731
    w = np.random.default_rng(12).standard_normal(nq + nv)
    d = np.random.default_rng(13).standard_normal(2 * nv)
    for scheme in ("euler", "rk4"):
        f = lambda x, u: h.numpy.plant_step(x, u, 0.01, scheme, output_convention="mujoco")  # noqa: E731
        jf = lambda x, u: h.plant_step(x, u, 0.01, scheme, output_convention="mujoco")  # noqa: E731
        gx, gu = jax.jit(jax.grad(lambda x, u: jnp.dot(w, jf(x, u)), argnums=(0, 1)))(x, u)
        gx_t = np.concatenate([np.asarray(h.tangent_gradient(x[:nq], gx[:nq], output_convention="mujoco")), gx[nq:]])
        assert rel(gx_t, w @ central_difference(lambda z: f(z, u), x, step=step, n=2 * nv)) < 1e-6, scheme
        assert rel(gu, w @ central_difference(lambda z: f(x, z), u)) < 1e-6, scheme
        dx = np.concatenate([np.asarray(h.from_tangent(x[:nq], d[:nv], output_convention="mujoco")), d[nv:]])
        _, jvp = jax.jvp(lambda x: jf(x, u), (x,), (dx,))
        eps = 1e-6
        want = (f(step(x, eps * d), u) - f(step(x, -eps * d), u)) / (2 * eps)
        assert rel(jvp, want) < 1e-6, scheme
    with pytest.raises(ValueError, match="output_convention"):
        h.tangent_gradient(x[:nq], gx[:nq], output_convention="mj")


# every robot family with an explicit and an implicit-stage scheme, every scheme on a floating base
STEP_CASES = [(n, f, s) for n, f in MODELS for s in ("euler", "rk4")] + \
    [("hyq", True, s) for s in SCHEMES if s not in ("euler", "rk4")]


@pytest.mark.parametrize("name,floating,scheme", STEP_CASES)
def test_step_gradients_against_central_differences(name, floating, scheme):
    h = handle(name, floating)
    q, qd, u = (a[0] for a in states(h, 1, seed=5))
    x = np.concatenate([q, qd])
    rng = np.random.default_rng(6)
    if True:
        wq, wqd = rng.standard_normal(h.nq), rng.standard_normal(h.nv)

        def f_np(q, qd, u):
            xn = h.numpy.integrator(q, qd, u, 0.01, scheme)
            return wq @ xn[:h.nq] + wqd @ xn[h.nq:]

        def f(q, qd, u):
            xn = h.integrator(q, qd, u, 0.01, scheme)
            return jnp.dot(wq, xn[:h.nq]) + jnp.dot(wqd, xn[h.nq:])

        gq, gqd, gu = jax.grad(f, argnums=(0, 1, 2))(q, qd, u)
        assert rel(h.tangent_gradient(q, gq), central_difference(lambda z: f_np(z, qd, u), q,
                                                                 **on_manifold(h))) < 1e-6, scheme
        assert rel(gqd, central_difference(lambda z: f_np(q, z, u), qd)) < 1e-6, scheme
        assert rel(gu, central_difference(lambda z: f_np(q, qd, z), u)) < 1e-6, scheme
        # plant_step: x⁺'s Jacobian in u, forward and reverse mode alike
        Jf = jax.jacfwd(lambda u: h.plant_step(x, u, 0.01, scheme))(u)
        Jr = jax.jacrev(lambda u: h.plant_step(x, u, 0.01, scheme))(u)
        Jn = central_difference(lambda z: h.numpy.plant_step(x, z, 0.01, scheme), u)
        assert rel(Jf, Jn) < 1e-6 and rel(Jr, Jn) < 1e-6, scheme


@pytest.mark.parametrize("name,floating", MODELS)
def test_configuration_gradients_against_central_differences(name, floating):
    h = handle(name, floating)
    q = states(h, 1, seed=9)[0][0]
    rng = np.random.default_rng(10)
    for op, kw in CONFIGURATION_CASES:
        f = configuration_call(h, op, kw)
        ws = [rng.standard_normal(np.shape(o)) for o in f(h.numpy, q)]
        # reverse mode: the gradient of Σ w·output, in the tangent space through tangent_gradient (jitted:
        # a third of the eager time)
        gq = jax.jit(jax.grad(lambda q: sum(jnp.sum(w * o) for w, o in zip(ws, f(h, q)))))(q)
        Jn = central_difference(lambda x: sum(np.sum(w * o) for w, o in zip(ws, f(h.numpy, x))), q,
                                **on_manifold(h))
        assert rel(h.tangent_gradient(q, gq), Jn) < 1e-6, (op, kw)
        # forward mode along a tangent direction d: the change of every output (reverse mode is its
        # transpose; one fixed and one floating base keep the test's time down)
        if name not in ("iiwa", "hyq"):
            continue
        d = rng.standard_normal(h.nv)
        dout = jax.jit(lambda q, dq: jax.jvp(lambda q: f(h, q), (q,), (dq,))[1])(q, h.from_tangent(q, d))
        e = 1e-5
        fd = [(a - b) / (2 * e) for a, b in zip(f(h.numpy, h.numpy.rbd.integrate(q, e * d)),
                                                 f(h.numpy, h.numpy.rbd.integrate(q, -e * d)))]
        assert max(rel(a, b) for a, b in zip(dout, fd)) < 1e-6, (op, kw, [rel(a, b) for a, b in zip(dout, fd)])


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True)])
def test_cost_and_barrier_derivatives_against_central_differences(name, floating):
    h = handle(name, floating)
    for op, arrays, mu in elementwise_cases(h.numpy, seed=11):
        kw = {} if mu is None else {"mu": mu}
        f = lambda *a: getattr(h, op)(*a, **kw)  # noqa: E731
        f_np = lambda *a: getattr(h.numpy, op)(*a, **kw)  # noqa: E731
        # every output (value, grad, H or Hdiag) with respect to every array, forward and reverse mode
        Jf = jax.jit(jax.jacfwd(f, argnums=(0, 1, 2)))(*arrays)
        Jr = jax.jit(jax.jacrev(f, argnums=(0, 1, 2)))(*arrays)
        for k in range(3):
            for o in range(3):
                def one(z, k=k, o=o):
                    args = list(arrays)
                    args[k] = z
                    return np.asarray(f_np(*args)[o])
                Jn = central_difference(one, arrays[k], eps=1e-6)
                assert rel(Jf[o][k], Jn) < 1e-6 and rel(Jr[o][k], Jn) < 1e-6, (op, k, o)


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True)])
def test_gauss_newton_cost_values_differentiate_against_central_differences(name, floating):
    h = handle(name, floating)
    for op, arrays in gauss_newton_cases(h, seed=12):
        names = list(arrays)
        f = lambda *a: getattr(h, op)(**dict(zip(names, a)))[0]  # noqa: E731
        grads = jax.jit(jax.grad(f, argnums=tuple(range(len(names)))))(*arrays.values())
        for k, n in enumerate(names):
            def value(z, n=n):
                return getattr(h.numpy, op)(**dict(arrays, **{n: z}))[0]
            assert rel(to_tangent_gradient(h, n, arrays[n], grads[k]), tangent_difference(h, value, n, arrays[n])) \
                < 1e-6, (op, n)
    # grad and H are values: a gradient through them says so
    q = arrays["q"]
    with pytest.raises(NotImplementedError, match="ee_pos_cost's grad and H outputs are values"):
        jax.grad(lambda q: jnp.sum(h.ee_pos_cost(q, arrays["p_des"], arrays["W"])[1]))(q)


def test_derivative_rules_with_lists_float32_and_default_end_effectors():
    h = handle("hyq", True)
    q = states(h, 1, seed=14)[0][0]
    # arrays given as Python lists
    g = jax.grad(lambda p: h.com_cost(q, p, [1.0, 2.0, 3.0])[0])([0.1, 0.2, 0.3])
    assert len(g) == 3 and all(np.isfinite(np.asarray(x)) for x in g)
    # a float32 handle with float64 inputs in 64-bit mode: the tangents in the outputs' dtype
    h32 = handle("hyq", True, "float32")
    J = jax.jacfwd(lambda q: h32.crba(q))(q)
    assert J.dtype == jnp.float32 and rel(J, jax.jacfwd(lambda q: h.crba(q))(q)) < 1e-3
    aba = lambda h, q: h.aba(q, np.zeros(h.nv), np.ones(h.nv))  # noqa: E731
    assert rel(jax.jacrev(lambda q: aba(h32, q))(q), jax.jacrev(lambda q: aba(h, q))(q)) < 1e-3
    # ee_pos_cost's default end effector with a tool offset (the model has several end effectors)
    p_des, W, off = np.array([0.1, 0.2, 0.3]), np.array([1.0, 2.0, 3.0]), np.array([0.05, -0.02, 0.1])
    gq = jax.grad(lambda q: h.ee_pos_cost(q, p_des, W, ee_offset=off)[0])(q)
    fd = central_difference(lambda z: h.numpy.ee_pos_cost(z, p_des, W, ee_offset=off)[0], q, **on_manifold(h))
    assert rel(h.tangent_gradient(q, gq), fd) < 1e-6


@pytest.mark.parametrize("name,floating", [("hyq", True), ("spherical", False)])
def test_coordinate_and_tangent_maps(name, floating):
    h = handle(name, floating)
    q = states(h, 1, seed=7)[0][0]
    # E: the derivative of integrate at zero, by central differences
    E = central_difference(lambda d: h.numpy.rbd.integrate(q, d), np.zeros(h.nv))
    I = np.eye(h.nv)
    Ej = np.stack([np.asarray(h.from_tangent(q, e)) for e in I], -1)
    assert rel(Ej, E) < 1e-8
    # E⁺ E = I, and Eᵀ is the transpose of E
    assert rel(np.stack([np.asarray(h.to_tangent(q, E[:, k])) for k in range(h.nv)], -1), I) < 1e-8
    g = np.random.default_rng(8).standard_normal(h.nq)
    assert rel(h.tangent_gradient(q, g), E.T @ g) < 1e-8
    # a coordinate gradient from JAX has no component along a quaternion (its norm is not a coordinate)
    gq = jax.grad(lambda q: jnp.sum(h.forward_dynamics(q, np.zeros(h.nv), np.ones(h.nv))))(q)
    for j in h.model.joints:
        if j["type"] in ("free", "spherical"):
            k = j["q_index"] + (3 if j["type"] == "free" else 0)
            assert abs(np.dot(gq[k:k + 4], q[k:k + 4])) < 1e-9


def test_operations_without_a_rule_say_so():
    h = handle("iiwa", False)
    q, qd, u = (a[0] for a in states(h, 1))
    with pytest.raises(NotImplementedError, match="coriolis_matrix computes values only"):
        jax.grad(lambda q: jnp.sum(h.coriolis_matrix(q, qd)))(q)
    with pytest.raises(NotImplementedError, match="end_effector_pose is differentiable with respect to q only"):
        jax.grad(lambda o: jnp.sum(h.end_effector_pose(q, ee_offsets=o)))(np.zeros((1, 3)))
    # MuJoCo's coordinates on a model with quaternions: the Gauss–Newton costs' values, but no derivative
    hq = handle("hyq", True)
    qm = hq.numpy.state_to_mujoco(np.concatenate(states(hq, 1)[:2], -1)[0])[:hq.nq]
    args = (qm, np.zeros(3), np.ones(3))
    np.testing.assert_array_equal(np.asarray(hq.com_cost(*args, output_convention="mujoco")[0]),
                                  hq.numpy.com_cost(*args, output_convention="mujoco")[0])
    with pytest.raises(NotImplementedError, match="MuJoCo's output convention"):
        jax.grad(lambda q: hq.com_cost(q, *args[1:], output_convention="mujoco")[0])(qm)
    # f_ext as a constant: fine
    g = jax.grad(lambda u: jnp.sum(h.aba(q, qd, u, f_ext=np.ones((h.nb, 6)))))(u)
    assert np.all(np.isfinite(g))


def test_bad_input_is_a_clear_error():
    h = handle("iiwa", False)
    q, qd, u = (a[0] for a in states(h, 1))
    with pytest.raises(ValueError, match=r"qd: expected shape \(\.\.\., 7\)"):
        h.inverse_dynamics(q, qd[:3], u)
    with pytest.raises(TypeError, match="unexpected keyword argument 'tau'"):
        h.inverse_dynamics(q, qd, tau=u)
    with pytest.raises(ValueError, match="integrator_type"):
        h.integrator(q, qd, u, 0.01, "rk5")
    with pytest.raises(ValueError, match="dt"):
        h.integrator(q, qd, u, -1.0)
    # parameters are Python values, fixed at trace time
    with pytest.raises(TypeError, match="dt"):
        jax.jit(lambda dt: h.integrator(q, qd, u, dt))(0.01)
    # the engine's checks inside a jitted call: the message names the argument and the sample
    bad = np.tile(q, (3, 1))
    bad[1, 2] = np.nan
    with pytest.raises(Exception, match=r"q\[1\]"):
        jax.block_until_ready(jax.jit(h.crba)(bad))
    with pytest.raises(ValueError, match="not built with it"):
        rj.Handle(h.model, algorithms=["inverse_dynamics"]).centroidal_momentum(q, qd)


def test_float64_needs_64_bit_mode_and_float32_works_without():
    code = ("import jax, numpy as np, rbdkit, rbdkit.jax as rj\n"
            "m = rbdkit.robots.load('iiwa')\n"
            "try:\n    rj.Handle(m)\nexcept ValueError as e:\n    print('refused:', e)\n"
            "h = rj.Handle(m, dtype='float32')\n"
            "print(h.crba(np.zeros(7, np.float32)).dtype)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd="/")
    assert r.returncode == 0, r.stderr
    assert "refused: dtype: a float64 handle needs JAX's 64-bit mode" in r.stdout
    assert "float32" in r.stdout.splitlines()[-1]


def test_rbdkit_imports_without_jax():
    assert "ImportError: rbdkit.jax needs JAX: pip install 'jax[cpu]'" in import_without('jax', 'jax')


SHARDED = r"""
import os
os.environ["XLA_FLAGS"] = "--xla_force_host_platform_device_count=4"
import jax, jax.numpy as jnp, numpy as np, rbdkit, rbdkit.jax as rj
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P
jax.config.update("jax_enable_x64", True)
assert len(jax.devices()) == 4
m = rbdkit.robots.load("hyq", floating_base=True)
h = rj.Handle(m, threads=1)
rng = np.random.default_rng(0)
B = 16
q = np.stack([m.random_configuration(rng) for _ in range(B)])
qd, u = rng.uniform(-1, 1, (B, m.nv)), rng.uniform(-1, 1, (B, m.nv))
mesh = Mesh(np.array(jax.devices()), ("batch",))
sh = NamedSharding(mesh, P("batch"))
qs, qds, us = (jax.device_put(a, sh) for a in (q, qd, u))
# each device computes its own shard: the custom call's operands are the 4-sample shards
fd = jax.shard_map(h.forward_dynamics, mesh=mesh, in_specs=P("batch"), out_specs=P("batch"))
f = jax.jit(fd)
out = f(qs, qds, us)
hlo = f.lower(qs, qds, us).compile().as_text()
calls = [l for l in hlo.splitlines() if 'custom_call_target="rbdkit_op"' in l]
assert calls and all("f64[4,18]" in l for l in calls), calls
assert out.sharding.spec == P("batch")
np.testing.assert_array_equal(np.asarray(out), h.numpy.forward_dynamics(q, qd, u))
# a sharded gradient equals the unsharded one
g = jax.jit(jax.grad(lambda u: (fd(qs, qds, u) ** 2).sum()))(us)
g1 = jax.grad(lambda u: (h.forward_dynamics(q, qd, u) ** 2).sum())(u)
np.testing.assert_allclose(np.asarray(g), np.asarray(g1), rtol=1e-13, atol=1e-12)
# plain jit over NamedSharding inputs partitions the call over the batch too (custom_partitioning):
# 4-sample operands, no gather, the output sharded as the inputs; so does its gradient
fj = jax.jit(h.forward_dynamics)
hlo = fj.lower(qs, qds, us).compile().as_text()
calls = [l for l in hlo.splitlines() if 'custom_call_target="rbdkit_op"' in l]
assert calls and all("f64[4,18]" in l for l in calls) and "all-gather" not in hlo, hlo
out = fj(qs, qds, us)
assert out.sharding.spec == P("batch")
np.testing.assert_array_equal(np.asarray(out), h.numpy.forward_dynamics(q, qd, u))
gj = jax.jit(jax.grad(lambda u: (h.forward_dynamics(qs, qds, u) ** 2).sum()))
hlo = gj.lower(us).compile().as_text()
calls = [l for l in hlo.splitlines() if 'custom_call_target="rbdkit_op"' in l]
assert calls and all("f64[4,18,18]" in l for l in calls) and "all-gather" not in hlo, hlo
# (here M⁻¹ comes from the gradient call, in g1 from the minv call: equal to rounding, amplified by cond(M))
np.testing.assert_allclose(np.asarray(gj(us)), np.asarray(g1), rtol=1e-10, atol=1e-10)
# the first input replicated, the others sharded: the call still takes the batch sharding (no gather)
qr = jax.device_put(q, NamedSharding(mesh, P()))
hlo = fj.lower(qr, qds, us).compile().as_text()
assert "all-gather" not in hlo, hlo
np.testing.assert_array_equal(np.asarray(fj(qr, qds, us)), h.numpy.forward_dynamics(q, qd, u))
# a sharded rollout step and a vmapped call under jit: the unsharded results
x = jnp.concatenate([qs, qds], -1)
np.testing.assert_array_equal(np.asarray(jax.jit(lambda x, u: h.plant_step(x, u, 0.01, "rk4"))(x, us)),
                              h.numpy.plant_step(np.concatenate([q, qd], -1), u, 0.01, "rk4"))
np.testing.assert_array_equal(np.asarray(jax.jit(jax.vmap(h.forward_dynamics))(qs, qds, us)),
                              h.numpy.forward_dynamics(q, qd, u))
print("sharded ok")
"""


def test_a_batch_sharded_over_four_host_devices():
    r = subprocess.run([sys.executable, "-c", SHARDED], capture_output=True, text=True, cwd="/")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "sharded ok" in r.stdout


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True)])
def test_inverse_dynamics_with_parameters(name, floating):
    # τ = Y(q, qd, qdd) π with π an input: at the model's π it is inverse_dynamics; ∂/∂π = Y; ∂/∂(q, qd,
    # qdd) against central differences at other parameters (through the regressor's rule)
    h = handle(name, floating)
    q, qd, qdd = (a[0] for a in states(h, 1, seed=8))
    pi = h.model.inertial_parameters()
    np.testing.assert_allclose(np.asarray(h.inverse_dynamics_with_parameters(q, qd, qdd, pi)),
                               h.numpy.inverse_dynamics(q, qd, qdd), rtol=1e-12, atol=1e-10)
    pi2 = pi * np.random.default_rng(9).uniform(0.8, 1.2, pi.shape)  # (physical consistency is not needed)
    w = np.random.default_rng(10).standard_normal(h.nv)
    f_np = lambda q, qd, qdd, p: h.numpy.inverse_dynamics_regressor(q, qd, qdd) @ p  # noqa: E731
    g = jax.jit(jax.grad(lambda *a: jnp.dot(w, h.inverse_dynamics_with_parameters(*a)), argnums=(0, 1, 2, 3)))(
        q, qd, qdd, pi2)
    assert rel(h.tangent_gradient(q, g[0]), w @ central_difference(lambda x: f_np(x, qd, qdd, pi2), q,
                                                                   **on_manifold(h))) < 1e-6
    assert rel(g[1], w @ central_difference(lambda x: f_np(q, x, qdd, pi2), qd)) < 1e-6
    assert rel(g[2], w @ central_difference(lambda x: f_np(q, qd, x, pi2), qdd)) < 1e-6
    np.testing.assert_allclose(np.asarray(g[3]), w @ h.numpy.inverse_dynamics_regressor(q, qd, qdd), rtol=1e-12,
                               atol=1e-12)
    # forward mode on qdd is M(q; π2), and a batch of parameter sets broadcasts against one state
    J = jax.jacfwd(lambda x: h.inverse_dynamics_with_parameters(q, qd, x, pi2))(qdd)
    assert rel(J, central_difference(lambda x: f_np(q, qd, x, pi2), qdd)) < 1e-6
    assert h.inverse_dynamics_with_parameters(q, qd, qdd, np.stack([pi, pi2])).shape == (2, h.nv)
    with pytest.raises(ValueError, match=r"pi: expected shape \(\.\.\., "):
        h.inverse_dynamics_with_parameters(q, qd, qdd, pi[:-1])


def test_system_identification_example_converges(tmp_path):
    # examples/jax_sysid.py: the gradient through the parametrisation and the regressor against central
    # differences; Adam brings the loss from ~1e7 to within 2x of the least-squares optimum, and the
    # held-out torque and mass-matrix errors down a hundredfold and fiftyfold
    jax_sysid = import_example("jax_sysid")
    plot = tmp_path / "sysid.png"
    r = jax_sysid.main(["--plot", str(plot)])
    assert r["grad_error"] < 1e-6
    assert r["loss_start"] > 1e4 and r["loss_final"] < 2 * r["loss_least_squares"]
    assert r["torque_error_final"] < r["torque_error_start"] / 100
    assert r["mass_error_final"] < r["mass_error_start"] / 50
    assert plot.stat().st_size > 0


def _cuda_backend_against_cpu(hc, h, q, qd, u, tol):
    """a backend="cuda" handle's values and gradients, jitted, against the CPU handle's"""
    for op, args in (("inverse_dynamics", (q, qd, u)), ("forward_dynamics", (q, qd, u)), ("crba", (q,)),
                     ("forward_dynamics_gradient", (q, qd, u))):
        for a, b in zip(as_list(jax.jit(getattr(hc, op))(*args)), as_list(getattr(h, op)(*args))):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=tol, atol=tol, err_msg=op)
    step = lambda hh: jax.jit(lambda q, qd, u: hh.integrator(q, qd, u, 0.01, "rk4"))  # noqa: E731
    np.testing.assert_allclose(np.asarray(step(hc)(q, qd, u)), np.asarray(step(h)(q, qd, u)), rtol=tol, atol=tol)
    loss = lambda hh: jax.jit(jax.grad(lambda q, qd, u: (hh.forward_dynamics(q, qd, u) ** 2).sum(),  # noqa: E731
                                       argnums=(0, 1, 2)))
    for a, b in zip(loss(hc)(q, qd, u), loss(h)(q, qd, u)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=tol, atol=tol)


def test_cuda_backend_in_interpret_mode(monkeypatch):
    # backend="cuda" on JAX's CPU platform: the arrays are host buffers the CUDA backend copies to its
    # device; in interpret mode (the kernels' source on the CPU) values and the derivative rules through
    # it equal the CPU handle's. XLA's GPU buffers need a GPU: test_cuda_arrays_on_the_device
    monkeypatch.setenv("RBDKIT_CUDA_INTERPRET", "1")
    model = rbdkit.robots.load("hyq", floating_base=True)
    hc, h = rj.Handle(model, backend="cuda", threads=1), rj.Handle(model, backend="cpu", threads=1)
    assert (hc.backend, h.backend) == ("cuda", "cpu")
    with jax.default_device(jax.devices("cpu")[0]):
        _cuda_backend_against_cpu(hc, h, *states(h, 4, seed=3), 1e-10)
    # the default chooses the CPU where JAX computes on the CPU
    if jax.default_backend() == "cpu":
        assert rj.Handle(model, threads=1).backend == "cpu"


def test_cuda_arrays_on_the_device(monkeypatch):
    # on a GPU with JAX's CUDA platform (scripts/gpu-check.sh): the custom call's CUDA handler reads and
    # writes XLA's device buffers in place on XLA's stream; values and gradients, jitted, equal the
    # CPU handle's; a CPU handle given GPU arrays says backend="cuda". Without one (CI), a cuda
    # handle outside interpret mode is a clear error
    monkeypatch.delenv("RBDKIT_CUDA_INTERPRET", raising=False)
    model = rbdkit.robots.load("hyq", floating_base=True)
    compiled, devices = rbdkit.cuda_available()
    gpus = [d for d in jax.devices() if d.platform == "gpu"] if jax.default_backend() == "gpu" else []
    if os.environ.get("RBDKIT_TEST_CUDA_DEVICE") != "1" or not (compiled and devices > 0 and gpus):
        assert os.environ.get("RBDKIT_TEST_CUDA_DEVICE") != "1", "RBDKIT_TEST_CUDA_DEVICE=1 needs JAX on a GPU"
        if compiled and devices > 0:
            assert rj.Handle(model, backend="cuda").backend == "cuda"
            return
        with pytest.raises(RuntimeError, match="RBDKIT_CUDA_INTERPRET=1"):
            rj.Handle(model, backend="cuda")
        return
    hc, h = rj.Handle(model), rj.Handle(model, backend="cpu", threads=1)
    assert hc.backend == "cuda"  # the default on JAX's GPU platform
    q, qd, u = states(h, 64, seed=4)
    gq, gqd, gu = (jax.device_put(a, gpus[0]) for a in (q, qd, u))
    out = jax.jit(hc.forward_dynamics)(gq, gqd, gu)
    assert out.devices() == {gpus[0]}
    with jax.default_device(jax.devices("cpu")[0]):
        cq, cqd, cu = (jax.device_put(a, jax.devices("cpu")[0]) for a in (q, qd, u))
        np.testing.assert_allclose(np.asarray(out), np.asarray(h.forward_dynamics(cq, cqd, cu)), rtol=1e-9, atol=1e-9)
        ref = [np.asarray(a) for a in jax.grad(lambda q, qd, u: (h.forward_dynamics(q, qd, u) ** 2).sum(),
                                               argnums=(0, 1, 2))(cq, cqd, cu)]
    got = jax.jit(jax.grad(lambda q, qd, u: (hc.forward_dynamics(q, qd, u) ** 2).sum(), argnums=(0, 1, 2)))(gq, gqd, gu)
    for a, b in zip(got, ref):
        np.testing.assert_allclose(np.asarray(a), b, rtol=1e-8, atol=1e-8)
    # the rk4 step and its [A | B] on the device, under vmap over a second batch axis
    step = jax.jit(jax.vmap(lambda q, qd, u: hc.integrator(q, qd, u, 0.01, "rk4")))
    x = step(gq.reshape(8, 8, -1), gqd.reshape(8, 8, -1), gu.reshape(8, 8, -1))
    np.testing.assert_allclose(np.asarray(x).reshape(64, -1), h.numpy.integrator(q, qd, u, 0.01, "rk4"),
                               rtol=1e-9, atol=1e-9)
    # a CPU handle's call on GPU arrays names the backend it needs; an interpret-mode one says it takes
    # host arrays
    with pytest.raises(Exception, match="backend='cuda'"):
        jax.block_until_ready(jax.jit(h.crba)(gq))
    monkeypatch.setenv("RBDKIT_CUDA_INTERPRET", "1")
    hi = rj.Handle(model, backend="cuda")
    with pytest.raises(Exception, match="interpret mode"):
        jax.block_until_ready(jax.jit(hi.crba)(gq))


def test_frameworks_benchmark_runs(tmp_path):
    # bench/frameworks.py (issue 15's overhead benchmark), a short run: a row per operation, each with
    # the three calls timed (the values are the tests above's)
    out = tmp_path / "frameworks.json"
    r = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "bench",
                                                     "frameworks.py"), "--quick", "--batch", "2", "--robots", "iiwa",
                        "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    import json
    rows = json.loads(out.read_text())["rows"]
    assert [row["op"] for row in rows] == ["inverse_dynamics", "forward_dynamics", "crba", "integrator_rk4",
                                           "forward_dynamics_grad"]
    assert all(row[k] > 0 for row in rows for k in ("numpy_us", "jax_us", "torch_us"))
    # --device cuda without a GPU is a clear refusal, not a crash
    if jax.default_backend() != "gpu":
        r = subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "bench",
                                                         "frameworks.py"), "--quick", "--device", "cuda"],
                           capture_output=True, text=True, timeout=600)
        assert r.returncode != 0 and "--device cuda needs" in r.stderr
