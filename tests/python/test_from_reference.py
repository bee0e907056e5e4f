"""Coming from the reference implementation (docs/conventions.md, "Coming from the reference
implementation"): what rbdkit accepts and offers in its terms.

- GRAVITY= is the spec's keyword for gravity (inverse_dynamics(q, qd, qdd=None, GRAVITY=-9.81)); every
  operation that takes gravity accepts it, on rbdkit.RBD, rbdkit.Handle and the JAX and PyTorch
  handles, and passing both spellings is an error.
- form="reference": the reference's step Hessian (the derivative of plant_step_gradient along
  integrate, checked here against central differences of it, every scheme, both conventions) and its
  end-effector pose Hessian (the symmetric part).
"""
import importlib
import inspect
import os

import numpy as np
import pytest

import rbdkit
from rbdkit._handle import OPERATIONS
from pinref import URDF_DIR
from test_handle import CALLS, assert_same, one_sample, values
from test_step_hessian import SCHEMES, state

G = -3.7  # not the default, so a dropped keyword shows


def _with_gravity(op):
    return "gravity" in inspect.signature(getattr(rbdkit.RBD, op)).parameters


GRAVITY_OPS = [op for op in OPERATIONS if _with_gravity(op)]


def _kw(op, **extra):
    names, kw = CALLS[op]
    return names, {**kw, **extra}


@pytest.fixture(scope="module")
def hyq():
    return rbdkit.robots.load("hyq", floating_base=True)


def test_the_walk_covers_the_dynamics():
    # the operations the spec writes with GRAVITY= are among those walked
    for op in ("inverse_dynamics", "aba", "forward_dynamics", "forward_dynamics_gradient", "integrator",
               "plant_step_gradient", "generalized_gravity", "potential_energy"):
        assert op in GRAVITY_OPS, op


@pytest.mark.parametrize("op", GRAVITY_OPS)
def test_gravity_alias_on_rbd_and_handle(hyq, op):
    v = one_sample(values(hyq))
    names, kw = CALLS[op]
    args = [v[n] for n in names]
    for obj in (rbdkit.RBD(hyq), rbdkit.Handle(hyq)):
        fn = getattr(obj, op)
        ref = fn(*args, **kw, gravity=G)
        assert_same(fn(*args, **kw, GRAVITY=G), ref)
        with pytest.raises(TypeError, match="both gravity and GRAVITY"):
            fn(*args, **kw, gravity=G, GRAVITY=G)
        with pytest.raises(TypeError, match="both gravity and GRAVITY"):
            fn(*args, **kw, GRAVITY=G, gravity=G)
        # gravity by position, GRAVITY by keyword: every argument before gravity by position (defaults
        # where the call leaves them out)
        params = list(inspect.signature(getattr(rbdkit.RBD, op)).parameters.values())[1:]  # (without self)
        named = dict(zip(names, args), **kw)
        before = [named.get(p.name, p.default) for p in params[:[p.name for p in params].index("gravity")]]
        with pytest.raises(TypeError, match="both gravity and GRAVITY"):
            fn(*before, G, GRAVITY=G)
    # gravity matters to these: the alias is not ignored
    if op in ("inverse_dynamics", "aba", "generalized_gravity"):
        r = rbdkit.RBD(hyq)
        a = np.asarray(getattr(r, op)(*args, **kw, GRAVITY=G)[0] if op == "inverse_dynamics"
                       else getattr(r, op)(*args, **kw, GRAVITY=G))
        b = np.asarray(getattr(r, op)(*args, **kw)[0] if op == "inverse_dynamics" else getattr(r, op)(*args, **kw))
        assert np.max(np.abs(a - b)) > 1e-3


def test_gravity_alias_unknown_elsewhere(hyq):
    # an operation without gravity keeps rejecting the keyword
    with pytest.raises(TypeError, match="unexpected keyword argument 'GRAVITY'"):
        rbdkit.RBD(hyq).crba(hyq.neutral(), GRAVITY=G)


@pytest.mark.parametrize("framework", ["jax", "torch"])
def test_gravity_alias_on_framework_handles(hyq, framework):
    # (CI has both frameworks: there a missing one fails instead of skipping)
    name = f"rbdkit.{framework}"
    mod = importlib.import_module(name) if os.environ.get("CI") == "true" else pytest.importorskip(name)
    if framework == "jax":
        import jax
        jax.config.update("jax_enable_x64", True)
    h = mod.Handle(hyq)
    v = one_sample(values(hyq))
    for op in ("inverse_dynamics", "aba", "forward_dynamics_gradient", "plant_step"):
        if not h.has(op):
            continue
        names, kw = CALLS[op]
        args = [v[n] for n in names]
        if framework == "torch":
            import torch
            args = [torch.as_tensor(a) if isinstance(a, np.ndarray) else a for a in args]
        fn = getattr(h, op)
        ref, got = fn(*args, **kw, gravity=G), fn(*args, **kw, GRAVITY=G)
        ref = ref if isinstance(ref, tuple) else (ref,)
        got = got if isinstance(got, tuple) else (got,)
        for a, b in zip(got, ref):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        for both in ({"gravity": G, "GRAVITY": G}, {"GRAVITY": G, "gravity": G}):
            with pytest.raises(TypeError, match="both gravity and GRAVITY"):
                fn(*args, **kw, **both)
    pi = hyq.inertial_parameters()
    q, qd, qdd = (v[n] for n in ("q", "qd", "qdd"))
    if framework == "torch":
        import torch
        q, qd, qdd = (torch.as_tensor(a) for a in (q, qd, qdd))
    a = h.inverse_dynamics_with_parameters(q, qd, qdd, pi, GRAVITY=G)
    b = h.inverse_dynamics_with_parameters(q, qd, qdd, pi, gravity=G)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    with pytest.raises(TypeError, match="both gravity and GRAVITY"):
        h.inverse_dynamics_with_parameters(q, qd, qdd, pi, gravity=G, GRAVITY=G)


# ------------------------------------------------------------ the reference's Hessian forms

def gradient_derivative(rbd, x, u, dt, scheme, convention, h=1e-4):
    """D[i, a, b] = ∂AB[i, b]/∂z_a along z = [δq; δqd; δu] (x ⊕ δq in the convention), by central
    differences of plant_step_gradient at steps h and h/2 with Richardson extrapolation (one batched call)"""
    nq, nv = rbd.nq, rbd.nv
    n = 3 * nv
    plus = rbd.integrate if convention == "pinocchio" else rbd.mujoco_integrate
    E = np.eye(n)
    Z = np.concatenate([h * E, -h * E, 0.5 * h * E, -0.5 * h * E])
    X = np.concatenate([plus(np.tile(x[:nq], (len(Z), 1)), Z[:, :nv]), x[nq:] + Z[:, nv:2 * nv]], axis=1)
    G = rbd.plant_step_gradient(X, u + Z[:, 2 * nv:], dt, scheme, output_convention=convention).reshape(4, n, 2 * nv, n)
    D1, D2 = (G[0] - G[1]) / (2 * h), (G[2] - G[3]) / h
    return np.transpose((4 * D2 - D1) / 3, (1, 0, 2))


def _models():
    return {"hyq_floating": rbdkit.robots.load("hyq", floating_base=True),
            "spherical_floating": rbdkit.Model.from_urdf(os.path.join(URDF_DIR, "spherical.urdf"), floating_base=True)}


MODELS = _models()


@pytest.mark.parametrize("name", sorted(MODELS))
@pytest.mark.parametrize("convention", ["pinocchio", "mujoco"])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_step_hessian_reference_form_is_the_gradients_derivative(name, convention, scheme):
    model = MODELS[name]
    rbd = rbdkit.RBD(model)
    x, u = state(model, seed=3, spin=True)
    if convention == "mujoco":
        x = rbd.state_to_mujoco(x)
    dt = 0.02
    H = rbd.plant_step_hessian(x, u, dt, scheme, output_convention=convention)
    Href = rbd.plant_step_hessian(x, u, dt, scheme, output_convention=convention, form="reference")
    D = gradient_derivative(rbd, x, u, dt, scheme, convention)
    scale = max(1.0, np.max(np.abs(D)))
    err = np.max(np.abs(Href - D)) / scale
    assert err < 1e-6, f"reference form vs d(AB)/dz: relative error {err:.1e}"
    # the two forms share their symmetric part and differ by a visible antisymmetric one
    np.testing.assert_allclose(Href + np.swapaxes(Href, 1, 2), 2 * H, rtol=0, atol=1e-12 * scale)
    assert np.max(np.abs(H - D)) / scale > 1e-4  # rbdkit's form is not the gradient's derivative here
    # the Handle (engine) gives the same
    h = rbdkit.Handle(model)
    np.testing.assert_allclose(h.plant_step_hessian(x, u, dt, scheme, output_convention=convention,
                                                    form="reference"), Href, rtol=0, atol=1e-10 * scale)


def test_step_hessian_forms_agree_without_brackets():
    # a fixed base with 1-DoF joints only: no Lie brackets, the two forms are the same tensor
    model = rbdkit.robots.load("iiwa")
    rbd = rbdkit.RBD(model)
    x, u = state(model)
    for scheme in ("euler", "rk4"):
        np.testing.assert_array_equal(rbd.plant_step_hessian(x, u, 0.01, scheme, form="reference"),
                                      rbd.plant_step_hessian(x, u, 0.01, scheme))


@pytest.mark.parametrize("op", ["end_effector_pose_hessian", "end_effector_pose_hessian_analytic"])
def test_end_effector_hessian_reference_form(op, hyq=MODELS["hyq_floating"]):
    rbd = rbdkit.RBD(hyq)
    q = hyq.random_configuration(np.random.default_rng(5))
    H = getattr(rbd, op)(q)
    Href = getattr(rbd, op)(q, form="reference")
    np.testing.assert_allclose(Href, 0.5 * (H + np.swapaxes(H, -1, -2)), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(Href, np.swapaxes(Href, -1, -2))
    assert np.max(np.abs(H - Href)) > 1e-3  # the free flyer's block is not symmetric in rbdkit's form
    # against central differences of the gradient along integrate, symmetrized
    nv, h = hyq.nv, 1e-6
    E = np.eye(nv)
    G = rbd.end_effector_pose_gradient(rbd.integrate(np.tile(q, (2 * nv, 1)), np.concatenate([h * E, -h * E])))
    D = np.moveaxis((G[:nv] - G[nv:]) / (2 * h), 0, -2)  # [..., j, k] = ∂gradient[..., k]/∂δ_j
    np.testing.assert_allclose(Href, 0.5 * (D + np.swapaxes(D, -1, -2)), rtol=0, atol=1e-6)


def test_form_is_checked():
    model = rbdkit.robots.load("iiwa")
    rbd = rbdkit.RBD(model)
    x, u = state(model)
    with pytest.raises(ValueError, match="form"):
        rbd.plant_step_hessian(x, u, 0.01, "euler", form="symmetric")


# ------------------------------------------------------------ the conversions (docs/conventions.md)

SWAP6 = [3, 4, 5, 0, 1, 2]                 # [linear; angular] <-> [angular; linear]
PI_ORDER = [0, 1, 2, 3, 4, 5, 7, 6, 8, 9]  # rbdkit's π per body <-> the reference's (I_xz and I_yy swap)


@pytest.fixture(scope="module")
def iiwa_ref():
    from pinref import ROBOTS_DIR, Reference
    return Reference(os.path.join(ROBOTS_DIR, "iiwa.urdf"))


def test_six_vector_and_gravity_acceleration_conversions(iiwa_ref):
    import pinocchio as pin
    ref, model = iiwa_ref, iiwa_ref.model
    rbd = rbdkit.RBD(model)
    rng = np.random.default_rng(2)
    q, qd, qdd = model.random_configuration(rng), rng.uniform(-1, 1, model.nv), rng.uniform(-1, 1, model.nv)
    gravity = -9.81
    _, v, a, f = rbd.inverse_dynamics(q, qd, qdd, gravity=gravity)
    R, _ = rbd.forward_kinematics(q)
    # the documented lines
    a_ref = a + np.concatenate([R.swapaxes(-1, -2) @ [0, 0, -gravity], np.zeros((model.nb, 3))], -1)
    v_ref, a_ref, f_ref = v[..., SWAP6], a_ref[..., SWAP6], f[..., SWAP6]
    # Pinocchio's per-joint quantities written out [angular; linear]: a_gf is its acceleration with gravity
    ref.set_gravity(gravity)
    pin.rnea(ref.pin, ref.data, ref.q(q), ref.v(qd), ref.v(qdd))
    for jid, b in ref.body_of_joint.items():
        ang_lin = lambda m: np.concatenate([m.angular, m.linear])
        np.testing.assert_allclose(v_ref[b], ang_lin(ref.data.v[jid]), atol=1e-12)
        np.testing.assert_allclose(a_ref[b], ang_lin(ref.data.a_gf[jid]), atol=1e-10)
        np.testing.assert_allclose(f_ref[b], ang_lin(ref.data.f[jid]), atol=1e-10)
    assert np.max(np.abs(a_ref - a[..., SWAP6])) > 1.0  # gravity's part is there
    # the swap is its own inverse
    np.testing.assert_array_equal(f_ref[..., SWAP6], f)


def test_inertial_parameter_conversion(iiwa_ref):
    ref, model = iiwa_ref, iiwa_ref.model
    rbd = rbdkit.RBD(model)
    pi = model.inertial_parameters()
    pi_ref = pi.reshape(-1, 10)[:, PI_ORDER].reshape(-1)
    # the reference's basis, from Pinocchio's inertias: [m, m·c, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz] about
    # the body origin
    for jid, b in ref.body_of_joint.items():
        Y = ref.pin.inertias[jid]
        m, c = Y.mass, Y.lever
        I_o = Y.inertia + m * (c @ c * np.eye(3) - np.outer(c, c))
        expect = [m, *(m * c), I_o[0, 0], I_o[0, 1], I_o[0, 2], I_o[1, 1], I_o[1, 2], I_o[2, 2]]
        np.testing.assert_allclose(pi_ref[10 * b:10 * b + 10], expect, atol=1e-12)
    # a regressor converts with the same permutation and keeps τ = Y π
    rng = np.random.default_rng(1)
    q, qd, qdd = model.random_configuration(rng), rng.uniform(-1, 1, model.nv), rng.uniform(-1, 1, model.nv)
    Y = rbd.inverse_dynamics_regressor(q, qd, qdd)
    Y_ref = Y.reshape(*Y.shape[:-1], -1, 10)[..., PI_ORDER].reshape(Y.shape)
    np.testing.assert_allclose(Y_ref @ pi_ref, rbd.inverse_dynamics(q, qd, qdd)[0], atol=1e-10)
    np.testing.assert_array_equal(pi_ref.reshape(-1, 10)[:, PI_ORDER].reshape(-1), pi)


def test_frame_jacobian_default_conversion(iiwa_ref):
    import pinocchio as pin
    ref, model = iiwa_ref, iiwa_ref.model
    rbd = rbdkit.RBD(model)
    q = model.random_configuration(np.random.default_rng(4))
    frame = model.frame_names[-1]
    J_lwa = rbd.frame_jacobian(q, frame, reference_frame="LOCAL_WORLD_ALIGNED")
    fid = ref.frame_id(frame)
    J_pin = pin.computeFrameJacobian(ref.pin, ref.data, ref.q(q), fid, pin.LOCAL_WORLD_ALIGNED)
    np.testing.assert_allclose(J_lwa, J_pin, atol=1e-12)
    # and it is not the default
    assert np.max(np.abs(J_lwa - rbd.frame_jacobian(q, frame))) > 1e-3


def test_barrier_clip_conversion():
    model = rbdkit.robots.load("iiwa")
    rbd = rbdkit.RBD(model)
    q = model.neutral()
    lo, hi, mu, eps = q - 0.5, q + 0.5, 0.1, 1e-6
    out = q.copy()
    out[0] = hi[0] + 0.2  # outside: rbdkit says so
    value, grad, hdiag = rbd.joint_position_barrier(out, lo, hi, mu)
    assert value == np.inf and np.isnan(grad[0]) and np.isnan(hdiag[0])
    clipped = np.clip(out, lo + eps, hi - eps)
    value, grad, hdiag = rbd.joint_position_barrier(clipped, lo, hi, mu)
    assert np.isfinite(value) and np.all(np.isfinite(grad)) and np.all(np.isfinite(hdiag))
    # the closed form at the clipped point: -mu Σ (log(x - lo) + log(hi - x))
    np.testing.assert_allclose(value, -mu * np.sum(np.log(clipped - lo) + np.log(hi - clipped)), rtol=1e-12)
    # inside the bounds the clip changes nothing
    inside = q + 0.1
    np.testing.assert_array_equal(rbd.joint_position_barrier(np.clip(inside, lo + eps, hi - eps), lo, hi, mu)[0],
                                  rbd.joint_position_barrier(inside, lo, hi, mu)[0])
