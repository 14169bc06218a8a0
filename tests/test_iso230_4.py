"""ISO 230-4 circular tests (issue 22): G with the least-squares centre against an independent geometric fit
(scipy's least_squares) to 0.01 um, the minimum-zone G against a brute-force search over centres, F against the
nominal radius, H between the two directions; on simulated ballbar circles written as a ballbar's software writes
them (positions at 0.001 mm, readings at 0.1 um); the ballbar's diagnostic list against the simulation's truth;
bad input as one-line errors."""
import json
import math

import numpy as np
import pytest
from scipy.optimize import least_squares

import fiveaxis
from fiveaxis.iso230 import circular as C
from fiveaxis.measurement.files import read
from fiveaxis.measurement.simulate import simulate, to_frame
from fiveaxis.report import iso230_text

from conftest import one_line_error, run_cli
from test_fuzz import _bad_json_numbers

NOISE = 1e-3
RADIUS = 150.0


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018")


@pytest.fixture(scope="module")
def circles_file(model, tmp_path_factory):
    sim = simulate(model, ["dx_x:xr=0.003", "dx_x:x1=0.05"], n=600, noise=NOISE, seed=7, instrument="ballbar",
                   errors={"Sxy": 5e-5})
    df = to_frame(sim, model)
    for c in ("X", "Y", "Z"):
        df[c] = df[c].round(3)
    df["du"] = df["du"].round(4)
    path = tmp_path_factory.mktemp("ballbar") / "circles.csv"
    df.to_csv(path, index=False)
    return path, df, sim


def _points(df):
    """In-plane path points (n, 2) about the nominal pivot and angles, per plane, from the file's columns: the
    bar's length 150 mm + du along the plane components of u."""
    planes = {"XY": ("ux", "uy"), "YZ": ("uy", "uz"), "ZX": ("uz", "ux")}
    out = {}
    for plane, (a, b) in planes.items():
        part = df[df["setup"] == plane]
        th = np.arctan2(part[b].to_numpy(), part[a].to_numpy())
        r = RADIUS + part["du"].to_numpy()
        out[plane] = (np.column_stack([r * np.cos(th), r * np.sin(th)]), th, part["t"].to_numpy())
    return out


def _geometric_fit(p):
    f = least_squares(lambda v: np.hypot(p[:, 0] - v[0], p[:, 1] - v[1]) - v[2], [0.0, 0.0, RADIUS],
                      xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return f.x[:2], f.x[2]


def test_G_F_H_against_independent_evaluations(model, circles_file):
    path, df, _ = circles_file
    circles = C.evaluate(read(path, model.machine), model)
    rec = C.to_json(circles)
    assert [c["plane"] for c in rec["circles"]] == ["XY", "YZ", "ZX"]
    pts = _points(df)
    for c in rec["circles"]:
        p, th, t = pts[c["plane"]]
        assert c["radius_mm"] == pytest.approx(RADIUS, abs=1e-4)
        assert [r["direction"] for r in c["runs"]] == ["ccw", "cw"] and [r["points"] for r in c["runs"]] == [100, 100]
        halves = (slice(0, 100), slice(100, 200))                  # the simulator runs ccw, then cw
        for run, half in zip(c["runs"], halves):
            centre, rho = _geometric_fit(p[half])
            r = np.hypot(*(p[half] - centre).T)
            assert run["G_um"] == pytest.approx(1e3 * np.ptp(r), abs=0.01)
            assert run["F_max_um"] == pytest.approx(1e3 * (r.max() - RADIUS), abs=0.1)
            assert run["F_min_um"] == pytest.approx(1e3 * (r.min() - RADIUS), abs=0.1)
            assert run["G_mz_um"] <= run["G_um"] + 1e-9
        # H: both paths about their common centre; the cw readings sit at the ccw ones' angles
        centre, _ = _geometric_fit(p)
        r = np.hypot(*(p - centre).T)
        key = np.round(np.mod(th, 2 * math.pi), 6)
        ccw = dict(zip(key[:100], r[:100]))
        H = max(abs(ccw[k] - v) for k, v in zip(key[100:], r[100:]))
        assert c["H_um"] == pytest.approx(1e3 * H, abs=0.01)


def _brute_zone(p, start, span):
    """Smallest max - min radius over a grid of centres, refined three times around the best (exact distances)."""
    best = np.asarray(start, float)
    for _ in range(4):
        g = np.linspace(-span, span, 81)
        cx, cy = np.meshgrid(best[0] + g, best[1] + g, indexing="ij")
        d = np.hypot(p[:, 0][None, None, :] - cx[..., None], p[:, 1][None, None, :] - cy[..., None])
        w = d.max(axis=2) - d.min(axis=2)
        k = np.unravel_index(np.argmin(w), w.shape)
        best, width = np.array([cx[k], cy[k]]), float(w[k])
        span *= 2.5 / 80
    return best, width


def test_minimum_zone_against_brute_force(model, circles_file):
    path, df, _ = circles_file
    for plane, (p, th, t) in _points(df).items():
        run = p[:100]
        a, _ = C.lsq_circle(run)
        c_mz, g_mz = C.minimum_zone(run, a)
        _, g_brute = _brute_zone(run, a, 0.02)
        assert g_mz <= g_brute + 1e-9 and g_brute - g_mz < 2e-6        # 2 nm: the grid's resolution
        assert g_mz < C.zone_width(run, a)
    # a shape whose minimum zone is clearly narrower than the least-squares one: a lobed path
    th = np.linspace(0, 2 * math.pi, 360, endpoint=False)
    r = 100 + 0.01 * np.cos(3 * th) + 0.006 * (th > 5.5) + 0.003 * np.sin(th)
    p = np.column_stack([r * np.cos(th) + 0.02, r * np.sin(th) - 0.01])
    a, _ = C.lsq_circle(p)
    c_mz, g_mz = C.minimum_zone(p, a)
    _, g_brute = _brute_zone(p, a, 0.02)
    assert g_mz <= g_brute + 1e-9 and g_brute - g_mz < 2e-6
    assert g_mz < C.zone_width(p, a) - 1e-4


def test_ballbar_diagnostics_against_the_truth(model, circles_file):
    path, df, sim = circles_file
    meas = sim.meas                      # unrounded: see test_ballbar_diagnostics_warn_when_the_fit_is_ill_conditioned
    diag = C.diagnostics(model, meas, C.evaluate(meas, model), max_rounds=3)
    assert not diag["warnings"] and sorted(diag["found"]) == ["dx_x:x1", "dx_x:xr"]
    items = {d["term"]: d for d in diag["items"]}
    b = items["backlash X"]
    assert b["found"] and b["effect"] == "dx_x:xr" and abs(b["size"] - 6.0) < 4 * b["std"]
    assert abs(items["backlash Y"]["size"]) < 4 * items["backlash Y"]["std"]
    s = items["scale mismatch X-Y"]                       # 0.05 mm at the end of X's 2500 mm: 20 ppm
    assert s["unit"] == "ppm" and abs(s["size"] - 20.0) < 4 * s["std"]
    q = items["squareness X-Y"]                           # as the circles see it: Sxy + ez_x
    truth = 1e6 * (sim.base_errors["Sxy"] + sim.base_errors["ez_x"])
    assert q["unit"] == "urad" and abs(q["size"] - truth) < 4 * q["std"] and "Sxy + ez_x" in q["note"]
    assert items["straightness X (XY)"]["effect"] == "dy_x:x2"
    assert "size" not in items["cyclic error"]


def test_ballbar_diagnostics_warn_when_the_fit_is_ill_conditioned(model, circles_file):
    """The same circles with the positions rounded to 0.001 mm, as a controller logs them: the fit takes a
    combination the circles cannot see (the roll of X) as determined at a condition number of ~1e6 and its sizes
    go wrong; the list says so instead of printing them silently (the fit's rank threshold is the fit's)."""
    path, _, _ = circles_file
    meas = read(path, model.machine)
    diag = C.diagnostics(model, meas, C.evaluate(meas, model), max_rounds=1)
    assert diag["fit"]["condition"] > C.ILL_CONDITIONED and "ill-conditioned" in diag["warnings"][0]
    assert "warning: the fit behind these sizes is ill-conditioned" in iso230_text.circles(C.to_json([], diag))


def test_cli_json_and_polar_plots(model, circles_file, tmp_path, capsys):
    path, _, _ = circles_file
    rc, out, err = run_cli("iso230-4", path, "--json", "--no-diagnosis", "--feed", "1000", "--plot",
                           tmp_path / "plots")
    assert rc == 0, err
    rec = json.loads(out)
    c = rec["circles"][0]
    assert {"setup", "plane", "radius_mm", "runs", "H_um"} <= set(c) and c["feed_mm_per_min"] == 1000.0
    assert not _bad_json_numbers(rec)
    assert {"G_um", "G_mz_um", "F_max_um", "F_min_um", "direction"} <= set(c["runs"][0])
    for plane in ("XY", "YZ", "ZX"):
        assert (tmp_path / "plots" / f"iso230-4_{plane}.png").stat().st_size > 10_000
    rc, out, _ = run_cli("iso230-4", path, "--no-diagnosis")
    assert rc == 0 and "circular hysteresis H (ccw / cw)" in out and "G (MZ)" in out


def _bad(model, tmp_path, df, match):
    return one_line_error(tmp_path, df, lambda path: C.evaluate(read(path, model.machine), model), match)


def test_bad_input_one_line_errors(model, circles_file, tmp_path):
    _, df, _ = circles_file
    xy = df[df["setup"] == "XY"]
    _bad(model, tmp_path, xy.iloc[:8], r"setup 'XY' \(data rows 1, 2, 3, 4 \.\.\. \(8 rows\)\): a circle with 8 "
                                       r"readings")
    short = xy.iloc[list(range(100)) + list(range(100, 108))]
    _bad(model, tmp_path, short, r"a run around the circle with 8 readings")
    tilted = xy.copy()
    tilted["uz"] = 0.5
    tilted[["ux", "uy", "uz"]] = tilted[["ux", "uy", "uz"]].div(np.sqrt((tilted[["ux", "uy", "uz"]] ** 2).sum(axis=1)),
                                                                 axis=0)
    _bad(model, tmp_path, tilted, r"do not lie in a coordinate plane")
    off = xy.copy()
    off.iloc[5, off.columns.get_loc("X")] += 1.0
    _bad(model, tmp_path, off, r"data row 6 \(setup 'XY'\): the pose is 0.99 mm off the circle of the other poses")
    _bad(model, tmp_path, xy.drop(columns=["du", "ux", "uy", "uz"]).assign(dx=0.0, dy=0.0, dz=0.0),
         r"no 1-D readings du")
    line = xy.copy()                                           # a laser line read as a ballbar: not a circle
    line["Y"], line["ux"], line["uy"] = 0.0, 1.0, 0.0
    _bad(model, tmp_path, line, r"the directions ux,uy,uz do not go around a circle \(they turn by 0 degrees")


def test_report_has_both_sections_for_mixed_instruments(model, tmp_path):
    """One file with a laser run of X and the ballbar circles (mixed instruments): the HTML report shows the ISO
    230-2 table of X and the ISO 230-4 table of the three circles, with their plots."""
    import pandas as pd
    from fiveaxis.report import html, record
    laser = simulate(model, ["dx_x:xr=0.003"], n=100, noise=NOISE, seed=8, instrument="interferometer",
                     options={"axes": ["X"], "targets": 7})
    balls = simulate(model, ["dx_x:xr=0.003"], n=300, noise=NOISE, seed=8, instrument="ballbar")
    path = tmp_path / "mixed.csv"
    pd.concat([to_frame(laser, model), to_frame(balls, model)], ignore_index=True).to_csv(path, index=False)
    rep = record.build(path, "li2018", max_rounds=1, sensitivity=False)
    iso = rep.record["iso230"]
    assert [r["axis"] for r in iso["positioning"]] == ["X"] and len(iso["circles"]["circles"]) == 3
    assert not iso["skipped"]
    page = html.render(rep)
    assert page.count('<section id="iso230-2">') == 1 and page.count('<section id="iso230-4">') == 1
    assert 'href="#iso230-2"' in page and "fig-iso230_4_2" in page
    assert f"{iso['positioning'][0]['E_um']:.3g}" in page
