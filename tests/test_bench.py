"""bench/ stays alive: every benchmark script is imported and its main(argv) run on tiny sizes (no timing asserted:
a refactor that breaks a benchmark fails here, not months later in `make bench`). Each run also checks what the
script itself compares (agreement of the baselines with the kernels, plan against its bound, blocks against in
memory), so a benchmark that runs but measures nonsense fails too."""
import importlib
import sys

import numpy as np
import pytest

from conftest import ROOT

BENCH = ROOT / "bench"
#: Modules of bench/ without a main: helpers the scripts import.
HELPERS = {"baselines"}
#: Every script and the tiny arguments the smoke test runs it with.
TINY = {
    "run": ["--poses", "3000", "--slow-poses", "100", "--fd-poses", "20", "--repeat", "1", "--grid", "3,3,3,4,3",
            "--no-compile", "--json", "--kernels", str(ROOT / "generated" / "li2018.py")],
    "baseline_split": ["--poses", "100"],
    "flops": ["--machine", "li2018"],
    "bench_diagnose": ["--poses", "200", "--subset-first", "2", "--subset-exact", "1", "--subset-period", "2",
                       "--repeat", "1"],
    "bench_profiles": ["--poses", "200", "--repeat", "1"],
    "bench_plan": ["--tiny"],
    "bench_plan_programs": None,          # needs a folder and rs274: its own test below
    "bench_scale": None,                  # subprocesses and a folder: its own test below
    "same_answers": None,                 # two folders of records: its own test below
    "exam": ["--trials", "3", "--poses", "200"],
    "sample_run": None,                   # writes a file: its own test below
    "joint_compensation": ["--seeds", "1", "--fits", "joint", "--rtest-poses", "40", "--poses", "100", "--nodes", "2",
                           "--comp-points", "3", "--json"],
}


def bench_module(name):
    """bench/NAME.py imported as a module (the scripts put bench/ on sys.path for their siblings themselves)."""
    if str(BENCH) not in sys.path:
        sys.path.insert(0, str(BENCH))
    return importlib.import_module(name)


def test_every_script_is_smoke_tested():
    scripts = {p.stem for p in BENCH.glob("*.py")}
    assert scripts == set(TINY) | HELPERS, "a bench script without a smoke test (add it to TINY), or a stale entry"
    for name in scripts:
        mod = bench_module(name)
        assert (name in HELPERS) != callable(getattr(mod, "main", None)), f"bench/{name}.py: main(argv) expected"


def test_run_gsil_rows_agree():
    rec = bench_module("run").main(TINY["run"])
    res = rec["results"]
    assert res["lambdify_numpy"]["max_rel_diff_vs_numba_gl8"] < 1e-12      # SymPy's lambdify vs the kernel
    assert res["numpy_htm_fd"]["max_rel_diff_vs_numba_gl8"] < 1e-6         # finite differences of a NumPy chain
    assert res["numba_1thread"]["max_rel_diff_vs_exact"] < 1e-12
    assert 1e-9 < res["numba_gl8_sensitivity_sum"]["max_rel_diff_vs_exact"] < 1e-3   # the 8-point rule's kinks
    assert rec["tensor_grid"]["max_rel_diff"] < 1e-12
    assert rec["tensor_grid"]["reduced_axes"] == ["X"]
    assert rec["flops_per_pose"] > 500 and 0 < rec["share_of_peak_avx2"]
    other = rec["kernels"][str(ROOT / "generated" / "li2018.py")]   # the same file loaded as another tree's
    assert other["max_rel_diff_vs_first"] == 0.0 and other["1_threads"]["poses_per_cpu_s"] > 0


def test_baseline_split_matches_the_kernel():
    import fiveaxis
    out = bench_module("baseline_split").main(TINY["baseline_split"])
    run = bench_module("run")
    rng = np.random.default_rng(0)
    q = run.WORKSPACE[:, 0] + (run.WORKSPACE[:, 1] - run.WORKSPACE[:, 0]) * rng.random((100, 5))
    x, w = np.polynomial.legendre.leggauss(8)
    W = np.zeros(41)
    fiveaxis.load("li2018").kernels.sensitivity_sum(q, run.L0 - run.LE / 2 + run.LE / 2 * x, run.LE / 2 * w,
                                                    np.full(41, 1e-4), 1e-12, W)
    for name, r in out.items():
        assert np.max(np.abs(r["W"] - W)) < 1e-12 * np.max(W), name


def test_flops_counts_the_kernel():
    out = bench_module("flops").main(TINY["flops"])
    assert 500 < out["flops_per_pose"]["li2018"] < 5000
    assert out["cpu"]["cores"] >= 1


@pytest.mark.slow
def test_bench_diagnose_tiny():
    out = bench_module("bench_diagnose").main(TINY["bench_diagnose"])
    assert out["poses"] == 200 and out["readings"] == 600
    assert set(out["families"]) >= {"polynomial", "periodic", "thermal"}
    assert out["diagnose_s"] > 0 and np.isfinite(out["speedup_vs_first_order_refit"])


@pytest.mark.slow
def test_bench_profiles_tiny():
    out = bench_module("bench_profiles").main(TINY["bench_profiles"])
    assert len(out) == 2 and all(r["profiles"] >= 1 and r["with_s"] > 0 for r in out.values())


@pytest.mark.slow
def test_bench_plan_tiny():
    out = bench_module("bench_plan").main(TINY["bench_plan"])
    (row,) = out["d"]
    assert row["D"] <= row["bound"] + 1e-9          # no N-pose plan from the candidates beats the bound
    assert row["bound"] <= row["bound_any"] + 1e-9
    (shares,) = out["detect"].values()
    assert all(0 <= s <= 1 for _, s in shares["plan"] + shares["random"])


@pytest.mark.slow
def test_bench_plan_programs_tiny(tmp_path, rs274):
    rows = bench_module("bench_plan_programs").main([str(tmp_path), "new", "--write", "ac_trunnion-rtest:12"])
    (row,) = rows
    assert row[:3] == ("ac_trunnion", "rtest", "joint") or row[:2] == ("ac_trunnion", "rtest")
    assert row[5].startswith("0 moves outside")      # a program plan writes keeps every move in the strokes


@pytest.mark.scale      # row blocks against memory, in processes: `make test-scale` (CI runs it)
def test_bench_scale_tiny(tmp_path):
    """Three processes (simulate, fit, diagnose in row blocks; the in-memory comparison is
    tests/test_row_blocks.py's); the hidden effect is found."""
    rows = bench_module("bench_scale").main(["--sizes", "3000", "--in-memory-upto", "0", "--keep", str(tmp_path)])
    assert [(r["command"], r["blocks"]) for r in rows] == [("fit", "on"), ("diagnose", "on")]
    assert rows[1]["readings"] == 9000 and 0.9 * 9000 < rows[0]["readings"] <= 9000   # the fit's: outliers out
    assert all(r["peak_mb"] > 0 for r in rows)
    assert rows[1]["found"], rows[1]


def test_same_answers_compares_records(tmp_path):
    """The JSON comparison of bench/same_answers.py: numbers by relative difference, anything else exactly."""
    import json
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    rec = {"verdict": "missing effect", "rms_mm": 0.002, "seconds": 3.0,
           "candidates": [{"id": "ex_x:x1", "delta_ebic": -120.5}, {"id": "dz_x:x2", "delta_ebic": -3.0}]}
    (a / "one.json").write_text(json.dumps(rec))
    rec2 = json.loads(json.dumps(rec))
    rec2["candidates"][0]["delta_ebic"] = -120.5 * (1 + 1e-12)
    rec2["seconds"] = 9.0                                                # times are not compared
    (b / "one.json").write_text(json.dumps(rec2))
    out = bench_module("same_answers").main(["compare", str(a), str(b)])
    assert out["other"] == 0 and 0.5e-12 < out["worst"] < 2e-12
    rec2["candidates"][1]["id"] = "dz_x:x1"                              # another candidate listed: a decision
    (b / "one.json").write_text(json.dumps(rec2))
    out = bench_module("same_answers").main(["compare", str(a), str(b)])
    assert out["other"] == 1


def test_exam_runs_and_measures():
    """The Monte-Carlo exam (issue 29) on three trials (tip readings on the three machines): every trial measured,
    the residual after the fit at the noise, the compensated workspace error below the uncompensated one, the
    summary's rates between 0 and 1 and its table printed."""
    out = bench_module("exam").main(TINY["exam"])
    s = out["summary"]
    assert s["trials"] == 3 and len(out["trials"]) == 3
    for r in out["trials"]:
        assert r["instrument"] == "tip" and 0.8 < r["rms_over_noise"] < 1.3
        assert r["workspace_after_um"] < r["workspace_before_um"] and r["band_um"][0] <= r["band_um"][1]
        assert 0 < r["quantities"] and 0 <= r["covered"] <= r["quantities"]
    for key in ("false_alarm_rate", "coverage_k2", "band_coverage"):
        assert s[key] is None or 0.0 <= s[key] <= 1.0
    assert out["table"].startswith("| measured | value") and set(out["tables"]) >= {"machine", "instrument"}


def test_joint_compensation_runs_and_measures():
    """Issue 29's joint criterion through the table (one seed, the joint fit, tiny sizes): the true error before and
    after measured from the independent chain, after below before, the predicted range ordered."""
    rows = bench_module("joint_compensation").main(TINY["joint_compensation"])
    assert len(rows) == 1 and set(rows[0]["fits"]) == {"joint"}
    f = rows[0]["fits"]["joint"]
    assert 0 < f["after_mm"] < rows[0]["before_mm"] and f["range_k2_mm"][0] <= f["range_k2_mm"][1]


def test_sample_run_samples_a_command(tmp_path):
    """bench/sample_run.py on a tiny simulate: the command ran, its RSS and its frames were sampled."""
    out = tmp_path / "s.csv"
    rec = bench_module("sample_run").main(["--period", "0.01", "--", "simulate", "--machine", "li2018", "--n", "50",
                                           "-o", str(out)])
    assert rec["rc"] == 0 and out.exists()
    assert rec["samples"] and all(rss > 0 for _, rss, _ in rec["samples"])
    assert "peak RSS" in rec["report"]
