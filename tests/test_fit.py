"""The fit on simulated data: what it determines is right, what it cannot determine gets no number."""
from types import SimpleNamespace

import numpy as np
import pytest

import fiveaxis
from fiveaxis.estimation import fit as F
from fiveaxis.measurement.simulate import simulate
from fiveaxis.estimation import result as R
from fiveaxis.report import text
from fiveaxis.estimation.problem import machine_effects, resolve_effects


@pytest.fixture(scope="module")
def model():
    return fiveaxis.load("li2018")


@pytest.fixture(scope="module")
def clean(model):
    sim = simulate(model, [], n=600, noise=0.0, seed=5)
    return sim, F.fit(model, sim.meas)


def test_noise_free_data_is_reproduced_by_the_exact_model(clean):
    sim, res = clean
    assert res.rms_mm < 1e-9                               # exact model, exact data
    assert res.idf.rank == 15 and res.idf.condition < 1e3


def test_determined_combinations_match_the_truth(clean):
    sim, res = clean
    assert len(res.combinations) >= 10
    for c in res.combinations:
        truth = sum(k * sim.base_errors[n] for n, k in c.terms.items())
        assert abs(c.value - truth) <= 1e-3 * abs(truth) + 1e-9, c.formula
    p = R.parameters(res)
    assert p["ex_x"]["value"] == pytest.approx(sim.base_errors["ex_x"], rel=1e-3)


def test_undetermined_parameters_get_no_number(clean):
    _, res = clean
    j = R.to_json(res)
    assert ["ex_y", "Syz"] in j["unidentifiable"]
    combo = next(c for c in j["combinations"] if set(c["terms"]) == {"ex_y", "Syz"})
    assert next(iter(combo["terms"])) == "Syz"          # led by the squareness, the quantity an engineer reports
    for name in ("ex_y", "Syz", "dx_x", "dXOB", "ez_A"):
        assert not j["parameters"][name]["determined"] and "value" not in j["parameters"][name]
    assert "no effect" in j["parameters"]["ez_A"]["note"]
    assert combo["formula"] in j["parameters"]["Syz"]["note"] and combo["formula"] in j["parameters"]["ex_y"]["note"]
    # L fixed at 200 mm: ey_A cannot be told from the translations of the rotary axes.
    assert any(set(c["terms"]) == {"dx_B", "ey_A", "dx_A"} for c in j["combinations"])
    out = text.fit(R.to_json(res))
    alone, combined = out.split("[[Determined by this data only as combinations")[:2]
    assert "Syz " not in alone                          # never printed as if determined alone
    line = next(x for x in combined.splitlines() if x.lstrip().startswith("E_A(0Y)Z + E_AY = "))
    assert "(Syz: " in line                            # the squareness, as the combination it is seen in


def test_another_tool_length_separates_ey_A(model):
    sim = simulate(model, [], n=600, noise=0.0, seed=6, tool_lengths=(100, 300))
    j = R.to_json(F.fit(model, sim.meas))
    assert j["parameters"]["ey_A"]["value"] == pytest.approx(sim.base_errors["ey_A"], rel=1e-3)


def test_standard_errors_are_calibrated(model):
    sim = simulate(model, [], n=800, noise=2e-3, seed=7, with_sigma=True)
    res = F.fit(model, sim.meas)
    p = R.parameters(res)
    z = [(p[n]["value"] - sim.base_errors[n]) / p[n]["std"] for n in p if p[n]["determined"]]
    z += [(c.value - sum(k * sim.base_errors[n] for n, k in c.terms.items())) / c.std for c in res.combinations]
    assert len(z) >= 12 and np.max(np.abs(z)) < 4.5
    assert 0.8 < res.chi2 / res.dof < 1.2


def test_refinement_on_the_exact_model(model):
    sim = simulate(model, [], n=400, noise=0.0, seed=8, base_scale=100)   # 0.3 mm, 2 mrad errors
    res = F.fit(model, sim.meas)
    first = np.sqrt(np.mean(res.residual_first ** 2))
    assert first > 1e-4 and res.rms_mm < 1e-3 * first


def test_added_effect_in_physical_units(model):
    sim = simulate(model, ["ex_x:x1=2e-5"], n=800, noise=1e-3, seed=9)
    p = R.parameters(F.fit(model, sim.meas, ["ex_x:x1"]))["ex_x:x1"]
    assert p["unit"] == "rad/mm"
    assert abs(p["value"] - 2e-5 / 2500) < 4 * p["std"] and p["std"] < 1e-10
    assert "twisted guideway" in p["description"]


def test_identifiable_count_and_bad_effects(model):
    assert F.identifiable_count(model) == 15
    with pytest.raises(fiveaxis.InputError, match="unknown parameter 'ex_q'"):
        resolve_effects(model, ["ex_q:x1"])
    with pytest.raises(fiveaxis.InputError, match="unknown variable 'C'"):
        resolve_effects(model, ["ex_x:C1"])
    with pytest.raises(fiveaxis.InputError, match="not an effect id"):
        resolve_effects(model, ["ex_x:x4"])


@pytest.mark.parametrize("table,expect", [
    ('[effects.s]\nerror = "dx_x"\nexpr = "p1*sin(x/p2)"\n', "not linear in its parameters"),
    ('[effects.s]\nerror = "dx_x"\nexpr = "q*x"\n', "unknown name(s) q"),
    ('[effects.s]\nerror = "dx_x"\nexpr = "x**2"\n', "no parameters"),
    ('[effects.s]\nerror = "dx_x"\nexpr = "p1*(x"\n', "not a valid expression"),
    ('[effects.s]\nerror = "dx_q"\nexpr = "p1*x"\n', "effects.s.error: expected an error name"),
    ('[model]\neffects = ["ex_x:x7"]\n', "model.effects[0]: 'ex_x:x7' is not an effect id"),
    ('[model]\neffects = ["ex_x:q1"]\n', "model.effects[0]: expected an effect id"),
    ('[model]\neffects = "ex_x:x1"\n', "model.effects: expected a list"),
])
def test_custom_effect_definitions_are_checked(tmp_path, table, expect):
    from fiveaxis.effects.custom import load_custom
    from fiveaxis.model.machine import MACHINES_DIR, load_machine
    path = tmp_path / "m.toml"
    path.write_text((MACHINES_DIR / "li2018.toml").read_text() + "\n" + table)
    with pytest.raises(fiveaxis.InputError) as exc:
        machine = load_machine(path)
        machine_effects(SimpleNamespace(machine=machine, errors=machine.error_names))   # ids: by their families
        load_custom(machine, "s")                      # a custom effect: checked when loaded
    assert expect in str(exc.value) and "\n" not in str(exc.value) and str(path) in str(exc.value)
