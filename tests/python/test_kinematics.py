"""rbdkit's kinematics against Pinocchio and central finite differences in the
tangent space, on the bundled robots and the joint-type test models, fixed
and floating base: body and frame placements, frame Jacobians and their time
variation in the three reference frames, end-effector poses with their
gradients and Hessians (multiple end effectors, tool offsets), and the
operational-space inertia.

Pinocchio agreement: max|err| <= 1e-9 · max(1, max|reference|); Jacobian
columns are mapped with G (J_ours = J_pin G). Finite differences: central,
q moved through rbd.integrate, 1e-6 relative."""

import numpy as np
import pinocchio as pin
import pytest

import rbdkit
from pinref import Reference, all_models, assert_close

CASES = all_models()
RFS = {"LOCAL": pin.LOCAL, "WORLD": pin.WORLD, "LOCAL_WORLD_ALIGNED": pin.LOCAL_WORLD_ALIGNED}
H_FD = 1e-6


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def ref(request):
    _, path, fb = request.param
    return Reference(path, fb)


def configs(model, n=3, seed=0):
    rng = np.random.default_rng(seed)
    return [model.random_configuration(rng, scale=np.pi) for _ in range(n)]


def some_frames(model, k=5):
    """a few frames spread over the model: the first, the last, and between"""
    names = model.frame_names
    idx = sorted(set(np.linspace(0, len(names) - 1, k).round().astype(int)))
    return [names[i] for i in idx]


def moving_joints(model):
    return [j["name"] for j in model.joints]


def fd(f, rbd, q, h=H_FD):
    """central differences of f(q) (any shape) along each tangent direction:
    result[..., j] = (f(q ⊕ h e_j) - f(q ⊕ -h e_j)) / 2h"""
    cols = []
    for j in range(rbd.nv):
        e = np.zeros(rbd.nv)
        e[j] = h
        cols.append((f(rbd.integrate(q, e)) - f(rbd.integrate(q, -e))) / (2 * h))
    return np.stack(cols, axis=-1)


def assert_fd(actual, reference, what, rtol=1e-6):
    assert_close(actual, reference, what + " (finite differences)", rtol)


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def rpy_rate_inverse(rpy):
    """E⁻¹ with ω = E d(rpy)/dt for R = Rz(y) Ry(p) Rx(r), built independently"""
    _, p, y = rpy
    E = np.array([[np.cos(y) * np.cos(p), -np.sin(y), 0.0],
                  [np.sin(y) * np.cos(p), np.cos(y), 0.0],
                  [-np.sin(p), 0.0, 1.0]])
    return np.linalg.inv(E)


def pin_point_jacobian(ref, q, body, offset):
    """Pinocchio's LOCAL_WORLD_ALIGNED Jacobian (6, nv, rbdkit columns) of the
    point `offset` of a body, shifted from the joint origin in NumPy"""
    d = ref.pin.createData()
    pin.computeJointJacobians(ref.pin, d, ref.q(q))
    jid = ref.joint_id(body)
    J = pin.getJointJacobian(ref.pin, d, jid, pin.LOCAL_WORLD_ALIGNED) @ ref.G
    r = d.oMi[jid].rotation @ offset
    J[:3] -= np.cross(r, J[3:].T).T  # v_point = v_origin + ω × r
    return J, d.oMi[jid]


# ------------------------------------------------------------ placements

def test_forward_kinematics(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model):
        R, p = rbd.forward_kinematics(q)
        pin.forwardKinematics(ref.pin, ref.data, ref.q(q))
        for jid, b in ref.body_of_joint.items():
            assert_close(R[b], ref.data.oMi[jid].rotation, f"R of body {b}")
            assert_close(p[b], ref.data.oMi[jid].translation, f"p of body {b}")


def test_frame_placement(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model):
        pin.framesForwardKinematics(ref.pin, ref.data, ref.q(q))
        for name in ref.model.frame_names:
            R, p = rbd.frame_placement(q, name)
            X = ref.data.oMf[ref.frame_id(name)]
            assert_close(R, X.rotation, f"R of frame {name}")
            assert_close(p, X.translation, f"p of frame {name}")


def test_merged_fixed_link_frames():
    # frames of links merged through fixed joints resolve and move with their body
    for path, names in ((CASES[0][1], ["iiwa_link_7", "iiwa_link_0", "base", "iiwa_base_joint"]),
                        (dict((c[0], c[1]) for c in CASES)["mixed-fixed"], ["tool", "sensor", "flange", "mount"])):
        ref = Reference(path)
        rbd = rbdkit.RBD(ref.model)
        q = configs(ref.model, 1, seed=3)[0]
        pin.computeJointJacobians(ref.pin, ref.data, ref.q(q))
        pin.updateFramePlacements(ref.pin, ref.data)
        for name in names:
            fid = ref.frame_id(name)
            assert_close(rbd.frame_placement(q, name)[1], ref.data.oMf[fid].translation, f"p of {name}")
            for rf, prf in RFS.items():
                assert_close(rbd.frame_jacobian(q, name, rf), pin.getFrameJacobian(ref.pin, ref.data, fid, prf) @ ref.G,
                             f"J of {name} ({rf})")


# ------------------------------------------------------------ frame Jacobians

def test_frame_jacobian(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model):
        pin.computeJointJacobians(ref.pin, ref.data, ref.q(q))
        pin.updateFramePlacements(ref.pin, ref.data)
        for name in ref.model.frame_names:
            fid = ref.frame_id(name)
            for rf, prf in RFS.items():
                J = rbd.frame_jacobian(q, name, rf)
                assert_close(J, pin.getFrameJacobian(ref.pin, ref.data, fid, prf) @ ref.G, f"J of {name} ({rf})")


def test_frame_jacobian_dot(ref):
    rbd = rbdkit.RBD(ref.model)
    rng = np.random.default_rng(1)
    for k, q in enumerate(configs(ref.model, seed=1)):
        qd = rng.uniform(-3, 3, ref.model.nv) * (10 if k == 2 else 1)
        pin.computeJointJacobiansTimeVariation(ref.pin, ref.data, ref.q(q), ref.v(qd))
        pin.updateFramePlacements(ref.pin, ref.data)
        for name in ref.model.frame_names:
            fid = ref.frame_id(name)
            for rf, prf in RFS.items():
                dJ = rbd.frame_jacobian_dot(q, qd, name, rf)
                dJ_ref = pin.getFrameJacobianTimeVariation(ref.pin, ref.data, fid, prf) @ ref.G
                assert_close(dJ, dJ_ref, f"dJ of {name} ({rf})")


def test_frame_jacobian_finite_differences(ref):
    # LOCAL: J δ = log(X⁻¹ X(q ⊕ δ)); WORLD = Ad(X) LOCAL; LOCAL_WORLD_ALIGNED:
    # the frame origin's world velocity and the world angular velocity
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model, 2, seed=2):
        for name in some_frames(ref.model):
            R, p = rbd.frame_placement(q, name)
            X0 = pin.SE3(R, p)

            def local_log(qq):
                return pin.log6(X0.actInv(pin.SE3(*rbd.frame_placement(qq, name)))).vector

            J_local = fd(local_log, rbd, q)
            assert_fd(rbd.frame_jacobian(q, name, "LOCAL"), J_local, f"J of {name} (LOCAL)")
            assert_fd(rbd.frame_jacobian(q, name, "WORLD"), X0.action @ J_local, f"J of {name} (WORLD)")
            J_lwa = np.vstack([fd(lambda qq: rbd.frame_placement(qq, name)[1], rbd, q), R @ J_local[3:]])
            assert_fd(rbd.frame_jacobian(q, name, "LOCAL_WORLD_ALIGNED"), J_lwa, f"J of {name} (LWA)")


def test_frame_jacobian_dot_finite_differences(ref):
    # dJ/dt along qd: (J(q ⊕ h qd) - J(q ⊕ -h qd)) / 2h
    rbd = rbdkit.RBD(ref.model)
    rng = np.random.default_rng(4)
    for q in configs(ref.model, 2, seed=4):
        qd = rng.uniform(-2, 2, ref.model.nv)
        qp, qm = rbd.integrate(q, H_FD * qd), rbd.integrate(q, -H_FD * qd)
        for name in some_frames(ref.model):
            for rf in RFS:
                fd_dJ = (rbd.frame_jacobian(qp, name, rf) - rbd.frame_jacobian(qm, name, rf)) / (2 * H_FD)
                assert_fd(rbd.frame_jacobian_dot(q, qd, name, rf), fd_dJ, f"dJ of {name} ({rf})")


def test_frame_jacobian_batched(ref):
    rbd = rbdkit.RBD(ref.model)
    Q = np.stack(configs(ref.model, 3, seed=5))
    Qd = np.random.default_rng(5).uniform(-1, 1, (3, ref.model.nv))
    name = ref.model.frame_names[-1]
    for rf in RFS:
        J, dJ = rbd.frame_jacobian(Q, name, rf), rbd.frame_jacobian_dot(Q, Qd, name, rf)
        assert J.shape == dJ.shape == (3, 6, ref.model.nv)
        for s in range(3):
            np.testing.assert_array_equal(J[s], rbd.frame_jacobian(Q[s], name, rf))
            np.testing.assert_array_equal(dJ[s], rbd.frame_jacobian_dot(Q[s], Qd[s], name, rf))
    R, p = rbd.frame_placement(Q, name)
    assert R.shape == (3, 3, 3) and p.shape == (3, 3)
    R, p = rbd.forward_kinematics(Q)
    assert R.shape == (3, ref.model.nb, 3, 3) and p.shape == (3, ref.model.nb, 3)


# ------------------------------------------------------------ end effectors

def end_effector_cases(model, seed=0):
    """(ee_joint_names, offsets, bodies): the default leaves without offsets,
    and up to three moving joints with random tool offsets"""
    rng = np.random.default_rng(seed)
    leaves = [i for i in range(model.nb) if i not in model.body_parents]
    names = moving_joints(model)
    pick = [names[i] for i in sorted(set(np.linspace(0, len(names) - 1, 3).round().astype(int)))]
    offsets = rng.uniform(-0.3, 0.3, (len(pick), 3))
    return [(None, None, leaves), (pick, offsets, [model.joint(n)["body"] for n in pick])]


def test_end_effector_pose(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model):
        pin.forwardKinematics(ref.pin, ref.data, ref.q(q))
        for names, offsets, bodies in end_effector_cases(ref.model):
            pose = rbd.end_effector_pose(q, names, offsets)
            assert pose.shape == (len(bodies), 6)
            for e, b in enumerate(bodies):
                X = ref.data.oMi[ref.joint_id(b)]
                o = np.zeros(3) if offsets is None else offsets[e]
                assert_close(pose[e, :3], X.act(o), f"ee {e} position")
                rpy = pose[e, 3:]
                assert -np.pi / 2 <= rpy[1] <= np.pi / 2
                assert_close(pin.rpy.rpyToMatrix(*rpy), X.rotation, f"ee {e} rpy -> R")
                assert_close(wrap(rpy - pin.rpy.matrixToRpy(X.rotation)), np.zeros(3), f"ee {e} rpy")


def test_end_effector_pose_gradient(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model):
        for names, offsets, bodies in end_effector_cases(ref.model):
            G = rbd.end_effector_pose_gradient(q, names, offsets)
            pose = rbd.end_effector_pose(q, names, offsets)
            assert G.shape == (len(bodies), 6, ref.model.nv)
            for e, b in enumerate(bodies):
                o = np.zeros(3) if offsets is None else offsets[e]
                J, _ = pin_point_jacobian(ref, q, b, o)
                assert_close(G[e, :3], J[:3], f"ee {e} position gradient")
                assert_close(G[e, 3:], rpy_rate_inverse(pose[e, 3:]) @ J[3:], f"ee {e} rpy gradient")


def test_end_effector_pose_gradient_finite_differences(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model, 2, seed=6):
        for names, offsets, _ in end_effector_cases(ref.model, seed=6):
            pose0 = rbd.end_effector_pose(q, names, offsets)
            # rpy differences taken about pose0 so that a ±π wrap does not matter
            G_fd = fd(lambda qq: pose0 + np.concatenate(
                [rbd.end_effector_pose(qq, names, offsets)[:, :3] - pose0[:, :3],
                 wrap(rbd.end_effector_pose(qq, names, offsets)[:, 3:] - pose0[:, 3:])], axis=1), rbd, q)
            assert_fd(rbd.end_effector_pose_gradient(q, names, offsets), G_fd, "pose gradient")


def test_end_effector_pose_hessians_agree(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model, 2, seed=7):
        for names, offsets, bodies in end_effector_cases(ref.model, seed=7):
            H = rbd.end_effector_pose_hessian(q, offsets, names)
            Ha = rbd.end_effector_pose_hessian_analytic(q, offsets, names)
            assert H.shape == Ha.shape == (len(bodies), 6, ref.model.nv, ref.model.nv)
            assert_close(Ha, H, "analytic vs dual-number pose Hessian", 1e-12)


def test_end_effector_pose_hessian_finite_differences(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model, 2, seed=8):
        for names, offsets, _ in end_effector_cases(ref.model, seed=8):
            # H[e, r, j, k] = ∂G[e, r, k]/∂δ_j: move the j axis ahead of k
            H_fd = np.moveaxis(fd(lambda qq: rbd.end_effector_pose_gradient(qq, names, offsets), rbd, q), -1, -2)
            assert_fd(rbd.end_effector_pose_hessian(q, offsets, names), H_fd, "pose Hessian (dual)")
            assert_fd(rbd.end_effector_pose_hessian_analytic(q, offsets, names), H_fd, "pose Hessian (analytic)")


def test_end_effector_pose_hessian_symmetric_part(ref):
    # ½(H + Hᵀ) is the Hessian of δ ↦ pose(q ⊕ δ) at δ = 0 (second central differences)
    rbd = rbdkit.RBD(ref.model)
    q, h, nv = configs(ref.model, 1, seed=3)[0], 1e-4, ref.model.nv
    H = rbd.end_effector_pose_hessian_analytic(q)
    D = np.zeros_like(H)
    for j in range(nv):
        for k in range(nv):
            ej, ek = h * np.eye(nv)[j], h * np.eye(nv)[k]
            f = [rbd.end_effector_pose(rbd.integrate(q, d)) for d in (ej + ek, ej - ek, ek - ej, -ej - ek)]
            D[..., j, k] = (f[0] - f[1] - f[2] + f[3]) / (4 * h * h)
    assert_close(0.5 * (H + np.swapaxes(H, -1, -2)), D, "symmetric part of the pose Hessian", 1e-5)


def test_end_effector_hessian_symmetry(ref):
    # symmetric in (j, k) except inside a free-flyer or spherical joint's own block
    rbd = rbdkit.RBD(ref.model)
    q = configs(ref.model, 1, seed=9)[0]
    H = rbd.end_effector_pose_hessian_analytic(q)
    multi = np.zeros((ref.model.nv, ref.model.nv), bool)
    for j in ref.model.joints:
        if j["nv"] > 1:
            sl = slice(j["v_index"], j["v_index"] + j["nv"])
            multi[sl, sl] = True
    asym = np.abs(H - np.swapaxes(H, -1, -2))
    assert_close(np.where(multi, 0.0, asym), np.zeros_like(asym), "H symmetric outside multi-DoF joints", 1e-12)
    if ref.model.floating_base:
        assert asym[..., multi].max() > 1e-6  # the base's rotation columns do not commute


def test_end_effector_offsets_broadcast_and_batch(ref):
    rbd = rbdkit.RBD(ref.model)
    names = moving_joints(ref.model)[-2:]
    o = np.array([0.1, -0.2, 0.05])
    q = configs(ref.model, 1, seed=10)[0]
    for fn in ("end_effector_pose", "end_effector_pose_gradient", "osc_inertia"):
        f = getattr(rbd, fn)
        try:
            a = f(q, names, o)
        except ValueError as e:  # fewer than 6 DoF reach an end effector
            assert fn == "osc_inertia" and "singular" in str(e)
            continue
        np.testing.assert_array_equal(a, f(q, names, np.tile(o, (len(names), 1))))
    for fn in ("end_effector_pose_hessian", "end_effector_pose_hessian_analytic"):
        f = getattr(rbd, fn)
        np.testing.assert_array_equal(f(q, o, names), f(q, np.tile(o, (len(names), 1)), names))
    # batched q, per-sample offsets
    Q = np.stack(configs(ref.model, 3, seed=11))
    O = np.random.default_rng(11).uniform(-0.2, 0.2, (3, len(names), 3))
    P, G = rbd.end_effector_pose(Q, names, O), rbd.end_effector_pose_gradient(Q, names, O)
    H = rbd.end_effector_pose_hessian(Q, O, names)
    assert P.shape == (3, len(names), 6) and G.shape == (3, len(names), 6, ref.model.nv)
    assert H.shape == (3, len(names), 6, ref.model.nv, ref.model.nv)
    for s in range(3):
        np.testing.assert_array_equal(P[s], rbd.end_effector_pose(Q[s], names, O[s]))
        np.testing.assert_array_equal(G[s], rbd.end_effector_pose_gradient(Q[s], names, O[s]))
        np.testing.assert_array_equal(H[s], rbd.end_effector_pose_hessian(Q[s], O[s], names))
    # the defaults are the leaf bodies in body order
    leaves = [i for i in range(ref.model.nb) if i not in ref.model.body_parents]
    leaf_names = [ref.model.joints[i]["name"] for i in leaves]
    np.testing.assert_array_equal(rbd.end_effector_pose(q), rbd.end_effector_pose(q, leaf_names))


# ------------------------------------------------------------ operational space

def test_osc_inertia(ref):
    rbd = rbdkit.RBD(ref.model)
    for q in configs(ref.model, 2, seed=12):
        M = ref.crba(q)
        for names, offsets, bodies in end_effector_cases(ref.model, seed=12):
            dofs = [np.count_nonzero(np.any(pin_point_jacobian(ref, q, b, np.zeros(3))[0] != 0, axis=0))
                    for b in bodies]
            if min(dofs) < 6:
                with pytest.raises(ValueError, match="singular"):
                    rbd.osc_inertia(q, names, offsets)
                continue
            L = rbd.osc_inertia(q, names, offsets)
            assert L.shape == (len(bodies), 6, 6)
            for e, b in enumerate(bodies):
                o = np.zeros(3) if offsets is None else offsets[e]
                J, _ = pin_point_jacobian(ref, q, b, o)
                L_ref = np.linalg.inv(J @ np.linalg.solve(M, J.T))
                cond = np.linalg.cond(L_ref)
                assert_close(L[e], L_ref, f"Λ of ee {e} (cond {cond:.1e})")
                assert_close(L[e], L[e].T, "Λ symmetric")


def test_osc_inertia_singular():
    rbd = rbdkit.RBD(rbdkit.robots.load("iiwa"))
    # at q = 0 joints 1, 3, 5, 7 share one axis: the Jacobian has rank 4
    with pytest.raises(ValueError, match="singular") as e:
        rbd.osc_inertia(np.zeros(7))
    assert "configuration is singular" in str(e.value)
    # a 3-DoF leg of fixed-base HyQ
    hyq = rbdkit.RBD(rbdkit.robots.load("hyq"))
    with pytest.raises(ValueError, match="only 3 DoF reach it"):
        hyq.osc_inertia(hyq.model.neutral())


# ------------------------------------------------------------ bad input

@pytest.fixture(scope="module")
def hyq():
    return rbdkit.RBD(rbdkit.robots.load("hyq", floating_base=True))


def test_unknown_names(hyq):
    q = hyq.model.neutral()
    with pytest.raises(ValueError, match=r"frame_name: unknown frame 'no_such_frame'"):
        hyq.frame_jacobian(q, "no_such_frame")
    with pytest.raises(ValueError, match=r"frame_name: unknown frame"):
        hyq.frame_jacobian_dot(q, np.zeros(hyq.nv), "no_such_frame")
    with pytest.raises(ValueError, match=r"frame_name: unknown frame"):
        hyq.frame_placement(q, "no_such_frame")
    with pytest.raises(TypeError, match="frame_name"):
        hyq.frame_jacobian(q, 3)
    for fn in ("end_effector_pose", "end_effector_pose_gradient", "osc_inertia"):
        with pytest.raises(ValueError, match=r"ee_joint_names: unknown joint 'nope'"):
            getattr(hyq, fn)(q, ["lf_haa_joint", "nope"])
        with pytest.raises(TypeError, match="ee_joint_names"):
            getattr(hyq, fn)(q, [1, 2])
        with pytest.raises(ValueError, match="ee_joint_names: expected at least one"):
            getattr(hyq, fn)(q, [])
    for fn in ("end_effector_pose_hessian", "end_effector_pose_hessian_analytic"):
        with pytest.raises(ValueError, match=r"ee_joint_names: unknown joint 'nope'"):
            getattr(hyq, fn)(q, None, ["nope"])


def test_fixed_or_planar_joint_as_end_effector():
    rbd = rbdkit.RBD(rbdkit.robots.load("iiwa"))
    with pytest.raises(ValueError, match=r"ee_joint_names: joint 'iiwa_base_joint' is fixed"):
        rbd.end_effector_pose(np.zeros(7), ["iiwa_base_joint"])
    mixed = rbdkit.RBD(rbdkit.Model.from_urdf(dict((c[0], c[1]) for c in CASES)["mixed-fixed"]))
    with pytest.raises(ValueError, match=r"ee_joint_names: joint 'tool_fix' is fixed .*joint 'hinge'"):
        mixed.end_effector_pose(mixed.model.neutral(), ["tool_fix"])
    planar = rbdkit.RBD(rbdkit.Model.from_urdf(dict((c[0], c[1]) for c in CASES)["planar-fixed"]))
    with pytest.raises(ValueError, match=r"ee_joint_names: joint 'plane' is a planar joint.*'plane_rot'"):
        planar.end_effector_pose(planar.model.neutral(), ["plane"])
    planar.end_effector_pose(planar.model.neutral(), ["plane_rot"])


def test_unknown_reference_frame(hyq):
    q = hyq.model.neutral()
    name = hyq.model.frame_names[-1]
    for bad in ("local", "GLOBAL", 1, None):
        expected = r"reference_frame: expected one of 'LOCAL', 'WORLD', 'LOCAL_WORLD_ALIGNED'"
        with pytest.raises(ValueError, match=expected):
            hyq.frame_jacobian(q, name, bad)
        with pytest.raises(ValueError, match=r"reference_frame: expected one of"):
            hyq.frame_jacobian_dot(q, np.zeros(hyq.nv), name, bad)


def test_malformed_offsets(hyq):
    q = hyq.model.neutral()
    names = ["lf_kfe_joint", "rh_kfe_joint"]
    calls = [(hyq.end_effector_pose, "ee_offsets", lambda o: dict(ee_joint_names=names, ee_offsets=o)),
             (hyq.end_effector_pose_gradient, "ee_offsets", lambda o: dict(ee_joint_names=names, ee_offsets=o)),
             (hyq.osc_inertia, "ee_offsets", lambda o: dict(ee_joint_names=names, ee_offsets=o)),
             (hyq.end_effector_pose_hessian, "offsets", lambda o: dict(offsets=o, ee_joint_names=names)),
             (hyq.end_effector_pose_hessian_analytic, "offsets", lambda o: dict(offsets=o, ee_joint_names=names))]
    for f, arg, kw in calls:
        for bad in (np.zeros(2), np.zeros((3, 3)), np.zeros((2, 4)), np.zeros((1, 3, 3)), np.zeros((2, 2, 2, 3))):
            with pytest.raises(ValueError, match=rf"{arg}: expected shape \(3,\), \(n_ee, 3\) or \(B, n_ee, 3\)"):
                f(q, **kw(bad))
        nan = np.zeros((2, 3))
        nan[1, 2] = np.nan
        with pytest.raises(ValueError, match=rf"{arg}: expected finite values"):
            f(q, **kw(nan))
        with pytest.raises(ValueError, match=rf"{arg}: expected finite values"):
            f(q, **kw(np.array([0.0, np.inf, 0.0])))
        with pytest.raises(TypeError, match=arg):
            f(q, **kw("abc"))
        with pytest.raises(TypeError, match=arg):
            f(q, **kw(np.zeros((2, 3), dtype=complex)))
        # batch mismatch between q and the offsets
        with pytest.raises(ValueError, match=rf"{arg}: batch size 3 does not match"):
            f(np.stack([q, q]), **kw(np.zeros((3, 2, 3))))


def test_wrong_shapes(hyq):
    q, qd = hyq.model.neutral(), np.zeros(hyq.nv)
    name = hyq.model.frame_names[-1]
    with pytest.raises(ValueError, match=r"q: expected shape \(19,\)"):
        hyq.frame_jacobian(np.zeros(hyq.nv), name)
    with pytest.raises(ValueError, match=r"qd: expected shape \(18,\)"):
        hyq.frame_jacobian_dot(q, np.zeros(hyq.nq), name)
    with pytest.raises(ValueError, match=r"qd: batch size 3 does not match q's batch size 2"):
        hyq.frame_jacobian_dot(np.stack([q, q]), np.zeros((3, hyq.nv)), name)
    for fn in ("end_effector_pose", "end_effector_pose_gradient", "end_effector_pose_hessian",
               "end_effector_pose_hessian_analytic", "osc_inertia", "forward_kinematics"):
        with pytest.raises(ValueError, match=r"q: expected shape"):
            getattr(hyq, fn)(np.zeros((2, 3, hyq.nq)))
        with pytest.raises(TypeError, match="q:"):
            getattr(hyq, fn)("q")
    with pytest.raises(ValueError, match=r"q: expected shape"):
        hyq.frame_placement(np.zeros(5), name)


def test_bad_values(hyq):
    q = hyq.model.neutral()
    name = hyq.model.frame_names[-1]
    bad_q = q.copy()
    bad_q[3:7] = 0.0
    with pytest.raises(ValueError, match=r"q: the quaternion of joint 'root_joint'"):
        hyq.frame_jacobian(bad_q, name)
    with pytest.raises(ValueError, match=r"q: the quaternion"):
        hyq.end_effector_pose_hessian(bad_q)
    nan_q = q.copy()
    nan_q[8] = np.nan
    for fn in ("end_effector_pose", "osc_inertia", "forward_kinematics"):
        with pytest.raises(ValueError, match=r"q: expected finite values"):
            getattr(hyq, fn)(nan_q)
    qd = np.zeros(hyq.nv)
    qd[2] = np.inf
    with pytest.raises(ValueError, match=r"qd: expected finite values"):
        hyq.frame_jacobian_dot(q, qd, name)
