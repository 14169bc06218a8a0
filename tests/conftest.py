"""Shared fixtures: the shipped machines and random poses within their strokes."""
from pathlib import Path

import numpy as np
import pytest

from fiveaxis.machine import MACHINES_DIR, load_machine

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"
SHIPPED = sorted(p.stem for p in MACHINES_DIR.glob("*.toml"))


def poses_and_lengths(machine, n, seed=0):
    """n random poses in the strokes (mm, rad) and tool lengths within +-50% of L0 (mm)."""
    rng = np.random.default_rng(seed)
    L0 = machine.tool_length or 100.0
    return machine.random_poses(n, rng), rng.uniform(0.5 * L0, 1.5 * L0, n)


@pytest.fixture(scope="session")
def li2018():
    return load_machine("li2018")


def pytest_addoption(parser):
    parser.addoption("--linuxcnc", action="store_true",
                     help="run the tests against the real LinuxCNC (make test-linuxcnc)")


def pytest_configure(config):
    config.addinivalue_line("markers", "linuxcnc: runs the real LinuxCNC (only with --linuxcnc: make test-linuxcnc)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--linuxcnc"):
        return
    skip = pytest.mark.skip(reason="runs the real LinuxCNC: make test-linuxcnc")
    for item in items:
        if "linuxcnc" in item.keywords:
            item.add_marker(skip)
