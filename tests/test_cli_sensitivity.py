"""End-to-end runs of `fiveaxis gsa`, `lsa`, `sobol`: the JSON shape, plots, one-line errors for bad input."""
import json

import pytest

from fiveaxis.cli import main
from fiveaxis.presets import PAPER_VITAL


def run_json(capsys, argv):
    assert main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


def check_shape(out):
    assert set(out) >= {"indices", "ranking", "settings"}
    assert len(out["indices"]) == 41 and sorted(out["ranking"]) == sorted(out["indices"])
    assert sum(out["indices"].values()) == pytest.approx(1.0)
    vals = [out["indices"][n] for n in out["ranking"]]
    assert vals == sorted(vals, reverse=True)


def test_gsa_json(capsys):
    out = run_json(capsys, ["gsa", "--machine", "li2018", "--convention", "printed",
                            "--axis", "X=-2500:2500:5", "--axis", "A=-30:30:5", "--axis", "B=-30:30:5"])
    check_shape(out)
    assert set(out["ranking"][:4]) == set(PAPER_VITAL["workspace"])
    s = out["settings"]
    assert s["kind"] == "GSIL" and s["convention"] == "printed" and s["LE_mm"] == 30 and s["L0_mm"] == 200
    assert s["grid"]["X"] == [-2500, 2500, 5] and s["grid"]["A"] == [-30, 30, 5] and s["poses"] == 5 * 9 * 5 * 25
    assert s["quadrature"]["order"] == "exact" and s["skipped_poses"] == 0
    assert s["quadrature"]["max_abs_change_of_proportion"] < 1e-4       # exact vs Gauss-Legendre 16


@pytest.mark.parametrize("cone,k", [(1, 6), (2, 7)])
def test_lsa_json(capsys, cone, k):
    out = run_json(capsys, ["lsa", "--machine", "li2018", "--convention", "printed", "--cone", str(cone)])
    check_shape(out)
    assert set(out["ranking"][:k]) == set(PAPER_VITAL[f"cone{cone}"])
    assert out["settings"]["cone"] == cone and out["settings"]["LE_mm"] == pytest.approx(34.64, abs=0.01)


def test_lsa_compensate_and_plots(capsys, tmp_path):
    assert main(["lsa", "--convention", "printed", "--cone", "1", "--compensate", "--normal-mode", "1",
                 "--plot", str(tmp_path), "--top", "6", "--errors", "dx_x=2e-4"]) == 0
    text = capsys.readouterr().out
    assert "LSIL proportions" in text and "Fig. 11" in text and "vital halved" in text
    assert len([ln for ln in text.splitlines() if ln.strip()[:1].isdigit() and "%" in ln]) >= 6
    names = {p.name for p in tmp_path.iterdir()}
    assert {"lsa_cone1_pie.png", "lsa_cone1_map_none.png", "lsa_cone1_map_vital.png"} <= names
    assert all((tmp_path / n).read_bytes()[:4] == b"\x89PNG" for n in names)


def test_gsa_compensate_json_and_plots(capsys, tmp_path):
    out = run_json(capsys, ["gsa", "--convention", "printed", "--axis", "X=-2500:2500:3", "--axis", "Z=0",
                            "--compensate", "--rot-count", "5", "--plot", str(tmp_path)])
    comp = out["compensation"]
    assert [r["scenario"] for r in comp["position_mm"]] == ["none", "vital halved", "others halved", "all halved"]
    assert comp["posture_rad"][3]["improvement_pct"] == pytest.approx(50.0)
    assert {"gsa_pie.png", "gsa_position_none.png", "gsa_posture_vital.png"} <= {p.name for p in tmp_path.iterdir()}


def test_errors_file(capsys, tmp_path):
    f = tmp_path / "errors.txt"
    f.write_text("# all but ex_x zero would be odd; set two\nex_x = 0\nSyz 0\n")
    out = run_json(capsys, ["gsa", "--convention", "printed", "--axis", "X=-2500:2500:3", "--errors", str(f)])
    assert out["indices"]["ex_x"] == 0 and out["indices"]["Syz"] == 0
    assert set(out["ranking"][:2]) == {"Sxy", "ez_x"}


@pytest.mark.parametrize("argv,needle", [
    (["gsa", "--axis", "X=10:-10:5"], "inverted range"),
    (["gsa", "--axis", "X=10:10:5"], "empty range"),
    (["gsa", "--axis", "X=-10:10:0"], "count must be at least 1"),
    (["gsa", "--axis", "W=-10:10:3"], "unknown axis 'W'"),
    (["gsa", "--errors", "ex_q=1e-4"], "unknown error name 'ex_q'"),
    (["gsa", "--errors", "ex_x=abc"], "must be a number"),
    (["gsa", "--le", "0"], "--le"),
    (["lsa", "--le", "-3"], "--le"),
    (["lsa", "--order", "0"], "--order"),
    (["gsa", "--order", "eight"], "--order"),
    (["lsa", "--order", "exact", "--normal-mode", "1"], "normal mode 0"),
    (["lsa", "--convention", "nope"], "unknown convention"),
    (["sobol", "--samples", "100"], "power of 2"),
])
def test_bad_input_is_one_line(capsys, argv, needle):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("fiveaxis: error:") and needle in err and len(err.strip().splitlines()) == 1


def test_bad_errors_file_names_the_line(capsys, tmp_path):
    f = tmp_path / "e.txt"
    f.write_text("ex_x=1e-4\nbogus_name=3\n")
    assert main(["lsa", "--errors", str(f)]) == 2
    err = capsys.readouterr().err
    assert f"{f}: line 2: unknown error name 'bogus_name'" in err and len(err.strip().splitlines()) == 1


def test_sobol_command(capsys):
    out = run_json(capsys, ["sobol", "--convention", "printed", "--samples", "32"])
    assert len(out["indices"]) == 41 and out["settings"]["evaluations"] == 32 * 43
    assert "spearman" in out["comparison"]


def test_progress_bar_on_request_and_off_otherwise(capsys):
    argv = ["gsa", "--convention", "printed", "--axis", "X=0", "--axis", "B=-30:30:3", "--chunk", "500"]
    assert main(argv + ["--progress"]) == 0
    err = capsys.readouterr().err
    assert "GSIL" in err and "100%" in err
    assert main(argv) == 0                       # stderr is not a terminal under pytest: no bar
    assert capsys.readouterr().err == ""
