"""Location errors (PIGEs) of tilting_head as ISO 230-7 defines them: all identifiable from tip and axis data,
and their aliases with the constant parts of the PDGEs exactly as docs/derivation.md lists them."""
import numpy as np
import pytest

import fiveaxis
from fiveaxis.model.machine import MACHINES_DIR, load_machine


def columns(model, n=300, seed=0):
    """Design columns (one per error): J at L0/2 and 3 L0/2 and K, stacked over n random poses (mm, rad)."""
    machine = model.machine
    poses = machine.random_poses(n, np.random.default_rng(seed))
    blocks = []
    for L in (0.5 * machine.tool_length, 1.5 * machine.tool_length):
        J, K = model.jk(poses, L)
        blocks += [J, K]
    D = np.concatenate(blocks, axis=2)                       # (n, ne, 12)
    return {name: D[:, i].ravel() for i, name in enumerate(model.errors)}


def rank(cols):
    """Numerical rank of columns, each scaled to unit norm (columns that are zero, such as ez_B, are dropped)."""
    A = np.stack(cols, axis=1)
    norms = np.linalg.norm(A, axis=0)
    s = np.linalg.svd(A[:, norms > 0] / norms[norms > 0], compute_uv=False)
    return int((s > 1e-6 * s[0]).sum())


@pytest.fixture(scope="module")
def tilting_head():
    return fiveaxis.load("tilting_head")


def test_every_location_error_of_tilting_head_is_identifiable(tilting_head):
    cols = columns(tilting_head)
    pige = tilting_head.machine.pige_names
    assert len(pige) == 13
    assert rank([cols[n] for n in pige]) == 13


@pytest.mark.slow
def test_the_old_tool_minus_workpiece_translations_were_not(tmp_path, monkeypatch):
    """The former file (plain translations tx, tz of B and tx, ty of C, no spindle errors) has rank 10 of 11:
    the same check fails on it, so the test above can fail."""
    text = (MACHINES_DIR / "tilting_head.toml").read_text()
    old = (text.replace('pige = { dXOS = "tx", SAOS = "rx" }\n', "")
           .replace('dXOB = "lx", dZOB = "lz"', 'dXOB = "tx", dZOB = "tz"')
           .replace('dXOC = "lx", dYOC = "ly"', 'dXOC = "tx", dYOC = "ty"'))
    path = tmp_path / "tilting_head_old.toml"
    path.write_text(old)
    monkeypatch.setenv("FIVEAXIS_CACHE", str(tmp_path / "cache"))
    model = fiveaxis.load(path)
    cols = columns(model)
    assert len(model.machine.pige_names) == 11
    assert rank([cols[n] for n in model.machine.pige_names]) == 10
    assert np.abs(cols["dXOB"] + cols["dXOC"]).max() < 1e-9 * np.abs(cols["dXOB"]).max()


def test_dXOB_and_dXOC_no_longer_cancel(tilting_head):
    cols = columns(tilting_head)
    assert np.linalg.norm(cols["dXOB"] + cols["dXOC"]) > 0.5 * np.linalg.norm(cols["dXOB"])
    # nor in the exact chain: the same shift of the B line and of the C line give different tip errors
    m = tilting_head
    poses = m.machine.random_poses(200, np.random.default_rng(3))
    Pb = m.position_error(poses, {"dXOB": 0.01}, exact=True)
    Pc = m.position_error(poses, {"dXOC": 0.01}, exact=True)
    assert np.abs(Pb + Pc).max() > 5e-3
    # a line shift does nothing where the axis is at zero
    zero = poses.copy()
    zero[:, m.variables.index("B")] = 0.0
    zero[:, m.variables.index("C")] = 0.0
    for name in ("dXOB", "dZOB", "dXOC", "dYOC"):
        assert np.abs(m.position_error(zero, {name: 0.01}, exact=True)).max() < 1e-13, name


#: docs/derivation.md, "Location errors": each location error of tilting_head as the constant parts of PDGEs
#: it cannot be told from (exact column identities on every pose and tool length).
ALIASES = {
    "Sxy": {"ez_x": 1}, "Sxz": {"ey_x": 1}, "Syz": {"ex_y": 1},
    "dXOB": {"dx_x": 1, "dx_B": -1}, "dZOB": {"dz_x": 1, "dz_B": -1}, "SAOB": {"ex_z": 1}, "SCOB": {"ez_y": 1},
    "dXOS": {"dx_B": 1}, "SAOS": {"ex_B": 1},
    "dXOC": {"dx_x": -1, "dx_C": -1}, "dYOC": {"dy_x": -1, "dy_C": -1}, "SAOC": {"ex_x": -1},
}


def test_aliases_with_pdge_constants_are_as_documented(tilting_head):
    cols = columns(tilting_head)
    scale = max(np.abs(c).max() for c in cols.values())
    for name, combo in ALIASES.items():
        assert np.abs(cols[name] - sum(k * cols[p] for p, k in combo.items())).max() < 1e-12 * scale, name
    # SBOC alone is not a constant PDGE: the one direction of the 13 beyond the PDGE constants
    pdge = [cols[n] for n in tilting_head.machine.pdge_names]
    pige = [cols[n] for n in tilting_head.machine.pige_names]
    assert rank(pdge + pige) - rank(pdge) == 1
    assert rank(pdge + [cols["SBOC"]]) == rank(pdge) + 1


def report(name: str) -> str:
    """The numbers of docs/derivation.md: rank of the location errors' columns, their smallest singular value
    (unit-norm columns), and how many of their directions lie beyond the constant parts of the PDGEs."""
    model = fiveaxis.load(name)
    cols = columns(model, n=500)
    pige = [cols[n] for n in model.machine.pige_names]
    pdge = [cols[n] for n in model.machine.pdge_names]
    A = np.stack(pige, axis=1)
    s = np.linalg.svd(A / np.linalg.norm(A, axis=0), compute_uv=False)
    return (f"{name}: {len(pige)} location errors, rank {rank(pige)}, smallest singular value {s[-1]:.3g} "
            f"(largest {s[0]:.3g}); PDGE constants rank {rank(pdge)}, with the location errors "
            f"{rank(pdge + pige)}")


def test_every_location_error_is_described_in_words():
    """diagnose describes candidate effects of every parameter: chain-end and axis-line errors too."""
    from fiveaxis.effects.families import describe_param
    m = load_machine("tilting_head")
    words = {n: describe_param(m, n) for n in m.pige_names}
    assert words["dXOS"] == "the offset dXOS of the spindle (along x)"
    assert words["SAOS"] == "the orientation (squareness) error SAOS of the spindle (rotation about x)"
    assert words["dXOB"] == "the position dXOB of the axis line of B (along x)"
    assert words["SBOC"] == "the orientation (squareness) error SBOC before axis C (rotation about y)"


if __name__ == "__main__":      # .venv/bin/python tests/test_location_errors.py tilting_head ac_trunnion li2018
    import sys
    for arg in sys.argv[1:] or ["tilting_head"]:
        print(report(arg))
