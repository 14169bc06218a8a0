"""Effects beyond polynomials (issue 9): reversal, periodic with the period searched, thermal with the time constant
searched, gross outliers, and the verdict when nothing in the vocabulary explains the residual. Every case is
simulated with the exact model; the truth (hidden effect, its period or time constant, the outlier rows) is known
independently of the diagnosis."""
import json

import numpy as np
import pytest

import fiveaxis
from fiveaxis.diagnosis import diagnose as D
from fiveaxis.diagnosis import searches as es
from fiveaxis.estimation import fit as F
from conftest import run_cli
from fiveaxis.measurement.simulate import simulate
from fiveaxis.estimation import result as R
from fiveaxis.report import text
from fiveaxis.diagnosis.candidates import param_columns
from fiveaxis.diagnosis.decision import basis_map

from conftest import first_fast

NOISE = 1e-3
DIRS = {"directions": True}          # tip plans with the approach directions of the linear axes (dir_ columns)


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018")


def ids_of(c):
    return {c["id"], *c["aliases"]}


def add_outliers(meas, fraction, size, seed):
    """Add +-size (mm) to a fraction of the tip readings; returns the data rows hit."""
    rng = np.random.default_rng(seed)
    m = meas.n
    k = int(round(fraction * 3 * m))
    flat = rng.choice(3 * m, k, replace=False)
    rows, comp = flat // 3, flat % 3
    meas.d[rows, comp] += size * rng.choice([-1.0, 1.0], k)
    return set(meas.rows[rows].tolist())


# -- reversal ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("instrument, n, options", [
    ("interferometer", 300, None),       # ISO 230-2 bidirectional runs
    ("ballbar", 600, None),              # ISO 230-4 circles, both directions
    ("tip", 800, DIRS),                  # random poses visited in order
])
def test_hidden_backlash_ranked_first_and_residual_falls_to_noise(model, instrument, n, options):
    sim = simulate(model, ["dx_x:xr=0.003"], n=n, noise=NOISE, seed=41, instrument=instrument, options=options)
    dg = D.diagnose(model, sim.meas, top=3)
    top = dg.candidates[0]
    assert dg.verdict == "missing effect" and dg.missing_effect
    assert "dx_x:xr" in ids_of(top) and top["family"] == "reversal", top
    assert dg.rms_mm_without_outliers > 1.5 * NOISE
    after = D.diagnose(model, sim.meas, ["dx_x:xr"], top=3)
    assert after.rms_mm_without_outliers <= 1.25 * NOISE
    assert after.verdict == "no missing effect"
    p = R.parameters(after.fit)["dx_x:xr"]
    assert abs(p["value"] - 0.003) < 4 * p["std"]                  # c of the backlash 2c = 6 um
    assert p["description"].startswith(f"the X axis reverses with a backlash of {2e3 * p['value']:.2g} um")


def test_reversal_candidates_only_with_direction_columns(model):
    with pytest.raises(fiveaxis.InputError, match="need a dir_X column"):
        simulate(model, ["dx_x:xr=0.003"], n=50, noise=NOISE, seed=42)
    sim = simulate(model, ["ex_x:x1=2e-5"], n=300, noise=NOISE, seed=42)           # no dir_ columns
    dg = D.diagnose(model, sim.meas, top=3)
    assert "reversal" not in dg.decision["families"]
    assert not any(c["family"] == "reversal" for c in dg.candidates)


# -- periodic and thermal: the searches ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def periodic_set(model):
    return simulate(model, ["dx_x:xp800=0.003,0.001"], n=1000, noise=NOISE, seed=43)


def test_hidden_periodic_error_found_with_its_period(model, periodic_set):
    dg = D.diagnose(model, periodic_set.meas, top=3)
    top = dg.candidates[0]
    assert dg.verdict == "missing effect" and top["family"] == "periodic"
    assert "dx_x" in {i.split(":")[0] for i in ids_of(top)}
    assert abs(top["period"] - 800) < 0.05 * 800, top
    assert "lead-screw" in top["description"] and "period of" in top["description"]
    assert top["amplitude"] == pytest.approx(np.hypot(0.003, 0.001), rel=0.1)
    after = D.diagnose(model, periodic_set.meas, [top["id"]], top=3)
    assert after.rms_mm_without_outliers <= 1.25 * NOISE and after.verdict == "no missing effect"
    # The search and its false-alarm count are in the JSON; every id parses back to the effect that was scored.
    j = dg.to_json()
    assert j["searched"]["periodic"]["trials"] == j["decision"]["families"]["periodic"]["M"] > 10_000


def test_periodic_in_time_found(model):
    sim = simulate(model, ["dz_z:tp600=0.003"], n=800, noise=NOISE, seed=44)
    top = D.diagnose(model, sim.meas, top=3).candidates[0]
    assert top["family"] == "periodic" and top["id"].split(":")[1].startswith("tp")
    assert abs(top["period"] - 600) < 0.05 * 600, top


@pytest.mark.parametrize("spec, tau", first_fast([("L:te600=0.01", 600.0), ("dz_z:te1500=0.008", 1500.0)]))
def test_hidden_exponential_drift_found_with_its_time_constant(model, spec, tau):
    sim = simulate(model, [spec], n=800, noise=NOISE, seed=45)
    dg = D.diagnose(model, sim.meas, top=3)
    top = dg.candidates[0]
    assert dg.verdict == "missing effect" and top["family"] == "thermal", top
    assert spec.split(":")[0] in {i.split(":")[0] for i in ids_of(top)}
    assert abs(top["tau_s"] - tau) < 0.2 * tau, top
    after = D.diagnose(model, sim.meas, [top["id"]], top=3)
    assert after.rms_mm_without_outliers <= 1.25 * NOISE and after.verdict == "no missing effect"


def test_search_gains_are_the_drop_of_an_actual_refit(model, periodic_set):
    """The exact gain of a searched candidate is the fall of the weighted RSS when the model is refitted with it
    (first order, least squares: the diagnosis decides on the data alone), for a periodic and a thermal
    candidate."""
    from fiveaxis.estimation.priors import PriorSpec
    res = F.fit(model, periodic_set.meas, refine=False, robust=False, prior=PriorSpec(off=True))
    prob = res.problem
    rw = res.residual * prob.w
    block = res.design.block
    Q, _ = basis_map(res.idf, block.A[:, prob.free] * prob.w[:, None])
    params, P = param_columns(block, prob.w)
    sums = es.row_sums(params, P, rw, Q, prob.obs.row, prob.meas.n)
    band = es.band("x", prob.ctx.raw("x"), sums.live)
    found = es.periodic(sums, [band], {"x": [params.index("dx_x")]})
    th = es.thermal(sums, es.tau_grid(prob.meas.t, sums.live), [params.index("ey_x")])
    for f in found + th:
        again = F.fit(model, periodic_set.meas, [f.effect], refine=False, robust=False, prior=PriorSpec(off=True))
        drop = float(rw @ rw) - float(np.sum((again.residual * again.problem.w) ** 2))
        assert f.gain == pytest.approx(drop, rel=1e-6)


def test_period_search_on_two_threads_gives_the_one_thread_answer(model, periodic_set, monkeypatch):
    """The frequency grid's chunks on the runner's threads: periods and gains bit-identical to one thread (each
    chunk's arithmetic is the same; only where it runs changes), every parameter of the band searched."""
    from fiveaxis import parallel
    from fiveaxis.estimation.priors import PriorSpec
    res = F.fit(model, periodic_set.meas, refine=False, robust=False, prior=PriorSpec(off=True))
    prob = res.problem
    Q, _ = basis_map(res.idf, res.design.block.A[:, prob.free] * prob.w[:, None])
    params, P = param_columns(res.design.block, prob.w)
    sums = es.row_sums(params, P, res.residual * prob.w, Q, prob.obs.row, prob.meas.n)
    bands = [es.band("x", prob.ctx.raw("x"), sums.live)]
    runs = []
    for n in ("1", "2"):
        monkeypatch.setenv(parallel.THREADS_ENV, n)
        runs.append([(f.effect.id, f.gain) for f in es.periodic(sums, bands)])
    assert len(runs[0]) > 10 and runs[0] == runs[1]


def test_bands_on_threads_and_kept_transposes_give_the_band_by_band_answer(model, periodic_set, monkeypatch):
    """Several bands searched at once (each on a thread) give, bit for bit, the finds of each band searched alone
    on one thread, in band order; the exact pair gains from the sums with each parameter's transposed W3 kept
    (`_LiveSums`) are those made afresh from plain sums."""
    from types import SimpleNamespace
    from fiveaxis import parallel
    from fiveaxis.estimation.priors import PriorSpec
    res = F.fit(model, periodic_set.meas, refine=False, robust=False, prior=PriorSpec(off=True))
    prob = res.problem
    Q, _ = basis_map(res.idf, res.design.block.A[:, prob.free] * prob.w[:, None])
    params, P = param_columns(res.design.block, prob.w)
    sums = es.row_sums(params, P, res.residual * prob.w, Q, prob.obs.row, prob.meas.n)
    bands = [es.band(t, prob.ctx.raw(t), sums.live) for t in ("x", "y")]
    pairs = {"x": [params.index("dx_x"), params.index("ey_x")], "y": [params.index("dy_y")]}
    monkeypatch.setenv(parallel.THREADS_ENV, "2")
    together = [(f.effect.id, f.gain, f.param_index) for f in es.periodic(sums, bands, pairs)]
    monkeypatch.setenv(parallel.THREADS_ENV, "1")
    alone = [(f.effect.id, f.gain, f.param_index) for b in bands for f in es.periodic(sums, [b], pairs)]
    assert len(together) == 3 and together == alone
    live = sums.live
    kept = es._LiveSums(sums, live)
    plain = SimpleNamespace(W1=sums.W1[live], W2=sums.W2[live], W3=sums.W3[live])     # no transposes kept
    v = bands[0].values[live]
    cols = np.repeat([params.index("dx_x"), params.index("ey_x")], 3)
    E = es._phase(v, np.linspace(1 / 900, 1 / 700, len(cols)))
    first = es._pair_gains(kept, cols, E, exact=True)
    assert np.array_equal(first, es._pair_gains(plain, cols, E, exact=True))
    assert np.array_equal(first, es._pair_gains(kept, cols, E, exact=True)) and len(kept.w3t) == 2


def test_period_digits_keep_the_phase_over_the_span():
    assert es.period_digits(800, 5000) == 3
    assert es.period_digits(10.0037, 5000) == 5
    P = es.rounded(10.0037, es.period_digits(10.0037, 5000))
    assert abs(5000 / P - 5000 / 10.0037) < 0.05                   # under 1/20 of a period over the span


# -- outliers ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("sigma", [False, True])
def test_gross_outliers_in_a_null_set_are_listed_and_raise_no_alarm(model, sigma):
    """0.5% of the readings off by 50 um: no missing effect (issue 13: a spurious ez_B:t3 with a sigma column),
    >= 90% of the rows listed with >= 90% precision, the noise estimate not inflated (issue 13: 2.3 um)."""
    sim = simulate(model, [], n=1000, noise=NOISE, seed=46, with_sigma=sigma)
    hit = add_outliers(sim.meas, 0.005, 0.05, seed=1)
    dg = D.diagnose(model, sim.meas, top=3)
    listed = set(dg.to_json()["outliers"])
    assert dg.verdict == "no missing effect"
    assert len(listed & hit) >= 0.9 * len(hit) and len(listed & hit) >= 0.9 * len(listed), (listed, hit)
    assert dg.noise_mm == pytest.approx(NOISE, rel=0.1)
    assert dg.rms_mm_without_outliers == pytest.approx(NOISE, rel=0.1)
    assert dg.rms_mm > 3 * NOISE                                     # the outliers are in rms_mm
    assert "left out of the decision" in text.diagnosis(dg.to_json())


@pytest.mark.slow
def test_outliers_on_top_of_a_hidden_effect(model):
    sim = simulate(model, ["ex_x:x1=2e-5"], n=1000, noise=NOISE, seed=47)
    hit = add_outliers(sim.meas, 0.005, 0.05, seed=2)
    dg = D.diagnose(model, sim.meas, top=3)
    assert dg.verdict == "missing effect" and "ex_x:x1" in ids_of(dg.candidates[0])
    listed = set(dg.to_json()["outliers"])
    assert len(listed & hit) >= 0.9 * len(hit) and len(listed & hit) >= 0.9 * len(listed)
    after = D.diagnose(model, sim.meas, ["ex_x:x1"], top=3)
    assert after.verdict == "no missing effect" and set(after.to_json()["outliers"]) == listed
    assert after.rms_mm_without_outliers <= 1.25 * NOISE


@pytest.mark.slow
def test_the_tails_of_a_missing_effect_are_not_outliers(model):
    """A roll error times a lever arm has long tails (|z| up to 10 against the median scale): those readings are
    the effect, not gross errors."""
    sim = simulate(model, ["ex_x:x1=2e-5"], n=1500, noise=NOISE, seed=3)
    dg = D.diagnose(model, sim.meas, top=1)
    assert dg.to_json()["outliers"] == [] and dg.candidates[0]["id"] == "ex_x:x1"


def test_a_period_near_the_span_is_refined_on_the_exact_gain():
    """A straightness of X with a period of 300 mm seen by a probed sphere over a few hundred mm of X: the model's
    columns absorb part of so long a sinusoid and move the periodogram's peak by a grid step. Refined on the
    approximate gain the period came out 201 mm (the exam: dy_y:yp84.3 named dy_y:yp82.8 and 9x the noise left);
    refined on the exact gain, within 10 %."""
    m = fiveaxis.load("ac_trunnion")
    sim = simulate(m, ["dz_x:xp300=0.01,0.008"], n=150, instrument="probe-sphere", seed=1)
    dg = D.diagnose(m, sim.meas, top=3)
    top = dg.candidates[0]
    assert dg.verdict == "missing effect" and top["id"].startswith("dz_x:xp"), top
    assert abs(float(top["id"].split("p")[-1]) / 300 - 1) < 0.1, top


def test_a_backlash_a_whole_laser_run_shows_is_not_outliers(model):
    """A reversal of X (backlash 26 um) on laser runs of X, Y, Z, both directions: against the scale of the Y and Z
    runs every reading of the X run is beyond the outlier threshold, and the other runs show nothing of it. The
    exam (bench/exam.py, li2018 interferometer) found it flagged as 110 outliers and 'no missing effect': the effect
    accepted on every reading now joins the model the outliers are flagged against."""
    sim = simulate(model, ["dx_x:xr=-0.013"], n=150, instrument="interferometer", seed=0)
    dg = D.diagnose(model, sim.meas, top=3)
    assert dg.to_json()["outliers"] == []
    assert dg.verdict == "missing effect" and "dx_x:xr" in ids_of(dg.candidates[0])


def test_outliers_by_data_row_of_the_file(capsys, model, tmp_path):
    """The rows listed are the file's data rows (1 = first row under the header), in fit and diagnose JSON."""
    path = tmp_path / "m.csv"
    assert run_cli("simulate", "--n", "400", "--seed", "5", "-o", str(path), echo=True)[0] == 0
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    dz = header.index("dz")
    rows = [17, 212, 333]
    for r in rows:
        cells = lines[r].split(",")
        cells[dz] = repr(float(cells[dz]) + 0.05)
        lines[r] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert run_cli("fit", str(path), "--json", echo=True)[0] == 0
    j = json.loads(capsys.readouterr().out)
    assert j["outliers"] == rows and j["rms_mm"] > j["rms_mm_without_outliers"]
    assert [o["reading"] for o in j["outlier_readings"]] == ["dz"] * 3
    assert run_cli("diagnose", str(path), "--json", "--top", "1", echo=True)[0] == 0
    j = json.loads(capsys.readouterr().out)
    assert j["outliers"] == rows and j["verdict"] == "no missing effect"
    assert run_cli("fit", str(path), echo=True)[0] == 0
    assert "row 17 dz" in capsys.readouterr().out


# -- the verdict -------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("sigma", first_fast([False, True]))
def test_effect_outside_every_vocabulary_is_unexplained_structure_along_x(model, sigma):
    """A 5 um step in dz at X = 0: polynomials and periods approximate it, but structure along X remains."""
    sim = simulate(model, [], n=800, noise=NOISE, seed=48, with_sigma=sigma)
    sim.meas.d[:, 2] += np.where(sim.meas.poses[:, 0] > 0, 0.0025, -0.0025)
    dg = D.diagnose(model, sim.meas, top=3)
    assert dg.verdict == "unexplained structure" and not dg.missing_effect
    u = dg.unexplained
    assert u["axis"] == "X" and u["reading"] == "dz"
    assert u["template"].startswith("[effects.dz_along_x]") and 'error = "dz_' in u["template"]
    steps = [b["mean"] for b in u["profile"]]
    # the profile shows the step at X = 0 (what the per-position profile the rule accepts leaves of it: the two
    # levels are drawn towards each other, the jump between the bins around X = 0 remains)
    k = int(np.argmax(np.abs(np.diff(steps))))
    assert u["profile"][k]["to"] <= 0 <= u["profile"][k + 1]["from"] and steps[k + 1] - steps[k] > 0.0006
    out = text.diagnosis(dg.to_json())
    assert "[[Unexplained structure]]" in out and "dz along X" in out and "no missing effect" not in out
    # The noise of the readings the structure does not explain (difference-based along X) is the noise.
    assert dg.structure_test["noise_local_mm"] == pytest.approx(NOISE, rel=0.15)


@pytest.mark.slow
def test_sigma_column_understating_the_noise(model):
    """chi2 fails (the rule with a sigma column) without structure along any variable: said so, no template."""
    sim = simulate(model, [], n=400, noise=2 * NOISE, seed=50, with_sigma=True)
    sim.meas.sigma = sim.meas.sigma / 2
    dg = D.diagnose(model, sim.meas, top=1)
    assert dg.verdict == "unexplained structure" and not dg.structure_test["significant"]
    assert "sigma column says" in dg.unexplained["note"] and "template" not in dg.unexplained


def test_text_report_is_built_from_the_json(model, periodic_set):
    dg = D.diagnose(model, periodic_set.meas, top=3)
    j = json.loads(json.dumps(dg.to_json()))
    assert text.diagnosis(j) == text.diagnosis(dg.to_json())
    assert j["verdict"] in D.VERDICTS and j["structure_test"]["significant"] in (True, False)


@pytest.mark.slow
def test_no_false_alarm_on_null_sets_with_the_larger_vocabulary(model):
    """20 null sets with approach directions (polynomial, reversal, periodic and thermal families), half with a
    sigma column: never "missing effect", never "unexplained structure"."""
    verdicts = []
    for seed in range(20):
        sim = simulate(model, [], n=400, noise=NOISE, seed=500 + seed, with_sigma=seed % 2 == 1, options=DIRS)
        dg = D.diagnose(model, sim.meas, top=1)
        verdicts.append(dg.verdict)
        assert set(dg.decision["families"]) >= {"polynomial", "reversal", "periodic", "thermal"}
    assert verdicts == ["no missing effect"] * 20, verdicts


@pytest.mark.slow
def test_backlash_and_a_linear_error_motion_found_in_two_rounds(model):
    sim = simulate(model, ["dx_x:xr=0.003", "ez_y:y1=3e-5"], n=800, noise=NOISE, seed=49, options=DIRS)
    hidden = {"dx_x:xr", "ez_y:y1"}
    found = []
    for _ in range(2):
        dg = D.diagnose(model, sim.meas, found, top=3)
        assert dg.verdict == "missing effect"
        top = dg.candidates[0]
        assert ids_of(top) & hidden, top
        found.append(top["id"])
    assert {f.split(":")[1] for f in found} == {"xr", "y1"}
    final = D.diagnose(model, sim.meas, found, top=3)
    assert final.verdict == "no missing effect" and final.rms_mm_without_outliers <= 1.25 * NOISE
