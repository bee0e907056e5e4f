"""The plant layer's costs and barriers: values against NumPy and Pinocchio,
gradients against central finite differences (through integrate on q),
Hessians against their closed forms, and the documented non-interior and
bad-input behaviour."""

import numpy as np
import pinocchio as pin
import pytest

import rbdkit
from pinref import ROBOTS_DIR, URDF_DIR, Reference, assert_close
import os

CASES = [("iiwa-fixed", os.path.join(ROBOTS_DIR, "iiwa.urdf"), False),
         ("hyq-floating", os.path.join(ROBOTS_DIR, "hyq.urdf"), True),
         ("spherical-floating", os.path.join(URDF_DIR, "spherical.urdf"), True)]


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def ref(request):
    return Reference(request.param[1], request.param[2])


def tangent_fd(rbd, f, q, eps=1e-6):
    cols = []
    for k in range(rbd.nv):
        d = np.zeros(rbd.nv)
        d[k] = eps
        cols.append((f(rbd.integrate(q, d)) - f(rbd.integrate(q, -d))) / (2 * eps))
    return np.stack(cols, -1)


def test_quadratic_costs(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    rng = np.random.default_rng(0)
    nx = m.nq + m.nv
    x, xd, Q = rng.normal(size=nx), rng.normal(size=nx), rng.uniform(0, 3, nx)
    v, g, H = rbd.quadratic_state_cost(x, xd, Q)
    assert np.isclose(v, 0.5 * np.sum(Q * (x - xd) ** 2))
    assert_close(g, Q * (x - xd), "state grad")
    assert_close(H, np.diag(Q), "state H")
    u, ud, R = rng.normal(size=m.nv), rng.normal(size=m.nv), rng.uniform(0, 3, m.nv)
    v, g, H = rbd.quadratic_input_cost(u, ud, R)
    assert np.isclose(v, 0.5 * np.sum(R * (u - ud) ** 2)) and g.shape == (m.nv,) and H.shape == (m.nv, m.nv)
    # batched
    V, G, HH = rbd.quadratic_input_cost(np.stack([u, ud]), ud, R)
    assert V.shape == (2,) and V[1] == 0 and G.shape == (2, m.nv) and HH.shape == (2, m.nv, m.nv)


def test_quadratic_state_cost_tangent(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    rng = np.random.default_rng(1)
    q, qdes = m.random_configuration(rng), m.random_configuration(rng)
    qd, qd_des = rng.normal(size=m.nv), rng.normal(size=m.nv)
    Q = rng.uniform(0.5, 2, 2 * m.nv)
    x, xd = np.concatenate([q, qd]), np.concatenate([qdes, qd_des])
    v, g, H = rbd.quadratic_state_cost_tangent(x, xd, Q)
    e = np.concatenate([rbd.difference(qdes, q), qd - qd_des])
    assert np.isclose(v, 0.5 * np.sum(Q * e * e))
    # the error map against Pinocchio's difference (the Lie-group log)
    assert_close(ref.G @ e[:m.nv], pin.difference(ref.pin, ref.q(qdes), ref.q(q)), "log-map error")
    # gradient by finite differences, Gauss–Newton Hessian from dDifference
    cost = lambda qq: rbd.quadratic_state_cost_tangent(np.concatenate([qq, qd]), xd, Q)[0]
    assert_close(g[:m.nv], tangent_fd(rbd, cost, q), "tangent grad q", 1e-6)
    assert_close(g[m.nv:], Q[m.nv:] * (qd - qd_des), "tangent grad qd")
    J = rbd.dDifference(qdes, q, "to")
    assert_close(H[:m.nv, :m.nv], J.T @ np.diag(Q[:m.nv]) @ J, "GN Hessian")
    assert_close(H[m.nv:, m.nv:], np.diag(Q[m.nv:]), "velocity block")


def test_ee_pos_cost(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    rng = np.random.default_rng(2)
    q, p_des, W = m.random_configuration(rng), rng.normal(size=3), rng.uniform(0.5, 2, 3)
    offset = np.array([0.0, 0.0, 0.1])
    v, g, H = rbd.ee_pos_cost(q, p_des, W, ee_offset=offset)
    nx = m.nq + m.nv
    assert g.shape == (nx,) and H.shape == (nx, nx)
    # the first leaf body's tool point, from Pinocchio's placement of that joint
    body = [b for b in range(m.nb) if b not in m.body_parents][0]
    pin.forwardKinematics(ref.pin, ref.data, ref.q(q))
    M = ref.data.oMi[ref.joint_id(body)]
    p = M.rotation @ offset + M.translation
    assert np.isclose(v, 0.5 * np.sum(W * (p - p_des) ** 2), rtol=1e-12)
    cost = lambda qq: rbd.ee_pos_cost(qq, p_des, W, ee_offset=offset)[0]
    assert_close(g[:m.nv], tangent_fd(rbd, cost, q), "ee grad", 1e-6)
    assert np.all(g[m.nv:] == 0)
    Jp = rbd.end_effector_pose_gradient(q, ee_offsets=offset)[0, :3]
    assert_close(H[:m.nv, :m.nv], Jp.T @ np.diag(W) @ Jp, "ee GN Hessian")
    assert np.all(H[m.nv:, :] == 0) and np.all(H[:, m.nv:] == 0)


def test_barriers():
    model = rbdkit.robots.load("iiwa")
    rbd = rbdkit.RBD(model)
    rng = np.random.default_rng(3)
    lo, hi = model.lower, model.upper
    q = 0.5 * (lo + hi) + 0.3 * (hi - lo) * rng.uniform(-1, 1, model.nq)
    v, g, h = rbd.joint_position_barrier(q, lo, hi, 0.1)
    assert np.isclose(v, -0.1 * np.sum(np.log(q - lo) + np.log(hi - q)))
    eps = 1e-6
    fd = np.array([(rbd.joint_position_barrier(q + eps * e, lo, hi, 0.1)[0] -
                    rbd.joint_position_barrier(q - eps * e, lo, hi, 0.1)[0]) / (2 * eps) for e in np.eye(model.nq)])
    assert_close(g, fd, "barrier grad", 1e-6)
    fd2 = np.array([(rbd.joint_position_barrier(q + eps * e, lo, hi, 0.1)[1] -
                     rbd.joint_position_barrier(q - eps * e, lo, hi, 0.1)[1]) / (2 * eps) for e in np.eye(model.nq)])
    assert_close(h, np.diag(fd2), "barrier Hessian diagonal", 1e-6)
    # infinite bounds contribute nothing
    inf = np.full(model.nv, np.inf)
    assert rbd.joint_velocity_barrier(np.ones(model.nv), -inf, inf, 1.0)[0] == 0
    v2, g2, _ = rbd.joint_torque_barrier(np.ones(model.nv), -inf, np.full(model.nv, 2.0), 1.0)
    assert np.isclose(v2, -model.nv * np.log(1.0)) and np.allclose(g2, 1.0)
    # outside the open interval: +inf and NaN derivatives for that coordinate only
    qb = q.copy()
    qb[2] = hi[2]
    v3, g3, h3 = rbd.joint_position_barrier(qb, lo, hi, 0.1)
    assert v3 == np.inf and np.isnan(g3[2]) and np.isnan(h3[2]) and np.all(np.isfinite(np.delete(g3, 2)))
    # bad bounds and weights
    with pytest.raises(ValueError, match="^mu: expected a positive"):
        rbd.joint_position_barrier(q, lo, hi, 0.0)
    with pytest.raises(ValueError, match="^lower, upper: expected lower < upper"):
        rbd.joint_position_barrier(q, hi, lo, 0.1)
    with pytest.raises(ValueError, match="^q: expected shape"):
        rbd.joint_position_barrier(q[:3], lo, hi, 0.1)


def test_cost_bad_input():
    model = rbdkit.robots.load("hyq", floating_base=True)
    rbd = rbdkit.RBD(model)
    nx = model.nq + model.nv
    x = np.concatenate([model.neutral(), np.zeros(model.nv)])
    with pytest.raises(ValueError, match="^Q: expected shape"):
        rbd.quadratic_state_cost(x, x, np.ones(model.nv))
    with pytest.raises(ValueError, match="^Q: expected non-negative weights"):
        rbd.quadratic_state_cost(x, x, -np.ones(nx))
    with pytest.raises(ValueError, match="^x_des: expected finite"):
        rbd.quadratic_state_cost(x, np.full(nx, np.nan), np.ones(nx))
    bad = x.copy()
    bad[3:7] = 0
    with pytest.raises(ValueError, match="^x: the quaternion of joint 'root_joint'"):
        rbd.quadratic_state_cost_tangent(bad, x, np.ones(2 * model.nv))
    with pytest.raises(ValueError, match="^W: expected shape"):
        rbd.ee_pos_cost(model.neutral(), np.zeros(3), np.ones(2))
    with pytest.raises(ValueError, match="^ee_joint_name"):
        rbd.ee_pos_cost(model.neutral(), np.zeros(3), np.ones(3), ee_joint_name="nope")
    with pytest.raises(ValueError, match="^ee_offset: expected shape"):
        rbd.ee_pos_cost(model.neutral(), np.zeros(3), np.ones(3), ee_offset=np.zeros(2))


def test_com_cost(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    rng = np.random.default_rng(5)
    q, p_des, W = m.random_configuration(rng), rng.normal(size=3), rng.uniform(0.5, 2, 3)
    v, g, H = rbd.com_cost(q, p_des, W)
    c = pin.centerOfMass(ref.pin, ref.data, ref.q(q))
    assert np.isclose(v, 0.5 * np.sum(W * (c - p_des) ** 2), rtol=1e-12)
    cost = lambda qq: rbd.com_cost(qq, p_des, W)[0]
    assert_close(g[:m.nv], tangent_fd(rbd, cost, q), "com grad", 1e-6)
    J = rbd.jacobian_com(q)
    assert_close(H[:m.nv, :m.nv], J.T @ np.diag(W) @ J, "com GN Hessian")


def test_momentum_cost(ref):
    rbd = rbdkit.RBD(ref.model)
    m = ref.model
    rng = np.random.default_rng(6)
    q, qd = m.random_configuration(rng), rng.normal(size=m.nv)
    h_des, W = rng.normal(size=6), rng.uniform(0.5, 2, 6)
    v, g, H = rbd.momentum_cost(q, qd, h_des, W)
    assert g.shape == (2 * m.nv,) and H.shape == (2 * m.nv, 2 * m.nv)
    pin.computeCentroidalMomentum(ref.pin, ref.data, ref.q(q), ref.v(qd))
    r = ref.data.hg.vector - h_des
    assert np.isclose(v, 0.5 * np.sum(W * r * r), rtol=1e-12)
    # exact gradient in [δq | δqd], by finite differences
    cost_q = lambda qq: rbd.momentum_cost(qq, qd, h_des, W)[0]
    assert_close(g[:m.nv], tangent_fd(rbd, cost_q, q), "momentum grad q", 1e-6)
    fdv = np.array([(rbd.momentum_cost(q, qd + 1e-6 * e, h_des, W)[0] - rbd.momentum_cost(q, qd - 1e-6 * e, h_des,
                                                                                         W)[0]) / 2e-6
                    for e in np.eye(m.nv)])
    assert_close(g[m.nv:], fdv, "momentum grad qd", 1e-6)
    # Gauss–Newton Hessian from the full residual Jacobian J = [(dA/dq) qd | A]
    A, _ = rbd.ccrba(q, qd)
    J = np.hstack([np.einsum("rjk,j->rk", rbd.dccrba(q), qd), A])
    assert_close(H, J.T @ np.diag(W) @ J, "momentum GN Hessian")
