"""The MuJoCo output convention, checked against the mujoco package itself.

The same URDF is loaded into MuJoCo (MjSpec; fusestatic off, a free joint
added to the root body for floating bases, the test URDF's spherical joints
turned into ball joints; contacts, limits, passive forces, damping, armature
and friction loss off, so that both sides describe the same dynamics) and
compared with rbdkit in the MuJoCo convention:
  - MuJoCo's body inertias equal the URDF's <inertial> (read here with ElementTree);
  - mj_integratePos / mj_differentiatePos equal rbdkit's MuJoCo ⊕ / ⊖;
  - one mj_step of MuJoCo's Euler integrator (semi-implicit) equals our
    semi_implicit_euler, with u as qfrc_applied; every scheme equals the same
    scheme written out on MuJoCo's mj_forward and mj_integratePos;
  - MuJoCo's RK4 equals our rk4 on models without quaternion joints. On free
    and ball joints MuJoCo 4.0's RK4 corrects the stage rates (Munthe-Kaas:
    K = Jr(Θ)⁻¹ ω); ours keeps the spec's base-point stages, so there the two
    agree to the local error (5e-8 to 6e-6 here at dt = 5 ms), and MuJoCo's result is
    reproduced to 1e-10 by that corrected rule written out here;
  - our [A | B] equals mjd_transitionFD (centred), B w.r.t. ctrl = u through
    motor actuators on the hinge/slide joints, the free/ball columns by central
    differences of mj_step with qfrc_applied; for RK4 (which mjd_transitionFD
    does not support), midpoint and constant acceleration: central differences
    of the MuJoCo-built step in MuJoCo's tangent;
  - the step Hessian (semi_implicit_euler, floating HyQ) contracted with a few
    tangent directions equals central differences of mjd_transitionFD's
    [A | B] at states moved along them with mj_integratePos.
Within rbdkit: the two conventions describe the same motion (state
conversions, an Euler step at zero base rotation rate, fine-step
trajectories for every scheme), a no-op without free/ball joints, [A | B]
of every scheme and the costs against central differences in MuJoCo's
tangent.

The bundled Atlas is not used here: MuJoCo rejects its published inertias
("inertia must have positive eigenvalues" on utorso); the floating HyQ and
the spherical test model (free + ball joints) cover the floating cases.
"""

import os
import re
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

import rbdkit
from pinref import ROBOTS_DIR, URDF_DIR

FREE = "mj_root_free"
CASES = [("iiwa-fixed", os.path.join(ROBOTS_DIR, "iiwa.urdf"), False),
         ("hyq-fixed", os.path.join(ROBOTS_DIR, "hyq.urdf"), False),
         ("hyq-floating", os.path.join(ROBOTS_DIR, "hyq.urdf"), True),
         ("spherical-fixed", os.path.join(URDF_DIR, "spherical.urdf"), False),
         ("spherical-floating", os.path.join(URDF_DIR, "spherical.urdf"), True)]
SCHEMES = ("euler", "semi_implicit_euler", "midpoint", "rk4", "trapezoidal", "constant_acceleration")


def rel_err(a, b):
    return np.max(np.abs(np.asarray(a) - np.asarray(b))) / max(1.0, np.max(np.abs(b)))


# ------------------------------------------------------------ the MuJoCo side


def urdf_text(path):
    """the URDF without visual/collision elements (no meshes or contacts to load)"""
    text = open(path).read()
    return re.sub(r"<(visual|collision)\b.*?</\1>", "", text, flags=re.S)


class MjCase:
    """a MuJoCo model of a URDF and the index maps between its qpos/qvel and
    rbdkit's MuJoCo-convention q/v (our joint order)"""

    def __init__(self, path, floating, dt=0.01, integrator="euler"):
        text = urdf_text(path)
        root = ET.fromstring(text)
        self.xml = root
        balls = [j.get("name") for j in root.findall("joint") if j.get("type") == "spherical"]
        spec = mujoco.MjSpec.from_string(text.replace('type="spherical"', 'type="continuous"'))
        spec.compiler.fusestatic = False
        children = {j.find("child").get("link") for j in root.findall("joint")}
        root_link = [lk.get("name") for lk in root.findall("link") if lk.get("name") not in children][0]
        if floating:
            spec.body(root_link).add_freejoint(name=FREE)
        self.actuated = []
        for j in spec.joints:
            if j.name in balls:
                j.type = mujoco.mjtJoint.mjJNT_BALL
            j.damping = np.zeros_like(j.damping) if np.ndim(j.damping) else 0.0
            j.armature = 0.0
            j.frictionloss = 0.0
            j.limited = mujoco.mjtLimited.mjLIMITED_FALSE
            if j.type in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
                a = spec.add_actuator()
                a.trntype = mujoco.mjtTrn.mjTRN_JOINT
                a.target = j.name
                a.gear[0] = 1.0
                a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
                self.actuated.append(j.name)
        spec.option.timestep = dt
        spec.option.gravity = [0.0, 0.0, -9.81]
        spec.option.integrator = {"euler": mujoco.mjtIntegrator.mjINT_EULER,
                                  "rk4": mujoco.mjtIntegrator.mjINT_RK4}[integrator]
        D = mujoco.mjtDisableBit
        spec.option.disableflags |= (D.mjDSBL_CONTACT | D.mjDSBL_LIMIT | D.mjDSBL_CONSTRAINT | D.mjDSBL_FRICTIONLOSS
                                     | D.mjDSBL_SPRING | D.mjDSBL_DAMPER)
        self.m = spec.compile()
        self.d = mujoco.MjData(self.m)
        self.spec = spec

    def maps(self, model):
        """iq, iv: MuJoCo qpos/qvel index of each of our (MuJoCo-layout) q/v coordinates;
        iu: our v index of each MuJoCo actuator"""
        m = self.m
        iq, iv = np.zeros(model.nq, int), np.zeros(model.nv, int)
        for j in model.joints:
            if j["mimic_of"] is not None:
                continue
            name = FREE if j["type"] in ("floating", "free") else j["name"]
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
            assert jid >= 0, f"joint {name} not in the MuJoCo model"
            iq[j["q_index"]:j["q_index"] + j["nq"]] = m.jnt_qposadr[jid] + np.arange(j["nq"])
            iv[j["v_index"]:j["v_index"] + j["nv"]] = m.jnt_dofadr[jid] + np.arange(j["nv"])
        ours_v = {j["name"]: j["v_index"] for j in model.joints}
        iu = np.array([ours_v[n] for n in self.actuated], int)
        assert sorted(iq) == list(range(m.nq)) and sorted(iv) == list(range(m.nv))
        return iq, iv, iu


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def case(request):
    _, path, floating = request.param
    model = rbdkit.Model.from_urdf(path, floating_base=floating)
    return path, floating, model, rbdkit.RBD(model)


def mj_state(rbd, seed, scale=1.0):
    """a random state and force in the MuJoCo convention (q, v, u)"""
    rng = np.random.default_rng(seed)
    m = rbd.model
    x = np.concatenate([m.random_configuration(rng), scale * rng.uniform(-2, 2, m.nv)])
    x = rbd.state_to_mujoco(x)
    return x[:m.nq], x[m.nq:], rng.uniform(-10, 10, m.nv)


def mj_set(mc, iq, iv, q, v, qfrc=None, ctrl=None):
    d = mc.d
    mujoco.mj_resetData(mc.m, d)
    d.qpos[iq] = q
    d.qvel[iv] = v
    if qfrc is not None:
        d.qfrc_applied[iv] = qfrc
    if ctrl is not None:
        d.ctrl[:] = ctrl


def quat_wxyz_matrix(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def rpy_matrix(r, p, y):
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return (np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]) @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
            @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]))


# ------------------------------------------------------------ MuJoCo loads the same model


def test_mujoco_inertias_equal_the_urdf(case):
    path, floating, model, rbd = case
    mc = MjCase(path, floating)
    m = mc.m
    checked = 0
    for link in mc.xml.findall("link"):
        inert = link.find("inertial")
        bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, link.get("name"))
        if inert is None or bid < 0:
            continue
        mass = float(inert.find("mass").get("value"))
        o = inert.find("origin")
        xyz = np.array([float(s) for s in o.get("xyz", "0 0 0").split()]) if o is not None else np.zeros(3)
        rpy = [float(s) for s in o.get("rpy", "0 0 0").split()] if o is not None else [0, 0, 0]
        I = inert.find("inertia")
        ixx, ixy, ixz, iyy, iyz, izz = (float(I.get(k)) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
        R = rpy_matrix(*rpy)
        I_urdf = R @ np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]) @ R.T
        Rm = quat_wxyz_matrix(m.body_iquat[bid])
        I_mj = Rm @ np.diag(m.body_inertia[bid]) @ Rm.T
        assert abs(m.body_mass[bid] - mass) < 1e-12 * max(1, mass), link.get("name")
        np.testing.assert_allclose(m.body_ipos[bid], xyz, atol=1e-12)
        np.testing.assert_allclose(I_mj, I_urdf, atol=1e-9 * max(1, np.abs(I_urdf).max()))
        checked += 1
    assert checked >= 4
    # and the same joint space: sizes match
    assert (m.nq, m.nv) == (model.nq, model.nv)


def test_retraction_equals_mujoco(case):
    path, floating, model, rbd = case
    mc = MjCase(path, floating)
    iq, iv, _ = mc.maps(model)
    m = mc.m
    for seed in range(3):
        q, v, _ = mj_state(rbd, seed, scale=2.0)
        q1, _, _ = mj_state(rbd, seed + 10)
        ref = np.zeros(m.nq)
        ref[iq] = q
        vel = np.zeros(m.nv)
        vel[iv] = v
        mujoco.mj_integratePos(m, ref, vel, 0.7)
        np.testing.assert_allclose(rbd.mujoco_integrate(q, 0.7 * v), ref[iq], rtol=0, atol=1e-13)
        a, b = np.zeros(m.nq), np.zeros(m.nq)
        a[iq], b[iq] = q, q1
        dv = np.zeros(m.nv)
        mujoco.mj_differentiatePos(m, dv, 1.0, a, b)
        np.testing.assert_allclose(rbd.mujoco_difference(q, q1), dv[iv], rtol=0, atol=1e-12)


# ------------------------------------------------------------ steps against MuJoCo


def mj_reference_step(mc, iq, iv, q, v, u, dt, scheme):
    """the scheme written out in NumPy on MuJoCo's own pieces: accelerations from
    mj_forward (u as qfrc_applied), ⊕ from mj_integratePos"""
    m, d = mc.m, mc.d

    def acc(qq, vv):
        mj_set(mc, iq, iv, qq, vv, qfrc=u)
        mujoco.mj_forward(m, d)
        return d.qacc[iv].copy()

    def integ(qq, w):
        a, ww = np.zeros(m.nq), np.zeros(m.nv)
        a[iq], ww[iv] = qq, w
        mujoco.mj_integratePos(m, a, ww, 1.0)
        return a[iq]

    if scheme in ("euler", "semi_implicit_euler", "constant_acceleration"):
        a = acc(q, v)
        vn = v + dt * a
        w = {"euler": dt * v, "semi_implicit_euler": dt * vn, "constant_acceleration": dt * v + 0.5 * dt * dt * a}
        return np.concatenate([integ(q, w[scheme]), vn])
    c, bw = {"midpoint": ([0, 0.5], [0, 1]), "trapezoidal": ([0, 1], [0.5, 0.5]),
             "rk4": ([0, 0.5, 0.5, 1], [1 / 6, 1 / 3, 1 / 3, 1 / 6])}[scheme]
    vs, a_s = v, acc(q, v)
    vsum, asum = bw[0] * vs, bw[0] * a_s
    for s in range(1, len(c)):
        qs = integ(q, c[s] * dt * vs)
        vs = v + c[s] * dt * a_s
        a_s = acc(qs, vs)
        vsum, asum = vsum + bw[s] * vs, asum + bw[s] * a_s
    return np.concatenate([integ(q, dt * vsum), v + dt * asum])


@pytest.mark.parametrize("scheme", SCHEMES)
def test_step_equals_mujoco_built_reference(case, scheme):
    path, floating, model, rbd = case
    dt = 0.005
    mc = MjCase(path, floating, dt=dt)
    iq, iv, _ = mc.maps(model)
    for seed in range(2):
        q, v, u = mj_state(rbd, seed)
        x = rbd.integrator(q, v, u, dt, scheme, output_convention="mujoco")
        assert rel_err(x, mj_reference_step(mc, iq, iv, q, v, u, dt, scheme)) < 1e-10
        np.testing.assert_array_equal(
            rbd.plant_step(np.concatenate([q, v]), u, dt, scheme, output_convention="mujoco"), x)


@pytest.mark.parametrize("scheme,mj_integrator", [("semi_implicit_euler", "euler"), ("rk4", "rk4")])
def test_step_equals_mj_step(case, scheme, mj_integrator):
    # MuJoCo's Euler is our semi_implicit_euler. MuJoCo 4.0's RK4 advances
    # quaternion joints with Munthe-Kaas-corrected stage rates (checked below);
    # ours uses base-point stages (spec), so on free/ball joints the two agree
    # to the scheme's local error only. Without quaternion joints they are one map.
    path, floating, model, rbd = case
    dt = 0.005
    mc = MjCase(path, floating, dt=dt, integrator=mj_integrator)
    iq, iv, _ = mc.maps(model)
    rotational = floating or "spherical" in path
    for seed in range(3):
        q, v, u = mj_state(rbd, seed)
        mj_set(mc, iq, iv, q, v, qfrc=u)
        mujoco.mj_step(mc.m, mc.d)
        ref = np.concatenate([mc.d.qpos[iq], mc.d.qvel[iv]])
        x = rbd.integrator(q, v, u, dt, scheme, output_convention="mujoco")
        tol = 1e-4 if scheme == "rk4" and rotational else 1e-10
        assert rel_err(x, ref) < tol, f"{rel_err(x, ref):.2e}"
        if scheme == "rk4" and rotational:
            assert rel_err(rk4_munthe_kaas(mc, iq, iv, model, q, v, u, dt), ref) < 1e-10


def rk4_munthe_kaas(mc, iq, iv, model, q, v, u, dt):
    """RK4 with Munthe-Kaas stages on the quaternion joints (rates K = Jr(Θ)⁻¹ ω
    in the Lie algebra), on MuJoCo's pieces: what MuJoCo 4.0's mj_RungeKutta computes"""
    m, d = mc.m, mc.d
    rot = []
    for j in model.joints:
        if j["type"] in ("free", "spherical"):
            rot.append(j["v_index"] + (3 if j["nv"] == 6 else 0))

    def acc(qq, vv):
        mj_set(mc, iq, iv, qq, vv, qfrc=u)
        mujoco.mj_forward(m, d)
        return d.qacc[iv].copy()

    def integ(qq, w):
        a, ww = np.zeros(m.nq), np.zeros(m.nv)
        a[iq], ww[iv] = qq, w
        mujoco.mj_integratePos(m, a, ww, 1.0)
        return a[iq]

    def jr_inv(th):
        W = np.array([[0, -th[2], th[1]], [th[2], 0, -th[0]], [-th[1], th[0], 0]])
        t2 = th @ th
        c = 1 / 12 if t2 < 1e-12 else (1 - 0.5 * np.sqrt(t2) * np.sin(np.sqrt(t2)) / (1 - np.cos(np.sqrt(t2)))) / t2
        return np.eye(3) + 0.5 * W + c * W @ W

    A = [[], [0.5], [0, 0.5], [0, 0, 1]]
    b = [1 / 6, 1 / 3, 1 / 3, 1 / 6]
    K, acc_s = [], []
    for s in range(4):
        th = sum((A[s][j] * dt * K[j] for j in range(s)), np.zeros(model.nv))
        vs = v + sum((A[s][j] * dt * acc_s[j] for j in range(s)), np.zeros(model.nv))
        acc_s.append(acc(integ(q, th), vs))
        k = vs.copy()
        for o in rot:
            k[o:o + 3] = jr_inv(th[o:o + 3]) @ vs[o:o + 3]
        K.append(k)
    th = sum(b[j] * dt * K[j] for j in range(4))
    return np.concatenate([integ(q, th), v + dt * sum(b[j] * acc_s[j] for j in range(4))])


def test_acceleration_equals_mujoco(case):
    # the continuous dynamics: d/dt qvel of MuJoCo (mj_forward) equals ours,
    # read off an Euler step of unit length: v⁺ = v + a
    path, floating, model, rbd = case
    mc = MjCase(path, floating)
    iq, iv, _ = mc.maps(model)
    q, v, u = mj_state(rbd, 5)
    mj_set(mc, iq, iv, q, v, qfrc=u)
    mujoco.mj_forward(mc.m, mc.d)
    x = rbd.integrator(q, v, u, 1.0, "euler", output_convention="mujoco")
    assert rel_err(x[model.nq:] - v, mc.d.qacc[iv]) < 1e-10


# ------------------------------------------------------------ [A | B] against MuJoCo


def test_gradient_equals_mjd_transition_fd(case):
    # MuJoCo's Euler integrator = our semi_implicit_euler
    path, floating, model, rbd = case
    dt = 0.01
    mc = MjCase(path, floating, dt=dt)
    iq, iv, iu = mc.maps(model)
    m, nv = mc.m, model.nv
    q, v, u = mj_state(rbd, 7)
    # controls: ctrl drives the hinge/slide dofs, qfrc_applied the free/ball dofs
    ctrl = u[iu]
    qfrc = u.copy()
    qfrc[iu] = 0.0
    mj_set(mc, iq, iv, q, v, qfrc=qfrc, ctrl=ctrl)
    A = np.zeros((2 * nv, 2 * nv))
    B = np.zeros((2 * nv, m.nu))
    mujoco.mjd_transitionFD(m, mc.d, 1e-7, True, A, B, None, None)
    # the other input columns: central differences of mj_step in qfrc_applied
    others = [k for k in range(nv) if k not in set(iu)]
    eps = 1e-6

    def step(du):
        mj_set(mc, iq, iv, q, v, qfrc=qfrc + du, ctrl=ctrl)
        mujoco.mj_step(m, mc.d)
        return mc.d.qpos.copy(), mc.d.qvel.copy()

    Bq = np.zeros((2 * nv, nv))
    for k in others:
        du = np.zeros(nv)
        du[k] = eps
        qp, vp = step(du)
        qm, vm = step(-du)
        dq = np.zeros(m.nv)
        mujoco.mj_differentiatePos(m, dq, 2 * eps, qm, qp)
        Bq[:nv, iv[k]] = dq
        Bq[nv:, iv[k]] = (vp - vm) / (2 * eps)
    AB = rbd.integrator_gradient(q, v, u, dt, "semi_implicit_euler", output_convention="mujoco")
    rows = np.concatenate([iv, nv + iv])
    ours_A = np.zeros_like(A)
    ours_A[np.ix_(rows, rows)] = AB[:, :2 * nv]
    assert rel_err(ours_A, A) < 1e-5, f"A: {rel_err(ours_A, A):.2e}"
    for a, k in enumerate(iu):
        col = np.zeros(2 * nv)
        col[rows] = AB[:, 2 * nv + k]
        assert rel_err(col, B[:, a]) < 1e-5, f"B ctrl column {a}"
    for k in others:
        col = np.zeros(2 * nv)
        col[rows] = AB[:, 2 * nv + k]
        assert rel_err(col, Bq[:, iv[k]]) < 1e-5, f"B qfrc column {k}"


@pytest.mark.parametrize("scheme", ("rk4", "midpoint", "constant_acceleration"))
def test_gradient_equals_mujoco_built_differences(case, scheme):
    # mjd_transitionFD does not support RK4: central differences of the
    # MuJoCo-built step (mj_forward, mj_integratePos) in MuJoCo's tangent
    path, floating, model, rbd = case
    dt = 0.01
    mc = MjCase(path, floating, dt=dt)
    iq, iv, _ = mc.maps(model)
    nq, nv = model.nq, model.nv
    q, v, u = mj_state(rbd, 8)
    x0 = mj_reference_step(mc, iq, iv, q, v, u, dt, scheme)
    F = np.zeros((2 * nv, 3 * nv))
    eps = 1e-6
    for k in range(3 * nv):
        d = np.zeros(3 * nv)
        d[k] = eps
        xs = []
        for sgn in (1, -1):
            a, w = np.zeros(mc.m.nq), np.zeros(mc.m.nv)
            a[iq], w[iv] = q, sgn * d[:nv]
            mujoco.mj_integratePos(mc.m, a, w, 1.0)
            xs.append(mj_reference_step(mc, iq, iv, a[iq], v + sgn * d[nv:2 * nv], u + sgn * d[2 * nv:], dt, scheme))
        p0, p1 = np.zeros(mc.m.nq), np.zeros(mc.m.nq)
        p0[iq], p1[iq] = xs[1][:nq], xs[0][:nq]
        dq = np.zeros(mc.m.nv)
        mujoco.mj_differentiatePos(mc.m, dq, 2 * eps, p0, p1)
        F[:nv, k] = dq[iv]
        F[nv:, k] = (xs[0][nq:] - xs[1][nq:]) / (2 * eps)
    AB = rbd.integrator_gradient(q, v, u, dt, scheme, output_convention="mujoco")
    assert rel_err(AB, F) < 1e-5, f"{scheme}: {rel_err(AB, F):.2e}"
    assert x0.shape == (nq + nv,)


# ------------------------------------------------------------ the step Hessian against MuJoCo


def mj_transition(mc, iq, iv, iu, q, v, u, eps=1e-4):
    """MuJoCo's [A | B] (mjd_transitionFD, centred) at (q, v, u) in our order:
    (2nv, 2nv + nu), B w.r.t. ctrl = u on the hinge/slide dofs (qfrc_applied the rest)"""
    m, nv = mc.m, len(iv)
    qfrc = u.copy()
    qfrc[iu] = 0.0
    mj_set(mc, iq, iv, q, v, qfrc=qfrc, ctrl=u[iu])
    A, B = np.zeros((2 * nv, 2 * nv)), np.zeros((2 * nv, m.nu))
    mujoco.mjd_transitionFD(m, mc.d, eps, True, A, B, None, None)
    rows = np.concatenate([iv, nv + iv])
    return np.concatenate([A[np.ix_(rows, rows)], B[rows]], axis=1)


def test_step_hessian_equals_differences_of_mjd_transition_fd():
    # MuJoCo's Euler = our semi_implicit_euler, on the floating HyQ with its base
    # spinning: central differences of mjd_transitionFD's [A | B] at states
    # x ⊕ ±h d (q through mj_integratePos, qvel and the forces additive) along a
    # few tangent directions d, against H contracted with d. MuJoCo's A at the
    # moved state is read in the charts there: on a quaternion's rows the output
    # chart turns by Jr(φ) ≈ I - ½[φ]× (φ = (AB d) on those rows), on its columns
    # the input chart by Jr⁻¹ ≈ I + ½[t d_θ]×, so
    #   d/dt G(x ⊕ t d) = H·d - ½ φ × AB (quaternion rows) + ½ AB[:, θ] (d_θ × e_j) (quaternion columns j)
    path = os.path.join(ROBOTS_DIR, "hyq.urdf")
    model = rbdkit.Model.from_urdf(path, floating_base=True)
    rbd = rbdkit.RBD(model)
    dt = 0.01
    mc = MjCase(path, True, dt=dt)
    iq, iv, iu = mc.maps(model)
    nq, nv = model.nq, model.nv
    q, v, u = mj_state(rbd, 21)
    v[3:6] = [4.0, -3.0, 3.5]  # ω, body frame
    x = np.concatenate([q, v])
    H = rbd.plant_step_hessian(x, u, dt, "semi_implicit_euler", output_convention="mujoco")
    AB = rbd.plant_step_gradient(x, u, dt, "semi_implicit_euler", output_convention="mujoco")
    cols = np.concatenate([np.arange(2 * nv), 2 * nv + iu])  # MuJoCo's A and ctrl columns in z = [δq; δv; δu]
    th = np.arange(3, 6)  # the free joint's quaternion tangent (our v order, MuJoCo layout)
    assert next(j for j in model.joints if j["type"] in ("floating", "free"))["v_index"] == 0
    G0 = mj_transition(mc, iq, iv, iu, q, v, u)
    assert rel_err(G0, AB[:, cols]) < 1e-6

    def moved(d, t):
        a, w = np.zeros(mc.m.nq), np.zeros(mc.m.nv)
        a[iq], w[iv] = q, t * d[:nv]
        mujoco.mj_integratePos(mc.m, a, w, 1.0)
        return mj_transition(mc, iq, iv, iu, a[iq], v + t * d[nv:2 * nv], u + t * d[2 * nv:])

    rng = np.random.default_rng(4)
    base_turn = np.zeros(3 * nv)
    base_turn[th] = [0.6, -0.3, 0.8]
    hinges_and_rates = np.concatenate([np.zeros(6), rng.uniform(-1, 1, nv - 6), rng.uniform(-1, 1, 2 * nv)])
    for d in (rng.uniform(-1, 1, 3 * nv), base_turn, hinges_and_rates):
        # the outer step is large against mjd_transitionFD's own (1e-4, centred): its
        # rounding noise stays small; Richardson takes the outer error to O(h⁴)
        h = 1e-2
        D = [(moved(d, s) - moved(d, -s)) / (2 * s) for s in (h, h / 2)]
        dG = (4 * D[1] - D[0]) / 3
        expect = np.einsum("ijk,k->ij", H, d)[:, cols]
        phi = (AB @ d)[th]
        expect[th] -= 0.5 * np.cross(phi, AB[th][:, cols], axis=0)
        for b in range(3):  # the input chart on the quaternion columns
            e = np.zeros(3)
            e[b] = 1.0
            expect[:, th[b]] += 0.5 * AB[:, th] @ np.cross(d[th], e)
        err = rel_err(dG, expect)
        assert err < 1e-6, f"H·d vs differences of mjd_transitionFD: {err:.2e}"
        # the corrections matter here: without them the comparison fails
        assert rel_err(dG, np.einsum("ijk,k->ij", H, d)[:, cols]) > 1e-4 or not np.any(d[th])


# ------------------------------------------------------------ within rbdkit


def test_state_conversions(case):
    # written out here in NumPy: quaternion x y z w -> w x y z, base linear velocity body -> world
    path, floating, model, rbd = case
    rng = np.random.default_rng(3)
    q, v = model.random_configuration(rng), rng.normal(size=model.nv)
    x_mj = rbd.state_to_mujoco(np.concatenate([q, v]))
    q_ref, v_ref = q.copy(), v.copy()
    for j in model.joints:
        if j["type"] in ("floating", "free", "spherical"):
            o = j["q_index"] + (3 if j["nq"] == 7 else 0)
            q_ref[o:o + 4] = np.roll(q[o:o + 4], 1)
        if j["nq"] == 7:
            xyzw = q[o:o + 4]
            R = quat_wxyz_matrix(np.roll(xyzw, 1))
            k = j["v_index"]
            v_ref[k:k + 3] = R @ v[k:k + 3]
            u = rng.normal(size=model.nv)
            uw = rbd.force_to_mujoco(q_ref, u)
            np.testing.assert_allclose(uw[k:k + 3], R @ u[k:k + 3], atol=1e-14)
            np.testing.assert_allclose(rbd.force_from_mujoco(q_ref, uw), u, atol=1e-13)
    np.testing.assert_allclose(x_mj, np.concatenate([q_ref, v_ref]), atol=1e-14)
    np.testing.assert_allclose(rbd.state_from_mujoco(x_mj), np.concatenate([q, v]), atol=1e-14)


def test_euler_step_at_zero_base_rotation_rate_is_the_same_motion(case):
    # with ω_base = 0 both retractions move the base along p + dt R v_lin, so one
    # Euler step in either convention is the same state (and a no-op without free joints)
    path, floating, model, rbd = case
    rng = np.random.default_rng(11)
    q, v, u = model.random_configuration(rng), rng.uniform(-2, 2, model.nv), rng.uniform(-10, 10, model.nv)
    if floating:
        v[3:6] = 0.0
    x_pin = rbd.integrator(q, v, u, 0.01, "euler")
    x0 = rbd.state_to_mujoco(np.concatenate([q, v]))
    u_mj = rbd.force_to_mujoco(x0[:model.nq], u)
    x_mj = rbd.integrator(x0[:model.nq], x0[model.nq:], u_mj, 0.01, "euler", output_convention="mujoco")
    assert rel_err(rbd.state_from_mujoco(x_mj), x_pin) < 1e-12


@pytest.mark.parametrize("scheme", SCHEMES)
def test_conventions_follow_the_same_trajectory(case, scheme):
    # fine steps of either convention converge to the same motion
    path, floating, model, rbd = case
    rng = np.random.default_rng(2)
    q, v = model.random_configuration(rng, 0.5), rng.uniform(-1, 1, model.nv)
    u = rng.uniform(-3, 3, model.nv)
    if floating:
        u[:6] = 0.0  # no force on the free joint: the same ODE in both conventions
    x0 = rbd.state_to_mujoco(np.concatenate([q, v]))
    qm, vm = x0[:model.nq], x0[model.nq:]
    n, T = 200, 0.05
    for _ in range(n):
        xp = rbd.integrator(q, v, u, T / n, scheme)
        xm = rbd.integrator(qm, vm, u, T / n, scheme, output_convention="mujoco")
        q, v, qm, vm = xp[:model.nq], xp[model.nq:], xm[:model.nq], xm[model.nq:]
    err = rel_err(rbd.state_from_mujoco(np.concatenate([qm, vm])), np.concatenate([q, v]))
    if not floating:
        assert err < 1e-12  # no free joint: the two conventions are the same map
    else:  # two discretisations of one motion, apart by the schemes' global errors
        assert err < {"euler": 1e-3, "semi_implicit_euler": 1e-3, "constant_acceleration": 1e-3}.get(scheme, 1e-6), \
            f"{scheme}: {err:.2e}"


def test_no_op_without_free_joints():
    # iiwa (hinges only): identical numbers in both conventions, every scheme, and the costs
    model = rbdkit.robots.load("iiwa")
    rbd = rbdkit.RBD(model)
    rng = np.random.default_rng(0)
    q, v, u = model.random_configuration(rng), rng.normal(size=model.nv), rng.normal(size=model.nv)
    for scheme in SCHEMES:
        for fn in (rbd.integrator, rbd.integrator_gradient):
            np.testing.assert_array_equal(fn(q, v, u, 0.01, scheme, output_convention="mujoco"),
                                          fn(q, v, u, 0.01, scheme))
    x = np.concatenate([q, v])
    xd = np.concatenate([model.random_configuration(rng), rng.normal(size=model.nv)])
    for a, b in ((rbd.quadratic_state_cost_tangent(x, xd, np.ones(2 * model.nv), output_convention="mujoco"),
                  rbd.quadratic_state_cost_tangent(x, xd, np.ones(2 * model.nv))),
                 (rbd.com_cost(q, [0.1, 0, 0.5], np.ones(3), output_convention="mujoco"),
                  rbd.com_cost(q, [0.1, 0, 0.5], np.ones(3))),
                 (rbd.ee_pos_cost(q, [0.1, 0, 0.5], np.ones(3), output_convention="mujoco"),
                  rbd.ee_pos_cost(q, [0.1, 0, 0.5], np.ones(3))),
                 (rbd.momentum_cost(q, v, np.ones(6), np.ones(6), output_convention="mujoco"),
                  rbd.momentum_cost(q, v, np.ones(6), np.ones(6)))):
        for p, r in zip(a, b):
            np.testing.assert_array_equal(p, r)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_gradient_by_finite_differences_in_mujoco_tangent(case, scheme):
    path, floating, model, rbd = case
    nq, nv = model.nq, model.nv
    q, v, u = mj_state(rbd, 13)
    fext = np.random.default_rng(1).uniform(-3, 3, (model.nb, 6))
    dt = 0.02
    kw = dict(f_ext=fext, output_convention="mujoco")
    AB = rbd.integrator_gradient(q, v, u, dt, scheme, **kw)
    x0 = rbd.integrator(q, v, u, dt, scheme, **kw)

    def step(d):
        return rbd.integrator(rbd.mujoco_integrate(q, d[:nv]), v + d[nv:2 * nv], u + d[2 * nv:], dt, scheme, **kw)

    def tangent(x):
        return np.concatenate([rbd.mujoco_difference(x0[:nq], x[:nq]), x[nq:] - x0[nq:]])

    F = np.zeros_like(AB)
    eps = 1e-5
    for k in range(3 * nv):
        d = np.zeros(3 * nv)
        d[k] = eps
        F[:, k] = (tangent(step(d)) - tangent(step(-d))) / (2 * eps)
    assert rel_err(AB, F) < 1e-6, f"{scheme}: {rel_err(AB, F):.2e}"
    np.testing.assert_array_equal(rbd.plant_step_gradient(np.concatenate([q, v]), u, dt, scheme, **kw), AB)


# ------------------------------------------------------------ costs in the MuJoCo convention


def fd_tangent(rbd, f, q, v, eps=1e-6):
    """central differences of f(q, v) (any shape) along MuJoCo's ⊕ and v: (..., 2nv)"""
    nv = rbd.nv
    cols = []
    for k in range(2 * nv):
        d = np.zeros(2 * nv)
        d[k] = eps
        fp = f(rbd.mujoco_integrate(q, d[:nv]), v + d[nv:])
        fm = f(rbd.mujoco_integrate(q, -d[:nv]), v - d[nv:])
        cols.append((np.asarray(fp) - np.asarray(fm)) / (2 * eps))
    return np.stack(cols, axis=-1)


def test_costs_by_finite_differences(case):
    path, floating, model, rbd = case
    nq, nv = model.nq, model.nv
    q, v, _ = mj_state(rbd, 21)
    qd_, vd_, _ = mj_state(rbd, 22)
    kw = dict(output_convention="mujoco")
    rng = np.random.default_rng(5)
    # log-map state cost: exact gradient, Gauss–Newton Hessian Jᵀ Q J
    Q = rng.uniform(0.5, 2, 2 * nv)
    val, g, H = rbd.quadratic_state_cost_tangent(np.concatenate([q, v]), np.concatenate([qd_, vd_]), Q, **kw)
    err = fd_tangent(rbd, lambda a, b: np.concatenate([rbd.mujoco_difference(qd_, a), b - vd_]), q, v)
    e = np.concatenate([rbd.mujoco_difference(qd_, q), v - vd_])
    assert abs(val - 0.5 * e @ (Q * e)) < 1e-12 * max(1, val)
    assert rel_err(g, err.T @ (Q * e)) < 1e-7
    assert rel_err(H, err.T @ (Q[:, None] * err)) < 1e-7
    fv = fd_tangent(rbd, lambda a, b: rbd.quadratic_state_cost_tangent(
        np.concatenate([a, b]), np.concatenate([qd_, vd_]), Q, **kw)[0], q, v)
    assert rel_err(g, fv) < 1e-6
    # position tracking: tangent blocks in [0, nv), velocity and extra quaternion entries zero
    x_pin = rbd.state_from_mujoco(np.concatenate([q, v]))
    for name, pos in (("com", lambda a: rbd.com(rbd.state_from_mujoco(np.concatenate([a, v]))[:nq])),
                      ("ee", lambda a: rbd.end_effector_pose(rbd.state_from_mujoco(np.concatenate([a, v]))[:nq])[..., :3]
                       .reshape(-1)[:3])):
        p_des, W = rng.normal(size=3), rng.uniform(0.5, 2, 3)
        cost = rbd.com_cost if name == "com" else rbd.ee_pos_cost
        val, g, H = cost(q, p_des, W, **kw)
        J = fd_tangent(rbd, lambda a, b: pos(a), q, v)[:, :nv]
        r = pos(q) - p_des
        assert abs(val - 0.5 * r @ (W * r)) < 1e-12 * max(1, val), name
        assert rel_err(g[:nv], J.T @ (W * r)) < 1e-7, name
        assert rel_err(H[:nv, :nv], J.T @ (W[:, None] * J)) < 1e-7, name
        assert not np.any(g[nv:]) and not np.any(H[nv:]) and not np.any(H[:, nv:]), name
    # momentum: r = A(q) Cᵀ qd - h_des with the configuration dependence of Cᵀ kept in J
    h_des, W = rng.normal(size=6), rng.uniform(0.5, 2, 6)

    def momentum(a, b):
        x = rbd.state_from_mujoco(np.concatenate([a, b]))
        return rbd.centroidal_momentum(x[:nq], x[nq:])

    val, g, H = rbd.momentum_cost(q, v, h_des, W, **kw)
    J = fd_tangent(rbd, momentum, q, v)
    r = momentum(q, v) - h_des
    assert abs(val - 0.5 * r @ (W * r)) < 1e-12 * max(1, val)
    assert rel_err(g, J.T @ (W * r)) < 1e-7
    assert rel_err(H, J.T @ (W[:, None] * J)) < 1e-7
    assert x_pin.shape == (nq + nv,)


def test_layout_only_costs_and_barriers(case):
    # quadratic state/input costs and the barriers act coordinate by coordinate on the given vectors
    path, floating, model, rbd = case
    nq, nv = model.nq, model.nv
    q, v, u = mj_state(rbd, 30)
    x, xd = np.concatenate([q, v]), np.concatenate(mj_state(rbd, 31)[:2])
    Q = np.linspace(0.5, 2, nq + nv)
    for a, b in zip(rbd.quadratic_state_cost(x, xd, Q, output_convention="mujoco"),
                    (0.5 * np.sum(Q * (x - xd) ** 2), Q * (x - xd), np.diag(Q))):
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-14)
    np.testing.assert_array_equal(rbd.quadratic_input_cost(u, 0 * u, np.ones(nv), output_convention="mujoco")[1], u)
    lo, hi = q - 1.5, q + 0.5
    ref = rbd.joint_position_barrier(q, lo, hi, 0.1)
    for a, b in zip(rbd.joint_position_barrier(q, lo, hi, 0.1, output_convention="mujoco"), ref):
        np.testing.assert_array_equal(a, b)
    for fn, z in ((rbd.joint_velocity_barrier, v), (rbd.joint_torque_barrier, u)):
        for a, b in zip(fn(z, z - 1, z + 2, 0.1, output_convention="mujoco"), fn(z, z - 1, z + 2, 0.1)):
            np.testing.assert_array_equal(a, b)


def test_bad_output_convention():
    model = rbdkit.robots.load("hyq", floating_base=True)
    rbd = rbdkit.RBD(model)
    rng = np.random.default_rng(0)
    q, v, u = model.random_configuration(rng), np.zeros(model.nv), np.zeros(model.nv)
    x = np.concatenate([q, v])
    calls = [lambda c: rbd.integrator(q, v, u, 0.01, output_convention=c),
             lambda c: rbd.integrator_gradient(q, v, u, 0.01, output_convention=c),
             lambda c: rbd.plant_step(x, u, 0.01, output_convention=c),
             lambda c: rbd.plant_step_gradient(x, u, 0.01, output_convention=c),
             lambda c: rbd.plant_step_hessian(x, u, 0.01, output_convention=c),
             lambda c: rbd.quadratic_state_cost(x, x, np.ones(model.nq + model.nv), output_convention=c),
             lambda c: rbd.quadratic_state_cost_tangent(x, x, np.ones(2 * model.nv), output_convention=c),
             lambda c: rbd.quadratic_input_cost(u, u, np.ones(model.nv), output_convention=c),
             lambda c: rbd.ee_pos_cost(q, np.zeros(3), np.ones(3), output_convention=c),
             lambda c: rbd.com_cost(q, np.zeros(3), np.ones(3), output_convention=c),
             lambda c: rbd.momentum_cost(q, v, np.zeros(6), np.ones(6), output_convention=c),
             lambda c: rbd.joint_position_barrier(q, q - 1, q + 1, 0.1, output_convention=c),
             lambda c: rbd.joint_velocity_barrier(v, v - 1, v + 1, 0.1, output_convention=c),
             lambda c: rbd.joint_torque_barrier(u, u - 1, u + 1, 0.1, output_convention=c)]
    for call in calls:
        for bad in ("MuJoCo", "mj", "", "drake"):
            with pytest.raises(ValueError, match=r"^output_convention: unknown convention .*expected one of "
                                                 r"pinocchio, mujoco"):
                call(bad)
        for bad in (1, None, b"mujoco"):
            with pytest.raises(TypeError, match=r"^output_convention: expected a string"):
                call(bad)
    # a non-unit quaternion names the MuJoCo layout
    qb = q.copy()
    qb[3:7] *= 2
    with pytest.raises(ValueError, match=r"^q: the quaternion of joint .*w x y z, MuJoCo layout"):
        rbd.integrator(qb, v, u, 0.01, output_convention="mujoco")
    with pytest.raises(ValueError, match=r"^x: the quaternion of joint .*w x y z, MuJoCo layout"):
        rbd.plant_step_hessian(np.concatenate([qb, v]), u, 0.01, output_convention="mujoco")
