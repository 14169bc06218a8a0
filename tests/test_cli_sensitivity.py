"""End-to-end runs of `fiveaxis gsa`, `lsa`, `sobol`: the JSON shape, plots, one-line errors for bad input."""
import json

import pytest

from conftest import run_cli
from fiveaxis.exceptions import InputError
from fiveaxis.sensitivity.paper import PAPER_VITAL


def run_json(capsys, argv):
    assert run_cli(*argv, "--json", echo=True)[0] == 0
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
    assert run_cli("lsa", "--convention", "printed", "--cone", "1", "--compensate", "--normal-mode", "1",
                 "--plot", str(tmp_path), "--top", "6", "--errors", "dx_x=2e-4", echo=True)[0] == 0
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
    assert run_cli(*argv, echo=True)[0] == 2
    err = capsys.readouterr().err
    assert err.startswith("fiveaxis: error:") and needle in err and len(err.strip().splitlines()) == 1


def test_bad_errors_file_names_the_line(capsys, tmp_path):
    f = tmp_path / "e.txt"
    f.write_text("ex_x=1e-4\nbogus_name=3\n")
    assert run_cli("lsa", "--errors", str(f), echo=True)[0] == 2
    err = capsys.readouterr().err
    assert f"{f}: line 2: unknown error name 'bogus_name'" in err and len(err.strip().splitlines()) == 1


def test_sobol_command(capsys):
    out = run_json(capsys, ["sobol", "--convention", "printed", "--samples", "32"])
    assert len(out["indices"]) == 41 and out["settings"]["evaluations"] == 32 * 43
    assert "spearman" in out["comparison"]


def test_progress_bar_on_request_and_off_otherwise(capsys):
    argv = ["gsa", "--convention", "printed", "--axis", "X=0", "--axis", "B=-30:30:3", "--chunk", "500"]
    assert run_cli(*argv, "--progress", echo=True)[0] == 0
    err = capsys.readouterr().err
    assert "GSIL" in err and "100%" in err
    assert run_cli(*argv, echo=True)[0] == 0                       # stderr is not a terminal under pytest: no bar
    assert capsys.readouterr().err == ""


# -- issue 13: each case reproduced (it failed before: traceback, hang, NaN or a silent wrong answer) -------------
@pytest.fixture(scope="module")
def odd_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("odd")
    (d / "binary.dat").write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00")
    (d / "true.json").write_text('{"ex_x": true}')
    return d


@pytest.mark.parametrize("argv, needle", [
    (["gsa", "--axis", "Y=0:1:inf"], "COUNT must be a whole number"),                     # was OverflowError
    (["gsa", "--axis", "Y=0:1:1e300"], "1e+300 points on axis Y"),                        # was ValueError
    (["gsa", "--axis", "Y=-1000:1000:1e9"], "8.45e+11 poses (Y 1000000000 x Z 5 x A 13 x B 13)"),   # hung
    (["gsa", "--axis", "X=0", "--compensate", "--rot-count", "-1"], "--rot-count"),       # was ValueError
    (["gsa", "--axis", "X=0", "--compensate", "--rot-count", "0"], "--rot-count"),        # printed NaN
    (["lsa", "--positions", "100000000"], "ask for it with --max-poses 100000000"),       # ran for minutes
    (["gsa", "--errors", "{d}/binary.dat"], "not a UTF-8 text file"),                     # UnicodeDecodeError
    (["gsa", "--le", "500"],                                                        # negative L, silently
     "--le: the effective cutting length 500 mm is longer than the tool length L0 = 200 mm"),
    (["gsa", "--top", "-3"], "--top"),                                                    # printed 38 rows
    (["gsa", "--errors", "{d}/true.json"], "value of ex_x must be a number (mm or rad), got true"),  # read as 1.0
    (["sobol", "--bound", "inf", "--samples", "32"], "--bound"),                          # Spearman nan
    (["gsa", "--l0", "1e308"], "--l0: the tool length must be a positive number of mm up to 100000"),
    (["gsa", "--axis", "A=5:1:3"], "inverted range 5:1 deg"),                             # was in radians
    (["sobol", "--seed", "-1", "--samples", "16"], "--seed"),                             # was ValueError
    (["gsa", "--axis", "A=40"], "axis A range [40, 40] deg leaves the stroke [-30, 30] deg"),
])
def test_issue13_sensitivity_inputs_are_one_line_errors(capsys, odd_files, argv, needle):
    argv = [a.replace("{d}", str(odd_files)) for a in argv]
    assert run_cli(*argv, echo=True)[0] == 2
    err = capsys.readouterr().err
    assert err.startswith("fiveaxis: error:") and needle in err and len(err.strip().splitlines()) == 1, err


def test_size_guard_says_how_large_and_how_to_ask(capsys):
    from fiveaxis.guards import check_size
    with pytest.raises(InputError, match=r"evaluate 12,000 things \(a x b\), more than the limit of 10,000; "
                                         r"ask for it with max_size=12000 if you mean it"):
        check_size(12000, "things", 10000, detail="a x b")
    assert check_size(10000, "things", 10000) == 10000
    for bad in (float("nan"), -1, True):
        with pytest.raises(InputError):
            check_size(bad, "things", 10)
    # asked for anyway: the same run goes ahead
    argv = ["gsa", "--axis", "X=0", "--axis", "Y=-1000:1000:3", "--axis", "Z=0", "--axis", "A=-30:30:4",
            "--axis", "B=0", "--json"]
    assert run_cli(*argv, "--max-poses", "11", echo=True)[0] == 2
    assert "evaluate 12 poses (Y 3 x A 4), more than the limit of 11; ask for it with --max-poses 12" in \
        capsys.readouterr().err
    assert run_cli(*argv, "--max-poses", "1.2e1", echo=True)[0] == 0
    capsys.readouterr()
    rc, _, err = run_cli(*argv, "--max-poses", "0")          # an argparse error: one line, exit 2
    assert rc == 2 and "--max-poses: expected a positive whole number" in err and err.count("\n") == 1


def test_progress_in_logs_for_long_runs(capsys):
    """A run of more than 4 chunks reports progress also when stderr is not a terminal (pytest's is not)."""
    argv = ["gsa", "--convention", "printed", "--axis", "X=-2500:2500:5", "--axis", "Y=-1000:1000:41",
            "--axis", "Z=-250:250:11", "--axis", "A=-30:30:49", "--axis", "B=-30:30:45", "--no-reduce", "--top", "1"]
    assert run_cli(*argv, echo=True)[0] == 0
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if "GSIL" in ln]
    assert lines and "100%" in lines[-1] and "\r" not in err
    assert run_cli(*argv, "--no-progress", echo=True)[0] == 0 and capsys.readouterr().err == ""


def test_json_has_no_nan_and_names_the_workspace(capsys):
    out = run_json(capsys, ["gsa", "--axis", "X=0", "--compensate", "--rot-count", "1"])
    assert out["settings"]["workspace"] == "[workspace] of li2018.toml; changed by --axis X=0"
    assert out["compensation"]["rot_count"] == 1
    assert all(isinstance(r["improvement_pct"], float) for r in out["compensation"]["posture_rad"])


# -- issue 11 item 5: the sensitivity plots ---------------------------------------------------------------------
def test_pie_slices_have_distinct_colours_and_others_is_grey(monkeypatch, tmp_path):
    from matplotlib.colors import to_hex

    from fiveaxis.plots import sensitivity as plots
    seen = {}
    real = plots._save

    def keep(fig, path):
        ax = fig.axes[0]
        seen["faces"] = [to_hex(w.get_facecolor()) for w in ax.patches]
        seen["legend"] = [t.get_text() for t in ax.get_legend().get_texts()]
        return real(fig, path)

    monkeypatch.setattr(plots, "_save", keep)
    p = [0.2, 0.15, 0.1, 0.08, 0.07, 0.06, 0.05, 0.05, 0.04, 0.04, 0.03, 0.03, 0.1]
    plots.pie([f"e{i}" for i in range(13)], p, tmp_path / "pie.png", "PG_i (%)")
    assert len(seen["faces"]) == 11 and len(set(seen["faces"])) == 11          # 10 named + others, all distinct
    assert seen["faces"][-1] == plots.OTHERS_COLOUR and seen["legend"][-1].startswith("others (3)")


def test_plots_are_world_readable_and_every_path_is_printed(capsys, tmp_path):
    import os
    old = os.umask(0o022)
    try:
        assert run_cli("gsa", "--convention", "printed", "--axis", "X=0", "--axis", "Z=0", "--compensate",
                     "--rot-count", "3", "--plot", str(tmp_path / "p"), "--top", "2", echo=True)[0] == 0
    finally:
        os.umask(old)
    err = capsys.readouterr().err
    files = sorted((tmp_path / "p").iterdir())
    assert len(files) == 7 and not any(f.name.startswith(".") for f in files)
    for f in files:
        assert (f.stat().st_mode & 0o777) == 0o644 and f"fiveaxis: wrote {f}" in err
    (tmp_path / "file").write_text("x")
    assert run_cli("gsa", "--axis", "X=0", "--plot", str(tmp_path / "file"), echo=True)[0] == 2
    assert "exists and is not a directory" in capsys.readouterr().err
