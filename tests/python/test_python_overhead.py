"""bench/python_overhead.py --quick runs end to end and writes a well-formed
JSON (no timing asserted: the script itself checks rbdkit's results against
Pinocchio's before it times them, and stops when they differ)."""

import json
import math
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, os.pardir, os.pardir, "bench", "python_overhead.py")
OPS = {"rnea", "crba", "aba", "minv", "rnea_derivatives", "aba_derivatives", "integrate"}
ROBOTS = {"iiwa", "hyq_floating"}


def positive(x):
    return isinstance(x, float) and math.isfinite(x) and x > 0


def test_quick_run_writes_the_report(tmp_path):
    out = tmp_path / "overhead.json"
    p = subprocess.run([sys.executable, SCRIPT, "--quick", "--out", str(out)], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "One sample per call" in p.stdout and "Thread scaling" in p.stdout
    res = json.loads(out.read_text())
    assert res["settings"]["quick"] is True

    single = res["single"]
    assert {(x["robot"], x["op"]) for x in single} == {(r, o) for r in ROBOTS for o in OPS}
    for x in single:
        assert positive(x["rbdkit_us"]) and positive(x["pinocchio_us"]), x
        assert math.isclose(x["ratio"], x["rbdkit_us"] / x["pinocchio_us"], rel_tol=1e-9), x
        assert x["meets"] == (x["ratio"] <= x["target"]) and x["target"] == 1.3
        assert x["max_abs_diff"] <= 1e-6, x

    handle = res["handle"]
    assert {(x["robot"], x["op"]) for x in handle} == {(r, o) for r in ROBOTS for o in OPS}
    for x in handle:
        assert positive(x["handle_us"]), x
        # C++ per-call time where time_per_call has the operation, the engine at B = 1 for every engine operation
        assert (x["cpp_us"] is not None) == (x["op"] in ("rnea", "crba", "aba", "minv")), x
        assert (x["engine_us"] is None) == (x["op"] == "integrate"), x
        if x["overhead_us"] is not None:
            base = x["cpp_us"] if x["overhead_above"] == "time_per_call" else x["engine_us"]
            assert math.isclose(x["overhead_us"], x["handle_us"] - base, rel_tol=1e-9, abs_tol=1e-9), x

    assert {x["B"] for x in res["batched"]} == {64}
    for x in res["batched"]:
        assert positive(x["handle_ns"]) and positive(x["engine_ns"]), x

    threads = res["threads"]
    assert len(threads) == len(ROBOTS) * 8  # the six above, the RK4 step and its gradient
    for x in threads:
        assert positive(x["engine_t1_ns"]) and positive(x["engine_t2_ns"]), x
        assert ("ratio_t2" in x) == (x["op"] in ("rnea", "aba")), x  # Pinocchio's rneaInParallel / abaInParallel

    bd = res["breakdown"]
    assert len(bd["pieces"]) == 8 and all(isinstance(p["us"], float) and p["us"] > 0 for p in bd["pieces"])
    assert set(res["cprofile"]) == {"rbd.inverse_dynamics", "Handle.inverse_dynamics B=1"}
