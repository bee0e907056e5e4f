"""The batched benchmark's report: Google Benchmark JSON in, a ratio table,
CSV, JSON and a PNG out (used by `rbdkit bench` and bench/report.py).

Benchmark names: <impl>/<robot>/<op>/<dtype>/B<B>/T<threads>, impl rbdkit or
pinocchio, dtype f64 or f32, B0 the single-call latency; each run carries the
user counter per_knot_ns (ns per knot point). Over repetitions the minimum is
kept (the least disturbed run on a shared machine).

Table rows: robot x op x impl/dtype x threads; columns B0 and each batch
size; a cell is the ns per knot point and, for rbdkit, the ratio
rbdkit / Pinocchio at the same robot, op, B and threads (Pinocchio runs in
float64 only, so the float32 rows are compared with Pinocchio float64).
"""

import csv
import json
import os
import platform
import re

NAME = re.compile(r"^(rbdkit|pinocchio)/([^/]+)/([^/]+)/(f64|f32)/B(\d+)/T(\d+)(/|$)")
OPS = ("rnea", "crba", "minv", "aba", "rnea_derivatives", "aba_derivatives", "integrator_rk4",
       "integrator_gradient_rk4")
ROBOTS = ("iiwa", "hyq", "atlas", "hyq_floating", "atlas_floating")
# targets of issue 7 (reported, not asserted): single call <= 1.0, batched B >= 64 <= 0.5
TARGET_SINGLE, TARGET_BATCH, TARGET_BATCH_FROM = 1.0, 0.5, 64


def _to_ns(value, unit):
    return value * {"ns": 1.0, "us": 1e3, "ms": 1e6, "s": 1e9}[unit]


def parse(doc):
    """Google Benchmark JSON (a dict or a file path) -> (context, cells):
    cells {(impl, robot, op, dtype, B, threads): ns per knot point}"""
    if not isinstance(doc, dict):
        with open(doc) as f:
            doc = json.load(f)
    runs, aggregates = {}, {}
    for b in doc.get("benchmarks", []):
        if b.get("error_occurred"):
            continue
        m = NAME.match(b.get("run_name", b.get("name", "")))
        if not m:
            continue
        impl, robot, op, dtype, B, T = m.groups()[:6]
        key = (impl, robot, op, dtype, int(B), int(T))
        if "per_knot_ns" in b:
            ns = float(b["per_knot_ns"])
        else:  # the time per iteration over the knot points of one call
            ns = _to_ns(float(b["real_time"]), b.get("time_unit", "ns")) / max(1, int(B))
        if b.get("run_type", "iteration") == "iteration":
            runs.setdefault(key, []).append(ns)
        else:
            aggregates.setdefault(key, {})[b.get("aggregate_name", "")] = ns
    cells = {k: min(v) for k, v in runs.items()}
    for k, agg in aggregates.items():  # only aggregates were written (--benchmark_report_aggregates_only)
        if k not in cells:
            for name in ("min", "median", "mean"):
                if name in agg:
                    cells[k] = agg[name]
                    break
    return doc.get("context", {}), cells


def _order(values, preferred):
    return sorted(values, key=lambda v: (preferred.index(v) if v in preferred else len(preferred), v))


def table(cells):
    """the report rows: dicts with robot, op, impl, dtype, threads and per B
    (B0 first) {'ns': ..., 'ratio': ...} (ratio None for Pinocchio rows or
    without a Pinocchio cell)"""
    batches = sorted({k[4] for k in cells})
    keys = {(k[1], k[2], k[0], k[3], k[5]) for k in cells}
    impl_order = {("rbdkit", "f64"): 0, ("rbdkit", "f32"): 1, ("pinocchio", "f64"): 2, ("pinocchio", "f32"): 3}
    robots = _order({k[0] for k in keys}, ROBOTS)
    ops = _order({k[1] for k in keys}, OPS)
    rows = []
    for robot in robots:
        for op in ops:
            for impl, dtype, T in sorted({(k[2], k[3], k[4]) for k in keys if k[:2] == (robot, op)},
                                         key=lambda x: (impl_order.get(x[:2], 9), x[2])):
                row = dict(robot=robot, op=op, impl=impl, dtype=dtype, threads=T, cells={})
                for B in batches:
                    ns = cells.get((impl, robot, op, dtype, B, T))
                    if ns is None:
                        continue
                    pin = cells.get(("pinocchio", robot, op, "f64", B, T))
                    ratio = ns / pin if impl == "rbdkit" and pin else None
                    row["cells"][B] = dict(ns=ns, pinocchio_ns=pin, ratio=ratio)
                rows.append(row)
    return rows, batches


def targets(rows):
    """(met, missed) lists of (row label, B, ratio) against the issue's targets"""
    met, missed = [], []
    for r in rows:
        if r["impl"] != "rbdkit" or r["dtype"] != "f64":
            continue
        for B, c in r["cells"].items():
            if c["ratio"] is None or (0 < B < TARGET_BATCH_FROM):
                continue
            limit = TARGET_SINGLE if B == 0 else TARGET_BATCH
            item = (f"{r['robot']}/{r['op']}/T{r['threads']}", B, c["ratio"], limit)
            (met if c["ratio"] <= limit else missed).append(item)
    return met, missed


def _fmt_ns(ns):
    return f"{ns:.0f}" if ns >= 100 else f"{ns:.1f}"


def format_table(rows, batches, context=None):
    """the table as text"""
    width = 16
    head = f"{'robot':<15}{'op':<24}{'impl':<10}{'dtype':<6}{'T':>2} " + "".join(
        f"{('B0 (1 call)' if B == 0 else f'B={B}'):>{width}}" for B in batches)
    lines = []
    if context:
        lines.append(f"host {context.get('host_name', '?')}, {context.get('num_cpus', '?')} CPUs @ "
                     f"{context.get('mhz_per_cpu', '?')} MHz, {context.get('date', '')}")
    lines.append("ns per knot point (min over repetitions); (ratio) = rbdkit / Pinocchio float64, same B and threads")
    lines += [head, "-" * len(head)]
    last = None
    for r in rows:
        if last is not None and (r["robot"], r["op"]) != last:
            lines.append("")
        last = (r["robot"], r["op"])
        cells = ""
        for B in batches:
            c = r["cells"].get(B)
            if c is None:
                s = "-"
            elif c["ratio"] is None:
                s = _fmt_ns(c["ns"])
            else:
                s = f"{_fmt_ns(c['ns'])} ({c['ratio']:.2f})"
            cells += f"{s:>{width}}"
        lines.append(f"{r['robot']:<15}{r['op']:<24}{r['impl']:<10}{r['dtype']:<6}{r['threads']:>2} {cells}")
    met, missed = targets(rows)
    if met or missed:
        lines.append("")
        lines.append(f"targets (rbdkit float64): single call ratio <= {TARGET_SINGLE}, B >= {TARGET_BATCH_FROM} "
                     f"ratio <= {TARGET_BATCH}: {len(met)} cells met, {len(missed)} missed")
        for label, B, ratio, limit in sorted(missed, key=lambda m: -m[2] / m[3])[:10]:
            lines.append(f"  missed {label} B{B}: {ratio:.2f} (target {limit})")
    return "\n".join(lines)


def machine_info(context):
    """Google Benchmark's context plus this interpreter's view of the machine"""
    info = {k: context[k] for k in ("host_name", "num_cpus", "mhz_per_cpu", "cpu_scaling_enabled", "caches",
                                    "load_avg", "library_build_type", "date", "executable") if k in context}
    info.update(platform=platform.platform(), machine=platform.machine(), processor=platform.processor(),
                python=platform.python_version(), cpu_count=os.cpu_count())
    return info


def write_csv(rows, path):
    """one line per cell: robot, op, impl, dtype, threads, B, ns_per_knot, pinocchio_ns_per_knot, ratio"""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["robot", "op", "impl", "dtype", "threads", "B", "ns_per_knot", "pinocchio_ns_per_knot", "ratio"])
        for r in rows:
            for B, c in sorted(r["cells"].items()):
                w.writerow([r["robot"], r["op"], r["impl"], r["dtype"], r["threads"], B, f"{c['ns']:.6g}",
                            "" if c["pinocchio_ns"] is None else f"{c['pinocchio_ns']:.6g}",
                            "" if c["ratio"] is None else f"{c['ratio']:.6g}"])


def write_json(rows, batches, context, path):
    met, missed = targets(rows)
    doc = dict(machine=machine_info(context), batches=batches,
               rows=[{**{k: v for k, v in r.items() if k != "cells"},
                      "cells": {str(B): c for B, c in sorted(r["cells"].items())}} for r in rows],
               targets=dict(single_call=TARGET_SINGLE, batched=TARGET_BATCH, batched_from=TARGET_BATCH_FROM,
                            met=len(met), missed=[dict(cell=m[0], B=m[1], ratio=m[2], target=m[3]) for m in missed]))
    with open(path, "w") as f:
        json.dump(doc, f, indent=1)


def write_png(rows, path):
    """time per knot point against B (log-log), one panel per robot and op:
    rbdkit f64 / f32 and Pinocchio, solid 1 thread, dashed 2 threads"""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    robots = _order({r["robot"] for r in rows}, ROBOTS)
    ops = _order({r["op"] for r in rows}, OPS)
    fig, axes = plt.subplots(len(ops), len(robots), figsize=(3.6 * len(robots), 2.8 * len(ops)), squeeze=False)
    colors = {("rbdkit", "f64"): "tab:blue", ("rbdkit", "f32"): "tab:green", ("pinocchio", "f64"): "tab:red",
              ("pinocchio", "f32"): "tab:orange"}
    for i, op in enumerate(ops):
        for j, robot in enumerate(robots):
            ax = axes[i][j]
            for r in rows:
                if (r["robot"], r["op"]) != (robot, op):
                    continue
                pts = sorted((B, c["ns"]) for B, c in r["cells"].items() if B > 0)
                if pts:
                    ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", ms=3,
                            color=colors.get((r["impl"], r["dtype"]), "k"),
                            linestyle="-" if r["threads"] == 1 else "--",
                            label=f"{r['impl']} {r['dtype']} T{r['threads']}")
            ax.set_title(f"{robot}: {op}", fontsize=9)
            if not ax.get_lines():
                ax.axis("off")
                ax.text(0.5, 0.5, "no runs", ha="center", va="center", transform=ax.transAxes, fontsize=8)
                continue
            ax.set_xscale("log", base=2)
            ax.set_yscale("log")
            ax.tick_params(labelsize=7)
            if i == len(ops) - 1:
                ax.set_xlabel("B (knot points per call)", fontsize=8)
            if j == 0:
                ax.set_ylabel("ns per knot point", fontsize=8)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def report(source, out_dir=None, png=True, stream=None):
    """parse `source` (a Google Benchmark JSON path or dict), print the
    table to `stream` (stdout) and write results.csv, results.json and
    per_knot.png into out_dir when given; returns (rows, paths)"""
    import sys
    stream = stream or sys.stdout
    context, cells = parse(source)
    if not cells:
        raise ValueError("benchmark JSON: no <impl>/<robot>/<op>/<dtype>/B<B>/T<threads> benchmarks in it")
    rows, batches = table(cells)
    print(format_table(rows, batches, context), file=stream)
    paths = {}
    if out_dir:
        os.makedirs(out_dir, exist_ok=True)
        paths["csv"] = os.path.join(out_dir, "results.csv")
        paths["json"] = os.path.join(out_dir, "results.json")
        write_csv(rows, paths["csv"])
        write_json(rows, batches, context, paths["json"])
        if png:
            paths["png"] = os.path.join(out_dir, "per_knot.png")
            write_png(rows, paths["png"])
        print("\n" + "\n".join(f"{k}: {v}" for k, v in paths.items()), file=stream)
    return rows, paths
