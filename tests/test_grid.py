"""Workspace grids and pose lists: flat C-order slices, fixed axes, huge sizes without memory, bad ranges."""
import math

import numpy as np
import pytest

from fiveaxis.exceptions import InputError
from fiveaxis.sensitivity.grid import Grid, GridAxis, PoseList, grid_from_specs, parse_axis_spec
from fiveaxis.model.machine import load_machine


def small_grid():
    return Grid((GridAxis("X", -10, 10, 3), GridAxis("Y", 0, 0, 1), GridAxis("Z", 1, 2, 2),
                 GridAxis("A", -0.5, 0.5, 5), GridAxis("B", 0, 1, 4)))


def test_poses_are_the_full_product_in_c_order_and_slices_agree():
    g = small_grid()
    axes = [a.values() for a in g.axes]
    full = np.stack([m.ravel() for m in np.meshgrid(*axes, indexing="ij")], axis=1)
    assert g.size == len(full) == 3 * 1 * 2 * 5 * 4
    np.testing.assert_array_equal(g.poses(0, g.size), full)
    np.testing.assert_array_equal(g.poses(7, 33), full[7:33])
    assert g.poses(5, 5).shape == (0, 5)
    np.testing.assert_array_equal(g.poses(g.size - 3, g.size + 10), full[-3:])   # clipped at the end


def test_huge_grid_is_not_built():
    g = Grid(tuple(GridAxis(n, -1.0, 1.0, 2001) for n in "XYZ") + (GridAxis("A", 0, 1, 2),))
    assert g.size == 2 * 2001 ** 3 and isinstance(g.size, int) and g.size > 2 ** 31
    last = g.poses(g.size - 1, g.size)
    np.testing.assert_array_equal(last, [[1, 1, 1, 1]])
    mid = g.poses(g.size // 2, g.size // 2 + 1)
    assert mid.shape == (1, 4)


def test_fixed_axis_and_describe():
    a = GridAxis("A", 0.3, 0.3, 1)
    np.testing.assert_array_equal(a.values(), [0.3])
    g = Grid((GridAxis("X", -5, 5, 3), GridAxis("A", -math.pi / 6, math.pi / 6, 3)))
    assert g.describe(rotary=("A",)) == {"X": [-5.0, 5.0, 3], "A": [-30.0, 30.0, 3]}


@pytest.mark.parametrize("lo,hi,count,word", [(1, 1, 5, "empty"), (2, -2, 5, "inverted"), (0, 1, 0, "count"),
                                              (0, 1, -3, "count"), (0, float("nan"), 3, "finite")])
def test_bad_axis_is_one_line_input_error(lo, hi, count, word):
    with pytest.raises(InputError, match=word) as exc:
        GridAxis("X", lo, hi, count)
    assert "\n" not in str(exc.value)


def test_specs_degrees_for_rotary_axes_and_unknown_axis():
    ax = parse_axis_spec("A=-30:30:7", rotary=("A", "B"))
    assert ax.count == 7 and ax.lo == pytest.approx(-math.pi / 6) and ax.hi == pytest.approx(math.pi / 6)
    assert parse_axis_spec("X=12.5").count == 1 and parse_axis_spec("X=12.5").lo == 12.5
    base = small_grid()
    g = grid_from_specs(base, ["X=-1:1:11", "B=10"], rotary=("A", "B"))
    assert g.axis("X").count == 11 and g.axis("B").lo == pytest.approx(math.radians(10))
    assert g.axis("Z") == base.axis("Z")
    for bad, msg in [("Q=0:1:3", "unknown axis 'Q'"), ("X=1:2", "NAME=LO:HI:COUNT"), ("X=a:b:3", "NAME=LO"),
                     ("X=0:1:2.5", "COUNT an integer"), ("X=0:1:0", "count must be at least 1"), ("X", "expected")]:
        with pytest.raises(InputError, match=msg):
            grid_from_specs(base, [bad])


def test_from_strokes_uses_the_machine_file():
    m = load_machine("li2018")
    g = Grid.from_strokes(m, {"X": 3, "A": 5}, fixed={"B": 15})
    assert g.names == m.variables
    assert (g.axis("X").lo, g.axis("X").hi) == (-2500, 2500)
    assert g.axis("A").hi == pytest.approx(math.radians(30))
    assert g.axis("B").count == 1 and g.axis("B").lo == pytest.approx(math.radians(15))
    assert g.axis("Y").count == 1 and g.axis("Y").lo == 0       # not asked for: the middle of the stroke
    with pytest.raises(InputError, match="unknown axis W"):
        Grid.from_strokes(m, {"W": 3})


def test_pose_list():
    pl = PoseList([[0, 0, 0, 0, 0], [1, 2, 3, 0.1, 0.2]], normals=[[0, 0, 2], [3, 0, 4]], labels=("a", "b"))
    assert pl.size == 2
    np.testing.assert_array_equal(pl.poses(1, 5), [[1, 2, 3, 0.1, 0.2]])
    np.testing.assert_allclose(pl.normals, [[0, 0, 1], [0.6, 0, 0.8]])
    with pytest.raises(InputError, match="non-zero"):
        PoseList([[0, 0, 0, 0, 0]], normals=[[0, 0, 0]])
    with pytest.raises(InputError, match="normals"):
        PoseList([[0, 0, 0, 0, 0]], normals=[[0, 0, 1], [0, 0, 1]])


def test_random_slices_match_unravel_index():
    shape = (7, 1, 5, 3, 11)
    g = Grid(tuple(GridAxis(n, 0.0, 0.0, 1) if c == 1 else GridAxis(n, -1.0, 2.0, c) for n, c in zip("XYZAB", shape)))
    rng = np.random.default_rng(0)
    for _ in range(50):
        start = int(rng.integers(0, g.size))
        stop = start + int(rng.integers(1, 200))
        stop = min(stop, g.size)
        idx = np.unravel_index(np.arange(start, stop), shape)
        ref = np.stack([a.values()[i] for a, i in zip(g.axes, idx)], axis=1)
        np.testing.assert_array_equal(g.poses(start, stop), ref)
