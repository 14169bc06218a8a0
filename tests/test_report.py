"""`fiveaxis report`: the record against the example's known truth, the page self-contained, the compensation
section, the command line's file handling. The browser and PDF checks are in test_report_browser.py."""
import json
import re
from html.parser import HTMLParser

import pytest

from conftest import run_cli
from fiveaxis.exceptions import InputError
from fiveaxis.report import compensation as C
from fiveaxis.report import html, record
from fiveaxis.estimation import result as R

from conftest import ROOT

EXAMPLE = ROOT / "examples" / "li2018_measurements.csv"


@pytest.fixture(scope="module")
def example():
    return record.build(EXAMPLE)


class _Tables(HTMLParser):
    """Rows of every table by id, img sources, scripts and external references of a page."""

    def __init__(self):
        super().__init__()
        self.rows, self.imgs, self.scripts, self.refs = {}, [], 0, []
        self._table = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self._table.append(a.get("id"))
            self.rows.setdefault(a.get("id"), 0)
        elif tag == "tr" and self._table and self._in_body:
            self.rows[self._table[-1]] += 1
        elif tag == "tbody":
            self._in_body = True
        elif tag == "img":
            self.imgs.append(a.get("src", ""))
        elif tag == "script":
            self.scripts += 1
        for k in ("src", "href"):
            if k in a and not a[k].startswith(("data:", "#")):
                self.refs.append(a[k])

    _in_body = False

    def handle_endtag(self, tag):
        if tag == "tbody":
            self._in_body = False
        elif tag == "table":
            self._table.pop()


def test_example_record_finds_the_hidden_effects(example):
    """examples/README.md: the example hides ex_x:x1 (2e-5 rad at the end of X's 2500 mm) and L:t1, 1 um noise."""
    rec = example.record
    v = rec["verdict"]
    # L:t1 (the tool growing) and dz_A:t1 (A's axial drift) are the same column (a translation along the tool axis):
    # either is the hidden effect, the other is listed as its alias
    tops = [r["candidates"][0] for r in rec["rounds"] if r["missing_effect"]]
    found = [{t["id"], *t["aliases"]} for t in tops]
    assert v["explained"] and len(v["effects_found"]) == 2 and len(found) == 2
    assert "ex_x:x1" in found[0] and "L:t1" in found[1]
    assert {f["id"] for f in v["effects_found"]} == {t["id"] for t in tops}
    assert "E_AX:x1" in {f["iso"] for f in v["effects_found"]}
    assert v["noise_source"] == "sigma column" and v["ratio"] == pytest.approx(1.0, abs=0.05)
    rms = [r["rms_um"] for r in rec["rounds"]]
    assert rms == sorted(rms, reverse=True) and rms[0] > 3 * rms[-1]
    assert [r["missing_effect"] for r in rec["rounds"]] == [True, True, False]
    p = {q["name"]: q for q in rec["fit"]["parameters"]}
    assert len(rec["fit"]["parameters"]) == rec["fit"]["n_parameters"] == 43
    coef = p["ex_x:x1"]
    assert coef["unit"] == "urad/mm" and coef["iso"] == "E_AX:x1"
    assert abs(coef["value"] - 2e-5 / 2500 * 1e6) < 2 * coef["u_k2"]          # truth within U (k = 2)
    assert p["ex_x"]["iso"] == "E_AX" and p["ex_x"]["unit"] == "urad" and p["ex_x"]["determined"]
    assert p["SAOB"]["iso"] == "E_C0B" and not p["SAOB"]["determined"] and p["SAOB"]["value"] is None


def test_expanded_uncertainty_is_twice_the_fit_standard_uncertainty(example):
    from fiveaxis.estimation import fit as F
    from fiveaxis.model.error_model import load
    from fiveaxis.measurement.files import read
    model = load("li2018")
    res = F.fit(model, read(EXAMPLE, model.machine), ["ex_x:x1", "L:t1"])
    j = R.to_json(res)["parameters"]
    p = {q["name"]: q for q in example.record["fit"]["parameters"]}
    assert p["ex_x"]["value"] == pytest.approx(j["ex_x"]["value"] * 1e6, rel=1e-6)
    assert p["ex_x"]["u_k2"] == pytest.approx(2 * j["ex_x"]["std"] * 1e6, rel=1e-6)
    assert p["dz_A"]["u_k2"] == pytest.approx(2 * j["dz_A"]["std"] * 1e3, rel=1e-6)     # mm -> um


def test_groups_say_why_and_what_would_separate_them(example):
    groups = {frozenset(g["members"]): g for g in example.record["fit"]["groups"]}
    assert "group 7 of Table 2" in groups[frozenset({"ex_y", "Syz"})]["why"]
    assert "no effect on the tool tip" in groups[frozenset({"ez_A"})]["why"]
    # ex_B + ex_A + 0.005*dy_A: dy_A enters with the tool length (J = a + L k), so another length separates it
    tips = groups[frozenset({"ex_B", "ex_A", "dy_A"})]["separate_by"]
    assert tips and tips[0]["measure"].startswith("another tool length") and "dy_A" in tips[0]["determines"]


def test_page_is_self_contained_with_one_row_per_parameter(example):
    """Issue 21.9: the page leads with what the data determine (one row per determined parameter, one per physical
    quantity), the parameters not determined alone are in the table of what the data cannot separate, each once."""
    page = html.render(example)
    t = _Tables()
    t.feed(page)
    assert t.scripts == 0 and t.refs == [], t.refs
    assert not re.search(r"https?://", page)
    assert len(t.imgs) == len(example.figures) == 4 and all(s.startswith("data:image/png;base64,") for s in t.imgs)
    fit = example.record["fit"]
    determined = [p for p in fit["parameters"] if p["determined"]]
    assert t.rows["parameters"] == len(determined) and 0 < len(determined) < fit["n_parameters"]
    assert t.rows["quantities"] == len(fit["quantities"]) > 0
    grouped = [n for g in fit["groups"] for n in g["members"]]
    assert len(grouped) == len(set(grouped))
    assert sorted(grouped) == sorted(p["name"] for p in fit["parameters"] if not p["determined"])
    assert t.rows["gsil"] == 10 and "E_C(0X)Y" in page and "&mu;" not in page and "\u00b5m" in page
    for section in ("verdict", "terms", "data", "fit", "residuals", "rounds", "sensitivity", "compensation"):
        assert f'id="{section}"' in page
    assert "No compensation was evaluated" in page


def _png(path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(2, 1.5))
    ax.plot([0, 1], [0, 1])
    fig.savefig(path)
    plt.close(fig)


def test_compensation_folder(tmp_path, example):
    """The report reads the folder `fiveaxis compensate` writes: the predicted tip error per stage, the map, the
    files for the controller; a summary for another machine or a damaged number is a one-line error."""
    from conftest import run_cli
    d = tmp_path
    assert run_cli("simulate", "--n", "300", "--seed", "2", "--effect", "ex_x:x1", "-o", str(d / "m.csv"))[0] == 0
    assert run_cli("fit", str(d / "m.csv"), "--add", "ex_x:x1", "-o", str(d / "model.json"))[0] == 0
    assert run_cli("compensate", str(d / "model.json"), "-o", str(d / "comp"), "--poses", "300", "--plot")[0] == 0
    summary = json.loads((d / "comp" / "summary.json").read_text())
    comp = C.read(d / "comp", "li2018")
    assert [st["key"] for st in comp["stages"]][0] == "before"
    by = {st["key"]: st for st in comp["stages"]}
    assert by["after_table"]["rms"] == summary["predicted_tip_error_mm"]["after_table"]["rms"]
    assert by["after_table"]["rms"] < by["before"]["rms"]
    assert comp["maps"][0]["png"].startswith(C.PNG_MAGIC) and any(f.endswith(".comp") for f in comp["files"])
    rep = record.Report(dict(example.record, compensation={k: v for k, v in comp.items() if k != "maps"}
                             | {"maps": [{"file": m["file"], "caption": m["caption"]} for m in comp["maps"]]}),
                        dict(example.figures, compensation_0=comp["maps"][0]["png"]))
    page = html.render(rep)
    assert 'id="compensation-summary"' in page and "after the volumetric table" in page and ".comp" in page
    bad = json.loads(json.dumps(summary))
    bad["predicted_tip_error_mm"]["after_table"]["rms"] = -1
    (d / "comp" / "summary.json").write_text(json.dumps(bad))
    with pytest.raises(InputError, match=r"summary.json: after_table.rms: expected a length >= 0 in mm"):
        C.read(d / "comp", "li2018")
    with pytest.raises(InputError, match="the compensation is for 'li2018'"):
        C.read(d / "comp", "ac_trunnion")


def test_compensation_by_tool_length(tmp_path, example):
    """A table over tool lengths (`compensate --tool-lengths`): the report shows the predicted error at each length,
    the numbers of summary.json's predicted_by_tool_length; a damaged length is a one-line error."""
    from conftest import run_cli
    d = tmp_path
    assert run_cli("simulate", "--n", "300", "--seed", "2", "--effect", "ex_x:x1", "-o", str(d / "m.csv"))[0] == 0
    assert run_cli("fit", str(d / "m.csv"), "--add", "ex_x:x1", "-o", str(d / "model.json"))[0] == 0
    nodes = [a for v in ("X=2", "Y=2", "Z=2", "A=3", "B=3") for a in ("--nodes", v)]
    assert run_cli("compensate", str(d / "model.json"), "-o", str(d / "comp"), "--poses", "400",
                 "--tool-lengths", "150,250", *nodes)[0] == 0
    summary = json.loads((d / "comp" / "summary.json").read_text())
    comp = C.read(d / "comp", "li2018")
    by = comp["by_tool_length"]
    assert [r["tool_length_mm"] for r in by] == [e["tool_length_mm"] for e in summary["predicted_by_tool_length"]]
    assert [r["tool_length_mm"] for r in by] == [150.0, 200.0, 250.0] and [r["table_node"] for r in by] == \
        [True, False, True]
    for r, e in zip(by, summary["predicted_by_tool_length"]):
        assert r["after_table"]["rms"] == e["tip_error_mm"]["after_table"]["rms"] < r["before"]["rms"]
    rep = record.Report(dict(example.record, compensation=comp), dict(example.figures))
    page = html.render(rep)
    assert 'id="compensation-by-tool-length"' in page and "200 (between)" in re.sub(r"<[^>]+>", "", page)
    bad = json.loads(json.dumps(summary))
    bad["predicted_by_tool_length"][1]["tool_length_mm"] = -5
    (d / "comp" / "summary.json").write_text(json.dumps(bad))
    with pytest.raises(InputError, match=r"predicted_by_tool_length\[1\]\.tool_length_mm: expected a tool length"):
        C.read(d / "comp", "li2018")


def test_people_units():
    assert record.people(2e-6, "mm") == pytest.approx((2e-3, "um"))
    v, u = record.people(8e-9, "rad/mm")
    assert u == "urad/mm" and v == pytest.approx(8e-3)
    assert record.people(None, "rad") == (None, "urad") and record.people(3.0, "") == (3.0, "")


def run(capsys, *argv):
    try:
        rc = run_cli(*argv, echo=True)[0]
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    return rc, out, err


def test_cli_writes_once_and_refuses_to_overwrite(capsys, tmp_path):
    small = tmp_path / "small.csv"
    assert run_cli("simulate", "--effect", "E_AX:x1=2e-5", "--n", "200", "--seed", "5", "--with-sigma",
                 "-o", str(small))[0] == 0
    out = tmp_path / "r.html"
    rc, stdout, err = run(capsys, "report", small, "-o", out, "--rounds", "2", "--no-sensitivity", "--json")
    assert rc == 0 and f"wrote {out}" in err and out.stat().st_mode & 0o044 == 0o044
    rec = json.loads(stdout)
    assert rec["sensitivity"] is None and len(rec["rounds"]) <= 2
    before = out.read_bytes()
    rc, _, err = run(capsys, "report", small, "-o", out)
    assert rc == 2 and err.count("\n") == 1 and "--force" in err and out.read_bytes() == before
    rc, _, err = run(capsys, "report", small, "-o", tmp_path / "r.txt")
    assert rc == 2 and "expected an .html file" in err
    rc, _, err = run(capsys, "report", small, "-o", tmp_path / "q.html", "--add", "E_QX:x1")
    assert rc == 2 and err.count("\n") == 1 and "unknown parameter 'E_QX'" in err
    rc, _, err = run(capsys, "report", small, "-o", tmp_path / "q.html", "--compensation", tmp_path / "nope")
    assert rc == 2 and "compensation folder not found" in err and not (tmp_path / "q.html").exists()


@pytest.mark.slow
def test_calibration_loop_is_written_once(capsys, example):
    """`diagnose --rounds` (the loop make run shows) and the report run the same loop: the same rounds, the same
    residuals, the same effects added, each round adding the previous round's best candidate."""
    rc, out, err = run(capsys, "diagnose", EXAMPLE, "--rounds", "4", "--top", "5", "--json")
    assert rc == 0, err
    js = json.loads(out)["rounds"]
    rounds = example.record["rounds"]
    assert [j["added"] for j in js] == [r["added"] for r in rounds]
    assert [j["rms_mm"] * 1e3 for j in js] == pytest.approx([r["rms_um"] for r in rounds], rel=1e-9)
    for a, b in zip(js, js[1:]):
        assert a["verdict"] == "missing effect" and b["added"] == a["added"] + [a["candidates"][0]["id"]]
    assert js[-1]["verdict"] != "missing effect"
    rc, text, _ = run(capsys, "diagnose", EXAMPLE, "--rounds", "4", "--top", "2")
    trail = " -> ".join(f"{j['rms_mm_without_outliers'] * 1000:.4g} um" for j in js)
    assert rc == 0 and text.count("[[Diagnosis]]") == len(js) and f"residual RMS {trail} against noise" in text
    assert f"effects found: {', '.join(js[-1]['added'])}; verdict: {js[-1]['verdict']}" in text
    rc, _, err = run(capsys, "diagnose", EXAMPLE, "--rounds", "0")
    assert rc == 2 and err.count("\n") == 1 and "--rounds" in err
