#!/usr/bin/env python3
"""Instructions per call from the callgrind dumps of `rbdkit_bench --count_calls=N`.

    bench/callgrind_report.py DIR N [--markdown]

DIR holds the dumps (callgrind.out.*) that bench/run.sh's COUNT_CALLS=N mode
writes, one per <library>/<operation>/<robot> loop of N calls. Prints, per
operation and robot, the instructions per call of both libraries and their
ratio rbdkit / Pinocchio. Instruction counts do not depend on the machine's
load, so they separate "more work" from "noisy timing".
"""
import argparse
import os
import re
import sys


def read_dumps(folder):
    """{(library, operation, robot): instructions} from every dump in folder."""
    counts = {}
    for name in sorted(os.listdir(folder)):
        if not name.startswith("callgrind.out"):
            continue
        trigger, total = None, None
        with open(os.path.join(folder, name), errors="replace") as f:
            for line in f:
                m = re.match(r"desc: Trigger: Client Request: (\S+)", line)
                if m:
                    trigger = m.group(1)
                m = re.match(r"(?:summary|totals): (\d+)", line)
                if m:
                    total = int(m.group(1))
        if trigger and total is not None and trigger.count("/") == 2:
            counts[tuple(trigger.split("/"))] = total
    return counts


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("calls", type=int)
    ap.add_argument("--markdown", action="store_true", help="a Markdown table")
    a = ap.parse_args()
    counts = read_dumps(a.folder)
    if not counts:
        sys.exit(f"callgrind_report: no dumps with a <library>/<operation>/<robot> trigger in {a.folder}")
    rows = sorted({(op, robot) for (_, op, robot) in counts}, key=lambda k: (k[0], k[1]))
    head = ("operation", "robot", "rbdkit Ir/call", "Pinocchio Ir/call", "ratio")
    out = []
    for op, robot in rows:
        r = counts.get(("rbdkit", op, robot))
        p = counts.get(("pinocchio", op, robot))
        cell = lambda x: "-" if x is None else f"{x / a.calls:.0f}"
        ratio = f"{r / p:.2f}" if r and p else "-"
        out.append((op, robot, cell(r), cell(p), ratio))
    if a.markdown:
        print("| " + " | ".join(head) + " |")
        print("|---|---|---:|---:|---:|")
        for row in out:
            print("| " + " | ".join(row) + " |")
    else:
        print("%-18s %-16s %15s %18s %7s" % head)
        for row in out:
            print("%-18s %-16s %15s %18s %7s" % row)


if __name__ == "__main__":
    main()
