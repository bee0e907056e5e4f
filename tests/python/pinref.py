"""Pinocchio references for rbdkit models.

pin_reference(path, floating_base) builds a Pinocchio model of the same URDF
and the map between the two coordinate systems:

  * Pinocchio reads standard URDF; the joint types it does not read from URDF
    are rebuilt by hand: spherical -> JointModelSpherical, helical/screw ->
    JointModelHelicalUnaligned(axis, pitch), planar (normal z) -> a
    prismatic-x, prismatic-y, revolute-z chain with massless links (the
    decomposition the URDF's planar joint means);
  * Pinocchio orders sibling joints by name, rbdkit by document order, so
    coordinates are matched by joint name;
  * Pinocchio's continuous joints use (cos, sin) coordinates;
  * mimic joints are independent joints in the Pinocchio model, and
    v_pin = G v, q_pin = map(q): reduced quantities are Gᵀ(·)G; with
    pin_mimic=True Pinocchio's own mimic joints (no coordinates) are used
    instead, and G is a permutation.
"""

import os
import re
import tempfile

import numpy as np
import pinocchio as pin

import rbdkit

HERE = os.path.dirname(os.path.abspath(__file__))
URDF_DIR = os.path.join(HERE, "..", "urdf")
ROBOTS_DIR = os.path.join(HERE, "..", "..", "robots")


def _expand_planar(xml):
    """planar joints (normal z) -> prismatic x, prismatic y, revolute z with
    massless intermediate links named like rbdkit's sub-joints"""
    out = xml
    for m in re.finditer(r'<joint name="([^"]+)" type="planar">(.*?)</joint>', xml, re.S):
        name, body = m.group(1), m.group(2)
        assert re.search(r'<axis xyz="0 0 1"/>', body), "the test harness expands planar joints with normal z only"
        parent = re.search(r'<parent link="([^"]+)"/>', body).group(1)
        child = re.search(r'<child link="([^"]+)"/>', body).group(1)
        origin = re.search(r"<origin[^>]*/>", body).group(0)
        lx, ly = f"{name}__x_link", f"{name}__y_link"
        rep = (f'<link name="{lx}"/><link name="{ly}"/>'
               f'<joint name="{name}_x" type="prismatic"><parent link="{parent}"/><child link="{lx}"/>{origin}'
               f'<axis xyz="1 0 0"/><limit lower="-10" upper="10" effort="1" velocity="1"/></joint>'
               f'<joint name="{name}_y" type="prismatic"><parent link="{lx}"/><child link="{ly}"/>'
               f'<axis xyz="0 1 0"/><limit lower="-10" upper="10" effort="1" velocity="1"/></joint>'
               f'<joint name="{name}_rot" type="continuous"><parent link="{ly}"/><child link="{child}"/>'
               f'<axis xyz="0 0 1"/></joint>')
        out = out.replace(m.group(0), rep)
    return out


def _placeholders(xml):
    """spherical / helical joints -> continuous placeholders; returns the
    new text and {name: JointModel} to put back"""
    replace = {}
    for m in re.finditer(r'<joint name="([^"]+)" type="(spherical|helical|screw)">(.*?)</joint>', xml, re.S):
        name, typ, body = m.groups()
        if typ == "spherical":
            replace[name] = pin.JointModelSpherical()
        else:
            ax = re.search(r'<axis xyz="([^"]+)"(?: pitch="([^"]+)")?/>', body)
            axis = np.array([float(x) for x in ax.group(1).split()])
            pitch = float(ax.group(2) or 0.0)
            replace[name] = pin.JointModelHelicalUnaligned(axis / np.linalg.norm(axis), pitch)
    xml = re.sub(r'type="(spherical|helical|screw)"', 'type="continuous"', xml)
    return xml, replace


def _rebuild(pm, replace):
    """a copy of pm with the joints named in `replace` swapped"""
    m = pin.Model()
    m.name = pm.name
    for jid in range(1, pm.njoints):
        name = pm.names[jid]
        jm = replace.get(name, pm.joints[jid])
        new = m.addJoint(pm.parents[jid], jm, pm.jointPlacements[jid], name)
        m.appendBodyToJoint(new, pm.inertias[jid], pin.SE3.Identity())
    # the frames (links, joints, merged fixed links) under the same ids; their
    # inertias are already in the joints' inertias
    for f in list(pm.frames)[1:]:
        m.addFrame(pin.Frame(f.name, f.parentJoint, f.parentFrame, f.placement, f.type, f.inertia), False)
    return m


class Reference:
    """A Pinocchio model mirroring an rbdkit model."""

    def __init__(self, path, floating_base=False, mimic=True, pin_mimic=False):
        self.model = rbdkit.Model.from_urdf(path, floating_base=floating_base, mimic=mimic)
        with open(path) as f:
            xml = f.read()
        xml = _expand_planar(xml)
        xml, replace = _placeholders(xml)
        with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
            f.write(xml)
            tmp = f.name
        try:
            # the free-flyer under rbdkit's name for it (root_joint, or a
            # unique variant when the file has a joint of that name)
            kw = {"mimic": True} if pin_mimic else {}
            pm = (pin.buildModelFromUrdf(tmp, pin.JointModelFreeFlyer(), self.model.joints[0]["name"], **kw)
                  if floating_base else pin.buildModelFromUrdf(tmp, **kw))
        finally:
            os.unlink(tmp)
        self.pin = _rebuild(pm, replace) if replace else pm
        self.data = self.pin.createData()
        self._build_map()

    def _build_map(self):
        m, pm = self.model, self.pin
        self.G = np.zeros((pm.nv, m.nv))
        self.body_of_joint = {}  # pin joint id -> rbdkit body index
        self.entries = []
        for jid in range(1, pm.njoints):
            name = pm.names[jid]
            j = m.joint(name)
            self.body_of_joint[jid] = j["body"]
            pj = pm.joints[jid]
            if pj.nv == 0:  # a Pinocchio mimic joint: no coordinates of its own
                assert j["mimic_of"], f"{name} is a mimic joint in Pinocchio only"
                continue
            self.entries.append((j, pj.idx_q, pj.idx_v, pj.nq, pj.nv))
            if j["mimic_of"]:
                self.G[pj.idx_v, j["v_index"]] = j["multiplier"]
            else:
                self.G[pj.idx_v:pj.idx_v + pj.nv, j["v_index"]:j["v_index"] + j["nv"]] = np.eye(pj.nv)
        self.bodies = [self.body_of_joint[jid] for jid in range(1, pm.njoints)]

    def q(self, q):
        """rbdkit configuration -> Pinocchio configuration"""
        out = np.zeros(self.pin.nq)
        for j, iq, iv, nq, nv in self.entries:
            if j["mimic_of"]:
                x = np.array([j["multiplier"] * q[j["q_index"]] + j["offset"]])
            else:
                x = q[j["q_index"]:j["q_index"] + j["nq"]]
            if nq == 2 and len(x) == 1:  # Pinocchio's unbounded revolute: (cos, sin)
                x = np.array([np.cos(x[0]), np.sin(x[0])])
            out[iq:iq + nq] = x
        return out

    def v(self, v):
        return self.G @ v

    def frame_id(self, name):
        """Pinocchio frame id of an rbdkit frame name; a planar joint's frame
        is the frame of its rotational sub-joint '<name>_rot'"""
        for n in (name, name + "_rot"):
            if self.pin.existFrame(n):
                return self.pin.getFrameId(n)
        raise KeyError(f"no Pinocchio frame for rbdkit frame '{name}'")

    def joint_id(self, body):
        """Pinocchio joint id moving rbdkit body `body`"""
        return next(jid for jid, b in self.body_of_joint.items() if b == body)

    def fext(self, f):
        """rbdkit (nb, 6) body-frame forces -> Pinocchio per-joint forces"""
        out = pin.StdVec_Force()
        out.append(pin.Force.Zero())
        for jid in range(1, self.pin.njoints):
            out.append(pin.Force(f[self.body_of_joint[jid]]))
        return out

    def set_gravity(self, g):
        self.pin.gravity.linear = np.array([0.0, 0.0, g])

    # ---- reduced-coordinate references
    def rnea(self, q, v, a, g=-9.81, fext=None):
        self.set_gravity(g)
        args = (self.pin, self.data, self.q(q), self.v(v), self.v(a))
        tau = pin.rnea(*args, self.fext(fext)) if fext is not None else pin.rnea(*args)
        # Pinocchio's RNEA keeps accelerations with the fictitious base
        # acceleration -g (a_gf); rbdkit reports them without it
        kin = self.pin.createData()
        pin.forwardKinematics(self.pin, kin, self.q(q))
        per_body = {}
        for jid in range(1, self.pin.njoints):
            b = self.body_of_joint[jid]
            a = self.data.a_gf[jid].vector.copy()
            a[:3] -= kin.oMi[jid].rotation.T @ (-self.pin.gravity.linear)
            per_body[b] = (self.data.v[jid].vector.copy(), a, self.data.f[jid].vector.copy())
        return self.G.T @ tau, per_body

    def crba(self, q):
        M = pin.crba(self.pin, self.data, self.q(q))
        M = np.triu(M) + np.triu(M, 1).T
        return self.G.T @ M @ self.G

    def nle(self, q, v, g=-9.81, fext=None):
        return self.rnea(q, v, np.zeros(self.model.nv), g, fext)[0]

    def forward(self, q, v, tau, g=-9.81, fext=None):
        """qdd of the reduced system: (Gᵀ M G)⁻¹ (tau - Gᵀ c); Pinocchio's ABA when G is a permutation"""
        if not self.model.has_mimic:
            self.set_gravity(g)
            args = (self.pin, self.data, self.q(q), self.v(v), self.G @ tau)
            qdd = pin.aba(*args, self.fext(fext)) if fext is not None else pin.aba(*args)
            return self.G.T @ qdd
        return np.linalg.solve(self.crba(q), tau - self.nle(q, v, g, fext))

    def rnea_derivatives(self, q, v, a, g=-9.81, fext=None):
        """(∂tau/∂q, ∂tau/∂qd) in reduced tangent coordinates"""
        self.set_gravity(g)
        args = (self.pin, self.data, self.q(q), self.v(v), self.v(a))
        dq, dv, _ = (pin.computeRNEADerivatives(*args, self.fext(fext)) if fext is not None
                     else pin.computeRNEADerivatives(*args))
        return self.G.T @ dq @ self.G, self.G.T @ dv @ self.G

    def aba_derivatives(self, q, v, tau, g=-9.81, fext=None):
        """(∂qdd/∂q, ∂qdd/∂qd): Pinocchio's computeABADerivatives, or for mimic
        models -(GᵀMG)⁻¹ Gᵀ ∂ID G at the reduced forward dynamics"""
        if not self.model.has_mimic:
            self.set_gravity(g)
            args = (self.pin, self.data, self.q(q), self.v(v), self.G @ tau)
            if fext is not None:
                pin.computeABADerivatives(*args, self.fext(fext))
            else:
                pin.computeABADerivatives(*args)
            return self.G.T @ self.data.ddq_dq @ self.G, self.G.T @ self.data.ddq_dv @ self.G
        qdd = self.forward(q, v, tau, g, fext)
        dq, dv = self.rnea_derivatives(q, v, qdd, g, fext)
        M = self.crba(q)
        return -np.linalg.solve(M, dq), -np.linalg.solve(M, dv)

    def body_jacobian(self, q, body):
        """Jacobian (6, nv) of an rbdkit body in its own frame"""
        jid = next(j for j, b in self.body_of_joint.items() if b == body)
        pin.computeJointJacobians(self.pin, self.data, self.q(q))
        return pin.getJointJacobian(self.pin, self.data, jid, pin.LOCAL) @ self.G

    def minv(self, q):
        if not self.model.has_mimic:
            Mi = pin.computeMinverse(self.pin, self.data, self.q(q))
            Mi = np.triu(Mi) + np.triu(Mi, 1).T
            return self.G.T @ Mi @ self.G
        return np.linalg.inv(self.crba(q))


def close(actual, reference, rtol=1e-9):
    """max |actual - reference| <= rtol · max(1, max |reference|)"""
    actual, reference = np.asarray(actual), np.asarray(reference)
    assert actual.shape == reference.shape, (actual.shape, reference.shape)
    scale = max(1.0, float(np.max(np.abs(reference))) if reference.size else 1.0)
    err = float(np.max(np.abs(actual - reference))) if reference.size else 0.0
    return err <= rtol * scale, err, scale


def assert_close(actual, reference, what, rtol=1e-9):
    ok, err, scale = close(actual, reference, rtol)
    assert ok, f"{what}: max error {err:.3e} > {rtol:g} x {scale:.3g}"


def compare_dynamics(ref, what, singular=False, seed=0):
    """RNEA, CRBA and ABA of the rbdkit model against the Pinocchio reference
    at two random states (the second with high velocities); on a singular
    mass matrix, ABA must raise in rbdkit and give NaN in Pinocchio"""
    m = ref.model
    assert sorted(ref.bodies) == list(range(m.nb)), f"{what}: Pinocchio's joints are not rbdkit's bodies"
    assert np.linalg.matrix_rank(ref.G) == m.nv, f"{what}: coordinates unmatched"
    rbd = rbdkit.RBD(m)
    rng = np.random.default_rng(seed)
    for k in range(2):
        q = m.random_configuration(rng, scale=np.pi)
        qd = rng.uniform(-1, 1, m.nv) * (3.0 if k == 0 else 30.0)
        qdd = rng.uniform(-5, 5, m.nv)
        tau = rng.uniform(-50, 50, m.nv)
        assert_close(rbd.inverse_dynamics(q, qd, qdd)[0], ref.rnea(q, qd, qdd)[0], f"{what}: RNEA")
        M_ref = ref.crba(q)
        assert_close(rbd.crba(q), M_ref, f"{what}: CRBA")
        if singular:
            w = np.linalg.eigvalsh(M_ref)
            assert w[0] <= 1e-12 * w[-1], f"{what}: M is not singular"
            try:
                rbd.aba(q, qd, tau)
                raise AssertionError(f"{what}: ABA did not raise on a singular mass matrix")
            except RuntimeError as e:
                assert "not positive definite" in str(e), e
            if not m.has_mimic:
                assert not np.all(np.isfinite(ref.forward(q, qd, tau))), f"{what}: Pinocchio's ABA is finite"
        else:
            assert_close(rbd.aba(q, qd, tau), ref.forward(q, qd, tau), f"{what}: ABA")


# the models every equivalence test runs on: (id, path, floating_base)
def all_models():
    cases = []
    for name in ("iiwa", "hyq", "atlas"):
        for fb in (False, True):
            cases.append((f"{name}-{'floating' if fb else 'fixed'}", os.path.join(ROBOTS_DIR, name + ".urdf"), fb))
    for name in ("spherical", "helical", "planar", "mixed", "mimic"):
        for fb in (False, True):
            cases.append((f"{name}-{'floating' if fb else 'fixed'}", os.path.join(URDF_DIR, name + ".urdf"), fb))
    return cases


# ---- inertial-parameter regressors (methods of Reference). Pinocchio's
# parameter blocks follow its joints; rbdkit's follow its bodies: P maps them.
def _parameter_map(self):
    """P (10·njoints, 10·nb): rbdkit's π = Pᵀ π_pin, Y_rbdkit = Gᵀ Y_pin P"""
    P = np.zeros((10 * (self.pin.njoints - 1), 10 * self.model.nb))
    for jid in range(1, self.pin.njoints):
        b = self.body_of_joint[jid]
        P[10 * (jid - 1):10 * jid, 10 * b:10 * b + 10] = np.eye(10)
    return P


def _dynamic_parameters(self):
    """Pinocchio's inertias as dynamic parameters, in rbdkit's body order (10·nb,)"""
    pi = np.concatenate([self.pin.inertias[j].toDynamicParameters() for j in range(1, self.pin.njoints)])
    return self.parameter_map().T @ pi


def _joint_torque_regressor(self, q, v, a, g=-9.81):
    self.set_gravity(g)
    Y = pin.computeJointTorqueRegressor(self.pin, self.data, self.q(q), self.v(v), self.v(a))
    return self.G.T @ Y @ self.parameter_map()


def _kinetic_energy_regressor(self, q, v):
    return pin.computeKineticEnergyRegressor(self.pin, self.data, self.q(q), self.v(v)) @ self.parameter_map()


def _potential_energy_regressor(self, q, g=-9.81):
    self.set_gravity(g)
    return pin.computePotentialEnergyRegressor(self.pin, self.data, self.q(q)) @ self.parameter_map()


def _potential_energy(self, q, g=-9.81):
    self.set_gravity(g)
    return pin.computePotentialEnergy(self.pin, self.data, self.q(q))


def _rnea_with_parameters(self, pi, q, v, a, g=-9.81):
    """reduced RNEA of a copy of the Pinocchio model whose inertias are rbdkit's π (10·nb,)"""
    pm = pin.Model(self.pin)
    pm.gravity.linear = np.array([0.0, 0.0, g])
    for jid in range(1, pm.njoints):
        b = self.body_of_joint[jid]
        pm.inertias[jid] = pin.Inertia.FromDynamicParameters(np.asarray(pi[10 * b:10 * b + 10], dtype=float))
    return self.G.T @ pin.rnea(pm, pm.createData(), self.q(q), self.v(v), self.v(a))


Reference.parameter_map = _parameter_map
Reference.dynamic_parameters = _dynamic_parameters
Reference.joint_torque_regressor = _joint_torque_regressor
Reference.kinetic_energy_regressor = _kinetic_energy_regressor
Reference.potential_energy_regressor = _potential_energy_regressor
Reference.potential_energy = _potential_energy
Reference.rnea_with_parameters = _rnea_with_parameters


# ---- energy, Coriolis and centroidal references (reduced coordinates: · G)
def _ref_kinetic_energy(self, q, v):
    return pin.computeKineticEnergy(self.pin, self.data, self.q(q), self.v(v))


def _ref_potential_energy(self, q, g=-9.81):
    self.set_gravity(g)
    return pin.computePotentialEnergy(self.pin, self.data, self.q(q))


def _ref_coriolis(self, q, v):
    C = pin.computeCoriolisMatrix(self.pin, self.data, self.q(q), self.v(v))
    return self.G.T @ C @ self.G


def _ref_com(self, q):
    return pin.centerOfMass(self.pin, self.data, self.q(q)).copy()


def _ref_jacobian_com(self, q):
    return pin.jacobianCenterOfMass(self.pin, self.data, self.q(q)) @ self.G


def _ref_ccrba(self, q, v):
    A = pin.ccrba(self.pin, self.data, self.q(q), self.v(v)) @ self.G
    return A, self.data.hg.vector.copy()


def _ref_cmm_time_variation(self, q, v):
    # Pinocchio 4.1's computeCentroidalMapTimeVariation reads data.vcom[0]
    # without computing it (it keeps whatever an earlier call left there), so
    # the centroidal momentum at the same (q, v) is computed first
    pin.computeCentroidalMomentum(self.pin, self.data, self.q(q), self.v(v))
    return pin.computeCentroidalMapTimeVariation(self.pin, self.data, self.q(q), self.v(v)) @ self.G


def _ref_centroidal_momentum_time_variation(self, q, v, a):
    return pin.computeCentroidalMomentumTimeVariation(self.pin, self.data, self.q(q), self.v(v),
                                                      self.v(a)).vector.copy()


def _ref_centroidal_dynamics_derivatives(self, q, v, a):
    out = pin.computeCentroidalDynamicsDerivatives(self.pin, self.data, self.q(q), self.v(v), self.v(a))
    return tuple(np.array(d) @ self.G for d in out)


Reference.kinetic_energy = _ref_kinetic_energy
Reference.potential_energy = _ref_potential_energy
Reference.coriolis = _ref_coriolis
Reference.com = _ref_com
Reference.jacobian_com = _ref_jacobian_com
Reference.ccrba = _ref_ccrba
Reference.cmm_time_variation = _ref_cmm_time_variation
Reference.centroidal_momentum_time_variation = _ref_centroidal_momentum_time_variation
Reference.centroidal_dynamics_derivatives = _ref_centroidal_dynamics_derivatives
