"""The workspace comes from the machine file (issue 14): [workspace] tables, strokes, the paper's preset; every
sensitivity command and compensation experiment on every shipped machine; the vital-set rule."""
import json
import math

import numpy as np
import pytest

import fiveaxis
from fiveaxis.sensitivity import paper as presets
from conftest import run_cli
from fiveaxis.exceptions import InputError
from fiveaxis.sensitivity.experiments import diagonal_points, vital_set
from fiveaxis.sensitivity.grid import describe_source, from_workspace, workspace_grid
from fiveaxis.model.machine import MACHINES_DIR, WORKSPACE_COUNT, load_machine

from conftest import SHIPPED

LI = (MACHINES_DIR / "li2018.toml").read_text()


def run_json(capsys, argv):
    assert run_cli(*argv, "--json", echo=True)[0] == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


def small_li2018(tmp_path):
    """li2018 with short strokes (X +-300, Y +-100 mm, A +-10 deg) and no [workspace] table."""
    text = LI.split("[workspace]")[0]
    text = text.replace("stroke = [-2500, 2500]", "stroke = [-300, 300]").replace(
        "stroke = [-1000, 1000]", "stroke = [-100, 100]")
    text = text.replace('axis = "A"\ntype = "rotary"\ndirection = [1, 0, 0]\nstroke = [-30, 30]',
                        'axis = "A"\ntype = "rotary"\ndirection = [1, 0, 0]\nstroke = [-10, 10]')
    path = tmp_path / "small.toml"
    path.write_text(text.replace('name = "li2018"', 'name = "small"'))
    return path


def test_li2018_workspace_is_the_papers_grid_exactly():
    m = fiveaxis.load("li2018")
    assert from_workspace(m.machine) == presets.workspace_grid(m)        # same axes, ranges and counts
    assert presets.workspace_preset("paper", m).size == 159705


def test_small_strokes_give_a_grid_within_them(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path / "cache"))
    path = small_li2018(tmp_path)
    m = load_machine(path)
    g = from_workspace(m)
    assert g.shape == (WORKSPACE_COUNT,) * 5
    for a in g.axes:
        lo, hi = m.axis(a.name).model_stroke
        assert (a.lo, a.hi) == pytest.approx((lo, hi))
    assert workspace_grid(m).describe(m.rotary) == {"X": [-300, 300, 5], "Y": [-100, 100, 5], "Z": [-250, 250, 5],
                                                    "A": [-10, 10, 5], "B": [-30, 30, 5]}
    assert describe_source(m) == "the strokes of small, 5 points per axis"
    # (the command builds the same grid: workspace_grid is the one builder of gsa, sobol and dask; running GSIL
    # here would compile a new model's kernels, ~40 s, so the command is only asked for what it refuses)
    # the paper's workspace does not fit this machine: refused, as is an --axis beyond the stroke
    for argv, needle in [(["--preset", "paper"], "preset paper: axis X range [-2500, 2500] mm leaves the stroke "
                                                 "[-300, 300] mm of small"),
                         (["--axis", "A=-30:30:3"], "--axis: axis A range [-30, 30] deg leaves the stroke")]:
        assert run_cli("gsa", "--machine", path, *argv, echo=True)[0] == 2
        err = [ln for ln in capsys.readouterr().err.splitlines()
               if not ln.startswith(("fiveaxis: deriving", "fiveaxis: compiling"))]
        assert len(err) == 1 and err[0].startswith("fiveaxis: error: ") and needle in err[0], err


@pytest.mark.parametrize("table, key", [
    ("X = [-3000, 3000, 5]", "workspace.X: [-3000, 3000] mm is outside the stroke [-2500, 2500] mm"),
    ("W = [0, 1, 3]", "workspace.W: unknown axis"),
    ("X = [10, -10, 5]", "workspace.X: expected lo < hi"),
    ("X = [-10, 10, 2.5]", "workspace.X: expected a whole number of points"),
    ("X = [-10, 10, 0]", "workspace.X: expected a whole number of points"),
    ("X = 'all'", "workspace.X: expected [lo, hi, count]"),
    ("A = [-40, 0, 3]", "workspace.A: [-40, 0] deg is outside the stroke [-30, 30] deg"),
])
def test_bad_workspace_table_is_one_line(tmp_path, table, key):
    path = tmp_path / "bad.toml"
    path.write_text(LI.split("[workspace]")[0] + "[workspace]\n" + table + "\n")
    with pytest.raises(InputError) as exc:
        load_machine(path)
    assert key in str(exc.value) and str(path) in str(exc.value) and "\n" not in str(exc.value)


def test_workspace_table_ranges_counts_and_fixed_axes(tmp_path):
    path = tmp_path / "w.toml"
    path.write_text(LI.split("[workspace]")[0] + "[workspace]\nX = [-100, 100]\nY = 5\nB = [-10, 20, 4]\n")
    g = from_workspace(load_machine(path))
    assert g.describe(("A", "B")) == {"X": [-100, 100, WORKSPACE_COUNT], "Y": [5, 5, 1], "Z": [-250, 250, 5],
                                      "A": [-30, 30, 5], "B": [-10, 20, 4]}


@pytest.mark.parametrize("machine", SHIPPED)
def test_every_command_on_every_machine(capsys, machine):
    """gsa, gsa --compensate, sobol, lsa --pose --compensate: valid JSON (no NaN), the experiments' invariants."""
    m = fiveaxis.load(machine)
    small = [f"--axis={v}={lo:g}:{hi:g}:3" for v in m.variables for lo, hi in [m.machine.axis(v).stroke]]
    g = run_json(capsys, ["gsa", "--machine", machine, "--compensate", "--rot-count", "3"] + small)
    assert g["settings"]["poses"] == 3 ** 5 and len(g["indices"]) == len(m.errors)
    comp = g["compensation"]
    assert comp["vital"] == g["ranking"][:len(comp["vital"])] and "largest relative drop" in comp["vital_rule"]
    for key in ("position_mm", "posture_rad"):
        rows = {r["scenario"]: r for r in comp[key]}
        assert rows["all halved"]["improvement_pct"] == pytest.approx(50.0)
        assert rows["none"]["value"] > 0
    s = run_json(capsys, ["sobol", "--machine", machine, "--samples", "16"] + small)
    assert len(s["indices"]) == len(m.errors) and -1 <= s["comparison"]["spearman"] <= 1
    mid = ",".join(f"{v}={0.5 * sum(m.machine.axis(v).stroke) + 1:g}" for v in m.variables)
    lo = ",".join(f"{v}={0.7 * m.machine.axis(v).stroke[0] + 0.3 * m.machine.axis(v).stroke[1]:g}"
                  for v in m.variables)
    ls = run_json(capsys, ["lsa", "--machine", machine, "--pose", mid, "--pose", lo, "--compensate"])
    assert ls["settings"]["poses"] == 2 and "without the surface normal" in ls["settings"]["normals"]
    rows = {r["scenario"]: r for r in ls["compensation"]["machining_error_mm"]}
    assert rows["all halved"]["improvement_pct"] == pytest.approx(50.0)
    assert ls["compensation"]["measure"].startswith("|P_err|")


def test_paper_preset_is_printed_and_keeps_the_papers_numbers(capsys):
    argv = ["gsa", "--convention", "printed", "--preset", "paper", "--axis", "X=0", "--compensate",
            "--rot-count", "5"]
    out = run_json(capsys, argv)
    assert out["settings"]["workspace"].startswith("preset paper (Sect. 4.2 of Li et al. 2018")
    assert out["compensation"]["vital"] == list(presets.PAPER_VITAL["workspace"])
    assert out["compensation"]["vital_rule"] == "the paper's vital set"
    # the machine's own workspace and vital rule give the same on li2018 (printed): the defaults stay the paper's
    own = run_json(capsys, [a for a in argv if a not in ("--preset", "paper")])
    assert own["indices"] == out["indices"]
    assert set(own["compensation"]["vital"]) == set(out["compensation"]["vital"])
    assert own["compensation"]["position_mm"] == out["compensation"]["position_mm"]
    assert run_cli("gsa", "--machine", "ac_trunnion", "--preset", "paper", echo=True)[0] == 2
    assert "the paper's presets need the li2018 kinematics" in capsys.readouterr().err


def test_lsa_without_a_path_on_another_machine_says_what_to_give(capsys):
    assert run_cli("lsa", "--machine", "tilting_head", echo=True)[0] == 2
    err = capsys.readouterr().err
    assert "give a path with --toolpath FILE or --pose X=..,Y=..,Z=..,B=..,C=.." in err


def test_vital_rule():
    names = list("abcdefghijkl")
    p = np.array([30, 20, 10, 2, 1.9, 1.8, 1, 1, 1, 1, 1, 1], float)
    assert vital_set(names, p / p.sum()) == ["a", "b", "c"]          # the largest ratio: 10 -> 2
    tie = np.array([5, 5, 4.9, 4.9, 1, 1, 1, 1, 1, 1, 1, 1], float)
    assert vital_set(names, tie) == ["a", "b", "c", "d"]             # ties are never split
    # on li2018 (printed convention) the rule gives the paper's vital sets of Sect. 4.2 and cone position 1
    m = fiveaxis.load("li2018", "printed")
    from fiveaxis.sensitivity.indices import gsil, lsil
    g = gsil(m, presets.workspace_grid(m, {"X": 1}), presets.paper_errors(m), 200.0, 30.0, progress=False)
    assert set(vital_set(g.names, g.proportions)) == set(presets.PAPER_VITAL["workspace"])
    r = lsil(m, presets.cone_poses(m, 1), presets.paper_errors(m), presets.CONE_L0, presets.CONE_LE)
    assert set(vital_set(r.names, r.proportions)) == set(presets.PAPER_VITAL["cone1"])


def test_diagonal_points_generalise_the_nine_points():
    np.testing.assert_array_equal(diagonal_points([-2500, -1000, -250], [2500, 1000, 250]), presets.nine_points())
    pts = diagonal_points([0, 10], [4, 30], "corner")
    assert pts.tolist() == [[0, 10], [0, 30], [4, 10], [4, 30], [2, 20]]
    assert math.isclose(presets.nine_point_errors(fiveaxis.load("li2018"), None, 3)["position_mm"],
                        presets.point_errors(fiveaxis.load("li2018"), presets.paper_box(fiveaxis.load("li2018")),
                                             None, 3)["position_mm"])
