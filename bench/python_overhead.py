"""What a call costs from Python: rbdkit against Pinocchio's Python bindings
in one run on the same machine (issue 13, point 4 "Fast calls").

    build/venv/bin/python bench/python_overhead.py                     # everything, table on stdout
    build/venv/bin/python bench/python_overhead.py --out overhead.json
    build/venv/bin/python bench/python_overhead.py --quick             # a few seconds, for the test

Robots: iiwa (fixed base, nv 7) and HyQ with a free-flyer root (nv 18); the
Pinocchio model is built from the same URDF file by the test suite's mirror
(tests/python/pinref.py: joints matched by name, JointModelFreeFlyer root),
and each library gets the same state in its own coordinates, converted
before any timing. Every pair of results is checked equal (1e-9 ·
max(1, max |reference|)) before it is timed.

Sections:
  single     one sample per call: rbdkit.RBD against pinocchio (µs per call,
             ratio, target ≤ 1.3×). Each side is called as a user would:
             rbdkit allocates and returns its outputs, Pinocchio writes into
             its Data and returns views or copies as its bindings do.
             Pinocchio's crba and computeMinverse fill the upper triangle
             only; rbdkit.crba and minv return the full matrix (timed as is).
  handle     rbdkit.Handle (threads=1) at B = 1 ((1, n) arrays) against the
             C++ time of the same operation: RBD.time_per_call (the per-sample
             algorithm on a held workspace, no checks) where it has the
             operation, and the batch engine called directly at B = 1
             (_core.Engine, preallocated outputs: what the Handle wraps).
             Target: at most 3 µs above C++.
  batched    rbdkit.Handle against _core.Engine at B = 1024, one thread, ns
             per knot point (the cost of the Handle's Python-side checks and
             copies).
  threads    _core.Engine with 1 and 2 threads at B in {256, 1024, 4096}, ns
             per knot point (the six operations above, the RK4 step and its
             gradient), the 2-thread speed-up (target ≥ 1.8×) and the
             ratio to Pinocchio's rneaInParallel / abaInParallel (OpenMP,
             a ModelPool) with the same threads (target ≤ 0.25×).
  breakdown  one rbd.inverse_dynamics(q, qd, qdd) call (iiwa) against the
             C++ kernel alone and the CPython / NumPy primitives it uses.

Timing: timeit loops (the garbage collector off) of prepared arguments,
`number` calls per repeat chosen for ~--min-time seconds, the best of
--repeats repeats; the two sides of a comparison alternate repeat by repeat
so that a load change on the machine hits both.
"""

import argparse
import datetime
import gc
import json
import math
import os
import platform
import sys
import time
import timeit

import numpy as np
import pinocchio as pin

import rbdkit
from rbdkit import _core

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, os.pardir, "tests", "python"))
from pinref import Reference, close  # noqa: E402  the test suite's Pinocchio mirror of a model

GRAVITY = -9.81
DT = 0.01
ROBOTS = (("iiwa", False), ("hyq", True))
SINGLE_TARGET = 1.3      # rbdkit / Pinocchio, one sample per call
HANDLE_TARGET_US = 3.0   # Handle at B = 1 above its C++ time
SPEEDUP_TARGET = 1.8     # 2 threads against 1
PARALLEL_TARGET = 0.25   # rbdkit / Pinocchio's *InParallel with the same threads
ENGINE_OPS = ("rnea", "crba", "minv", "aba", "rnea_derivatives", "aba_derivatives")


def robot_label(name, floating):
    return name + ("_floating" if floating else "")


# ---------------------------------------------------------------- timing
def make_timer(f, *args):
    """a timeit.Timer of f(*args) with the arguments bound as globals (no
    lambda, no unpacking in the timed statement)"""
    names = [f"a{i}" for i in range(len(args))]
    return timeit.Timer(f"f({', '.join(names)})", globals={"f": f, **dict(zip(names, args))})


def calibrate(timer, min_time):
    """calls per repeat so that one repeat takes about min_time seconds"""
    n = 1
    while True:
        t = timer.timeit(n)
        if t >= min_time / 4 or n >= 1 << 24:
            return max(1, int(math.ceil(n * min_time / max(t, 1e-9))))
        n *= 4


def best_times(timers, repeats, min_time):
    """seconds per call of each timer, best of `repeats`, repeats interleaved"""
    numbers = [calibrate(t, min_time) for t in timers]
    best = [math.inf] * len(timers)
    for _ in range(repeats):
        for i, t in enumerate(timers):
            best[i] = min(best[i], t.timeit(numbers[i]) / numbers[i])
    return best


def busy_cpu_seconds():
    """CPU time all processes have used (Linux /proc/stat), seconds"""
    with open("/proc/stat") as f:
        v = [int(x) for x in f.readline().split()[1:]]
    return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")


def idle_best_times(timers, repeats, min_time, tries=20, quiet=0.05):
    """best_times on an idle machine: wait until other processes use less
    than `quiet` of a core, time, and time again when they used more than
    that meanwhile (at most `tries` times; the last is kept). Returns the
    times and the cores the others used during the kept measurement."""
    for _ in range(tries):
        for _ in range(600):  # wait up to a minute for a quiet second
            b0, c0 = busy_cpu_seconds(), time.process_time()
            time.sleep(0.1)
            if (busy_cpu_seconds() - b0) - (time.process_time() - c0) < quiet * 0.1:
                break
        b0, c0, w0 = busy_cpu_seconds(), time.process_time(), time.perf_counter()
        t = best_times(timers, repeats, min_time)
        others = ((busy_cpu_seconds() - b0) - (time.process_time() - c0)) / (time.perf_counter() - w0)
        if others < quiet:
            break
    return t, max(others, 0.0)


# ---------------------------------------------------------------- the robots
class Robot:
    """an rbdkit model, its Pinocchio mirror and one state in both coordinate systems"""

    def __init__(self, name, floating, seed=0):
        self.label = robot_label(name, floating)
        self.ref = Reference(rbdkit.robots.path(name), floating_base=floating)
        self.model = self.ref.model
        self.rbd = rbdkit.RBD(self.model)
        self.pm, self.pd = self.ref.pin, self.ref.data
        self.pm.gravity.linear = np.array([0.0, 0.0, GRAVITY])
        self.nq, self.nv = self.model.nq, self.model.nv
        self.G = self.ref.G
        rng = np.random.default_rng(seed)
        self.q = self.model.random_configuration(rng)
        self.qd, self.qdd, self.tau, self.dv = (rng.uniform(-1, 1, self.nv) for _ in range(4))
        # Pinocchio's coordinates
        self.qp = self.ref.q(self.q)
        self.qdp, self.qddp, self.taup, self.dvp = (self.G @ x for x in (self.qd, self.qdd, self.tau, self.dv))

    def batch(self, B, seed=1):
        """B random states (rbdkit: (B, n) C order; Pinocchio: (n, B) F order)"""
        rng = np.random.default_rng(seed)
        Q = self.rbd.integrate(np.tile(self.model.neutral(), (B, 1)), rng.uniform(-1, 1, (B, self.nv)))
        QD, QDD, TAU = (rng.uniform(-1, 1, (B, self.nv)) for _ in range(3))
        Qp = np.asfortranarray(np.stack([self.ref.q(x) for x in Q], axis=1))
        QDp, QDDp, TAUp = (np.asfortranarray(self.G @ X.T) for X in (QD, QDD, TAU))
        return (Q, QD, QDD, TAU), (Qp, QDp, QDDp, TAUp)


def sym(upper):
    """the symmetric matrix whose upper triangle is given"""
    upper = np.asarray(upper)
    return np.triu(upper) + np.triu(upper, 1).T


def reduce(r, M):
    """a Pinocchio (nv, nv) matrix in rbdkit's coordinates"""
    return r.G.T @ M @ r.G


def single_ops(r):
    """[(op, rbdkit call, Pinocchio call, check)]; check(rbdkit result,
    Pinocchio result) -> (rbdkit array, Pinocchio array in rbdkit's coordinates)"""
    rb, pm, pd = r.rbd, r.pm, r.pd
    G = r.G

    def aba_derivatives_check(a, p):
        # Pinocchio 4.1 returns nothing from computeABADerivatives here or a
        # tuple, depending on the overload: the results are in its Data
        return np.hstack(a), np.hstack([reduce(r, pd.ddq_dq), reduce(r, pd.ddq_dv)])

    return [
        ("rnea", (rb.inverse_dynamics, r.q, r.qd, r.qdd), (pin.rnea, pm, pd, r.qp, r.qdp, r.qddp),
         lambda a, p: (a[0], G.T @ p)),
        ("crba", (rb.crba, r.q), (pin.crba, pm, pd, r.qp), lambda a, p: (a, reduce(r, sym(p)))),
        ("aba", (rb.aba, r.q, r.qd, r.tau), (pin.aba, pm, pd, r.qp, r.qdp, r.taup), lambda a, p: (a, G.T @ p)),
        ("minv", (rb.minv, r.q), (pin.computeMinverse, pm, pd, r.qp), lambda a, p: (a, reduce(r, sym(p)))),
        ("rnea_derivatives", (rb.inverse_dynamics_gradient, r.q, r.qd, r.qdd),
         (pin.computeRNEADerivatives, pm, pd, r.qp, r.qdp, r.qddp),
         lambda a, p: (a, np.hstack([reduce(r, p[0]), reduce(r, p[1])]))),
        ("aba_derivatives", (rb.forward_dynamics_gradient, r.q, r.qd, r.tau),
         (pin.computeABADerivatives, pm, pd, r.qp, r.qdp, r.taup), aba_derivatives_check),
        ("integrate", (rb.integrate, r.q, r.dv), (pin.integrate, pm, r.qp, r.dvp),
         lambda a, p: (r.ref.q(a), p)),
    ]


RBD_NAME = {"rnea": "inverse_dynamics", "crba": "crba", "aba": "aba", "minv": "minv",
            "rnea_derivatives": "inverse_dynamics_gradient", "aba_derivatives": "forward_dynamics_gradient",
            "integrate": "integrate"}


def checked(what, actual, reference):
    ok, err, scale = close(actual, reference, rtol=1e-9)
    if not ok:
        raise SystemExit(f"{what}: the two results differ by {err:.3e} (scale {scale:.3g}); nothing timed")
    return err


# ---------------------------------------------------------------- sections
def section_single(robots, opt):
    rows = []
    for r in robots:
        for op, (fa, *aa), (fp, *ap), check in single_ops(r):
            a, p = fa(*aa), fp(*ap)
            p = tuple(np.array(x) for x in p) if isinstance(p, tuple) else np.array(p)
            err = checked(f"{r.label} {op}", *check(a, p))
            ta, tp = best_times([make_timer(fa, *aa), make_timer(fp, *ap)], opt.repeats, opt.min_time)
            rows.append(dict(robot=r.label, op=op, rbdkit_us=ta * 1e6, pinocchio_us=tp * 1e6, ratio=ta / tp,
                             target=SINGLE_TARGET, meets=ta / tp <= SINGLE_TARGET, max_abs_diff=err))
    return rows


def handle_ops(r, h, e, X):
    """[(op, Handle call, engine call or None, C++ time_per_call op or None,
    index of the RBD result the Handle returns)] on the (1, n) arrays X"""
    Q, QD, QDD, TAU, DV = X
    nv = r.nv

    def out(*shape):
        return np.empty((1,) + shape)

    return [
        ("rnea", (h.inverse_dynamics, Q, QD, QDD), (e.inverse_dynamics, Q, QD, QDD, GRAVITY, out(nv)),
         "inverse_dynamics"),
        ("crba", (h.crba, Q), (e.crba, Q, out(nv, nv)), "crba"),
        ("aba", (h.aba, Q, QD, TAU), (e.forward_dynamics, Q, QD, TAU, GRAVITY, out(nv)), "aba"),
        ("minv", (h.minv, Q), (e.minv, Q, out(nv, nv)), "minv"),
        ("rnea_derivatives", (h.inverse_dynamics_gradient, Q, QD, QDD),
         (e.inverse_dynamics_gradient, Q, QD, QDD, GRAVITY, out(nv, nv), out(nv, nv)), None),
        ("aba_derivatives", (h.forward_dynamics_gradient, Q, QD, TAU),
         (e.forward_dynamics_gradient, Q, QD, TAU, GRAVITY, out(nv, nv), out(nv, nv)), None),
        ("integrate", (h.integrate, Q, DV), None, None),
    ]


def section_handle(robots, opt):
    rows = []
    for r in robots:
        h = rbdkit.Handle(r.model, threads=1)
        e = _core.Engine(r.model._core, 1, "float64")
        X = tuple(np.ascontiguousarray(x[None]) for x in (r.q, r.qd, r.qdd, r.tau, r.dv))
        for op, (fh, *ah), eng, cpp_op in handle_ops(r, h, e, X):
            # the Handle's result at B = 1 against RBD's single-sample one
            ref = getattr(r.rbd, RBD_NAME[op])(*(x[0] for x in ah))
            ref = ref[0] if op == "rnea" else np.hstack(ref) if op == "aba_derivatives" else ref
            got = fh(*ah)
            got = np.concatenate(got, axis=-1) if op == "aba_derivatives" else got
            checked(f"{r.label} Handle {op}", got[0], ref)
            timers = [make_timer(fh, *ah)]
            if eng is not None:
                timers.append(make_timer(*eng))
            times = best_times(timers, opt.repeats, opt.min_time)
            th, te = times[0], (times[1] if eng is not None else None)
            cpp = None
            if cpp_op is not None:
                cpp = r.rbd.time_per_call(cpp_op, r.q, r.qd, r.tau, iters=opt.cpp_iters)
            base, source = ((cpp, "time_per_call") if cpp is not None else (te, "engine B=1") if te is not None
                            else (None, None))
            over = None if base is None else (th - base) * 1e6
            rows.append(dict(robot=r.label, op=op, handle_us=th * 1e6, engine_us=None if te is None else te * 1e6,
                             cpp_us=None if cpp is None else cpp * 1e6, overhead_us=over, overhead_above=source,
                             target_us=HANDLE_TARGET_US, meets=None if over is None else over <= HANDLE_TARGET_US))
    return rows


def engine_ops(r, e, X):
    """[(op, engine call with preallocated outputs, Handle method name, Handle args)] on batched X"""
    Q, QD, QDD, TAU = X
    B, nv = len(Q), r.nv
    mat = lambda: np.empty((B, nv, nv))  # noqa: E731
    return [
        ("rnea", (e.inverse_dynamics, Q, QD, QDD, GRAVITY, np.empty((B, nv))), "inverse_dynamics", (Q, QD, QDD)),
        ("crba", (e.crba, Q, mat()), "crba", (Q,)),
        ("minv", (e.minv, Q, mat()), "minv", (Q,)),
        ("aba", (e.forward_dynamics, Q, QD, TAU, GRAVITY, np.empty((B, nv))), "aba", (Q, QD, TAU)),
        ("rnea_derivatives", (e.inverse_dynamics_gradient, Q, QD, QDD, GRAVITY, mat(), mat()),
         "inverse_dynamics_gradient", (Q, QD, QDD)),
        ("aba_derivatives", (e.forward_dynamics_gradient, Q, QD, TAU, GRAVITY, mat(), mat()),
         "forward_dynamics_gradient", (Q, QD, TAU)),
    ]


def thread_ops(r, e, X):
    """engine_ops and the integrator step and its gradient (RK4), which the
    Handle section does not time: [(op, engine call)]"""
    Q, QD, QDD, TAU = X
    B, nq, nv = len(Q), r.nq, r.nv
    return [(op, call) for op, call, _, _ in engine_ops(r, e, X)] + [
        ("integrator_rk4", (e.integrator, Q, QD, TAU, DT, GRAVITY, "rk4", np.empty((B, nq + nv)))),
        ("integrator_gradient_rk4",
         (e.integrator_gradient, Q, QD, TAU, DT, GRAVITY, "rk4", np.empty((B, nq + nv)), np.empty((B, 2 * nv, 3 * nv)))),
    ]


def engine_result(op, call):
    """the engine's outputs after `call` ran, in the Handle's layout (the
    integrator gradient: x and AB flattened side by side)"""
    two = op.endswith("derivatives") or op.startswith("integrator_gradient")
    outs = [a for a in call[1:] if isinstance(a, np.ndarray)][-2 if two else -1:]
    if op == "rnea_derivatives":
        return np.concatenate(outs, axis=-1)
    if op.startswith("integrator_gradient"):
        return np.concatenate([o.reshape(len(o), -1) for o in outs], axis=1)
    return np.stack(outs, axis=0) if op == "aba_derivatives" else outs[0]


def section_batched(robots, opt):
    rows = []
    B = opt.batch
    for r in robots:
        h = rbdkit.Handle(r.model, threads=1)
        e = _core.Engine(r.model._core, 1, "float64")
        X, _ = r.batch(B)
        for op, call, hname, hargs in engine_ops(r, e, X):
            fh = getattr(h, hname)
            got = fh(*hargs)
            call[0](*call[1:])
            ref = engine_result(op, call)
            checked(f"{r.label} B={B} {op}", np.stack(got, axis=0) if op == "aba_derivatives" else got, ref)
            th, te = best_times([make_timer(fh, *hargs), make_timer(*call)], opt.repeats, opt.min_time)
            rows.append(dict(robot=r.label, op=op, B=B, threads=1, handle_ns=th / B * 1e9, engine_ns=te / B * 1e9,
                             ratio=th / te))
    return rows


def pin_parallel(r, nt, pool, Xp, B):
    """{op: Pinocchio's *InParallel call} with preallocated outputs"""
    Qp, QDp, QDDp, TAUp = Xp
    return {"rnea": (pin.rneaInParallel, nt, pool, Qp, QDp, QDDp, np.empty((r.pm.nv, B), order="F")),
            "aba": (pin.abaInParallel, nt, pool, Qp, QDp, TAUp, np.empty((r.pm.nv, B), order="F"))}


def section_threads(robots, opt):
    rows = []
    have_pin = hasattr(pin, "rneaInParallel") and hasattr(pin, "ModelPool")
    for r in robots:
        engines = {t: _core.Engine(r.model._core, t, "float64") for t in (1, 2)}
        pool = pin.ModelPool(r.pm, 2) if have_pin else None
        for B in opt.batches:
            X, Xp = r.batch(B)
            calls = {t: thread_ops(r, engines[t], X) for t in (1, 2)}
            pins = {t: pin_parallel(r, t, pool, Xp, B) for t in (1, 2)} if have_pin else {1: {}, 2: {}}
            for k, (op, c1) in enumerate(calls[1]):
                c2 = calls[2][k][1]
                for c in (c1, c2):
                    c[0](*c[1:])
                checked(f"{r.label} B={B} {op} threads", engine_result(op, c2), engine_result(op, c1))
                timers = [make_timer(*c1), make_timer(*c2)]
                p1, p2 = pins[1].get(op), pins[2].get(op)
                if p1 is not None:
                    for p in (p1, p2):
                        p[0](*p[1:])
                        checked(f"{r.label} B={B} {op} Pinocchio in parallel",
                                engine_result(op, c1), (r.G.T @ p[-1]).T)
                    timers += [make_timer(*p1), make_timer(*p2)]
                if opt.idle:
                    t, others = idle_best_times(timers, opt.repeats, opt.min_time)
                else:
                    t, others = best_times(timers, opt.repeats, opt.min_time), None
                row = dict(robot=r.label, op=op, B=B, engine_t1_ns=t[0] / B * 1e9, engine_t2_ns=t[1] / B * 1e9,
                           others_cores=others,
                           speedup=t[0] / t[1], speedup_target=SPEEDUP_TARGET, speedup_meets=t[0] / t[1] >= SPEEDUP_TARGET)
                if p1 is not None:
                    row.update(pin_t1_ns=t[2] / B * 1e9, pin_t2_ns=t[3] / B * 1e9, pin_speedup=t[2] / t[3],
                               ratio_t1=t[0] / t[2], ratio_t2=t[1] / t[3], ratio_target=PARALLEL_TARGET,
                               ratio_meets=max(t[0] / t[2], t[1] / t[3]) <= PARALLEL_TARGET)
                rows.append(row)
    return rows


# ---------------------------------------------------------------- breakdown of one call
def section_breakdown(r, opt):
    """µs of one rbd.inverse_dynamics(q, qd, qdd) call and of its parts: the
    compiled callable (python/src/bind_ops.cpp: argument parsing, array
    checks, output allocation, C++ value checks, the kernel), the C++ kernel
    alone, and reference costs of the CPython and NumPy primitives it uses"""
    rb, q, qd, qdd = r.rbd, r.q, r.qd, r.qdd
    nv = rb.nv
    h = rbdkit.Handle(r.model, threads=1)
    Q, QD, QDD = (np.ascontiguousarray(x[None]) for x in (q, qd, qdd))
    pieces = [
        ("rbd.inverse_dynamics(q, qd, qdd), whole call (tau and per-body v, a, f)", (rb.inverse_dynamics, q, qd, qdd)),
        ("rbd.inverse_dynamics(q=q, qd=qd, qdd=qdd), by keyword", (lambda: rb.inverse_dynamics(q=q, qd=qd, qdd=qdd),)),
        ("rbd.inverse_dynamics(list q, list qd, list qdd): converted", (rb.inverse_dynamics, list(q), list(qd),
                                                                        list(qdd))),
        ("Handle.inverse_dynamics(Q, QD, QDD), B = 1, whole call (tau only)", (h.inverse_dynamics, Q, QD, QDD)),
        ("rbd.integrate(q, qd), whole call", (rb.integrate, q, qd)),
        ("np.empty((nv,)): one output allocation, for scale", (np.empty, (nv,))),
        ("len(q): a call of a C function, for scale", (len, q)),
    ]
    times = best_times([make_timer(*p[1]) for p in pieces], opt.repeats, opt.min_time)
    detail = [dict(what=p[0], us=t * 1e6) for p, t in zip(pieces, times)]
    detail.append(dict(what="C++ rnea alone (RBD.time_per_call: held workspace, no checks)",
                       us=rb.time_per_call("inverse_dynamics", q, qd, qdd, iters=opt.cpp_iters) * 1e6))
    return dict(robot=r.label, pieces=detail)


def section_cprofile(r, n=2000):
    """cProfile of rbd.inverse_dynamics and Handle.inverse_dynamics (B = 1):
    own time per call of each function, µs (cProfile inflates every Python
    call alike: read it for shares, not for totals)"""
    import cProfile
    import pstats

    h = rbdkit.Handle(r.model, threads=1)
    out = {}
    for name, f, args in (("rbd.inverse_dynamics", r.rbd.inverse_dynamics, (r.q, r.qd, r.qdd)),
                          ("Handle.inverse_dynamics B=1", h.inverse_dynamics,
                           tuple(x[None] for x in (r.q, r.qd, r.qdd)))):
        p = cProfile.Profile()
        p.enable()
        for _ in range(n):
            f(*args)
        p.disable()
        st = pstats.Stats(p).stats
        rows = []
        for (file, line, fn), (cc, nc, tt, ct, _) in st.items():
            where = f"{os.path.basename(file)}:{fn}" if file != "~" else fn
            rows.append(dict(function=where, calls_per_call=nc / n, own_us=tt / n * 1e6, cumulative_us=ct / n * 1e6))
        rows.sort(key=lambda x: -x["own_us"])
        out[name] = rows[:15]
    return out


# ---------------------------------------------------------------- report
def fmt(x, digits=2):
    return "-" if x is None else f"{x:.{digits}f}"


def print_report(res):
    print(f"# rbdkit vs Pinocchio from Python ({res['machine']['pinocchio']} / rbdkit {res['machine']['rbdkit']}, "
          f"{res['machine']['cpus']} CPUs, load {res['machine']['load']})")
    if "single" in res:
        print(f"\n## One sample per call (µs; target rbdkit/Pinocchio ≤ {SINGLE_TARGET}×)\n")
        print("| robot | op | rbdkit | Pinocchio | ratio | meets |\n|---|---|---:|---:|---:|---|")
        for x in res["single"]:
            print(f"| {x['robot']} | {x['op']} | {fmt(x['rbdkit_us'])} | {fmt(x['pinocchio_us'])} | "
                  f"{x['ratio']:.1f}× | {'yes' if x['meets'] else 'no'} |")
        print("\ncrba, minv: Pinocchio fills the upper triangle only, rbdkit returns the full matrix.")
    if "handle" in res:
        print(f"\n## rbdkit.Handle at B = 1 (µs; target ≤ {HANDLE_TARGET_US} µs above C++)\n")
        print("| robot | op | Handle | engine B=1 | C++ | above | above what | meets |\n"
              "|---|---|---:|---:|---:|---:|---|---|")
        for x in res["handle"]:
            meets = "-" if x["meets"] is None else "yes" if x["meets"] else "no"
            print(f"| {x['robot']} | {x['op']} | {fmt(x['handle_us'])} | {fmt(x['engine_us'])} | {fmt(x['cpp_us'])} | "
                  f"{fmt(x['overhead_us'])} | {x['overhead_above'] or '-'} | {meets} |")
    if "batched" in res:
        print("\n## Handle vs _core.Engine, batched, 1 thread (ns per knot point)\n")
        print("| robot | op | B | Handle | Engine | ratio |\n|---|---|---:|---:|---:|---:|")
        for x in res["batched"]:
            print(f"| {x['robot']} | {x['op']} | {x['B']} | {fmt(x['handle_ns'], 0)} | {fmt(x['engine_ns'], 0)} | "
                  f"{x['ratio']:.2f} |")
    if "threads" in res:
        print(f"\n## Thread scaling, _core.Engine vs Pinocchio *InParallel (ns per knot point; targets: speed-up "
              f"≥ {SPEEDUP_TARGET}×, rbdkit/Pinocchio ≤ {PARALLEL_TARGET}×)\n")
        print("| robot | op | B | T1 | T2 | speed-up | pin T1 | pin T2 | pin speed-up | ratio T1 | ratio T2 | others |\n"
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for x in res["threads"]:
            print(f"| {x['robot']} | {x['op']} | {x['B']} | {fmt(x['engine_t1_ns'], 0)} | {fmt(x['engine_t2_ns'], 0)} | "
                  f"{x['speedup']:.2f} | {fmt(x.get('pin_t1_ns'), 0)} | {fmt(x.get('pin_t2_ns'), 0)} | "
                  f"{fmt(x.get('pin_speedup'))} | {fmt(x.get('ratio_t1'))} | {fmt(x.get('ratio_t2'))} | "
                  f"{fmt(x.get('others_cores'))} |")
        print("\nothers: cores that other processes used while the row was timed (--idle)")
    if "breakdown" in res:
        bd = res["breakdown"]
        print(f"\n## Where one rbd.inverse_dynamics(q, qd, qdd) goes ({bd['robot']}, µs)\n")
        print("| piece (timeit) | µs |\n|---|---:|")
        for x in bd["pieces"]:
            print(f"| {x['what']} | {x['us']:.2f} |")
    if "cprofile" in res:
        for name, rows in res["cprofile"].items():
            print(f"\n### cProfile, {name} (own µs per call, inflated by the profiler)\n")
            for x in rows[:10]:
                print(f"  {x['own_us']:7.2f}  x{x['calls_per_call']:<4g} {x['function']}")


def machine():
    return dict(python=platform.python_version(), numpy=np.__version__, pinocchio=f"pinocchio {pin.__version__}",
                rbdkit=rbdkit.__version__, platform=platform.platform(), processor=platform.processor(),
                cpus=os.cpu_count(), load=" ".join(f"{x:.2f}" for x in os.getloadavg()),
                date=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))


SECTIONS = ("single", "handle", "batched", "threads", "breakdown", "cprofile")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", help="write the results as JSON here")
    p.add_argument("--quick", action="store_true", help="short loops, B = 64 only: a smoke run of a few seconds")
    p.add_argument("--sections", nargs="+", choices=SECTIONS, default=list(SECTIONS))
    p.add_argument("--robots", nargs="+", choices=[robot_label(*x) for x in ROBOTS],
                   default=[robot_label(*x) for x in ROBOTS])
    p.add_argument("--repeats", type=int, default=7, help="repeats per measurement (the best is kept)")
    p.add_argument("--min-time", type=float, default=0.05, help="seconds per repeat")
    p.add_argument("--batch", type=int, default=1024, help="B of the Handle-vs-Engine section")
    p.add_argument("--batches", type=int, nargs="+", default=[256, 1024, 4096], help="B of the threads section")
    p.add_argument("--idle", action="store_true",
                   help="threads section: time each row when other processes leave the CPUs idle, and again when "
                        "they used more than 5%% of a core meanwhile (Linux; for a shared machine)")
    opt = p.parse_args(argv)
    if opt.quick:
        opt.repeats, opt.min_time, opt.batch, opt.batches = 2, 0.002, 64, [64]
    opt.cpp_iters = 200 if opt.quick else 5000
    robots = [Robot(n, fb) for n, fb in ROBOTS if robot_label(n, fb) in opt.robots]
    res = dict(machine=machine(), settings=dict(repeats=opt.repeats, min_time_s=opt.min_time, batch=opt.batch,
                                                batches=opt.batches, quick=opt.quick, robots=opt.robots))
    if "single" in opt.sections:
        res["single"] = section_single(robots, opt)
    if "handle" in opt.sections:
        res["handle"] = section_handle(robots, opt)
    if "batched" in opt.sections:
        res["batched"] = section_batched(robots, opt)
    if "threads" in opt.sections:
        res["threads"] = section_threads(robots, opt)
    if "breakdown" in opt.sections:
        res["breakdown"] = section_breakdown(robots[0], opt)
    if "cprofile" in opt.sections:
        res["cprofile"] = section_cprofile(robots[0], n=200 if opt.quick else 5000)
    print_report(res)
    if opt.out:
        with open(opt.out, "w") as f:
            json.dump(res, f, indent=1)
    return res


if __name__ == "__main__":
    main()
