"""The Python example of the README runs exactly as written."""
import re

import numpy as np

from conftest import ROOT


def test_readme_python_example_runs():
    text = (ROOT / "README.md").read_text()
    section = text.split("<!-- section: derive (issue 2) -->")[1].split("<!-- end section: derive -->")[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert blocks, "the README shows the Python API"
    scope = {}
    exec(compile(blocks[0], "README.md", "exec"), scope)
    J, P = scope["J"], scope["P"]
    assert J.shape == (2, 41, 3) and P.shape == (2, 3)
    # Syz and ex_x at 1e-4 rad: the tip moves by about 1e-4 x lever arm (hundreds of mm) -> tens of um
    assert 1e-3 < np.abs(P).max() < 0.1


def test_docs_python_examples_run():
    """Every Python block of the docs runs as written (a renamed module fails here, not in a reader's hands), and
    the ISO names example gives what its comments say."""
    ran = 0
    for doc in sorted((ROOT / "docs").glob("*.md")):
        for k, block in enumerate(re.findall(r"```python\n(.*?)```", doc.read_text(), re.S)):
            scope = {}
            exec(compile(block, f"{doc.name} block {k + 1}", "exec"), scope)
            ran += 1
            if doc.name == "iso230.md":
                iso, m = scope["iso"], scope["m"]
                assert (iso.table(m)["SAOB"].iso, iso.name(m, "ex_x:x1"), iso.label(m, "ex_x"),
                        iso.canonical(m, "E_C0B"), iso.canonical_effect(m, "E_AX:x1")) == \
                    ("E_C0B", "E_AX:x1", "ex_x (E_AX)", "SAOB", "ex_x:x1")
    assert ran >= 1


def test_docs_name_files_that_exist():
    """Every path to a Python file the docs name (`src/fiveaxis/report/dcc.py`, `report/dcc.py`, `tests/...`) exists:
    a module renamed or moved fails here, not in a reader's hands. Bare names (`grid.py`), templates (`.py.j2`) and
    patterns (`effects/<family>.py`) are left out."""
    missing = []
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for m in re.finditer(r"`([^`\s]*/[^`\s]*\.py)`", doc.read_text()):
            path = m.group(1)
            if re.search(r"[<>{}\[\]*]", path):            # a pattern (effects/<family>.py), not a file
                continue
            if not any((base / path).is_file() for base in (ROOT, ROOT / "src" / "fiveaxis", ROOT / "src")):
                missing.append(f"{doc.name}: {path}")
    assert missing == []
