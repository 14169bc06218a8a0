"""Issue 29.2: printouts that cannot mislead. One rule for the text, the report and the JSON, kept in the fit's
record (`fiveaxis.estimation.result.PRINT_RULES`): what the data determine first, as physical quantities with U
(k = 2); what they determine only in combination printed as that combination; members of a combination with an
artefact's placement named, not valued; the prior's values apart; held values as held; no "relative to" nothing,
no coefficient below 1e-3 in a formula, no value beyond 1 mm or 10,000 urad printed as a result. Checked on every
shipped machine and instrument at controller resolution, and on the issue's R-test cases (their truth files)."""
import re

import numpy as np
import pytest

from fiveaxis.estimation import fit as F
from fiveaxis.estimation.result import PLAUSIBLE, to_json
from fiveaxis.measurement.files import read
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model.error_model import load
from fiveaxis.report import text
from fiveaxis.report.record import _fit_record

from conftest import first_fast
from written import controller_csv, too_large

MACHINES = ("li2018", "ac_trunnion", "tilting_head")
INSTRUMENTS = ("tip", "rtest", "probe-sphere", "ballbar", "interferometer", "tracker", "test-part")
COEF = re.compile(r"(?:^|[=(\s+-])(\d+(?:\.\d*)?(?:e[-+]?\d+)?)\*")


def check_printout(model, j: dict, out: str):
    """The rules on a fit's record and its text."""
    assert not too_large(out), too_large(out)[:3]
    assert not re.search(r"relative to\s*($|[;,)])", out, re.M)
    for q in j["quantities"]:
        assert q["relative_to"] or q.get("alone"), q
        for c in COEF.findall(q["formula_iso"]):
            assert 1e-3 <= float(c), (c, q["formula_iso"])
        if q.get("plausible", True):
            assert abs(q["value"]) <= PLAUSIBLE.get(q["unit"], np.inf)
    for name, p in j["parameters"].items():
        if p["determined"] and not p.get("fixed") and p["unit"] in PLAUSIBLE and p.get("plausible", True):
            assert abs(p["value"]) <= PLAUSIBLE[p["unit"]], (name, p["value"])
        if "posterior" in p and p["unit"] in PLAUSIBLE:
            assert abs(p["posterior"]["value"]) <= PLAUSIBLE[p["unit"]], (name, p["posterior"])
    rec = _fit_record(model, j, [])
    for q in rec["quantities"]:
        assert q["relative_to"].strip()
    for p in rec["parameters"]:
        if p["determined"] and p["value"] is not None and p["unit"] == "um":
            assert abs(p["value"]) <= 1000
        if p["determined"] and p["value"] is not None and p["unit"] == "urad":
            assert abs(p["value"]) <= 10000


@pytest.mark.parametrize("machine, instrument", first_fast([(m, i) for m in MACHINES for i in INSTRUMENTS], 2))
def test_every_machine_and_instrument_at_controller_resolution(machine, instrument, tmp_path):
    model = load(machine)
    sim = simulate(model, n=400, instrument=instrument, seed=3)
    meas = read(controller_csv(model, sim, tmp_path / "c.csv"), model.machine)
    j = to_json(F.fit(model, meas))
    check_printout(model, j, text.fit(j))


def test_make_run_rtest_example(tmp_path):
    """`make run`'s R-test (ac_trunnion, 600 poses, hidden dx_C:C1, sigma column) printed ex_C (E_AC) -5222 urad
    +- 97 and dy_C 718.5 um "relative to the placement of sphere1, sphere2, sphere3" (truth: -22.5 urad, -4.0 um):
    now they are named as not separable from the placement, and their values are the prior's, containing the
    truth (k = 2)."""
    model = load("ac_trunnion")
    sim = simulate(model, ["dx_C:C1=0.01"], instrument="rtest", n=600, seed=2, with_sigma=True)
    res = F.fit(model, sim.meas)
    j = to_json(res)
    out = text.fit(j)
    check_printout(model, j, out)
    group = j["not_separable"][0]
    assert {"ex_C", "ey_C", "dx_C", "dy_C"} <= set(group["members"])
    assert group["setups"] == ["sphere1", "sphere2", "sphere3"]
    assert "Not separable from the placement of sphere1, sphere2, sphere3" in out
    assert not any(line.lstrip().startswith(("ex_C", "dy_C")) and "+-" in line
                   for line in out.split("[[Decided by the prior]]")[0].splitlines())
    for name in ("ex_C", "ey_C", "dx_C", "dy_C"):
        p = j["parameters"][name]
        truth = sim.base_errors[name]
        assert p["decided_by"] == "prior" and abs(p["posterior"]["value"] - truth) <= p["posterior"]["expanded_k2"]


def test_trunnion_rtest_written_to_a_micrometre_with_the_effect_found_and_a_held_value(tmp_path):
    """ac_trunnion R-test, X Y Z written to 0.001 mm, the effect just found added: it is printed with its value
    (the issue: "Parameters determined by this data" empty), nothing reads ez_A 2.066e+07 urad or dx_C 1.24e+06 um,
    no empty "relative to", no dust such as -1.464e-06*E_CA, and a --fix value is printed as held, not as
    determined by the data."""
    model = load("ac_trunnion")
    sim = simulate(model, ["dx_C:C1=0.01"], instrument="rtest", n=600, seed=2)
    path = tmp_path / "rt.csv"
    df = __import__("fiveaxis.measurement.simulate", fromlist=["to_frame"]).to_frame(sim, model)
    for c in ("X", "Y", "Z"):
        df[c] = df[c].map(lambda v: f"{v:.3f}")
    df.to_csv(path, index=False)
    meas = read(path, model.machine)
    res = F.fit(model, meas, ["dx_C:C1"], fixed={"dXOC": sim.base_errors["dXOC"]})
    j = to_json(res)
    out = text.fit(j)
    check_printout(model, j, out)
    determined = out.split("[[Determined by this data]]")[1].split("[[")[0]
    assert "dx_C:C1 (E_XC:C1)" in determined and "dXOC" not in determined
    held = out.split("[[Held fixed]]")[1].split("[[")[0]
    assert "dXOC (E_X0C)" in held and "(held)" in held
    assert j["parameters"]["dXOC"]["decided_by"] == "held"


def test_an_impossible_value_is_said_not_printed():
    """A value beyond 1 mm (a unit slip: readings in um written as mm) is not printed as a result."""
    model = load("li2018")
    sim = simulate(model, n=300, seed=4)
    sim.meas.d = sim.meas.d * 1000.0
    j = to_json(F.fit(model, sim.meas))
    out = text.fit(j)
    results = out[out.index("[[Determined by this data]]"):]      # the residual, a fact of the data, may be large
    assert not too_large(results), too_large(results)[:3]
    assert "not an error of a machine tool" in results


def test_a_tool_axis_error_of_arithmetic_dust_prints_as_zero():
    """A laser run of one linear axis leaves the tool axis untouched: compensate printed 'after the table 9.7e-15'
    urad; below 0.001 urad the printout says 0, above it the value."""
    assert text._urad(9.7e-21) == "0" and text._urad(-3e-10) == "0"
    assert text._urad(2.5e-9) == "0.0025" and text._urad(1.234e-5) == "12.3"
