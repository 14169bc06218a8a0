"""Heat from temperature sensors against a known truth: an independent plain NumPy chain (fiveaxis.model.htm) and
thermal errors written out here (a first-order lag integrated on a 1 s grid, not the family's exact step), tip
readings at controller resolution (0.001 mm, 0.0001 deg, 0.1 um, 0.01 degC, 0.1 s) read back through the
measurement reader.

The test of the issue, on li2018 and ac_trunnion: 4 h, the spindle running 2 h then stopped; the tool length grows
with temp_spindle through a 600 s lag (1.5 um/degC), the X scale with temp_xscale (11.5 um/m/degC about the stroke's
centre); two irrelevant channels: temp_air (a day's cycle) and temp_motor (partly correlated: 0.4 of the spindle's
rise plus the air). diagnose names both drivers with the right channels and none of the irrelevant ones, fit --add
reaches the noise; the same poses without heat: no false alarm; the file without temp_spindle: "missing effect";
transfer to a day 2 with another history (the spindle started after an hour, stopped for lunch, started again).
"""
import math

import numpy as np
import pytest

import fiveaxis
from fiveaxis.diagnosis import diagnose as D
from fiveaxis.effects import families as fx
from fiveaxis.effects.base import first_order_lag
from fiveaxis.estimation import fit as F
from fiveaxis.estimation import fitted_model as MF
from fiveaxis.measurement.files import read
from fiveaxis.model import htm

NOISE = 1e-3                   # mm per tip component
HOURS = 4.0
GAIN_L = 1.5e-3                # mm per degC of the spindle's lagged temperature
LAG = 600.0                    # s
ALPHA = 11.5e-6                # 1/degC: the X scale
N = 1000


def spindle_history(t, runs, rise=15.0, tau=900.0, start=20.0):
    """The spindle housing's temperature (degC): towards start + rise while running (runs: [(on, off)] s), back
    towards start when standing, tau both ways; integrated on a 1 s grid (an independent integration)."""
    grid = np.arange(0.0, float(np.max(t)) + 2.0, 1.0)
    on = np.zeros(len(grid), bool)
    for a, b in runs:
        on |= (grid >= a) & (grid < b)
    s = np.zeros(len(grid))
    for k in range(1, len(grid)):
        target = 1.0 if on[k - 1] else 0.0
        s[k] = target + (s[k - 1] - target) * math.exp(-1.0 / tau)
    T = start + rise * s
    return grid, T


def lagged(grid, T, tau):
    """tau y' = T - y on the grid (1 s steps, exact for T held over each step), at rest at the start."""
    y = np.empty(len(T))
    y[0] = T[0]
    a = math.exp(-1.0 / tau)
    for k in range(1, len(T)):
        y[k] = T[k - 1] + (y[k - 1] - T[k - 1]) * a
    return y


def day(model, seed, runs, heat=True, air_shift=0.0, drop=(), base=None, start=20.0):
    """A measurement file of one day (tmp CSV read back) and its truth: (Measurements, base errors, temps); the
    machine's errors are stated at 20 degC (the spindle starts at `start`)."""
    machine = model.machine
    rng = np.random.default_rng(seed)
    n = N
    q = machine.random_poses(n, rng)
    t = np.sort(rng.uniform(0, HOURS * 3600, n))
    grid, Ts = spindle_history(t, runs, start=start)
    T_spindle = np.interp(t, grid, Ts)
    T_lag = np.interp(t, grid, lagged(grid, Ts, LAG))
    T_x = 20.0 + 3.0 * -np.expm1(-t / 5000.0)
    T_air = 20.0 + 1.0 * np.sin(2 * math.pi * (t + air_shift) / 86400.0)
    T_motor = 20.0 + 0.4 * (T_spindle - 20.0) + (T_air - 20.0)
    if base is None:
        sd = np.array([20e-6 if machine.is_angular(e) else 3e-3 for e in model.errors])
        base = rng.normal(0.0, 1.0, len(sd)) * sd
    E = np.tile(base, (n, 1))
    L = np.full(n, machine.tool_length)
    if heat:
        jx = list(model.errors).index("dx_x")
        lo, hi = machine.axis("X").model_stroke
        u = (q[:, 0] - 0.5 * (lo + hi)) / (0.5 * (hi - lo))
        E[:, jx] += ALPHA * 0.5 * (hi - lo) * (T_x - 20.0) * u          # 11.5 um/m/degC about the centre
        L = L + GAIN_L * (T_lag - 20.0)
    P, _ = htm.tool(machine, q, L, E)
    P0, _ = model.ideal_tool(q, np.full(n, machine.tool_length))
    d = P - P0 + rng.normal(0.0, NOISE, (n, 3))
    cols = {}
    for j, v in enumerate(machine.variables):
        vals = np.degrees(q[:, j]) if machine.axis(v).type == "rotary" else q[:, j]
        cols[v] = np.round(vals, 4 if machine.axis(v).type == "rotary" else 3)
    cols["t"] = np.round(t, 1)
    temps = {"temp_spindle": T_spindle, "temp_xscale": T_x, "temp_air": T_air, "temp_motor": T_motor}
    for name, T in temps.items():
        if name not in drop:
            cols[name] = np.round(T + rng.normal(0.0, 0.02, n), 2)
    for k, c in enumerate(("dx", "dy", "dz")):
        cols[c] = np.round(d[:, k], 4)
    return cols, base


def write(tmp_path, name, cols):
    import pandas as pd
    path = tmp_path / name
    pd.DataFrame(cols).to_csv(path, index=False)
    return path


def channels(effects) -> set:
    return {e.var for e in effects if isinstance(e, fx.Temperature)}


@pytest.fixture(scope="module", params=["li2018", "ac_trunnion"])
def case(request, tmp_path_factory):
    model = fiveaxis.load(request.param)
    tmp = tmp_path_factory.mktemp("heat")
    cols, base = day(model, 5, [(0.0, 7200.0)])
    meas = read(write(tmp, "day1.csv", cols), model.machine)
    return model, meas, base, tmp


@pytest.mark.slow
def test_diagnose_names_both_drivers_and_the_fit_reaches_the_noise(case):
    model, meas, _, _ = case
    dg = D.diagnose(model, meas)
    accepted = dg.decision["accepted"]
    effects = [fx.parse(i, model.machine, model.errors) for i in accepted]
    print(f"{model.machine.name}: verdict {dg.verdict}; accepted {accepted}; heat {dg.heat.get('sensors')}")
    assert dg.verdict == "missing effect"
    assert channels(effects) == {"temp_spindle", "temp_xscale"}
    spindle = [e for e in effects if isinstance(e, fx.Temperature) and e.var == "temp_spindle"]
    assert spindle and abs(spindle[0].tau - LAG) < 0.25 * LAG          # the lag found (600 s)
    scale = [e for e in effects if isinstance(e, fx.Temperature) and e.var == "temp_xscale"]
    assert scale and scale[0].axis == "x" and scale[0].param == "dx_x"
    assert dg.heat["sensors"]["smallest_set"] == ["temp_spindle", "temp_xscale"] or \
        sorted(dg.heat["sensors"]["smallest_set"]) == ["temp_spindle", "temp_xscale"]
    res = F.fit(model, meas, accepted)
    rms = res.rms_mm                                                  # per reading (tip component)
    k = list(res.problem.names).index(scale[0].id)
    alpha = res.theta[k] / (0.5 * np.ptp(model.machine.axis("X").model_stroke))
    print(f"{model.machine.name}: fit with the accepted set: {1e3 * rms:.3f} um per component (noise 1 um); X scale "
          f"{alpha * 1e6:.2f} um/m/degC (true 11.5)")
    assert rms <= 1.1 * NOISE
    assert abs(alpha - ALPHA) < 0.05 * ALPHA


@pytest.mark.slow
def test_no_false_alarm_without_heat(case, tmp_path):
    model, _, base, _ = case
    cols, _ = day(model, 5, [(0.0, 7200.0)], heat=False, base=base)
    dg = D.diagnose(model, read(write(tmp_path, "cold.csv", cols), model.machine))
    print(f"{model.machine.name} without heat: {dg.verdict}; best {dg.candidates[0]['id'] if dg.candidates else '-'}")
    assert dg.verdict == "no missing effect"


@pytest.mark.slow
def test_without_the_driving_channel_a_missing_effect(case, tmp_path):
    model, _, base, _ = case
    cols, _ = day(model, 5, [(0.0, 7200.0)], base=base, drop=("temp_spindle",))
    dg = D.diagnose(model, read(write(tmp_path, "nospindle.csv", cols), model.machine))
    accepted = dg.decision.get("accepted", [])
    print(f"{model.machine.name} without temp_spindle: {dg.verdict}; accepted {accepted}; "
          f"missing sensor: {(dg.heat or {}).get('missing_sensor', {}).get('note', '-')[:120]}")
    assert dg.verdict in ("missing effect", "unexplained structure")
    assert dg.verdict != "no missing effect"
    assert "temp_xscale" in channels(fx.parse(i, model.machine, model.errors) for i in accepted)


@pytest.mark.slow
def test_transfer_to_another_day(case, tmp_path):
    """The model fitted on day 1 applied to day 2 (the same machine; the spindle started after an hour, stopped
    for lunch, started again; the air half a day later): at most 1.5 x the noise, where the best time-only model
    of day 1 (diagnose on day 1 without its temperature columns) leaves at least 5 x."""
    model, meas, base, _ = case
    dg = D.diagnose(model, meas)
    fm = MF.from_fit(F.fit(model, meas, dg.decision["accepted"]))
    cols2, _ = day(model, 6, [(3600.0, 7200.0), (9000.0, 14400.0)], air_shift=43200.0, base=base)
    day2 = read(write(tmp_path, "day2.csv", cols2), model.machine)
    left = _applied(fm, model, day2)
    cols1, _ = day(model, 5, [(0.0, 7200.0)], base=base,
                   drop=("temp_spindle", "temp_xscale", "temp_air", "temp_motor"))
    day1_time = read(write(tmp_path, "day1_time.csv", cols1), model.machine)
    timed = D.diagnose(model, day1_time)
    fm_time = MF.from_fit(F.fit(model, day1_time, timed.decision.get("accepted", [])))
    left_time = _applied(fm_time, model, day2)
    print(f"{model.machine.name} day 2: temperature model of day 1 leaves {1e3 * left:.3f} um per component, the "
          f"best time-only model of day 1 ({', '.join(timed.decision.get('accepted', []))}) {1e3 * left_time:.2f} um "
          f"(noise 1 um)")
    assert left <= 1.5 * NOISE
    assert left_time >= 5 * NOISE


def _applied(fm, model, meas) -> float:
    """RMS per tip component of day-2 readings minus what the fitted model predicts there (its errors at the
    day's poses, times and temperatures, through the model's chain)."""
    E, dL = MF.errors_at(fm, model, meas.poses, t=meas.t, temps=meas.temps)
    P, _ = model.tool_errors(meas.poses, np.ascontiguousarray(E), meas.L + dL, exact=True)
    _, V0 = model.ideal_tool(meas.poses, meas.L)
    pred = P + V0 * dL[:, None]
    return float(np.sqrt(np.mean((meas.d - pred) ** 2)))


def test_lag_is_the_exact_first_order_solution():
    """first_order_lag against SciPy's ODE solver on an irregular, noisy history (2e-5 degC)."""
    from scipy.integrate import solve_ivp
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 20000, 300))
    x = 20 + 5 * np.sin(t / 1000) + rng.normal(0, .1, len(t))
    for tau in (60.0, 600.0):
        sol = solve_ivp(lambda s, y: (np.interp(s, t, x) - y) / tau, (t[0], t[-1]), [x[0]], t_eval=t, rtol=1e-11,
                        atol=1e-11, max_step=2, method="DOP853")
        assert np.max(np.abs(first_order_lag(t, x, tau) - sol.y[0])) < 2e-5


# -- the temperature columns -------------------------------------------------------------------------------------
def _file(tmp_path, rows, header="X,Y,Z,A,B,t,temp_spindle,dx,dy,dz"):
    path = tmp_path / "m.csv"
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


def _rows(temps):
    return [f"{10 * k},{k},0,0,0,{k * 60},{T},0.001,0,0" for k, T in enumerate(temps)]


def test_temperature_columns_are_checked(tmp_path):
    from fiveaxis.exceptions import InputError
    machine = fiveaxis.load("li2018").machine
    with pytest.raises(InputError, match=r"data row 3 \(line 4\), column temp_spindle: expected a temperature from "
                                         r"-50 to 200 degC.*got 2000"):
        read(_file(tmp_path, _rows([20, 21, 2000, 22])), machine)
    with pytest.raises(InputError, match=r"header: column 'temp_Spindle': a temperature channel is named temp_"):
        read(_file(tmp_path, _rows([20, 21]), "X,Y,Z,A,B,t,temp_Spindle,dx,dy,dz"), machine)
    with pytest.raises(InputError, match="column temp_spindle: no reading in any row"):
        read(_file(tmp_path, _rows(["", ""])), machine)
    meas = read(_file(tmp_path, _rows([20.5] * 6)), machine)
    assert any("temp_spindle: the temperature never changes (20.5 degC in all 6 readings)" in w for w in meas.warnings)
    meas = read(_file(tmp_path, _rows([20, "", "", 23, 24, 25])), machine)
    ctx = fx.context(machine, meas.poses, meas.t, temps=meas.temps)
    assert np.allclose(ctx.temps["temp_spindle"], [20, 21, 22, 23, 24, 25])       # blanks: linear in time


def test_temperature_effect_without_times_or_channel(tmp_path):
    from fiveaxis.exceptions import InputError
    model = fiveaxis.load("li2018")
    rows = [f"{10 * k},{k},0,0,0,{20 + k if k != 2 else ''},0.001,0,0" for k in range(8)]
    meas = read(_file(tmp_path, rows, "X,Y,Z,A,B,temp_spindle,dx,dy,dz"), model.machine)
    with pytest.raises(InputError, match="temp_spindle has rows without a reading and the measurements no t column"):
        F.fit(model, meas, ["L:temp_spindle"])
    with pytest.raises(InputError, match="needs a t column"):
        F.fit(model, read(_file(tmp_path, [r.replace(",,", ",21,") for r in rows],
                                "X,Y,Z,A,B,temp_spindle,dx,dy,dz"), model.machine), ["L:temp_spindle~60"])
    with pytest.raises(InputError, match="needs a temp_bed column"):
        F.fit(model, meas, ["L:temp_bed"])


@pytest.mark.slow
def test_confounded_when_everything_rises_with_time():
    """A warm-up without a stop: the temperature rises with time all along, so L:temp_spindle and a time effect
    explain the same readings; the diagnosis says so and what would separate them."""
    from fiveaxis.measurement.simulate import simulate
    model = fiveaxis.load("li2018")
    sim = simulate(model, ["L:temp_spindle~300=0.0015"], n=600, seed=4, duration=7200.0,
                   temperatures={"spindle": "spindle:rise=15,tau=1800,off=99999"})
    dg = D.diagnose(model, sim.meas)
    conf = dg.heat.get("confounded", [])
    print(f"monotone warm-up: accepted {dg.decision['accepted']}; confounded {conf}")
    pairs = [{fx.parse(c[k], model.machine, model.errors).var for k in ("effect", "with")} for c in conf]
    assert {"temp_spindle", fx.TIME} in pairs
    assert "cool-down phase, a spindle stop or a second day" in dg.heat["confounded_note"]


# -- the plausibility of a rate per degC (compensation.plausible.THERMAL) ---------------------------------------
def test_a_rate_per_degC_beyond_a_machine_is_flagged_and_refused(tmp_path):
    """A spindle growing 1.5 um/degC and an X scale of 11.5 um/m/degC pass without a word; the same readings
    against a sensor that barely changed (its changes a hundredth: 150 um/degC fitted) are flagged by fit with the
    hint, and a model of 1 mm/degC or 1 mm/m/degC (edited, a unit slip) is refused by compensate, nothing written."""
    import dataclasses
    import json
    from conftest import run_cli
    from fiveaxis.compensation import plausible
    from fiveaxis.measurement.simulate import simulate
    model = fiveaxis.load("li2018")
    ids = ["L:temp_spindle", "dx_x:x.temp_xscale"]
    half = 0.5 * float(np.ptp(model.machine.axis("X").model_stroke))      # mm: the scale effect's c at the end
    sim = simulate(model, ["L:temp_spindle=0.0015", f"dx_x:x.temp_xscale={ALPHA * half}"], n=200, seed=4,
                   duration=14400.0, temperatures={"spindle": "spindle", "xscale": "bed:rise=3,tau=5000"})
    fm = MF.from_fit(F.fit(model, sim.meas, ids))
    rates = {e.id: e.values[0] for e in fm.effects}
    assert abs(rates["L:temp_spindle"] - 1.5e-3) < 0.1e-3                    # the truth, so the bound is judged on it
    assert abs(rates["dx_x:x.temp_xscale"] / half - ALPHA) < 0.2 * ALPHA
    assert plausible.model_findings(fm, model.machine) == []
    # the sensor that barely changed: the same readings, its changes a hundredth (0.15 degC over the test)
    T = sim.meas.temps["temp_spindle"]
    slip = dataclasses.replace(sim.meas, temps=dict(sim.meas.temps, temp_spindle=T[0] + (T - T[0]) / 100.0))
    found = plausible.model_findings(MF.from_fit(F.fit(model, slip, ids)), model.machine)
    assert len(found) == 1 and found[0].startswith("effect L:temp_spindle: 1") and "um/degC of temp_spindle" in found[0]
    assert plausible.unit_slip(found).endswith(plausible.TEMPERATURE_HINT)
    eff, ctx = fx.parse("L:temp_spindle", model.machine, model.errors), fx.context(model.machine, slip.poses, slip.t,
                                                                                 temps=slip.temps)
    assert "NOT A MACHINE'S RATE: 150 um/degC: beyond" in eff.describe(model.machine, [0.15], ctx)   # fit's text
    assert "NOT A MACHINE" not in eff.describe(model.machine, [0.0015], ctx)
    # compensate refuses a model of 1 mm/degC (and reports the scale's 1 mm/m/degC beside it), nothing written
    path = tmp_path / "m.json"
    MF.save(fm, path)
    data = json.loads(path.read_text())
    for e in data["effects"]:
        e["coefficients_mm_rad"] = {k: (1.0 if e["param"] == "L" else 1e-3 * half) for k in e["coefficients_mm_rad"]}
    path.write_text(json.dumps(data))
    out = tmp_path / "c"
    out.mkdir()
    rc, _, err = run_cli("compensate", path, "-o", out)
    assert rc == 2 and err.count("\n") == 1 and list(out.iterdir()) == [], err
    assert "L:temp_spindle: 1000 um/degC" in err and "(and 1 more)" in err and plausible.TEMPERATURE_HINT in err
    assert "nothing is written for the controller" in err
    bad = MF.load(path)
    found = plausible.model_findings(bad, model.machine)
    assert any(f.startswith("effect dx_x:x.temp_xscale: 1000 um/m/degC") for f in found), found


# -- a stated reference temperature (--reference-temperature) -----------------------------------------------------
def test_a_stated_reference_is_the_machine_at_that_temperature(tmp_path):
    """A spindle warm from the previous shift (26 degC at the first reading) on a machine whose tool length is the
    presetter's at 20 degC (the truth: L grows 1.5 um/degC from 20). Fitted with the stated reference 20 (the option
    of fit and diagnose), the model holds 20 (kept in model.json as stated, the kinematics module's pin default) and
    predicts the tool 9 um longer at a steady 26 degC, as the truth; reckoned from the first reading it predicts
    nothing there. The option's refusals name it."""
    from conftest import run_cli
    from fiveaxis.commands.options import references_of
    model = fiveaxis.load("li2018")
    cols, _ = day(model, 7, [(0.0, 7200.0)], start=26.0, drop=("temp_air", "temp_motor"))
    path = write(tmp_path, "warm.csv", cols)
    meas = read(path, model.machine)
    ids = [f"L:temp_spindle~{LAG:g}", "dx_x:x.temp_xscale"]
    stated = meas.with_references(references_of(["20"]))
    assert stated.references == {"temp_spindle": 20.0, "temp_xscale": 20.0}
    fm = MF.from_fit(F.fit(model, stated, ids))
    MF.save(fm, tmp_path / "m.json")
    fm = MF.load(tmp_path / "m.json")
    sc = fm.scales["temp_spindle"]
    assert sc.centre == 20.0 and sc.stated
    at = model.machine.random_poses(5, np.random.default_rng(0))
    _, dL = MF.errors_at(fm, model, at, temps={"temp_spindle": 26.0, "temp_xscale": 20.0})
    assert np.allclose(dL, GAIN_L * 6.0, rtol=0.05), dL                 # the truth: 9 um longer at 26 degC
    first = MF.from_fit(F.fit(model, meas, ids))
    assert not first.scales["temp_spindle"].stated and abs(first.scales["temp_spindle"].centre - 26.0) < 0.5
    _, dL_first = MF.errors_at(first, model, at, temps={"temp_spindle": 26.0, "temp_xscale": 20.0})
    assert np.all(np.abs(dL_first) < 1e-3)                              # under 1 um: its reference is ~26
    assert meas.with_references(references_of(["20", "spindle=21.5"])).references == \
        {"temp_spindle": 21.5, "temp_xscale": 20.0}                      # a channel's own after every channel's
    for spec, said in (("foo=20", "no column temp_foo"), ("2000", "from -50 to 200 degC"), ("=20", "[NAME=]DEGC"),
                       ("spindle=warm", "[NAME=]DEGC")):
        rc, _, err = run_cli("fit", path, "--machine", "li2018", "--reference-temperature", spec)
        assert rc == 2 and err.count("\n") == 1 and "--reference-temperature" in err and said in err, err


# -- the cross-validation folds search the lags again -------------------------------------------------------------
def test_the_folds_search_the_lags_again(monkeypatch):
    """A lag chosen on all the readings must not enter a fold's held-out test (it has seen the held-out rows):
    every lagged temperature candidate a fold's "add the best candidate" can choose was searched on that fold's
    training rows; the all-data ones are left out of every fold, as the periods and time constants are."""
    from fiveaxis.diagnosis import decision as dc
    from fiveaxis.measurement.simulate import simulate
    model = fiveaxis.load("li2018")
    sim = simulate(model, [f"L:temp_spindle~{LAG:g}=0.0015"], n=300, seed=2, duration=14400.0,
                   temperatures={"spindle": "spindle:off=7200", "air": "air:amp=1"})
    seen = {}
    real = dc.cross_validate

    def spy(rows, lay, *args):
        seen["lay"] = lay
        return real(rows, lay, *args)
    monkeypatch.setattr(dc, "cross_validate", spy)
    dg = D.diagnose(model, sim.meas)
    lay = seen["lay"]
    temps = [k for k, e in enumerate(lay.effects) if isinstance(e, fx.Temperature) and e.tau > 0]
    main = [k for k in temps if lay.fold[k] is None]
    assert main and all(k in lay.resampled for k in main if lay.effects[k].var == "temp_spindle"
                        and lay.effects[k].param == fx.TOOL)
    spindle = next(k for k in main if lay.effects[k].param == fx.TOOL and lay.effects[k].var == "temp_spindle")
    own = {}
    for f in range(dc.K_FOLDS):
        usable = [k for k in temps if (lay.fold[k] is None and k not in lay.resampled) or lay.fold[k] == f]
        assert not [k for k in usable if lay.fold[k] is None and lay.effects[k].param == fx.TOOL
                    and lay.effects[k].var == "temp_spindle"]                # the all-data lag: in no fold
        own[f] = [lay.effects[k].tau for k in usable if lay.fold[k] == f and lay.effects[k].param == fx.TOOL
                  and lay.effects[k].var == "temp_spindle"]
        assert len(own[f]) == 1 and abs(own[f][0] - LAG) < 0.3 * LAG, own  # its own search finds the lag
    print(f"all data: {lay.effects[spindle].id}; folds' own lags {own}; CV chose {dg.decision['cv_chosen']}")
    assert len({v[0] for v in own.values()} | {lay.effects[spindle].tau}) > 1   # searched, not copied
    assert "L:temp_spindle" in " ".join(dg.decision["accepted"])


# -- the calibration loop says where it is (make run's heat section runs it once) --------------------------------
def test_the_loop_reports_each_round(tmp_path):
    """`diagnose --rounds N` prints one line per round on stderr as it goes (a loop runs for seconds to minutes):
    its verdict, residual and the effect added next, the same as the JSON record it prints once at the end."""
    import json
    from conftest import run_cli
    from fiveaxis.measurement.simulate import simulate, to_frame
    model = fiveaxis.load("li2018")
    sim = simulate(model, ["L:temp_spindle=0.0015"], n=120, seed=5, duration=14400.0,
                   temperatures={"spindle": "spindle:off=7200"})
    path = tmp_path / "h.csv"
    to_frame(sim, model).to_csv(path, index=False)
    rc, out, err = run_cli("diagnose", path, "--rounds", "3", "--top", "1", "--json")
    rounds = json.loads(out)["rounds"]
    lines = [line for line in err.splitlines() if line.startswith("fiveaxis: diagnose round")]
    print("\n".join(lines))
    assert rc == 0 and len(lines) == len(rounds) >= 2
    for k, (line, r) in enumerate(zip(lines, rounds)):
        assert line.startswith(f"fiveaxis: diagnose round {k + 1} of at most 3: {r['verdict']} (residual RMS "
                               f"{1e3 * r['rms_mm']:.3g} um)")
        if k + 1 < len(rounds):
            assert line.endswith(f"adding {rounds[k + 1]['added'][-1]}")
    assert lines[-1].endswith("the loop ends")
    assert "L:temp_spindle" in " ".join(rounds[-1]["added"])


def test_compensate_shows_its_stages_on_a_terminal_only(monkeypatch):
    """compensate (seconds to a minute) draws its stages as a bar on a terminal; in a pipe or a log it stays silent
    (a refusal there is one line)."""
    import io
    import sys
    from fiveaxis.commands.compensate import _stages
    from fiveaxis.compensation.pipeline import STAGES

    class Terminal(io.StringIO):
        def isatty(self):
            return True
    for stream, shown in ((Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr(sys, "stderr", stream)
        with _stages(STAGES) as stage:
            for name in STAGES:
                stage(name)
        text = stream.getvalue()
        assert ("compensate: 100%" in text and all(name in text for name in STAGES)) if shown else text == ""


def test_diagnose_flags_a_candidates_rate_beyond_a_machine():
    """The spindle readings against a sensor that barely changed: diagnose's candidate L:temp_spindle (150 um/degC)
    is flagged plausible: false with the bound it exceeds, and its text says NOT A MACHINE'S RATE; against the
    real sensor (1.5 um/degC) it is not flagged."""
    import dataclasses
    from fiveaxis.measurement.simulate import simulate
    from fiveaxis.report import text
    model = fiveaxis.load("li2018")
    sim = simulate(model, ["L:temp_spindle=0.0015"], n=200, seed=4, duration=14400.0,
                   temperatures={"spindle": "spindle"})
    T = sim.meas.temps["temp_spindle"]
    slip = dataclasses.replace(sim.meas, temps=dict(sim.meas.temps, temp_spindle=T[0] + (T - T[0]) / 100.0))
    for meas, flagged in ((sim.meas, False), (slip, True)):
        dg = D.diagnose(model, meas)
        (c,) = [c for c in dg.candidates if c["id"] == "L:temp_spindle"]
        assert (c.get("plausible") is False) == flagged and ("implausible_rate" in c) == flagged, c
        if flagged:
            assert c["implausible_rate"].startswith("150") and "100 um/degC" in c["implausible_rate"]
            assert "NOT A MACHINE'S RATE" in text.diagnosis(dg.to_json())
