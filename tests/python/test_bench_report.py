"""rbdkit.benchreport and `rbdkit bench` on a small synthetic Google
Benchmark JSON written here: the table's ratios, the CSV and JSON contents,
the PNG, the benchmark filter, and the command end to end with a stand-in
bench/run.sh (no build, no timing)."""

import csv
import io
import json
import os
import re
import stat
import subprocess
import sys

import pytest

from rbdkit import benchreport, cli

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, os.pardir, os.pardir))

# (impl, robot, op, dtype, B, threads) -> ns per knot point, over two repetitions
TIMES = {
    ("rbdkit", "iiwa", "rnea", "f64", 0, 1): (400.0, 420.0),
    ("pinocchio", "iiwa", "rnea", "f64", 0, 1): (500.0, 800.0),
    ("rbdkit", "iiwa", "rnea", "f64", 64, 1): (100.0, 90.0),
    ("rbdkit", "iiwa", "rnea", "f32", 64, 1): (60.0, 70.0),
    ("pinocchio", "iiwa", "rnea", "f64", 64, 1): (450.0, 460.0),
    ("rbdkit", "iiwa", "rnea", "f64", 64, 2): (50.0, 55.0),
    ("pinocchio", "iiwa", "rnea", "f64", 64, 2): (230.0, 240.0),
    ("rbdkit", "atlas_floating", "integrator_gradient_rk4", "f64", 1024, 2): (30000.0, 31000.0),
    ("pinocchio", "atlas_floating", "integrator_gradient_rk4", "f64", 1024, 2): (40000.0, 41000.0),
    ("rbdkit", "atlas_floating", "integrator_gradient_rk4", "f64", 16, 1): (62000.0, 61000.0),  # no Pinocchio cell
}


def synthetic_json(aggregates_only=False):
    """Google Benchmark's JSON layout: context, then runs (repetitions as
    iteration runs, plus aggregates), names with the /repeats: suffix"""
    benches = [{"name": "rbdkit/iiwa/old_style_name", "run_name": "rbdkit/rnea/iiwa", "run_type": "iteration",
                "real_time": 1.0, "cpu_time": 1.0, "time_unit": "ns"}]
    for (impl, robot, op, dt, B, T), reps in TIMES.items():
        name = f"{impl}/{robot}/{op}/{dt}/B{B}/T{T}"
        base = dict(run_name=name, time_unit="us", threads=1, repetitions=len(reps))
        if not aggregates_only:
            for k, ns in enumerate(reps):
                benches.append(dict(base, name=name + "/repeats:2", run_type="iteration", repetition_index=k,
                                    real_time=ns * max(1, B) / 1e3, cpu_time=ns * max(1, B) / 1e3, per_knot_ns=ns))
        for agg, f in (("mean", lambda r: sum(r) / len(r)), ("median", lambda r: sorted(r)[0]), ("min", min)):
            benches.append(dict(base, name=f"{name}/repeats:2_{agg}", run_type="aggregate", aggregate_name=agg,
                                real_time=0.0, cpu_time=0.0, per_knot_ns=f(reps)))
    benches.append(dict(name="rbdkit/iiwa/rnea/f64/B16/T1", run_name="rbdkit/iiwa/rnea/f64/B16/T1",
                        run_type="iteration", error_occurred=True, error_message="skipped"))
    return {"context": {"host_name": "testhost", "num_cpus": 2, "mhz_per_cpu": 3000, "date": "today",
                        "library_build_type": "release"}, "benchmarks": benches}


@pytest.fixture
def bench_json(tmp_path):
    p = tmp_path / "gb.json"
    p.write_text(json.dumps(synthetic_json()))
    return str(p)


def cell(rows, robot, op, impl, dtype, threads, B):
    for r in rows:
        if (r["robot"], r["op"], r["impl"], r["dtype"], r["threads"]) == (robot, op, impl, dtype, threads):
            return r["cells"].get(B)
    return None


@pytest.mark.parametrize("aggregates_only", [False, True])
def test_parse_takes_the_minimum_and_skips_the_rest(aggregates_only):
    ctx, cells = benchreport.parse(synthetic_json(aggregates_only))
    assert ctx["host_name"] == "testhost"
    assert cells == {k: min(v) for k, v in TIMES.items()}  # old-style and errored runs left out


def test_table_ratios(bench_json):
    rows, batches = benchreport.table(benchreport.parse(bench_json)[1])
    assert batches == [0, 16, 64, 1024]
    # rbdkit / Pinocchio float64, same B and threads, minima over repetitions
    assert cell(rows, "iiwa", "rnea", "rbdkit", "f64", 1, 0)["ratio"] == pytest.approx(400 / 500)
    assert cell(rows, "iiwa", "rnea", "rbdkit", "f64", 1, 64)["ratio"] == pytest.approx(90 / 450)
    assert cell(rows, "iiwa", "rnea", "rbdkit", "f64", 2, 64)["ratio"] == pytest.approx(50 / 230)
    # float32 rows against Pinocchio float64
    assert cell(rows, "iiwa", "rnea", "rbdkit", "f32", 1, 64)["ratio"] == pytest.approx(60 / 450)
    # Pinocchio rows carry times, no ratio; a cell without Pinocchio has none either
    assert cell(rows, "iiwa", "rnea", "pinocchio", "f64", 1, 64) == dict(ns=450.0, pinocchio_ns=450.0, ratio=None)
    assert cell(rows, "atlas_floating", "integrator_gradient_rk4", "rbdkit", "f64", 1, 16)["ratio"] is None
    assert cell(rows, "atlas_floating", "integrator_gradient_rk4", "rbdkit", "f64", 2, 1024)["ratio"] == \
        pytest.approx(30000 / 40000)
    # rows in robot, op, then rbdkit f64, rbdkit f32, Pinocchio order
    labels = [(r["robot"], r["impl"], r["dtype"], r["threads"]) for r in rows]
    assert labels[:5] == [("iiwa", "rbdkit", "f64", 1), ("iiwa", "rbdkit", "f64", 2), ("iiwa", "rbdkit", "f32", 1),
                          ("iiwa", "pinocchio", "f64", 1), ("iiwa", "pinocchio", "f64", 2)]
    # targets: single call 0.8 <= 1 met; B64 T1 0.2 and T2 0.217 met; B1024 0.75 > 0.5 missed
    met, missed = benchreport.targets(rows)
    assert len(met) == 3 and [(m[0], m[1]) for m in missed] == [("atlas_floating/integrator_gradient_rk4/T2", 1024)]


def test_printed_table(bench_json):
    out = io.StringIO()
    benchreport.report(bench_json, stream=out)
    text = out.getvalue()
    assert "host testhost, 2 CPUs" in text
    line = next(l for l in text.splitlines() if l.startswith("iiwa") and " rbdkit " in l and " f64 " in l)
    assert "400 (0.80)" in line and "90.0 (0.20)" in line
    assert re.search(r"1 missed|missed atlas_floating/integrator_gradient_rk4/T2 B1024: 0\.75", text)


def test_csv_json_png_written(bench_json, tmp_path):
    out = tmp_path / "report"
    rows, paths = benchreport.report(bench_json, str(out), stream=io.StringIO())
    assert set(paths) == {"csv", "json", "png"}
    with open(paths["csv"]) as f:
        lines = list(csv.DictReader(f))
    assert len(lines) == sum(len(r["cells"]) for r in rows) == len(TIMES)
    l = next(l for l in lines if (l["robot"], l["impl"], l["dtype"], l["threads"], l["B"]) ==
             ("iiwa", "rbdkit", "f32", "1", "64"))
    assert float(l["ns_per_knot"]) == 60 and float(l["pinocchio_ns_per_knot"]) == 450
    assert float(l["ratio"]) == pytest.approx(60 / 450, rel=1e-5)
    doc = json.load(open(paths["json"]))
    assert doc["machine"]["host_name"] == "testhost" and "platform" in doc["machine"]
    assert doc["batches"] == [0, 16, 64, 1024]
    r = next(r for r in doc["rows"]
             if (r["robot"], r["impl"], r["dtype"], r["threads"]) == ("iiwa", "rbdkit", "f64", 1))
    assert r["cells"]["0"]["ratio"] == pytest.approx(0.8)
    assert doc["targets"]["missed"][0]["cell"] == "atlas_floating/integrator_gradient_rk4/T2"
    with open(paths["png"], "rb") as f:
        assert f.read(8) == b"\x89PNG\r\n\x1a\n"
    assert os.path.getsize(paths["png"]) > 10000


def test_empty_json_is_an_error(tmp_path):
    p = tmp_path / "empty.json"
    p.write_text(json.dumps({"context": {}, "benchmarks": []}))
    with pytest.raises(ValueError, match="no <impl>/<robot>/<op>/<dtype>/B<B>/T<threads> benchmarks"):
        benchreport.report(str(p), stream=io.StringIO())


def test_benchmark_filter():
    names = [f"{i}/{r}/{o}/{d}/B{b}/T{t}" for i in ("rbdkit", "pinocchio") for r in ("iiwa", "hyq_floating")
             for o in ("rnea", "integrator_rk4") for d in ("f64", "f32") for b in (0, 1, 16, 1024) for t in (1, 2)]
    f = re.compile(cli.bench_filter(["iiwa"], ["rnea"], [1, 1024], [2]))
    picked = [n for n in names if f.search(n)]
    assert picked and all(n.split("/")[1:3] == ["iiwa", "rnea"] for n in picked)
    assert {n.split("/")[4] for n in picked} == {"B1", "B1024"}  # not B16 (prefix B1)
    assert {n.split("/")[5] for n in picked} == {"T2"}
    assert all(re.compile(cli.bench_filter()).search(n) for n in names)
    assert re.compile(cli.bench_filter(batch=[0])).search("rbdkit/iiwa/rnea/f64/B0/T1/repeats:5")


def test_bench_report_only_from_json(bench_json, tmp_path, capsys):
    out = tmp_path / "o"
    assert cli.main(["bench", "--json", bench_json, "--out", str(out)]) == 0
    assert "(0.80)" in capsys.readouterr().out
    assert sorted(os.listdir(out)) == ["per_knot.png", "results.csv", "results.json"]


def test_bench_runs_run_sh_and_reports(tmp_path, monkeypatch, capsys):
    # a stand-in source checkout whose bench/run.sh records its arguments and
    # environment and writes the synthetic JSON where BENCH_JSON says
    src = tmp_path / "src"
    (src / "bench").mkdir(parents=True)
    (tmp_path / "gb.json").write_text(json.dumps(synthetic_json()))
    script = src / "bench" / "run.sh"
    script.write_text(f'#!/usr/bin/env bash\nprintf "%s\\n" "$@" > {tmp_path}/args\n'
                      f'echo "$BENCH_REPORT $REPS $MIN_TIME" > {tmp_path}/env\n'
                      f'for a in "$@"; do [[ $a == --benchmark_out=* ]] && cp {tmp_path}/gb.json "${{a#*=}}"; done\n'
                      f'exit 0\n')
    script.chmod(script.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("RBDKIT_SOURCE_DIR", str(src))
    monkeypatch.delenv("REPS", raising=False)
    monkeypatch.delenv("MIN_TIME", raising=False)
    out = tmp_path / "o"
    rc = cli.main(["bench", "--robots", "iiwa,atlas_floating", "--ops", "rnea", "--batch", "0,64", "--threads", "1",
                   "--quick", "--out", str(out), "--no-png", "--", "--benchmark_min_warmup_time=0"])
    assert rc == 0
    args = (tmp_path / "args").read_text().split()
    assert args == ["--benchmark_filter=" + cli.bench_filter(["iiwa", "atlas_floating"], ["rnea"], [0, 64], [1]),
                    "--benchmark_min_warmup_time=0", f"--benchmark_out={out / 'benchmark.json'}",
                    "--benchmark_out_format=json"]
    assert (tmp_path / "env").read_text().split() == ["0", "1", "0.05"]
    assert "(0.80)" in capsys.readouterr().out
    assert sorted(os.listdir(out)) == ["benchmark.json", "results.csv", "results.json"]


def test_bench_bad_options(tmp_path, monkeypatch, capsys):
    for argv, msg in ((["--robots", "iiwa,nope"], "--robots: unknown robot 'nope'; expected some of iiwa, hyq"),
                      (["--ops", "rk4"], "--ops: unknown op 'rk4'"),
                      (["--batch", "16,x"], "--batch: expected integers >= 0, got 'x'"),
                      (["--threads", "0"], "--threads: expected integers >= 1, got '0'"),
                      (["--robots", ","], "--robots: expected a comma-separated list"),
                      (["--json", str(tmp_path / "missing.json")], "--json: no file at")):
        assert cli.main(["bench", "--out", str(tmp_path / "o"), *argv]) == 2
        assert msg in capsys.readouterr().err


def test_bench_without_a_source_checkout(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("RBDKIT_SOURCE_DIR", str(tmp_path))  # no bench/run.sh there
    monkeypatch.setattr(cli, "source_dir", lambda: None)
    assert cli.main(["bench", "--out", str(tmp_path / "o")]) == 2
    assert "rbdkit bench needs the rbdkit source checkout (bench/run.sh)" in capsys.readouterr().err


def test_source_dir_is_this_checkout():
    # the installed package records the checkout it was built from
    assert os.path.samefile(cli.source_dir(), ROOT)


def test_bench_report_py_delegates(bench_json, tmp_path):
    # bench/report.py (run by bench/run.sh) prints the batched table from the same JSON
    r = subprocess.run([sys.executable, os.path.join(ROOT, "bench", "report.py"), bench_json, "--csv",
                        str(tmp_path / "latest.csv")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "batched: rbdkit vs Pinocchio per knot point" in r.stdout and "(0.80)" in r.stdout
    assert os.path.isfile(tmp_path / "batched" / "results.csv")


def test_bench_prefers_the_batched_script(tmp_path, monkeypatch, capsys):
    src = tmp_path / "src"
    (src / "bench").mkdir(parents=True)
    (tmp_path / "gb.json").write_text(json.dumps(synthetic_json()))
    for name in ("run.sh", "run_batch.sh"):
        (src / "bench" / name).write_text(
            f'#!/usr/bin/env bash\necho {name} > {tmp_path}/which\n'
            f'for a in "$@"; do [[ $a == --benchmark_out=* ]] && cp {tmp_path}/gb.json "${{a#*=}}"; done\nexit 0\n')
    monkeypatch.setenv("RBDKIT_SOURCE_DIR", str(src))
    assert cli.main(["bench", "--out", str(tmp_path / "o"), "--no-png"]) == 0
    assert (tmp_path / "which").read_text().strip() == "run_batch.sh"
    # a failing script: its exit status and name
    (src / "bench" / "run_batch.sh").write_text("#!/usr/bin/env bash\nexit 3\n")
    capsys.readouterr()
    assert cli.main(["bench", "--out", str(tmp_path / "o"), "--no-png"]) == 3
    assert "bench/run_batch.sh failed (exit status 3)" in capsys.readouterr().err
