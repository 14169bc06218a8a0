"""The exam of issue 29 (bench/exam.py) on a handful of sets, asserting only what a handful can show: no false alarm
on four null sets; on four sets hiding one effect (random family) at 10x the noise, the verdict 'missing effect' on
each, the hidden physics named on at least three (the done criterion is 90 %) and the residual at the noise once the
right one is added. The true readings come from the independent NumPy chain (fiveaxis.model.htm), written as a
controller writes them or with 7 digits; the rates over hundreds of sets are in docs/exam.md."""
import numpy as np
import pytest

import fiveaxis
from test_bench import bench_module

#: (machine, instrument, resolution, seed): every machine, both ways of writing.
SETS = (("li2018", "tip", "controller", 1), ("ac_trunnion", "tip", "seven digits", 2),
        ("tilting_head", "tip", "seven digits", 3), ("ac_trunnion", "rtest", "controller", 4))
POSES = 100


@pytest.fixture(scope="module")
def exam():
    return bench_module("exam")


@pytest.fixture(scope="module")
def models():
    return {m: fiveaxis.load(m) for m in {s[0] for s in SETS}}


def _runs(exam, models, k, tmp_path, monkeypatch):
    monkeypatch.setattr(exam, "WORKSPACE_POSES", 100)
    return [exam.run_set(models[machine], instrument, resolution, POSES, seed, k, np.random.default_rng(seed),
                         tmp_path / f"{machine}-{instrument}.csv", seed)
            for machine, instrument, resolution, seed in SETS]


def test_no_false_alarm_on_four_null_sets(exam, models, tmp_path, monkeypatch):
    for rec in _runs(exam, models, None, tmp_path, monkeypatch):
        assert rec["verdict"] == "no missing effect" and 0.75 < rec["rms_over_noise"] < 1.25, rec


def test_effects_at_ten_times_the_noise_are_found(exam, models, tmp_path, monkeypatch):
    recs = _runs(exam, models, 10.0, tmp_path, monkeypatch)
    assert not any(r["null"] for r in recs)                # an effect each plan sees was drawn
    assert all(r["verdict"] == "missing effect" for r in recs), recs
    right = [r for r in recs if r["right"]]
    assert len(right) >= 3, recs
    for r in right:
        assert r["rms_over_noise"] < 1.5 and r["workspace_after_um"] < 0.5 * r["workspace_before_um"], r
