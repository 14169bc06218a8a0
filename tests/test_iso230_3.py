"""ISO 230-3 thermal tests (issue 31): the figures of `fiveaxis iso230-3` against an independent NumPy evaluation of
the definitions (docs/iso230-3.md) written out again here on the file's columns read with the csv module, on
simulated tests written as a logger writes them (displacements at 0.1 um, temperatures at 0.01 degC), and against
hand-computed values of closed-form drifts; bad input as one-line errors naming file, row and column."""
import csv
import json
import math
import re

import numpy as np
import pandas as pd
import pytest

from fiveaxis.exceptions import InputError
from fiveaxis.iso230 import thermal as T
from fiveaxis.iso230.thermal_sim import simulate

from conftest import ROOT, one_line_error, run_cli

TOL = 0.01           # um and urad: the done criterion
SPACING = 100.0      # mm


def write(tmp_path, columns: dict, name="test.csv", fmt="%.12g") -> str:
    path = tmp_path / name
    pd.DataFrame(columns).to_csv(path, index=False, float_format=fmt)
    return str(path)


def simulated(tmp_path, test="spindle", **kw):
    sim = simulate(test, **kw)
    path = tmp_path / f"{test}.csv"
    sim.frame().to_csv(path, index=False, float_format="%.10g")
    return str(path), sim


def columns_of(path) -> dict:
    """The file's columns as float arrays (blank: NaN), read with the csv module."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], rows[1:]
    return {h: np.array([float(r[i]) if r[i].strip() else np.nan for r in body]) for i, h in enumerate(head)}


# -- the independent evaluation: the definitions of docs/iso230-3.md written out again ---------------------------
def ref_directions(c, spacing=SPACING) -> dict:
    out = {}
    if "dx" in c:
        out["X"] = c["dx"] * 1000.0
    if "dy" in c:
        out["Y"] = c["dy"] * 1000.0
    if "dz" in c:
        out["Z"] = c["dz"] * 1000.0
    if "dy2" in c:
        out["A"] = (c["dy"] - c["dy2"]) / spacing * 1e6       # rotation about +X moves a point at +l along Z by -a l
    if "dx2" in c:
        out["B"] = (c["dx2"] - c["dx"]) / spacing * 1e6       # rotation about +Y moves it by +b l along X
    return out


def ref_figures(t_s, v) -> dict:
    """Drift from the first reading: the signed drift of largest magnitude (the earliest of equal ones), peak to
    valley, the last drift and the change over the last hour (linear interpolation)."""
    d = v - v[0]
    hi, lo = d.max(), d.min()
    biggest = d[min(i for i in range(len(d)) if abs(d[i]) == max(hi, -lo))]
    out = {"max_drift": biggest, "range": hi - lo, "change": d[-1]}
    if t_s[-1] - t_s[0] >= 3600:
        t0 = t_s[-1] - 3600
        j = np.searchsorted(t_s, t0)                    # first reading at or after t0
        if t_s[j] == t0:
            before = v[j]
        else:
            w = (t0 - t_s[j - 1]) / (t_s[j] - t_s[j - 1])
            before = v[j - 1] + w * (v[j] - v[j - 1])
        out["last_hour_change"] = v[-1] - before
    return out


def ref_phases(running: np.ndarray) -> list:
    """(state, indices, reference index) of the runs of one spindle state; the reference of a later run is the last
    reading before it."""
    cuts = [0] + list(np.flatnonzero(running[1:] != running[:-1]) + 1) + [len(running)]
    out = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        state = "running" if running[a] else ("stopped" if running[:a].any() else "at rest")
        out.append((state, np.arange(a, b), a - 1 if a else 0))
    return out


def close(rec_dirs, ref: dict, tol=TOL):
    """Every figure of every direction of a record equals the reference's within tol."""
    assert [d["direction"] for d in rec_dirs] == list(ref)
    for d in rec_dirs:
        u = d["unit"]
        for k, v in ref[d["direction"]].items():
            assert d[f"{k}_{u}"] == pytest.approx(v, abs=tol), (d["direction"], k)


# -- simulated tests --------------------------------------------------------------------------------------------
def test_spindle_test_equals_numpy_evaluation(tmp_path):
    path, sim = simulated(tmp_path, "spindle", hours=6.0, run_hours=4.0, seed=3)
    rec = T.evaluate_file(path, spacing_mm=SPACING)
    c = columns_of(path)
    t = c["t"]
    dirs = ref_directions(c)
    assert rec["test"] == "spindle" and rec["readings"] == len(t)
    close(rec["directions"], {k: ref_figures(t, v) for k, v in dirs.items()})
    phases = ref_phases(c["spindle_rpm"] != 0)
    assert [p["phase"] for p in rec["phases"]] == [s for s, _, _ in phases] == ["running", "stopped"]
    for p, (state, idx, r) in zip(rec["phases"], phases):
        sel = np.concatenate([[r], idx]) if r < idx[0] else idx
        close(p["directions"], {k: ref_figures(t[sel], v[sel]) for k, v in dirs.items()})
        for d in p["directions"]:
            assert d[f"from_start_{d['unit']}"] == pytest.approx(dirs[d["direction"]][idx[-1]]
                                                                 - dirs[d["direction"]][0], abs=TOL)
        assert p["start_min"] == t[idx[0]] / 60 and p["end_min"] == t[idx[-1]] / 60
        assert p["speed_rpm"] == ([8000.0, 8000.0] if state == "running" else None)
    # the phases' changes add up to the test's
    for k, d in enumerate(rec["directions"]):
        u = d["unit"]
        assert sum(p["directions"][k][f"change_{u}"] for p in rec["phases"]) == pytest.approx(d[f"change_{u}"],
                                                                                             abs=1e-9)
    for tc in rec["temperatures"]:
        T_ = c[tc["channel"]]
        assert (tc["first_degC"], tc["last_degC"], tc["min_degC"], tc["max_degC"]) == pytest.approx(
            (T_[0], T_[-1], T_.min(), T_.max()), abs=1e-9)
        assert tc["range_degC"] == pytest.approx(T_.max() - T_.min(), abs=1e-9)
        assert tc["resolution_degC"] == pytest.approx(0.01)
    # what the drift is: the truth's largest drift of Z within a few noise steps (0.1 um sensors, 0.1 um steps)
    z_true = sim.truth["Z_um"]
    zr = next(d for d in rec["directions"] if d["direction"] == "Z")
    assert zr["max_drift_um"] == pytest.approx(z_true[np.argmax(np.abs(z_true))], abs=0.5)
    assert zr["max_drift_um"] < -20                        # the spindle grows towards the table by over 20 um
    assert next(e for e in rec["directions_read"] if e["direction"] == "X")["resolution_um"] == pytest.approx(0.1)
    assert next(e for e in rec["directions_read"] if e["direction"] == "X")["noise_um"] == pytest.approx(0.1,
                                                                                                        rel=0.25)


def test_etve_test_equals_numpy_evaluation(tmp_path):
    path, _ = simulated(tmp_path, "etve", hours=8.0, seed=4)
    rec = T.evaluate_file(path, spacing_mm=SPACING)
    c = columns_of(path)
    dirs = ref_directions(c)
    assert rec["test"] == "etve" and [p["phase"] for p in rec["phases"]] == ["at rest"]
    assert rec["test_from"] == "no spindle or position information" and "taken as an ETVE test" in rec["notes"][0]
    close(rec["directions"], {k: ref_figures(c["t"], v) for k, v in dirs.items()})
    for d in rec["directions"]:
        assert d[f"ETVE_{d['unit']}"] == pytest.approx(np.ptp(dirs[d["direction"]]), abs=TOL)


def test_moving_axis_equals_numpy_evaluation(tmp_path):
    path, sim = simulated(tmp_path, "axis", hours=6.0, seed=5)
    rec = T.evaluate_file(path, spacing_mm=SPACING)
    c = columns_of(path)
    t, x = c["t"], c["X"]
    dirs = ref_directions(c)
    assert rec["test"] == "axis" and rec["axis"] == "X"
    positions = sorted(set(np.round(x, 3)))
    assert [tg["position_mm"] for tg in rec["targets"]] == pytest.approx(positions)
    for tg, p in zip(rec["targets"], positions):
        at = np.flatnonzero(np.round(x, 3) == p)
        close(tg["directions"], {k: ref_figures(t[at], v[at]) for k, v in dirs.items()})
    first, last = (np.flatnonzero(np.round(x, 3) == p) for p in (positions[0], positions[-1]))
    m = min(len(first), len(last))
    e = (dirs["X"][last[:m]] - dirs["X"][last[0]]) - (dirs["X"][first[:m]] - dirs["X"][first[0]])
    ex = rec["expansion"]
    biggest = e[np.flatnonzero(np.abs(e) == np.abs(e).max())[0]]
    assert ex["max_drift_um"] == pytest.approx(biggest, abs=TOL)
    assert ex["range_um"] == pytest.approx(np.ptp(e), abs=TOL)
    assert ex["max_drift_um_per_m"] == pytest.approx(biggest / 0.4, abs=TOL)
    # a steel screw warming by 4 K over 400 mm: 11.5 um/m/K * 4 K * 0.4 m * (1 - exp(-6)) = 18.35 um
    assert ex["change_um"] == pytest.approx(11.5 * 4 * 0.4 * (1 - math.exp(-6)), abs=0.5)


def test_stated_spindle_times_and_minutes_give_the_same_figures(tmp_path):
    path, _ = simulated(tmp_path, "spindle", hours=5.0, run_hours=3.0, seed=6)
    rec = T.evaluate_file(path, spacing_mm=SPACING)
    c = columns_of(path)
    del c["spindle_rpm"]
    c["t_min"] = c.pop("t") / 60.0
    stated = write(tmp_path, c, "stated.csv")
    rec2 = T.evaluate_file(stated, spindle=T.Spindle(on_min=0.0, off_min=180.0, speed_rpm=8000.0),
                           spacing_mm=SPACING)
    assert rec2["test"] == "spindle" and rec2["time_column"] == "t_min"
    for a, b in zip(rec["phases"], rec2["phases"]):
        assert (a["phase"], a["start_min"], a["end_min"]) == (b["phase"], b["start_min"], pytest.approx(b["end_min"]))
        for da, db in zip(a["directions"], b["directions"]):
            assert {k: v for k, v in da.items()} == pytest.approx(db, abs=1e-9)


# -- a closed-form drift, its figures by hand -------------------------------------------------------------------
def test_known_drift_by_hand(tmp_path):
    """Running 4 h, stopped 2 h, readings every minute at full precision: Z = -20 um (1 - exp(-t/1 h)) while
    running, then back with exp(-(t - 4 h)/1 h); B = 30 urad (1 - exp(-t/1 h)) likewise; X = 2 um t/6 h; the air
    20 + 1.5 sin(2 pi t / 24 h) degC."""
    h = 3600.0
    t = np.arange(0, 6 * h + 1, 60.0)
    run = t <= 4 * h
    peak = 1 - math.exp(-4)
    shape = np.where(run, 1 - np.exp(-t / h), peak * np.exp(-(t - 4 * h) / h))
    Z, B, X = -20.0 * shape, 30.0 * shape, 2.0 * t / (6 * h)
    cols = {"t": t, "dx": 1e-3 * X, "dz": 1e-3 * Z, "dx2": 1e-3 * X + 1e-6 * B * SPACING,
            "temp_air": 20 + 1.5 * np.sin(2 * np.pi * t / (24 * h)), "spindle_rpm": np.where(run, 12000.0, 0.0)}
    path = write(tmp_path, cols, "closed.csv", fmt="%.15g")
    rec = T.evaluate_file(path, spacing_mm=SPACING)
    d = {x["direction"]: x for x in rec["directions"]}
    assert set(d) == {"X", "Z", "B"}
    # over the test: the largest drift at the stop (4 h), the end value after 2 h of cooling
    assert d["Z"]["max_drift_um"] == pytest.approx(-20 * 0.9816844, abs=TOL)          # -19.634 um
    assert d["Z"]["max_drift_t_min"] == 240.0
    assert d["Z"]["range_um"] == pytest.approx(19.634, abs=TOL)
    assert d["Z"]["change_um"] == pytest.approx(-19.634 * math.exp(-2), abs=TOL)      # -2.657 um
    assert d["Z"]["last_hour_change_um"] == pytest.approx(-19.634 * (math.exp(-2) - math.exp(-1)), abs=TOL)
    assert d["B"]["max_drift_urad"] == pytest.approx(29.4505, abs=TOL)
    assert d["X"]["max_drift_um"] == pytest.approx(2.0, abs=TOL) and d["X"]["range_um"] == pytest.approx(2.0, abs=TOL)
    assert d["X"]["last_hour_change_um"] == pytest.approx(2 / 6, abs=TOL)
    run_p, stop_p = rec["phases"]
    assert (run_p["phase"], run_p["end_min"], stop_p["start_min"], stop_p["reference_min"]) == \
        ("running", 240.0, 241.0, 240.0)
    rz = next(x for x in run_p["directions"] if x["direction"] == "Z")
    assert rz["change_um"] == pytest.approx(-19.634, abs=TOL)
    assert rz["last_hour_change_um"] == pytest.approx(-20 * (math.exp(-3) - math.exp(-4)), abs=TOL)   # -0.629 um
    sz = next(x for x in stop_p["directions"] if x["direction"] == "Z")
    assert sz["change_um"] == pytest.approx(19.634 * (1 - math.exp(-2)), abs=TOL)     # recovers 16.98 um
    assert sz["max_drift_um"] == pytest.approx(sz["change_um"], abs=1e-9)
    air = rec["temperatures"][0]
    assert air["max_degC"] == pytest.approx(21.5, abs=1e-9) and air["range_degC"] == pytest.approx(1.5, abs=1e-9)
    # the stated resolution of full-precision numbers: below 1 nm, printed with 3 decimals
    assert d["Z"]["max_drift_um"] == pytest.approx(-19.634, abs=1e-3)


def test_known_etve_by_hand(tmp_path):
    """The machine at rest 8 h while X follows the air: X = 1.5 um sin(2 pi t / 24 h): the largest drift 1.5 um at
    6 h, ETVE 1.5 um; Y = -0.5 um t / 8 h: ETVE 0.5 um."""
    h = 3600.0
    t = np.arange(0, 8 * h + 1, 300.0)
    cols = {"t": t, "dx": 1.5e-3 * np.sin(2 * np.pi * t / (24 * h)), "dy": -0.5e-3 * t / (8 * h)}
    rec = T.evaluate_file(write(tmp_path, cols, "etve.csv", fmt="%.15g"))
    d = {x["direction"]: x for x in rec["directions"]}
    assert rec["test"] == "etve"
    assert d["X"]["ETVE_um"] == pytest.approx(1.5, abs=TOL) and d["X"]["max_drift_t_min"] == 360.0
    assert d["X"]["change_um"] == pytest.approx(1.5 * math.sin(2 * math.pi / 3), abs=TOL)
    assert d["Y"]["ETVE_um"] == pytest.approx(0.5, abs=TOL) and d["Y"]["max_drift_um"] == pytest.approx(-0.5, abs=TOL)


# -- the command line ---------------------------------------------------------------------------------------------
def test_command_line_text_json_plot(tmp_path, capsys):
    out = tmp_path / "sim.csv"
    rc, _, err = run_cli("simulate", "--iso230-3", "spindle", "-o", out, "--hours", "5", "--seed", "2", "--truth",
                         tmp_path / "truth.json")
    assert rc == 0 and "wrote" in err
    # one simulate: the test's options only with --iso230-3, a machine's readings' options never with it
    for argv, said in ((["--hours", "5"], "--hours: an option of the ISO 230-3 test"),
                       (["--iso230-3", "etve", "--effect", "ex_x:x1"], "--effect: an option of a machine's"),
                       (["--iso230-3", "etve", "--machine", "li2018"], "--machine: the ISO 230-3 test"),
                       (["--iso230-3", "etve", "--hours", "0"], "--hours")):
        rc, _, e = run_cli("simulate", *argv, "-o", tmp_path / "no.csv")
        assert rc == 2 and e.count("\n") == 1 and said in e and not (tmp_path / "no.csv").exists(), e
    rc, text, _ = run_cli("iso230-3", out, "--spacing", "100", "--plot", tmp_path / "plots")
    assert rc == 0 and "thermal distortion caused by a rotating spindle" in text
    assert "X to 0.1 um" in text and "A to 1 urad" in text and "running 0 to 239 min, 8000 rpm" in text
    assert (tmp_path / "plots" / "iso230-3_spindle.png").stat().st_size > 10_000
    rc, js, _ = run_cli("iso230-3", out, "--spacing", "100", "--json")
    rec = json.loads(js)
    z = next(d for d in rec["directions"] if d["direction"] == "Z")
    assert f"{z['max_drift_um']:10.1f}" in text              # the text prints the record's numbers, to 0.1 um
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert z["max_drift_um"] == pytest.approx(min(truth["Z_um"]), abs=0.5)
    # the file the simulator writes, read back: 0.1 um, 0.01 degC
    c = columns_of(out)
    assert np.allclose(c["dx"] * 1e4, np.round(c["dx"] * 1e4)) and np.allclose(c["temp_air"] * 100,
                                                                               np.round(c["temp_air"] * 100))


# -- bad input ----------------------------------------------------------------------------------------------------
def good(n=30):
    t = np.arange(n) * 60.0
    return {"t": t, "dx": 1e-4 * np.round(np.sin(t / 600) * 20), "dz": -1e-4 * np.arange(n),
            "temp_spindle": 20 + 0.01 * np.arange(n)}


@pytest.mark.parametrize("change, match", [
    (lambda c: c.update(temp_spindle=np.where(np.arange(30) == 7, 2000.0, c["temp_spindle"])),
     r"data row 8 \(line 9\), column temp_spindle: expected a temperature from -50 to 200 degC.*got 2000"),
    (lambda c: c.update(temp_bed=np.full(30, 21.3)), r"column temp_bed: the temperature never changes"),
    (lambda c: c.update(dz=np.zeros(30)), r"column dz: the reading never changes"),
    (lambda c: c.update(t=np.where(np.arange(30) == 12, 600.0, c["t"])),
     r"data row 13 \(line 14\), column t: time 600 does not increase"),
    (lambda c: c.update(dx2=c["dx"] + 1e-4), r"column dx2: a tilt needs the spacing"),
    (lambda c: c.update(dz=-0.1 * np.arange(30)), r"column dz: the displacement changes by 2\.9 mm.*um in a mm"),
    (lambda c: c.update(t=np.arange(30) * 0.1), r"column t: the test lasts 2\.9 s, under a minute"),
    (lambda c: c.update(t_min=np.arange(30.0)), r"both t \(s\) and t_min"),
    (lambda c: [c.pop("dx"), c.pop("dz")], r"no displacement column"),
    (lambda c: c.update(dy2=c["dx"]), r"column dy2 without dy"),
    (lambda c: c.update(temp_Spindle=c["temp_spindle"]), r"temp_Spindle.*lower-case"),
    (lambda c: c.update(dx=np.where(np.arange(30) == 3, np.nan, c["dx"])), r"data row 4.*column dx: empty cell"),
    (lambda c: c.update(spindle_rpm=np.full(30, 5e6)), r"column spindle_rpm: 5e\+06 rpm is not a spindle"),
])
def test_bad_input_is_one_line(tmp_path, change, match):
    c = good()
    change(c)
    one_line_error(tmp_path, pd.DataFrame(c), lambda p: T.evaluate_file(p), match)


def test_bad_statements(tmp_path, capsys):
    c = good()
    path = write(tmp_path, c)
    with pytest.raises(InputError, match="spindle_off_min: 500 min is not within the test"):
        T.evaluate_file(path, spindle=T.Spindle(off_min=500))
    c["spindle_rpm"] = np.where(np.arange(30) < 10, 6000.0, 0.0)
    path = write(tmp_path, c, "running.csv")
    with pytest.raises(InputError, match=r"data row 1, column spindle_rpm: the spindle runs.*ETVE"):
        T.evaluate_file(path, test="etve")
    with pytest.raises(InputError, match="column spindle_rpm and stated spindle times"):
        T.evaluate_file(path, spindle=T.Spindle(off_min=10))
    c["dx2"] = c["dx"] + 1e-4 * np.arange(30)
    path = write(tmp_path, c, "pair.csv")
    rc, _, err = run_cli("iso230-3", path)
    assert rc == 2 and "state it with --spacing MM" in err and err.count("\n") == 1
    rc, _, err = run_cli("iso230-3", path, "--spacing", "0.001")
    assert rc == 2 and "--spacing: expected the distance" in err
    rc, _, err = run_cli("iso230-3", path, "--spacing", "50", "--test", "axis")
    assert rc == 2 and "needs the axis' position" in err


# -- the report's section -------------------------------------------------------------------------------------------
def _cells(page: str, table_id: str) -> list:
    body = re.search(rf'<table id="{table_id}">.*?<tbody>(.*?)</tbody>', page).group(1)
    return [[re.sub(r"<[^>]+>", "", c) for c in re.findall(r"<td[^>]*>(.*?)</td>", row)]   # text, not <data> tags
            for row in re.findall(r"<tr[^>]*>(.*?)</tr>", body)]


def test_report_section_prints_the_record(tmp_path):
    """Every number of the section's tables is the record's, to the decimals of the readings' resolution."""
    from fiveaxis.report import html
    from fiveaxis.report.iso230_3 import section
    path, _ = simulated(tmp_path, "spindle", hours=5.0, run_hours=3.0, seed=8)
    rec, figs = section(path, spacing_mm=SPACING)
    page = html._iso230_3({"iso230_3": rec}, figs)
    assert page.startswith('<section id="iso230-3">') and 'id="fig-iso230_3"' in page
    from test_certificate import check_numbers
    assert check_numbers(page, {"iso230_3": rec}) == {"iso230_3"}     # every number is the record's, as keyed
    assert html._has_iso({"iso230_3": rec}, "iso230-3") and not html._has_iso({}, "iso230-3")
    step = {"um": 0.05, "urad": 0.5}              # half the last printed decimal (0.1 um; 1 urad: 0.1 um / 100 mm)
    rows = _cells(page, "iso230-3-figures")
    assert len(rows) == len(rec["directions"]) == 5
    for row, d in zip(rows, rec["directions"]):
        u = d["unit"]
        values = [float(x) for x in row[1:]]
        assert values == pytest.approx([d[f"{k}_{u}"] for k in ("max_drift", "range", "change", "last_hour_change")],
                                       abs=step[u] + 1e-9)
    for row, c in zip(_cells(page, "iso230-3-temperatures"), rec["temperatures"]):
        assert row[0] == c["channel"]
        assert [float(x) for x in row[1:]] == pytest.approx(
            [c[k] for k in ("first_degC", "last_degC", "min_degC", "max_degC", "range_degC", "change_degC")],
            abs=0.005 + 1e-9)


def test_report_refuses_a_bad_thermal_file_before_the_fit(tmp_path, capsys):
    c = good()
    c["temp_spindle"][4] = 2000.0
    bad = write(tmp_path, c, "bad.csv")
    out = tmp_path / "r.html"
    rc, _, err = run_cli("report", ROOT / "examples" / "li2018_measurements.csv", "-o", out, "--iso230-3",
                         bad)
    assert rc == 2 and err.count("\n") == 1 and "bad.csv: data row 5" in err and "temp_spindle" in err
    assert not out.exists()


@pytest.mark.slow
def test_report_with_a_thermal_test(tmp_path, capsys):
    path, _ = simulated(tmp_path, "spindle", hours=5.0, run_hours=3.0, seed=9)
    out = tmp_path / "r.html"
    rc, js, err = run_cli("report", ROOT / "examples" / "li2018_measurements.csv", "-o", out, "--iso230-3",
                          path, "--spacing", "100", "--rounds", "1", "--no-sensitivity", "--json")
    assert rc == 0, err
    rec = json.loads(js)["iso230_3"]
    page = out.read_text()
    assert '<a href="#iso230-3">ISO 230-3</a>' in page and '<section id="iso230-3">' in page
    assert rec["test"] == "spindle" and rec == T.evaluate_file(path, spacing_mm=SPACING)


def test_parquet_and_blank_temperatures(tmp_path):
    """The same test as Parquet gives the same figures; a temperature not read in some rows (blank) is evaluated
    over the rows where it was read, and the note says how many."""
    path, sim = simulated(tmp_path, "spindle", hours=4.0, run_hours=2.0, seed=11)
    df = pd.read_csv(path)
    df.loc[::3, "temp_column"] = np.nan
    df.to_csv(tmp_path / "blank.csv", index=False)
    df.to_parquet(tmp_path / "blank.parquet", index=False)
    a = T.evaluate_file(tmp_path / "blank.csv", spacing_mm=SPACING)
    b = T.evaluate_file(tmp_path / "blank.parquet", spacing_mm=SPACING)
    assert a["directions"] == b["directions"]
    assert [{k: v for k, v in c.items() if k != "resolution_degC"} for c in a["temperatures"]] == \
        [{k: v for k, v in c.items() if k != "resolution_degC"} for c in b["temperatures"]]
    # the CSV writes its resolution (0.01 degC, 0.1 um); Parquet's binary numbers do not say it
    assert {c["resolution_degC"] for c in a["temperatures"]} == {0.01}
    assert {c["resolution_degC"] for c in b["temperatures"]} == {None}
    assert b["directions_read"][0]["resolution_um"] is None
    col = next(c for c in a["temperatures"] if c["channel"] == "temp_column")
    read = df["temp_column"].dropna().to_numpy()
    assert col["readings"] == len(read) < len(df)
    assert (col["first_degC"], col["last_degC"], col["max_degC"]) == pytest.approx((read[0], read[-1], read.max()))
    assert any(f"temp_column: {len(read)} readings of {len(df)}" in n for n in a["notes"])
    assert a["series"]["temp_column_degC"][0] is None


def test_files_are_read_through_the_public_table_reader(tmp_path):
    """One reader of checked columns (`measurement.files.read_table`): no module outside measurement/files.py
    reaches its private helpers, and the ISO 230-3 reader names a bad cell's row, line and column as it does."""
    import ast
    private = []
    for path in sorted((ROOT / "src" / "fiveaxis").rglob("*.py")):
        text = path.read_text()
        if path.name == "files.py" and path.parent.name == "measurement" or "files" not in text:
            continue
        tree = ast.parse(text)
        aliases = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").endswith("measurement.files"):
                private += [f"{path.name}: {a.name}" for a in node.names if a.name.startswith("_")]
            if isinstance(node, ast.ImportFrom) and (node.module or "").endswith("measurement"):
                aliases |= {a.asname or a.name for a in node.names if a.name == "files"}
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases \
                    and node.attr.startswith("_"):
                private.append(f"{path.name}: {node.value.id}.{node.attr}")
    assert private == []
    bad = tmp_path / "bad.csv"
    bad.write_text("t,dx,temp_spindle\n0,0.001,20\n\n60,0.002,abc\n120,0.003,21\n")
    with pytest.raises(InputError, match=r"bad.csv: data row 3 \(line 4\), column temp_spindle: expected a number, "
                                         r"got 'abc'"):
        from fiveaxis.iso230.thermal_file import read
        read(bad)
