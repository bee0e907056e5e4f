"""rbdkit.torch: the custom operator against the NumPy handle (the same
engine: bit for bit), leading batch shapes, torch.autograd.gradcheck in
float64, the backward formulas against central differences of the NumPy path
on every robot family (in the tangent space for quaternion coordinates),
torch.compile without graph breaks, and the errors."""

import os
import subprocess
import sys

import numpy as np
import pytest

torch = pytest.importorskip("torch") if os.environ.get("CI") != "true" else __import__("torch")

import rbdkit  # noqa: E402
import rbdkit.torch as rt  # noqa: E402

from framework_cases import (CONFIGURATION_CASES, ROOT, SCHEMES, central_difference, configuration_call,  # noqa: E402
                             elementwise_cases, gauss_newton_cases, Handles, import_example,
                             import_without, registry_cases, rel, states, tangent_difference,
                             to_tangent_gradient)

handle = Handles(lambda model, dtype: rt.Handle(model, dtype=dtype, threads=1))


def tensors(*arrays, grad=True):
    return [torch.tensor(a, requires_grad=grad) for a in arrays]


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("hyq", True), ("atlas", True)])
@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_values_equal_the_numpy_handle(name, floating, dtype):
    h = handle(name, floating, dtype)
    q, qd, u = (a.astype(dtype) for a in states(h, 4))
    x = np.concatenate([q, qd], -1)
    frame = h.model.frame_names[len(h.model.frame_names) // 2]
    for op, args, kw in [("inverse_dynamics", (q, qd, u), {}), ("inverse_dynamics", (q, qd), {"gravity": -2.0}),
                         ("forward_dynamics_gradient", (q, qd, u), {}), ("crba", (q,), {}),
                         ("integrator", (q, qd, u, 0.01, "rk4"), {}), ("plant_step", (x, u, 0.01), {}),
                         ("frame_jacobian", (q, frame), {}), ("idsva_so", (q, qd, u), {}),
                         ("end_effector_pose", (q,), {})]:
        want = getattr(h.numpy, op)(*args, **kw)
        targs = [torch.from_numpy(a) if isinstance(a, np.ndarray) else a for a in args]
        got = getattr(h, op)(*targs, **kw)
        want, got = (list(r) if isinstance(r, tuple) else [r] for r in (want, got))
        assert len(want) == len(got), op
        for w, g in zip(want, got):
            assert g.dtype == getattr(torch, dtype), op
            np.testing.assert_array_equal(g.numpy(), w, err_msg=op)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_every_registered_operation_equals_the_numpy_handle(dtype):
    # the whole registry on a floating base, batched and one sample (test_handle's arguments for each
    # operation): the same outputs bit for bit, shapes and dtypes included
    ht = rt.Handle(rbdkit.robots.load("hyq", floating_base=True), threads=1, dtype=dtype)
    for op, call, v, want in registry_cases(dtype):
        got = call(ht, {k: torch.from_numpy(x) if isinstance(x, np.ndarray) else x for k, x in v.items()})
        assert len(got) == len(want), op
        for g, w in zip(got, want):
            assert g.dtype == getattr(torch, dtype) and g.shape == w.shape, op
            np.testing.assert_array_equal(g.numpy(), w, err_msg=op)


def test_leading_batch_shapes_and_broadcasting():
    h = handle("hyq", True)
    q, qd, u = states(h, 6)
    out = h.aba(torch.tensor(q).reshape(2, 3, -1), torch.tensor(qd).reshape(2, 3, -1), torch.tensor(u).reshape(2, 3, -1))
    assert out.shape == (2, 3, h.nv)
    np.testing.assert_array_equal(out.reshape(6, -1).numpy(), h.numpy.aba(q, qd, u))
    out = h.aba(torch.tensor(q[0]), torch.tensor(qd), torch.tensor(u))
    np.testing.assert_array_equal(out.numpy(), h.numpy.aba(np.tile(q[0], (6, 1)), qd, u))
    # a broadcast input's gradient is summed over the batch, as for any expanded tensor
    q0 = torch.tensor(q[0], requires_grad=True)
    h.aba(q0, torch.tensor(qd), torch.tensor(u)).sum().backward()
    assert q0.grad.shape == (h.nq,)


def test_eager_fast_path_and_its_fallbacks_agree():
    # a call with no autograd runs the kernel on the tensors' memory (Handle._eager, its layout cached
    # per parameters); a non-contiguous tensor, another dtype, a NumPy array, leading axes that
    # broadcast and a changed parameter take the general path or a new layout, with the same values
    h = handle("hyq", True)
    q, qd, u = states(h, 6)
    want = h.numpy.inverse_dynamics(q, qd, u)
    tq, tqd, tu = (torch.tensor(a) for a in (q, qd, u))
    np.testing.assert_array_equal(h.inverse_dynamics(tq, tqd, tu).numpy(), want)
    strided = torch.tensor(np.concatenate([qd, qd], -1))[:, ::2]
    assert not strided.is_contiguous()
    np.testing.assert_array_equal(h.inverse_dynamics(tq, torch.tensor(qd[:, ::1]), tu).numpy(), want)
    np.testing.assert_array_equal(h.inverse_dynamics(tq, strided, tu).numpy(),
                                  h.numpy.inverse_dynamics(q, np.ascontiguousarray(strided.numpy()), u))
    np.testing.assert_allclose(h.inverse_dynamics(tq.float(), tqd, tu).numpy(),
                               h.numpy.inverse_dynamics(q.astype(np.float32).astype(np.float64), qd, u), rtol=0,
                               atol=0)
    np.testing.assert_array_equal(h.inverse_dynamics(q, tqd, tu).numpy(), want)
    np.testing.assert_array_equal(h.inverse_dynamics(tq.reshape(2, 3, -1), tqd.reshape(2, 3, -1),
                                                     tu.reshape(2, 3, -1)).reshape(6, -1).numpy(), want)
    np.testing.assert_array_equal(h.inverse_dynamics(tq, tqd, tu, gravity=-2.0).numpy(),
                                  h.numpy.inverse_dynamics(q, qd, u, gravity=-2.0))
    np.testing.assert_array_equal(h.inverse_dynamics(tq[0], tqd[0], tu[0]).numpy(),
                                  h.numpy.inverse_dynamics(q[0], qd[0], u[0]))  # (one sample: not the batch path)
    # a scalar result of one sample (shape ()): the kinetic energy ½ qdᵀ M qd, and a cost
    M = h.numpy.crba(q[0])
    e = h.kinetic_energy(tq[0], tqd[0])
    assert e.shape == () and np.isclose(e.item(), 0.5 * qd[0] @ M @ qd[0], rtol=1e-12)
    rng = np.random.default_rng(4)
    x, x_des, w = rng.standard_normal(h.nq + h.nv), rng.standard_normal(h.nq + h.nv), rng.uniform(0.5, 2, h.nq + h.nv)
    c = h.quadratic_state_cost(*(torch.tensor(a) for a in (x, x_des, w)))[0]  # (value, gradient, Hessian)
    assert c.shape == () and c.item() == h.numpy.quadratic_state_cost(x, x_des, w)[0]
    # CPU tensors' outputs are made on the CPU whatever torch's default device (the engine writes them)
    with torch.device("meta"):
        out = h.inverse_dynamics(tq, tqd, tu)
        tg = tu.clone().requires_grad_()
        h.forward_dynamics(tq, tqd, tg).sum().backward()
    assert out.device.type == "cpu" and tg.grad.device.type == "cpu"
    np.testing.assert_array_equal(out.numpy(), want)
    # under torch.no_grad a tensor that requires grad takes the fast path, and its result has no graph
    with torch.no_grad():
        out = h.inverse_dynamics(tq.clone().requires_grad_(), tqd, tu)
    assert not out.requires_grad
    np.testing.assert_array_equal(out.numpy(), want)


@pytest.mark.parametrize("name,floating", [("iiwa", False), ("planar", False), ("helical", False), ("mimic", False)])
def test_gradcheck(name, floating):
    h = handle(name, floating)
    q, qd, u = tensors(*states(h, 2, seed=1))
    f = torch.tensor(np.random.default_rng(2).standard_normal((h.nb, 6)), requires_grad=True)
    # eps 1e-5, not gradcheck's 1e-6: forward_dynamics (M⁻¹ in world coordinates) rounds its outputs
    # of up to ~750 to about 1e-11, which over 1e-6 is a numerical Jacobian noisy at atol's 1e-5
    for op in ("inverse_dynamics", "forward_dynamics", "aba"):
        assert torch.autograd.gradcheck(lambda q, qd, u: getattr(h, op)(q, qd, u), (q, qd, u), eps=1e-5), op
        assert torch.autograd.gradcheck(lambda q, f: getattr(h, op)(q, qd, u, f_ext=f), (q, f), eps=1e-5), op
    pi = torch.tensor(h.model.inertial_parameters() * np.random.default_rng(3).uniform(0.8, 1.2, 10 * h.nb),
                      requires_grad=True)
    assert torch.autograd.gradcheck(lambda q, qd, qdd: h.inverse_dynamics_regressor(q, qd, qdd), (q, qd, u))
    assert torch.autograd.gradcheck(lambda q, qd, qdd, pi: h.inverse_dynamics_with_parameters(q, qd, qdd, pi),
                                    (q, qd, u, pi))
    for scheme in SCHEMES:
        assert torch.autograd.gradcheck(lambda q, qd, u: h.integrator(q, qd, u, 0.01, scheme), (q, qd, u)), scheme
    x = torch.cat([q, qd], -1).detach().requires_grad_()
    assert torch.autograd.gradcheck(lambda x, u: h.plant_step(x, u, 0.01, "rk4"), (x, u))
    for scheme in SCHEMES:  # with external forces
        assert torch.autograd.gradcheck(lambda q, u, f: h.integrator(q, qd, u, 0.01, scheme, f_ext=f), (q, u, f))
    assert torch.autograd.gradcheck(lambda x, f: h.plant_step(x, u, 0.01, "rk4", f_ext=f), (x, f))
    for op, kw in CONFIGURATION_CASES:
        f = configuration_call(h, op, kw)
        assert torch.autograd.gradcheck(lambda q: tuple(f(h, q)), (q,)), (op, kw)
    for op, arrays, mu in elementwise_cases(h.numpy):
        kw = {} if mu is None else {"mu": mu}
        assert torch.autograd.gradcheck(lambda *a: getattr(h, op)(*a, **kw), tuple(tensors(*arrays))), op
    for op, arrays in gauss_newton_cases(h):
        names = list(arrays)
        assert torch.autograd.gradcheck(lambda *a: getattr(h, op)(**dict(zip(names, a)))[0],
                                        tuple(tensors(*arrays.values()))), op


@pytest.mark.parametrize("name,floating,convention", [("iiwa", False, "pinocchio"), ("hyq", True, "pinocchio"),
                                                      ("hyq", True, "mujoco"), ("mimic", False, "pinocchio")])
def test_gradients_of_some_inputs_only(name, floating, convention):
    # the backward formulas compute what the inputs that require grad need (M or M⁻¹ alone for the
    # third input of the dynamics, no tangent map for a q that needs none): each subset's gradients
    # equal those of the call where every input requires grad (checked against gradcheck and central
    # differences above and below)
    h = handle(name, floating)
    if convention == "mujoco":
        h = rt.Handle(h.model, threads=1, output_convention="mujoco")
    q, qd, u = states(h, 3, seed=5)
    if convention == "mujoco":  # MuJoCo's coordinates: quaternions w first, the free joints' velocity in the world
        x = np.stack([h.numpy.state_to_mujoco(np.concatenate([a, b])) for a, b in zip(q, qd)])
        q, qd = x[:, :h.nq], x[:, h.nq:]
    f_ext = 0.3 * np.random.default_rng(6).standard_normal((3, h.nb, 6))
    ct = torch.tensor(np.random.default_rng(7).standard_normal((3, h.nv)))
    ct_x = torch.tensor(np.random.default_rng(8).standard_normal((3, h.nq + h.nv)))
    calls = {"inverse_dynamics": (lambda a, b, c, f: h.inverse_dynamics(a, b, c, f_ext=f), ct),
             "forward_dynamics": (lambda a, b, c, f: h.forward_dynamics(a, b, c, f_ext=f), ct),
             "aba": (lambda a, b, c, f: h.aba(a, b, c, f_ext=f), ct),
             "integrator": (lambda a, b, c, f: h.integrator(a, b, c, 0.01, "rk4", f_ext=f), ct_x),
             "plant_step": (lambda a, b, c, f: h.plant_step(torch.cat([a, b], -1), c, 0.01, "euler", f_ext=f), ct_x)}
    for op, (f, w) in calls.items():
        if convention == "mujoco" and op not in ("integrator", "plant_step"):  # (the dynamics refuse it there)
            continue
        full = tensors(q, qd, u, f_ext)
        (f(*full) * w).sum().backward()
        for need in ({2}, {0}, {1}, {0, 2}, {1, 2}, {3}, {2, 3}):
            xs = [torch.tensor(a, requires_grad=k in need) for k, a in enumerate((q, qd, u, f_ext))]
            (f(*xs) * w).sum().backward()
            for k in range(4):
                if k in need:
                    np.testing.assert_allclose(xs[k].grad.numpy(), full[k].grad.numpy(), rtol=1e-9, atol=1e-9,
                                               err_msg=f"{op} {need} {k}")
                else:
                    assert xs[k].grad is None


@pytest.mark.parametrize("name,floating", [("hyq", True), ("spherical", False), ("spherical", True)])
@pytest.mark.parametrize("mujoco", [False, True])
def test_tangent_maps_against_central_differences(name, floating, mujoco):
    # the rules' maps between tangents and coordinates (rt._tangent_map), in both conventions, against E,
    # the derivative of ⊕ at zero by central differences: E x, Eᵀ y, and E⁺ᵀ x, which has no component
    # along a quaternion (E⁺ E = I); on batches of unequal rank (q batched, x one sample, and the reverse)
    h = handle(name, floating)
    rbd = h.numpy.rbd
    q = states(h, 3, seed=9)[0]
    if mujoco:
        q = np.stack([h.numpy.state_to_mujoco(np.concatenate([a, np.zeros(h.nv)]))[:h.nq] for a in q])
    plus = (lambda q, d: h.numpy.mujoco_integrate(q, d)) if mujoco else rbd.integrate  # noqa: E731
    E = np.stack([central_difference(lambda d: plus(a, d), np.zeros(h.nv)) for a in q])  # (3, nq, nv)
    rng = np.random.default_rng(10)
    x, y = rng.standard_normal((3, h.nv)), rng.standard_normal((3, h.nq))
    tq = torch.tensor(q)
    for xs, qs, Es in ((x, tq, E), (x[0], tq, E), (x, tq[0], E[:1])):
        ex = rt._tangent_map(h, qs, torch.tensor(xs), "from_tangent", mujoco).numpy()
        assert rel(ex, np.einsum("bij,...j->bi", Es, xs) if xs.ndim == 1 else np.einsum("bij,bj->bi", Es, xs)) < 1e-8
        pt = rt._tangent_map(h, qs, torch.tensor(xs), "pinv_T", mujoco).numpy()
        Ep = np.linalg.pinv(Es)  # (b, nv, nq)
        want = np.einsum("bji,...j->bi", Ep, xs) if xs.ndim == 1 else np.einsum("bji,bj->bi", Ep, xs)
        assert rel(pt, want) < 1e-7
    et = rt._tangent_map(h, tq, torch.tensor(y), "transpose", mujoco).numpy()
    assert rel(et, np.einsum("bji,bj->bi", E, y)) < 1e-8
    with pytest.raises(ValueError, match="kind"):
        rt._tangent_map(h, tq, torch.tensor(x), "pinv_t")


@pytest.mark.parametrize("name,floating", [("hyq", True), ("atlas", True), ("spherical", False)])
def test_quaternion_models_against_central_differences(name, floating):
    h = handle(name, floating)
    q, qd, u = (a[0] for a in states(h, 1, seed=2))
    w = np.random.default_rng(3).standard_normal(h.nv)
    manifold = {"step": h.numpy.rbd.integrate, "n": h.nv}
    for op in ("inverse_dynamics", "forward_dynamics", "aba"):
        tq, tqd, tu = tensors(q, qd, u)
        (getattr(h, op)(tq, tqd, tu) @ torch.tensor(w)).backward()
        f = getattr(h.numpy, op)
        assert rel(h.tangent_gradient(tq.detach(), tq.grad), w @ central_difference(lambda z: f(z, qd, u), q,
                                                                                   **manifold)) < 1e-6, op
        assert rel(tqd.grad, w @ central_difference(lambda z: f(q, z, u), qd)) < 1e-6, op
        assert rel(tu.grad, w @ central_difference(lambda z: f(q, qd, z), u)) < 1e-6, op
        if op == "inverse_dynamics":  # with the inertial parameters as an input (the regressor's rule)
            tq, tpi = tensors(q, h.model.inertial_parameters())
            (h.inverse_dynamics_with_parameters(tq, torch.tensor(qd), torch.tensor(u), tpi) @ torch.tensor(w)).backward()
            assert rel(h.tangent_gradient(tq.detach(), tq.grad), w @ central_difference(lambda z: f(z, qd, u), q,
                                                                                       **manifold)) < 1e-6
            np.testing.assert_allclose(tpi.grad.numpy(), w @ h.numpy.inverse_dynamics_regressor(q, qd, u), rtol=1e-12,
                                       atol=1e-12)
        # with external forces (body frames): ∂/∂f_ext, and ∂/∂q with the forces on
        fx = np.random.default_rng(4).standard_normal((h.nb, 6))
        tq, tf = tensors(q, fx)
        (getattr(h, op)(tq, torch.tensor(qd), torch.tensor(u), f_ext=tf) @ torch.tensor(w)).backward()
        assert rel(h.tangent_gradient(tq.detach(), tq.grad),
                   w @ central_difference(lambda z: f(z, qd, u, f_ext=fx), q, **manifold)) < 1e-6, op
        assert rel(tf.grad.reshape(-1), w @ central_difference(lambda z: f(q, qd, u, f_ext=z.reshape(h.nb, 6)),
                                                               fx.ravel())) < 1e-6, op
    # plant_step in MuJoCo's coordinates ([A | B] along mj_integratePos)
    x = h.numpy.state_to_mujoco(np.concatenate([q, qd]))
    nq, nv = h.nq, h.nv
    step = lambda x, d: np.concatenate([h.numpy.mujoco_integrate(x[:nq], d[:nv]), x[nq:] + d[nv:]])  # noqa: E731
    wx = np.random.default_rng(5).standard_normal(nq + nv)
    tx, tu = tensors(x, u)
    (h.plant_step(tx, tu, 0.01, "rk4", output_convention="mujoco") @ torch.tensor(wx)).backward()
    f = lambda x, u: h.numpy.plant_step(x, u, 0.01, "rk4", output_convention="mujoco")  # noqa: E731
    gx = torch.cat([h.tangent_gradient(tx.detach()[:nq], tx.grad[:nq], output_convention="mujoco"), tx.grad[nq:]])
    assert rel(gx, wx @ central_difference(lambda z: f(z, u), x, step=step, n=2 * nv)) < 1e-6
    assert rel(tu.grad, wx @ central_difference(lambda z: f(x, z), u)) < 1e-6
    for scheme in ("euler", "rk4"):
        tq, tqd, tu = tensors(q, qd, u)
        wx = np.random.default_rng(4).standard_normal(h.nq + h.nv)
        (h.integrator(tq, tqd, tu, 0.01, scheme) @ torch.tensor(wx)).backward()
        f = lambda q, qd, u: wx @ h.numpy.integrator(q, qd, u, 0.01, scheme)  # noqa: E731
        assert rel(h.tangent_gradient(tq.detach(), tq.grad), central_difference(lambda z: f(z, qd, u), q,
                                                                               **manifold)) < 1e-6, scheme
        assert rel(tu.grad, central_difference(lambda z: f(q, qd, z), u)) < 1e-6, scheme
    # a step's external forces (integrator_f_ext_gradient), with q's gradient alongside; and in MuJoCo's
    # coordinates
    fx = np.random.default_rng(6).standard_normal((h.nb, 6))
    for scheme in ("semi_implicit_euler", "rk4"):
        tq, tf = tensors(q, fx)
        (h.integrator(tq, torch.tensor(qd), torch.tensor(u), 0.01, scheme, f_ext=tf) @ torch.tensor(wx)).backward()
        f = lambda q, fx: wx @ h.numpy.integrator(q, qd, u, 0.01, scheme, f_ext=fx.reshape(h.nb, 6))  # noqa: E731
        assert rel(tf.grad.reshape(-1), central_difference(lambda z: f(q, z), fx.ravel())) < 1e-6, scheme
        assert rel(h.tangent_gradient(tq.detach(), tq.grad), central_difference(lambda z: f(z, fx), q, **manifold)) \
            < 1e-6, scheme
    xm = h.numpy.state_to_mujoco(np.concatenate([q, qd]))
    tf = tensors(fx)[0]
    (h.plant_step(torch.tensor(xm), torch.tensor(u), 0.01, "rk4", f_ext=tf, output_convention="mujoco")
     @ torch.tensor(wx)).backward()
    f = lambda fx: wx @ h.numpy.plant_step(xm, u, 0.01, "rk4", f_ext=fx.reshape(h.nb, 6),  # noqa: E731
                                           output_convention="mujoco")
    assert rel(tf.grad.reshape(-1), central_difference(f, fx.ravel())) < 1e-6
    rng = np.random.default_rng(5)
    for op, kw in CONFIGURATION_CASES:
        f = configuration_call(h, op, kw)
        ws = [rng.standard_normal(np.shape(o)) for o in f(h.numpy, q)]
        tq = torch.tensor(q, requires_grad=True)
        sum((o * torch.tensor(w)).sum() for w, o in zip(ws, f(h, tq))).backward()
        g = central_difference(lambda z: sum(np.sum(w * o) for w, o in zip(ws, f(h.numpy, z))), q, **manifold)
        assert rel(h.tangent_gradient(tq.detach(), tq.grad), g) < 1e-6, (op, kw)


@pytest.mark.parametrize("name,floating", [("hyq", True)])
def test_gauss_newton_cost_values_on_a_floating_base(name, floating):
    h = handle(name, floating)
    for op, arrays in gauss_newton_cases(h, seed=13):
        t = dict(zip(arrays, tensors(*arrays.values())))
        getattr(h, op)(**t)[0].backward()
        for n, x in arrays.items():
            def value(z, n=n):
                return getattr(h.numpy, op)(**dict(arrays, **{n: z}))[0]
            assert rel(to_tangent_gradient(h, n, x, t[n].grad), tangent_difference(h, value, n, x)) < 1e-6, (op, n)
    with pytest.raises(RuntimeError, match="com_cost's grad and H outputs are values"):
        q = torch.tensor(arrays["q"], requires_grad=True)
        h.com_cost(q, torch.zeros(3, dtype=torch.float64), torch.ones(3, dtype=torch.float64))[1].sum().backward()


def test_torch_compile_traces_without_graph_breaks():
    h = handle("iiwa", False)
    q, qd, u = tensors(*states(h, 3))
    fx = np.random.default_rng(3).standard_normal((h.nb, 6))
    f_ext, f_ext2 = tensors(fx, fx)

    def loss(q, qd, u, f_ext):  # the step's f_ext rule (integrator_f_ext_gradient) traced too
        return (h.aba(q, qd, u) ** 2).sum() + h.integrator(q, qd, u, 0.01, "rk4").sum() + \
            (h.integrator(q, qd, u, 0.01, "midpoint", f_ext=f_ext) ** 2).sum()

    y = torch.compile(loss, fullgraph=True, backend="aot_eager")(q, qd, u, f_ext)
    y.backward()
    q2, qd2, u2 = tensors(*states(h, 3))
    y2 = loss(q2, qd2, u2, f_ext2)
    y2.backward()
    assert torch.allclose(y, y2, rtol=1e-14, atol=0)
    for a, b in ((q, q2), (qd, qd2), (u, u2), (f_ext, f_ext2)):
        assert torch.allclose(a.grad, b.grad, rtol=1e-12, atol=1e-12)
    # traced with only u requiring grad (the rule then computes M⁻¹ alone): the eager gradient
    qc, qdc = q.detach(), qd.detach()
    uc, ue = u.detach().clone().requires_grad_(), u.detach().clone().requires_grad_()
    torch.compile(lambda u: (h.aba(qc, qdc, u) ** 2).sum(), fullgraph=True, backend="aot_eager")(uc).backward()
    (h.aba(qc, qdc, ue) ** 2).sum().backward()
    assert torch.allclose(uc.grad, ue.grad, rtol=1e-12, atol=1e-12)


def test_errors_are_clear():
    h = handle("iiwa", False)
    q, qd, u = tensors(*states(h, 1))
    with pytest.raises(RuntimeError, match="coriolis_matrix computes values only"):
        h.coriolis_matrix(q, qd).sum().backward()
    with pytest.raises(RuntimeError, match="first order; second derivatives"):
        torch.autograd.functional.hessian(lambda q: h.com(q)[2], q.detach()[0])
    with pytest.raises(NotImplementedError, match="differentiable with respect to q only, not ee_offsets"):
        h.end_effector_pose(q, ee_offsets=torch.zeros(1, 3, dtype=torch.float64, requires_grad=True))
    with pytest.raises(ValueError, match=r"qd: expected shape \(\.\.\., 7\)"):
        h.aba(q, qd[..., :3], u)
    with pytest.raises(ValueError, match="integrator_type"):
        h.integrator(q, qd, u, 0.01, "rk5")
    bad = q.detach().clone()
    bad[0, 1] = float("nan")
    with pytest.raises(ValueError, match="q"):
        h.crba(bad)
    with pytest.raises(ValueError, match="not built with it"):
        rt.Handle(h.model, algorithms=["inverse_dynamics"]).centroidal_momentum(q, qd)


def test_refusals_under_torch_compile_and_parameters_that_are_tensors():
    # torch.compile traces the same refusals as eager calls (a derivative no rule gives is never
    # silently wrong); a tensor or an equal value of another type as a parameter never reuses a cached
    # layout (gravity=tensor was read as 0, output_dense=1 passed after a True)
    h = handle("hyq", True)
    qm = h.numpy.state_to_mujoco(np.concatenate(states(h, 1)[:2], -1)[0])[:h.nq]
    p_des, W = torch.zeros(3, dtype=torch.float64), torch.ones(3, dtype=torch.float64)
    f = torch.compile(lambda q: h.com_cost(q, p_des, W, output_convention="mujoco")[0], fullgraph=True,
                      backend="aot_eager")
    with pytest.raises(Exception, match="MuJoCo's output convention|Observed exception"):
        f(torch.tensor(qm, requires_grad=True))
    g = torch.compile(lambda q, fx: h.aba(q, q.new_zeros(h.nv), q.new_zeros(h.nv), f_ext=fx).sum(), fullgraph=True,
                      backend="aot_eager")
    q = torch.tensor(states(h, 1)[0][0])
    g(q, torch.zeros(h.nb, 6, dtype=torch.float64, requires_grad=True)).backward()  # aba has f_ext's rule
    hi = handle("iiwa", False)
    q, qd, u = (torch.tensor(a) for a in states(hi, 2))
    hi.inverse_dynamics(q, qd, u)  # a cached layout for gravity's default
    with pytest.raises(TypeError, match="gravity"):
        hi.inverse_dynamics(q, qd, u, gravity=torch.tensor(-9.81))
    hi.minv(q, output_dense=True)
    with pytest.raises(TypeError, match="output_dense"):
        hi.minv(q, output_dense=1)


def test_rbdkit_imports_without_torch():
    assert 'ImportError: rbdkit.torch needs PyTorch: pip install torch' in import_without('torch', 'torch')


def test_torch_distributed_shards_equal_the_unsharded_call():
    script = os.path.join(ROOT, "examples", "torch_distributed.py")
    r = subprocess.run([sys.executable, script, "--world", "2", "--batch", "16"], capture_output=True, text=True,
                       cwd="/", timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "all-gathered shards equal the unsharded call" in r.stdout


def test_torch_distributed_under_torchrun():
    """the same example as ranks of torchrun's group (docs/scaling.md), 2 processes on this machine"""
    script = os.path.join(ROOT, "examples", "torch_distributed.py")
    r = subprocess.run([sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", "2",
                        script, "--batch", "16"], capture_output=True, text=True, cwd="/", timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "2 processes (gloo), 16 knot points" in r.stdout and "equal the unsharded call" in r.stdout


def test_rollout_example_gradient_is_the_analytical_chain(tmp_path):
    # examples/torch_rollout.py as it runs: autograd through 50 rk4 plant steps equals the [A | B]
    # chain, and L-BFGS brings every joint to the target (0.3 rad away) within 1e-3 rad, at rest
    torch_rollout = import_example("torch_rollout")
    plot = tmp_path / "rollout.png"
    err, first, final, joint_error = torch_rollout.main(["--plot", str(plot)])
    assert err < 1e-12
    assert final < first * 1e-6 and joint_error < 1e-3
    assert plot.stat().st_size > 0


def test_cuda_backend_in_interpret_mode(monkeypatch):
    # backend="cuda": CPU tensors are host arrays the CUDA backend copies to its device; in interpret
    # mode (RBDKIT_CUDA_INTERPRET=1, the kernels' source on the CPU) values and the autograd formulas
    # through it equal the CPU handle's. CUDA tensors (device arrays on PyTorch's current stream) need
    # a GPU: scripts/gpu-check.sh runs test_cuda_tensors_on_the_device there
    monkeypatch.setenv("RBDKIT_CUDA_INTERPRET", "1")
    model = rbdkit.robots.load("hyq", floating_base=True)
    hc, h = rt.Handle(model, backend="cuda", threads=1), rt.Handle(model, threads=1)
    assert hc.backend == "cuda"
    q, qd, u = states(h, 4, seed=3)
    for op, args in (("inverse_dynamics", (q, qd, u)), ("forward_dynamics", (q, qd, u)), ("crba", (q,)),
                     ("integrator", (q, qd, u, 0.01, "rk4"))):
        targs = [torch.tensor(a) if isinstance(a, np.ndarray) else a for a in args]
        np.testing.assert_allclose(getattr(hc, op)(*targs).numpy(), getattr(h, op)(*targs).numpy(), rtol=1e-10,
                                   atol=1e-10, err_msg=op)
    grads = []
    for hh in (hc, h):
        tq, tqd, tu = tensors(q, qd, u)
        (hh.forward_dynamics(tq, tqd, tu) ** 2).sum().backward()
        grads.append([t.grad.numpy() for t in (tq, tqd, tu)])
    for a, b in zip(*grads):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
    # tensors on another device: a CPU handle says which backend they need
    with pytest.raises(ValueError, match="need a handle with backend='cuda'"):
        h.crba(torch.empty(2, h.nq, dtype=torch.float64, device="meta"))


def test_cuda_tensors_on_the_device(monkeypatch):
    # on a GPU (scripts/gpu-check.sh): CUDA tensors in, CUDA tensors out, on PyTorch's current stream;
    # values and gradients equal the CPU handle's. Without one (CI), a cuda handle outside interpret
    # mode is a clear error, as rbdkit.Handle's
    monkeypatch.delenv("RBDKIT_CUDA_INTERPRET", raising=False)
    model = rbdkit.robots.load("hyq", floating_base=True)
    compiled, devices = rbdkit.cuda_available()
    if os.environ.get("RBDKIT_TEST_CUDA_DEVICE") != "1" or not (compiled and devices > 0 and torch.cuda.is_available()):
        assert os.environ.get("RBDKIT_TEST_CUDA_DEVICE") != "1", "RBDKIT_TEST_CUDA_DEVICE=1 needs a CUDA device"
        if compiled and devices > 0:  # a GPU without PyTorch's CUDA: the handle itself works
            assert rt.Handle(model, backend="cuda").backend == "cuda"
            return
        with pytest.raises(RuntimeError, match="RBDKIT_CUDA_INTERPRET=1"):
            rt.Handle(model, backend="cuda")
        return
    hc, h = rt.Handle(model, backend="cuda"), rt.Handle(model, threads=1)
    q, qd, u = states(h, 64, seed=4)
    out = hc.forward_dynamics(*(torch.tensor(a).cuda() for a in (q, qd, u)))
    assert out.is_cuda
    np.testing.assert_allclose(out.cpu().numpy(), h.numpy.forward_dynamics(q, qd, u), rtol=1e-9, atol=1e-9)
    grads = []
    for hh, dev in ((hc, "cuda"), (h, "cpu")):
        tq, tqd, tu = (torch.tensor(a, device=dev, requires_grad=True) for a in (q, qd, u))
        (hh.forward_dynamics(tq, tqd, tu) ** 2).sum().backward()
        grads.append([t.grad.cpu().numpy() for t in (tq, tqd, tu)])
    for a, b in zip(*grads):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-8)
