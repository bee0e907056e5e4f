"""How the O(n) algorithms scale with the number of links (issue 12).

A serial chain of n revolute links (URDF generated as a string), for each n:
the time to load it, and per operation the time of one call from Python and
the peak memory of the process. Each (n, operation) runs in its own
subprocess, so that the peak resident set (ru_maxrss) is that operation's
and a crash (a workspace too large to allocate) is reported, not fatal.

    build/venv/bin/python bench/chain_scaling.py                 # n = 1k, 5k, 20k, 100k
    build/venv/bin/python bench/chain_scaling.py --sizes 5000 --repeats 5

Columns: load (s, Model.from_urdf_string), then per operation the median
time per call (ms, over --repeats calls after a first one) and the peak RSS
of the process (MB; the model and the interpreter included: compare with
the "model" column, the peak after loading alone); for rnea and aba also
"core", the ms of the algorithm alone (RBD.time_per_call: C++ calls on one
held workspace, best of 5 runs; the difference to the first column is the
per-call cost of checks, a fresh workspace and the outputs). Operations:
rnea (RBD.inverse_dynamics), aba, integrate, fk (forward_kinematics) and
euler (RBD.integrator(..., "euler"), one explicit step through ABA).
"""

import argparse
import json
import os
import subprocess
import sys
import time

OPS = ("model", "rnea", "aba", "integrate", "fk", "euler")


def chain_urdf(n):
    """a serial chain of n revolute links about alternating axes"""
    parts = ['<robot name="chain">', '<link name="l0"/>']
    for i in range(1, n + 1):
        axis = ("1 0 0", "0 1 0", "0 0 1")[i % 3]
        parts.append(
            f'<link name="l{i}"><inertial><origin xyz="0 0 0.05"/><mass value="1"/>'
            f'<inertia ixx="0.01" iyy="0.01" izz="0.005" ixy="0" ixz="0" iyz="0"/></inertial></link>'
            f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/>'
            f'<origin xyz="0 0 0.1"/><axis xyz="{axis}"/>'
            f'<limit lower="-3" upper="3" effort="100" velocity="10"/></joint>')
    parts.append("</robot>")
    return "".join(parts)


def child(n, op, repeats):
    """runs in the subprocess: load, run op, print one JSON line"""
    import resource

    import numpy as np

    import rbdkit

    xml = chain_urdf(n)
    t0 = time.perf_counter()
    model = rbdkit.Model.from_urdf_string(xml)
    load = time.perf_counter() - t0
    del xml
    rbd = rbdkit.RBD(model)
    rng = np.random.default_rng(0)
    q, qd, x = (rng.uniform(-0.1, 0.1, model.nv) for _ in range(3))
    calls = {
        "model": lambda: None,
        "rnea": lambda: rbd.inverse_dynamics(q, qd, x),
        "aba": lambda: rbd.aba(q, qd, x),
        "integrate": lambda: rbd.integrate(q, qd),
        "fk": lambda: rbd.forward_kinematics(q),
        "euler": lambda: rbd.integrator(q, qd, x, 1e-3, "euler"),
    }
    fn = calls[op]
    fn()  # first call (outputs allocated, pages touched)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # kilobytes on Linux
    # the algorithm alone: C++ calls on one held workspace, no checks, no allocation
    core = {"rnea": "inverse_dynamics", "aba": "aba"}.get(op)
    core_ms = 1e3 * rbd.time_per_call(core, q, qd, x, iters=repeats) if core else None
    print(json.dumps({"load": load, "ms": 1e3 * sorted(times)[len(times) // 2], "mb": peak_kb / 1024,
                      "core_ms": core_ms}))


def run(n, op, repeats, timeout):
    cmd = [sys.executable, os.path.abspath(__file__), "--child", str(n), op, "--repeats", str(repeats)]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"timeout {timeout}s"}
    if p.returncode != 0:
        last = (p.stderr.strip().splitlines() or ["?"])[-1]
        return {"error": f"rc {p.returncode}: {last[:60]}"}
    return json.loads(p.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 5000, 20000, 100000])
    ap.add_argument("--ops", nargs="+", default=list(OPS[1:]), choices=OPS[1:])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--timeout", type=float, default=300)
    ap.add_argument("--child", nargs=2, metavar=("N", "OP"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        child(int(a.child[0]), a.child[1], a.repeats)
        return
    ops = ["model"] + a.ops
    head = [f"{o + ' ms':>10} {o + ' MB':>9}" + (f" {o + ' core':>9}" if o in ("rnea", "aba") else "") for o in ops[1:]]
    print(f"{'links':>7} {'load s':>7} {'model MB':>8} " + " ".join(head))
    for n in a.sizes:
        cells, load = [], None
        for op in ops:
            r = run(n, op, a.repeats, a.timeout)
            if "error" in r:
                cells.append(r["error"])
                continue
            load = r["load"] if load is None else load
            cell = f"{r['mb']:8.0f}" if op == "model" else f"{r['ms']:10.3f} {r['mb']:9.0f}"
            if r["core_ms"] is not None:
                cell += f" {r['core_ms']:9.3f}"
            cells.append(cell)
        load_s = f"{load:7.2f}" if load is not None else f"{'-':>7}"
        print(f"{n:7d} {load_s} " + " ".join(cells), flush=True)


if __name__ == "__main__":
    main()
