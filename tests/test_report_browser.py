"""The report in a real browser: headless Chromium (Debian packages chromium, chromium-driver) driven by
playwright-python with that executable (no browser download). On the bundled example and on an ac_trunnion
simulation (tool tip relative to the table, as an R-test measures it): the page loads with no console error and
no network request, every figure has a non-zero rendered size, the parameter table has one row per parameter; a
full-page screenshot of each is saved in tests/artifacts/ (not committed); the PDF prints.
"""
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import run_cli

from conftest import ROOT

ARTIFACTS = ROOT / "tests" / "artifacts"
FLAGS = ["--disable-gpu", "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--no-first-run"]


@pytest.fixture(scope="module")
def chromium():
    """/usr/bin/chromium, installed with apt-get when missing (as root), else the test is skipped."""
    exe = shutil.which("chromium")
    if exe is None and shutil.which("apt-get") and os.geteuid() == 0:
        env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
        subprocess.run(["apt-get", "update", "-qq"], env=env, capture_output=True)
        subprocess.run(["apt-get", "install", "-y", "-qq", "chromium", "chromium-driver"], env=env,
                       capture_output=True)
        exe = shutil.which("chromium")
    if exe is None:
        pytest.skip("chromium is not installed and apt-get is unavailable (not root or no Debian): no browser test")
    return exe


@pytest.fixture(scope="module")
def reports(tmp_path_factory, chromium):
    d = tmp_path_factory.mktemp("reports")
    sim = d / "ac_trunnion_rtest.csv"
    assert run_cli("simulate", "--machine", "ac_trunnion", "--instrument", "rtest", "--effect", "dx_C:C1=0.01",
                 "--n", "400", "--seed", "2", "--with-sigma", "-o", str(sim))[0] == 0
    out = {}
    for name, data, machine in (("example", ROOT / "examples" / "li2018_measurements.csv", "li2018"),
                                ("ac_trunnion", sim, "ac_trunnion")):
        page = d / f"{name}.html"
        assert run_cli("report", str(data), "--machine", machine, "-o", str(page), "--pdf")[0] == 0
        out[name] = page
    return out


def _n_parameters(page: Path) -> int:
    """The number of fitted parameters, read from the page's own record of the fit (the summary sentence)."""
    import re
    m = re.search(r"(\d+)(?:</data>)? parameters, of which the data determines", page.read_text(encoding="utf-8"))
    return int(m.group(1))


#: The tables of what the data determine and cannot separate: the browser shows every row the page holds.
TABLES = ("parameters", "quantities", "combinations", "groups", "setups")


def _rows_written(page: Path) -> dict:
    """Rows of each table's body as written in the page's HTML (read as text, not by a browser)."""
    import re
    text = page.read_text(encoding="utf-8")
    out = {}
    for t in TABLES:
        m = re.search(rf'<table[^>]*id="{t}".*?<tbody>(.*?)</tbody>', text, re.S)
        out[t] = m.group(1).count("<tr") if m else 0
    return out


@pytest.mark.slow
@pytest.mark.parametrize("name, n_params", [("example", 43), ("ac_trunnion", 51)])
def test_report_in_headless_chromium(reports, chromium, name, n_params):
    sync_api = pytest.importorskip("playwright.sync_api", reason="playwright-python is not installed")
    page_file = reports[name]
    assert _n_parameters(page_file) == n_params   # 41 errors + the effects found (+ 3 spheres x 3 offsets)
    errors, requests = [], []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("request", lambda r: requests.append(r.url))
            page.goto(page_file.as_uri(), wait_until="load")
            figures = page.eval_on_selector_all(
                "img", "els => els.map(e => ({w: e.naturalWidth, h: e.naturalHeight, done: e.complete, "
                       "rw: e.getBoundingClientRect().width, rh: e.getBoundingClientRect().height}))")
            rows = {t: page.locator(f"#{t} tbody tr").count() for t in TABLES}
            verdict = page.locator("#verdict .headline").inner_text()
            ARTIFACTS.mkdir(exist_ok=True)
            shot = ARTIFACTS / f"report-{name}.png"
            page.screenshot(path=str(shot), full_page=True)
        finally:
            browser.close()
    assert errors == []
    assert all(u.startswith(("file:", "data:")) for u in requests), [u for u in requests if "data:" not in u[:5]]
    assert len(figures) >= 4 and all(f["done"] and f["w"] > 0 and f["h"] > 0 and f["rw"] > 0 and f["rh"] > 0
                                     for f in figures), figures
    assert rows == _rows_written(page_file) and rows["parameters"] + rows["quantities"] > 0
    assert "explains the measurements" in verdict
    assert shot.stat().st_size > 50_000
    print(f"screenshot: {shot}")


@pytest.mark.slow
@pytest.mark.parametrize("name", ["example", "ac_trunnion"])
def test_report_pdf(reports, name):
    pdf = reports[name].with_suffix(".pdf")
    data = pdf.read_bytes()
    assert data.startswith(b"%PDF") and len(data) > 50_000
    import re
    assert len(re.findall(rb"/Type\s*/Page[^s]", data)) >= 4        # several A4 pages: the page's print style
    assert pdf.stat().st_mode & 0o044 == 0o044


@pytest.mark.slow
def test_record_of_the_trunnion_names_its_axes_by_iso(reports, capsys, tmp_path):
    sim = reports["ac_trunnion"].parent / "ac_trunnion_rtest.csv"
    assert run_cli("report", str(sim), "--machine", "ac_trunnion", "-o", str(tmp_path / "r.html"), "--json",
                 "--no-sensitivity", echo=True)[0] == 0
    rec = json.loads(capsys.readouterr().out)
    assert [f["id"] for f in rec["verdict"]["effects_found"]] == ["dx_C:C1"]
    assert rec["verdict"]["effects_found"][0]["iso"] == "E_XC:C1"
    assert {p["setup"] for p in rec["fit"]["setups"]} == {"sphere1", "sphere2", "sphere3"}
    p = {q["name"]: q["iso"] for q in rec["fit"]["parameters"]}
    assert p["SBOA"] == "E_B0A" and p["dXOC"] == "E_X0C" and p["ez_C"] == "E_CC"
