"""Long serial chains: a 100,000-link chain loads and its RNEA matches the
closed-form gravity torques; RNEA, ABA, forward kinematics, integrate and an
explicit integrator step on a 20,000-link chain, one sample at a time and
batched through a Handle's engine, stay under 1 GB of peak memory (O(n)
workspaces; timing is in bench/chain_scaling.py)."""

import os
import subprocess
import sys
import textwrap

import numpy as np

import rbdkit


def horizontal_chain(n):
    """n revolute links about x: joint k 0.1 along y from joint k-1, link k
    of mass 1 at 0.05 along y from its joint"""
    link = ('<link name="l{i}"><inertial><origin xyz="0 0.05 0"/><mass value="1"/>'
            '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>'
            '<joint name="j{i}" type="revolute"><parent link="l{p}"/><child link="l{i}"/>'
            '<origin xyz="0 0.1 0"/><axis xyz="1 0 0"/>'
            '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>')
    body = "".join(link.format(i=i, p=i - 1) for i in range(1, n + 1))
    return f'<robot name="chain"><link name="l0"/>{body}</robot>'


def test_hundred_thousand_links_load_and_run_rnea():
    n = 100_000
    model = rbdkit.Model.from_urdf_string(horizontal_chain(n))
    assert (model.nb, model.nq, model.nv) == (n, n, n)
    rbd = rbdkit.RBD(model)
    # at rest at q = 0, joint k carries N = n - k + 1 links at 0.05, 0.15, ...
    # along y: tau_k = g·Σ_{i<N} (0.1 i + 0.05) = g·0.05·N²
    tau = rbd.generalized_gravity(np.zeros(n))
    N = np.arange(n, 0, -1, dtype=float)
    expect = 9.81 * 0.05 * N**2
    assert np.max(np.abs(tau - expect)) / expect.max() < 1e-9


PEAK_SCRIPT = textwrap.dedent("""
    import sys
    import numpy as np
    sys.path.insert(0, {here!r})
    import rbdkit
    from test_long_chain import horizontal_chain
    n = 20_000
    rbd = rbdkit.RBD(rbdkit.Model.from_urdf_string(horizontal_chain(n)))
    rng = np.random.default_rng(0)
    q, qd, u = (rng.uniform(-0.1, 0.1, n) for _ in range(3))
    tau = rbd.inverse_dynamics(q, qd, u)[0]
    qdd = rbd.aba(q, qd, tau)
    # ABA inverts RNEA (backward error: qdd's own torques; the chain is too
    # ill-conditioned for qdd itself to match u closely)
    back = rbd.inverse_dynamics(q, qd, qdd)[0]
    assert np.max(np.abs(back - tau)) < 1e-12 * np.max(np.abs(tau))
    rbd.forward_kinematics(q)
    rbd.integrate(q, qd)
    rbd.integrator(q, qd, tau, 1e-3, "euler")
    # the batched engine behind a Handle: linear workspaces for these too
    h = rbdkit.Handle(rbd.model, threads=2)
    Q, V, U = (rng.uniform(-0.1, 0.1, (4, n)) for _ in range(3))
    T = h.inverse_dynamics(Q, V, U)
    assert np.max(np.abs(T[1] - rbd.inverse_dynamics(Q[1], V[1], U[1])[0])) < 1e-9 * np.max(np.abs(T[1]))
    h.aba(Q, V, T)
    h.integrator(Q, V, T, 1e-3, "rk4")
    # this process's own peak (VmHWM, kB): ru_maxrss would be the parent's when it is larger (Linux keeps
    # it across fork and exec), e.g. a pytest process that has imported PyTorch
    print(next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:")))
""")


def test_twenty_thousand_links_stay_under_1gb():
    script = PEAK_SCRIPT.format(here=os.path.dirname(os.path.abspath(__file__)))
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    peak_mb = int(p.stdout.split()[-1]) / 1024
    assert peak_mb < 1024, f"peak RSS {peak_mb:.0f} MB"
