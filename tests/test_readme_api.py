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
