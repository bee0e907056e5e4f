#!/usr/bin/env python3
"""Ratio table from the benchmark's Google Benchmark JSON output.

    report.py RESULTS.json [--csv OUT.csv] [--time cpu|real]

Benchmarks are named <library>/<operation>/<robot> (the single-call table
below); the batched ones, <impl>/<robot>/<op>/<dtype>/B<B>/T<threads>, are
reported by rbdkit.benchreport (python/rbdkit/benchreport.py, loaded from the
source tree: no installed rbdkit needed) after it, with its CSV, JSON and PNG
next to --csv. For each (robot,
operation) the time is the minimum over the repetitions (the least disturbed
on a shared machine); the median is kept in the CSV, and the table's "noise"
column is the larger median/min - 1 of the two libraries. ratio =
rbdkit / Pinocchio (below 1: rbdkit faster). Operations timed for Pinocchio
alone show "-" for rbdkit.
"""

import argparse
import csv
import json
import os
import statistics
import sys

LIBS = ("rbdkit", "pinocchio")


def to_ns(value, unit):
    return value * {"ns": 1.0, "us": 1e3, "ms": 1e6, "s": 1e9}[unit]


def load(path, key):
    with open(path) as f:
        doc = json.load(f)
    runs = {}   # (lib, op, robot) -> [ns per call, one per repetition]
    order = {}  # (lib, op, robot) -> family_index (registration order)
    nv = {}
    for b in doc["benchmarks"]:
        if b.get("run_type", "iteration") != "iteration" or b.get("error_occurred"):
            continue
        parts = b["run_name"].split("/")
        if len(parts) != 3 or parts[0] not in LIBS:
            continue
        k = tuple(parts)
        runs.setdefault(k, []).append(to_ns(b[key], b.get("time_unit", "ns")))
        order[k] = b.get("family_index", len(order))
        if "nv" in b:
            nv[parts[2]] = int(b["nv"])
    return doc.get("context", {}), runs, order, nv


def batched_report(path, out_dir):
    """the batched table (rbdkit.benchreport) when the JSON has batched runs; True if it had"""
    import importlib.util
    here = os.path.dirname(os.path.abspath(__file__))
    spec = importlib.util.spec_from_file_location(
        "benchreport", os.path.join(here, os.pardir, "python", "rbdkit", "benchreport.py"))
    br = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(br)
    if not br.parse(path)[1]:
        return False
    print("\nbatched: rbdkit vs Pinocchio per knot point")
    br.report(path, os.path.join(out_dir, "batched") if out_dir else None)
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("json")
    ap.add_argument("--csv", help="write the table here too")
    ap.add_argument("--time", choices=("cpu", "real"), default="cpu",
                    help="cpu: thread CPU time (default; preemption by other processes does not count), real: wall time")
    args = ap.parse_args()

    ctx, runs, order, nv = load(args.json, args.time + "_time")
    batched_dir = os.path.dirname(os.path.abspath(args.csv)) if args.csv else None
    if not runs:
        if batched_report(args.json, batched_dir):
            return
        sys.exit(f"report: no <library>/<operation>/<robot> benchmarks in {args.json}")

    # robots and operations in registration order (the JSON's order is
    # shuffled by --benchmark_enable_random_interleaving)
    first = {}
    for (lib, op, robot), fam in order.items():
        first[("op", op)] = min(first.get(("op", op), fam), fam)
        first[("robot", robot)] = min(first.get(("robot", robot), fam), fam)
    ops = sorted({k[1] for k in runs}, key=lambda o: first[("op", o)])
    robots = sorted({k[2] for k in runs}, key=lambda r: first[("robot", r)])

    rows = []
    for robot in robots:
        for op in ops:
            t = {lib: runs.get((lib, op, robot)) for lib in LIBS}
            if not any(t.values()):
                continue
            mn = {lib: min(v) if v else None for lib, v in t.items()}
            md = {lib: statistics.median(v) if v else None for lib, v in t.items()}
            noise = max((md[lib] / mn[lib] - 1 for lib in LIBS if mn[lib]), default=0.0)
            ratio = mn["rbdkit"] / mn["pinocchio"] if mn["rbdkit"] and mn["pinocchio"] else None
            reps = min(len(v) for v in t.values() if v)
            rows.append(dict(robot=robot, nv=nv.get(robot, ""), operation=op,
                             rbdkit_ns=mn["rbdkit"], pinocchio_ns=mn["pinocchio"], ratio=ratio,
                             rbdkit_ns_median=md["rbdkit"], pinocchio_ns_median=md["pinocchio"],
                             noise=noise, repetitions=reps))

    def f(x, width, prec):
        return f"{'-':>{width}}" if x is None else f"{x:{width}.{prec}f}"

    load_avg = ctx.get("load_avg")
    print(f"\nrbdkit vs Pinocchio, ns per call (min over {rows[0]['repetitions']} repetitions, "
          f"{args.time} time); ratio = rbdkit / Pinocchio")
    print(f"host {ctx.get('host_name', '?')}, {ctx.get('num_cpus', '?')} CPUs @ {ctx.get('mhz_per_cpu', '?')} MHz"
          + (f", load average {' '.join(f'{x:.2f}' for x in load_avg)}" if load_avg else "")
          + (", CPU scaling on" if ctx.get("cpu_scaling_enabled") else ""))
    head = f"{'robot':<16}{'nv':>4}  {'operation':<18}{'rbdkit':>11}{'pinocchio':>11}{'ratio':>8}{'noise':>8}"
    print(head)
    print("-" * len(head))
    last = None
    for r in rows:
        if last is not None and r["robot"] != last:
            print()
        last = r["robot"]
        print(f"{r['robot']:<16}{r['nv']:>4}  {r['operation']:<18}{f(r['rbdkit_ns'], 11, 0)}"
              f"{f(r['pinocchio_ns'], 11, 0)}{f(r['ratio'], 8, 2)}{r['noise'] * 100:7.0f}%")
    print("noise: median/min - 1 over the repetitions (the larger of the two libraries); "
          "a shared machine makes single timings noisy, compare ratios, not absolute times.")

    if args.csv:
        os.makedirs(os.path.dirname(os.path.abspath(args.csv)), exist_ok=True)
        with open(args.csv, "w", newline="") as out:
            w = csv.DictWriter(out, fieldnames=list(rows[0].keys()))
            w.writeheader()
            for r in rows:
                w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else ("" if v is None else v))
                            for k, v in r.items()})
        print(f"csv: {args.csv}")
    batched_report(args.json, batched_dir)


if __name__ == "__main__":
    main()
