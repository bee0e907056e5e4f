"""rbdkit's configuration-space (Lie-group) operations against Pinocchio:
integrate, difference, dIntegrate, dDifference on floating-base HyQ and
Atlas and on the spherical-joint test model (fixed and floating base), with
random configurations and tangent steps from exactly zero and 1e-9 up to
rotations well past π; plus round trips, batching, finite-difference checks
of the Jacobians and of d2Integrate.

Agreement with Pinocchio: max|err| <= 1e-9 · max(1, max|reference|).

Quaternion sign (checked against Pinocchio 4.1 before writing these tests):
  * free-flyer joints: Pinocchio's SE(3) integrate flips the result into the
    hemisphere of the input quaternion, as rbdkit does, so the results are
    compared exactly, sign included;
  * spherical joints: Pinocchio's SO(3) integrate returns q·exp(ω) as is,
    whose dot product with q is cos(|ω|/2): it lies in the opposite
    hemisphere whenever cos(|ω|/2) < 0 (π < |ω| < 3π). rbdkit always returns
    the representative in q's hemisphere. So a spherical joint's quaternion
    is compared up to sign, and only where Pinocchio's differs by the sign
    exactly, i.e. where cos(|ω|/2) < 0; elsewhere the signs must match too.
"""

import os

import numpy as np
import pinocchio as pin
import pytest

import rbdkit
from pinref import ROBOTS_DIR, URDF_DIR, Reference, assert_close

CASES = [
    ("hyq-floating", os.path.join(ROBOTS_DIR, "hyq.urdf"), True),
    ("atlas-floating", os.path.join(ROBOTS_DIR, "atlas.urdf"), True),
    ("spherical-fixed", os.path.join(URDF_DIR, "spherical.urdf"), False),
    ("spherical-floating", os.path.join(URDF_DIR, "spherical.urdf"), True),
]
FD_CASES = [c for c in CASES if c[0] in ("hyq-floating", "spherical-floating")]

# norms of every rotation block of the tangent steps: exactly zero, tiny,
# either side of the series/closed-form switch at θ = 1, near, at and past π,
# near 2π and past it
THETAS = [0.0, 1e-9, 1e-5, 0.3, 0.999, 1.001, 2.5, np.pi - 1e-6, np.pi, np.pi + 1e-6, 4.0, 2 * np.pi - 0.1, 7.5]
THETAS_BELOW_PI = [t for t in THETAS if t < np.pi - 1e-7]

_refs = {}


def reference(case):
    if case[0] not in _refs:
        _refs[case[0]] = Reference(case[1], case[2])
    return _refs[case[0]]


@pytest.fixture(scope="module", params=CASES, ids=[c[0] for c in CASES])
def ref(request):
    return reference(request.param)


@pytest.fixture(scope="module", params=FD_CASES, ids=[c[0] for c in FD_CASES])
def fd_ref(request):
    return reference(request.param)


def rotation_blocks(model):
    """(v slice, q slice of the quaternion, joint name, type) of each joint with a rotation"""
    out = []
    for j in model.joints:
        if j["mimic_of"]:
            continue
        if j["type"] == "free":
            out.append((slice(j["v_index"] + 3, j["v_index"] + 6), slice(j["q_index"] + 3, j["q_index"] + 7),
                        j["name"], "free"))
        elif j["type"] == "spherical":
            out.append((slice(j["v_index"], j["v_index"] + 3), slice(j["q_index"], j["q_index"] + 4), j["name"],
                        "spherical"))
    return out


def tangent(model, rng, theta):
    """a random tangent step whose every rotation block has norm theta; the
    other coordinates uniform in ±max(theta, 1e-9) (all zero for theta = 0)"""
    if theta == 0.0:
        return np.zeros(model.nv)
    v = rng.uniform(-1, 1, model.nv) * max(theta, 1e-9)
    for vs, _, _, _ in rotation_blocks(model):
        w = rng.normal(size=3)
        v[vs] = theta * w / np.linalg.norm(w)
    return v


def configurations(model, n, seed):
    rng = np.random.default_rng(seed)
    return [model.random_configuration(rng, scale=np.pi) for _ in range(n)], rng


def quat_dist(a, b):
    """distance of two unit quaternions as rotations (sign ignored)"""
    return min(np.max(np.abs(a - b)), np.max(np.abs(a + b)))


def assert_same_configuration(model, q, q_ref, what, rtol=1e-9):
    """equal as configurations: quaternions compared up to sign"""
    q, q_ref = np.array(q), np.array(q_ref)
    for _, qs, name, _ in rotation_blocks(model):
        if np.max(np.abs(q[qs] + q_ref[qs])) < np.max(np.abs(q[qs] - q_ref[qs])):
            q[qs] = -q[qs]
    assert_close(q, q_ref, what, rtol)


# ------------------------------------------------------------ against Pinocchio


def test_integrate_matches_pinocchio(ref):
    m, G = ref.model, ref.G
    rbd = rbdkit.RBD(m)
    qs, rng = configurations(m, 6, seed=10)
    sign_flips = 0
    for q in qs:
        for theta in THETAS:
            v = tangent(m, rng, theta)
            ours = rbd.integrate(q, v)
            theirs = pin.integrate(ref.pin, ref.q(q), G @ v)
            mapped = ref.q(ours)
            for _, qsl, name, kind in rotation_blocks(m):
                a = ours[qsl]
                pin_j = ref.pin.joints[ref.pin.getJointId(name)]
                pq = slice(pin_j.idx_q + (3 if kind == "free" else 0), pin_j.idx_q + (7 if kind == "free" else 4))
                b = theirs[pq]
                # rbdkit's result is a unit quaternion in the hemisphere of the input one
                assert a @ q[qsl] >= -1e-12, f"{name}: integrate left the hemisphere of q (theta={theta})"
                assert abs(np.linalg.norm(a) - 1) < 1e-14, f"{name}: result not unit ({np.linalg.norm(a)})"
                c = np.cos(theta / 2)  # = the dot product of q·exp(ω) with q
                if abs(c) < 1e-12:
                    # |ω| = π exactly: the result is orthogonal to q up to
                    # rounding, so either library may pick either sign
                    if np.max(np.abs(a + b)) < np.max(np.abs(a - b)):
                        mapped[pq] = -mapped[pq]
                elif kind == "spherical" and c < 0:
                    # Pinocchio's SO(3) integrate: q·exp(ω) with no hemisphere fix
                    assert_close(a, -b, f"{name} quaternion (Pinocchio's sign flipped, theta={theta})")
                    mapped[pq] = -mapped[pq]
                    sign_flips += 1
                else:
                    # free flyer (Pinocchio's SE(3) keeps q's hemisphere) or cos(|ω|/2) > 0
                    assert_close(a, b, f"{name} quaternion (theta={theta})")
            assert_close(mapped, theirs, f"integrate (theta={theta})")
    if any(k == "spherical" for *_, k in rotation_blocks(m)):
        assert sign_flips > 0  # the cases past π were exercised


def test_difference_matches_pinocchio(ref):
    m, G = ref.model, ref.G
    rbd = rbdkit.RBD(m)
    qs, rng = configurations(m, 8, seed=11)
    pairs = list(zip(qs[:-1], qs[1:]))
    # pairs a given step apart, including steps near π (below it: the log is unique)
    for q in qs[:3]:
        for theta in THETAS_BELOW_PI + [np.pi - 1e-4]:
            pairs.append((q, rbd.integrate(q, tangent(m, rng, theta))))
    for q0, q1 in pairs:
        d = rbd.difference(q0, q1)
        assert_close(G @ d, pin.difference(ref.pin, ref.q(q0), ref.q(q1)), "difference")


def test_difference_past_pi_wraps_like_pinocchio(ref):
    # a step of norm θ > π ends where a step of norm 2π - θ the other way ends
    m, G = ref.model, ref.G
    rbd = rbdkit.RBD(m)
    qs, rng = configurations(m, 3, seed=12)
    for q in qs:
        for theta in (np.pi + 1e-3, 4.0, 2 * np.pi - 0.1):
            v = tangent(m, rng, theta)
            q1 = rbd.integrate(q, v)
            d = rbd.difference(q, q1)
            assert_close(G @ d, pin.difference(ref.pin, ref.q(q), ref.q(q1)), f"difference (theta={theta})")
            for vs, _, name, _ in rotation_blocks(m):
                w = v[vs]
                assert_close(d[vs], -(2 * np.pi - theta) * w / np.linalg.norm(w), f"{name} wrapped rotation", 1e-8)


def test_difference_ignores_quaternion_sign(ref):
    m = ref.model
    rbd = rbdkit.RBD(m)
    qs, _ = configurations(m, 4, seed=13)
    for q0, q1 in zip(qs[:-1], qs[1:]):
        q1n, q0n = q1.copy(), q0.copy()
        for _, qsl, _, _ in rotation_blocks(m):
            q1n[qsl] *= -1
            q0n[qsl] *= -1
        d = rbd.difference(q0, q1)
        assert_close(rbd.difference(q0, q1n), d, "difference with -q1's quaternions")
        assert_close(rbd.difference(q0n, q1), d, "difference with -q0's quaternions")
        assert_close(rbd.difference(q0n, q1n), d, "difference with both negated")
        for arg in ("from", "to"):
            J = rbd.dDifference(q0, q1, arg)
            assert_close(rbd.dDifference(q0n, q1n, arg), J, f"dDifference({arg}) with negated quaternions")
            assert_close(rbd.dDifference(q0, q1n, arg), J, f"dDifference({arg}) with -q1's quaternions")


@pytest.mark.parametrize("arg", ["q", "v"])
def test_dintegrate_matches_pinocchio(ref, arg):
    m, G = ref.model, ref.G
    rbd = rbdkit.RBD(m)
    pin_arg = pin.ARG0 if arg == "q" else pin.ARG1
    qs, rng = configurations(m, 4, seed=14)
    for q in qs:
        for theta in THETAS:
            v = tangent(m, rng, theta)
            J = rbd.dIntegrate(q, v, with_respect_to=arg)
            J_pin = pin.dIntegrate(ref.pin, ref.q(q), G @ v, pin_arg)
            assert J.shape == (m.nv, m.nv)
            assert_close(J, G.T @ J_pin @ G, f"dIntegrate/d{arg} (theta={theta})")


@pytest.mark.parametrize("arg", ["from", "to"])
def test_ddifference_matches_pinocchio(ref, arg):
    m, G = ref.model, ref.G
    rbd = rbdkit.RBD(m)
    pin_arg = pin.ARG0 if arg == "from" else pin.ARG1
    qs, rng = configurations(m, 6, seed=15)
    pairs = list(zip(qs[:-1], qs[1:])) + [(q, q) for q in qs[:2]]
    for q in qs[:2]:
        for theta in THETAS_BELOW_PI + [np.pi - 1e-3]:
            pairs.append((q, rbd.integrate(q, tangent(m, rng, theta))))
    for q0, q1 in pairs:
        J = rbd.dDifference(q0, q1, with_respect_to=arg)
        J_pin = pin.dDifference(ref.pin, ref.q(q0), ref.q(q1), pin_arg)
        assert_close(J, G.T @ J_pin @ G, f"dDifference/d{arg}")


def test_jacobians_at_identity(ref):
    m = ref.model
    rbd = rbdkit.RBD(m)
    I = np.eye(m.nv)
    qs, _ = configurations(m, 2, seed=16)
    for q in qs + [m.neutral()]:
        z = np.zeros(m.nv)
        # up to rounding: the quaternions are renormalised
        assert_close(rbd.integrate(q, z), q, "q ⊕ 0", 1e-14)
        assert_close(rbd.difference(q, q), z, "q ⊖ q", 1e-14)
        assert_close(rbd.dIntegrate(q, z, "q"), I, "dIntegrate/dq at v = 0", 1e-15)
        assert_close(rbd.dIntegrate(q, z, "v"), I, "dIntegrate/dv at v = 0", 1e-15)
        assert_close(rbd.dDifference(q, q, "to"), I, "dDifference/dq1 at q0 = q1", 1e-15)
        assert_close(rbd.dDifference(q, q, "from"), -I, "dDifference/dq0 at q0 = q1", 1e-15)


# ------------------------------------------------------------ round trips


def test_difference_inverts_integrate(ref):
    m = ref.model
    rbd = rbdkit.RBD(m)
    qs, rng = configurations(m, 5, seed=20)
    for q in qs:
        for theta in THETAS_BELOW_PI + [np.pi - 1e-4]:
            v = tangent(m, rng, theta)
            assert_close(rbd.difference(q, rbd.integrate(q, v)), v, f"difference(q, q ⊕ v) (theta={theta})", 1e-8)


def test_integrate_inverts_difference(ref):
    m = ref.model
    rbd = rbdkit.RBD(m)
    qs, _ = configurations(m, 8, seed=21)
    for q0, q1 in zip(qs[:-1], qs[1:]):
        back = rbd.integrate(q0, rbd.difference(q0, q1))
        assert_same_configuration(m, back, q1, "q0 ⊕ (q1 ⊖ q0)")
        # and the result keeps q0's hemisphere
        for _, qsl, name, _ in rotation_blocks(m):
            assert back[qsl] @ q0[qsl] >= -1e-12, name


def test_batch_equals_single(ref):
    m = ref.model
    rbd = rbdkit.RBD(m)
    qs, rng = configurations(m, 6, seed=22)
    Q0, Q1 = np.stack(qs[:3]), np.stack(qs[3:])
    V = np.stack([tangent(m, rng, t) for t in (0.0, 1.5, 4.0)])
    B = 3
    Qn = rbd.integrate(Q0, V)
    D = rbd.difference(Q0, Q1)
    assert Qn.shape == (B, m.nq) and D.shape == (B, m.nv)
    Jq, Jv = rbd.dIntegrate(Q0, V, "q"), rbd.dIntegrate(Q0, V, "v")
    Jf, Jt = rbd.dDifference(Q0, Q1, "from"), rbd.dDifference(Q0, Q1, "to")
    H = rbd.d2Integrate(Q0, V, "v", "v")
    assert Jq.shape == Jv.shape == Jf.shape == Jt.shape == (B, m.nv, m.nv)
    assert H.shape == (B, m.nv, m.nv, m.nv)
    for k in range(B):
        np.testing.assert_array_equal(Qn[k], rbd.integrate(Q0[k], V[k]))
        np.testing.assert_array_equal(D[k], rbd.difference(Q0[k], Q1[k]))
        np.testing.assert_array_equal(Jq[k], rbd.dIntegrate(Q0[k], V[k], "q"))
        np.testing.assert_array_equal(Jv[k], rbd.dIntegrate(Q0[k], V[k], "v"))
        np.testing.assert_array_equal(Jf[k], rbd.dDifference(Q0[k], Q1[k], "from"))
        np.testing.assert_array_equal(Jt[k], rbd.dDifference(Q0[k], Q1[k], "to"))
        np.testing.assert_array_equal(H[k], rbd.d2Integrate(Q0[k], V[k], "v", "v"))
    # an unbatched argument is broadcast against a batched one
    for k in range(B):
        np.testing.assert_array_equal(rbd.integrate(Q0, V[1])[k], rbd.integrate(Q0[k], V[1]))
        np.testing.assert_array_equal(rbd.difference(Q0[0], Q1)[k], rbd.difference(Q0[0], Q1[k]))


# ------------------------------------------------------------ finite differences


EPS = 1e-6


def fd_dintegrate(rbd, q, v, arg):
    """central differences of integrate in the tangent space (through difference)"""
    nv = rbd.nv
    J = np.empty((nv, nv))
    q_next = rbd.integrate(q, v)
    for k in range(nv):
        e = np.zeros(nv)
        e[k] = EPS
        if arg == "v":
            plus, minus = rbd.integrate(q, v + e), rbd.integrate(q, v - e)
        else:
            plus, minus = rbd.integrate(rbd.integrate(q, e), v), rbd.integrate(rbd.integrate(q, -e), v)
        J[:, k] = (rbd.difference(q_next, plus) - rbd.difference(q_next, minus)) / (2 * EPS)
    return J


def fd_ddifference(rbd, q0, q1, arg):
    nv = rbd.nv
    J = np.empty((nv, nv))
    for k in range(nv):
        e = np.zeros(nv)
        e[k] = EPS
        if arg == "to":
            plus, minus = rbd.difference(q0, rbd.integrate(q1, e)), rbd.difference(q0, rbd.integrate(q1, -e))
        else:
            plus, minus = rbd.difference(rbd.integrate(q0, e), q1), rbd.difference(rbd.integrate(q0, -e), q1)
        J[:, k] = (plus - minus) / (2 * EPS)
    return J


def test_dintegrate_by_finite_differences():
    ref = reference(CASES[3])  # spherical-floating
    rbd = rbdkit.RBD(ref.model)
    qs, rng = configurations(ref.model, 3, seed=30)
    for q in qs:
        for theta in (0.0, 1e-9, 0.5, 1.001, 2.5, 3.0):  # |step| + ε stays below π for the log
            v = tangent(ref.model, rng, theta)
            for arg in ("q", "v"):
                assert_close(rbd.dIntegrate(q, v, arg), fd_dintegrate(rbd, q, v, arg),
                             f"dIntegrate/d{arg} vs finite differences (theta={theta})", 1e-6)


def test_ddifference_by_finite_differences():
    ref = reference(CASES[3])  # spherical-floating
    m = ref.model
    rbd = rbdkit.RBD(m)
    qs, rng = configurations(m, 4, seed=31)
    pairs = [(q, q) for q in qs[:1]] + list(zip(qs[:-1], qs[1:]))
    pairs += [(qs[0], rbd.integrate(qs[0], tangent(m, rng, t))) for t in (1e-9, 0.999, 2.5, 3.0)]
    for q0, q1 in pairs:
        for arg in ("from", "to"):
            assert_close(rbd.dDifference(q0, q1, arg), fd_ddifference(rbd, q0, q1, arg),
                         f"dDifference/d{arg} vs finite differences", 1e-6)


def fd_d2integrate(rbd, q, v, arg1, arg2):
    nv = rbd.nv
    H = np.empty((nv, nv, nv))
    for k in range(nv):
        e = np.zeros(nv)
        e[k] = EPS
        if arg2 == "v":
            plus, minus = rbd.dIntegrate(q, v + e, arg1), rbd.dIntegrate(q, v - e, arg1)
        else:
            plus, minus = rbd.dIntegrate(rbd.integrate(q, e), v, arg1), rbd.dIntegrate(rbd.integrate(q, -e), v, arg1)
        H[:, :, k] = (plus - minus) / (2 * EPS)
    return H


@pytest.mark.parametrize("arg1", ["q", "v"])
@pytest.mark.parametrize("arg2", ["q", "v"])
def test_d2integrate_by_finite_differences(fd_ref, arg1, arg2):
    m = fd_ref.model
    rbd = rbdkit.RBD(m)
    qs, rng = configurations(m, 2, seed=40)
    for q in qs:
        for theta in (0.0, 1e-9, 0.3, 0.999, 1.001, 2.5, np.pi, 4.0, 7.5):
            v = tangent(m, rng, theta)
            H = rbd.d2Integrate(q, v, arg1, arg2)
            assert H.shape == (m.nv, m.nv, m.nv)
            assert np.all(np.isfinite(H))
            assert_close(H, fd_d2integrate(rbd, q, v, arg1, arg2),
                         f"d2Integrate({arg1}, {arg2}) vs finite differences (theta={theta})", 1e-6)


def test_d2integrate_at_zero(fd_ref):
    """at v = 0: dIntegrate/dv = Jr(v) = I - ½ ad(v) + …, dIntegrate/dq =
    Ad(exp(v)⁻¹) = I - ad(v) + …, so ∂/∂v_k is -½ ad(e_k) and -ad(e_k) on
    each joint's block (ad on SE(3) twists [ν; ω], [ω]× on SO(3)); every
    derivative along q vanishes (the Jacobians do not depend on q)"""
    m = fd_ref.model
    rbd = rbdkit.RBD(m)
    nv = m.nv

    def skew(w):
        return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])

    ad = np.zeros((nv, nv, nv))  # ad[:, :, k]: the block-diagonal ad(e_k)
    for j in m.joints:
        o = j["v_index"]
        for c in range(j["nv"]):
            e = np.zeros(j["nv"])
            e[c] = 1.0
            if j["type"] == "free":
                A = np.zeros((6, 6))
                A[:3, :3] = A[3:, 3:] = skew(e[3:])
                A[:3, 3:] = skew(e[:3])
                ad[o:o + 6, o:o + 6, o + c] = A
            elif j["type"] == "spherical":
                ad[o:o + 3, o:o + 3, o + c] = skew(e)
    qs, _ = configurations(m, 2, seed=41)
    z = np.zeros(nv)
    for q in qs + [m.neutral()]:
        assert_close(rbd.d2Integrate(q, z, "v", "v"), -0.5 * ad, "d2Integrate(v, v) at v = 0")
        assert_close(rbd.d2Integrate(q, z, "q", "v"), -ad, "d2Integrate(q, v) at v = 0")
        for arg1 in ("q", "v"):
            assert_close(rbd.d2Integrate(q, z, arg1, "q"), np.zeros((nv, nv, nv)), f"d2Integrate({arg1}, q) at v = 0")
            for arg2 in ("q", "v"):
                assert_close(rbd.d2Integrate(q, z, arg1, arg2), fd_d2integrate(rbd, q, z, arg1, arg2),
                             f"d2Integrate({arg1}, {arg2}) at v = 0 vs finite differences", 1e-6)


def test_d2integrate_default_arguments(fd_ref):
    m = fd_ref.model
    rbd = rbdkit.RBD(m)
    qs, rng = configurations(m, 1, seed=42)
    v = tangent(m, rng, 1.3)
    np.testing.assert_array_equal(rbd.d2Integrate(qs[0], v), rbd.d2Integrate(qs[0], v, "v", "v"))
