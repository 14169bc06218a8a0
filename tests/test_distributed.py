"""GSIL on Dask: a local cluster of worker processes gives the single-process result; grid reduction is exact."""
import numpy as np
import pytest

import fiveaxis
from fiveaxis import parallel
from fiveaxis.sensitivity import distributed
from fiveaxis.exceptions import InputError
from fiveaxis.sensitivity.grid import Grid, GridAxis, PoseList
from fiveaxis.sensitivity.indices import gsil, reduce_grid


@pytest.fixture(scope="module")
def model():
    m = fiveaxis.load("li2018")
    distributed.warm(m)          # compile once here, before worker processes load the cache
    return m


def _grid(nx=3):
    return Grid((GridAxis("X", -2500, 2500, nx), GridAxis("Y", -1000, 1000, 7), GridAxis("Z", -250, 250, 4),
                 GridAxis("A", -0.5, 0.5, 9), GridAxis("B", -0.5, 0.5, 11)))


def _kernel_mean(model, grid):
    W = np.zeros(41)
    model.kernels.gsil_sum(grid.poses(0, grid.size), 170.0, 200.0, np.full(41, 1e-4), 1e-12, W)
    return W / grid.size


def test_reduce_grid_drops_axes_absent_from_J_exactly(model):
    grid = _grid(nx=5)
    small, factor = reduce_grid(model, grid)
    assert factor == 5 and small.axis("X").count == 1 and small.size * 5 == grid.size
    assert "X" not in model.kernels.JK_VARIABLES
    np.testing.assert_allclose(_kernel_mean(model, small), _kernel_mean(model, grid), rtol=1e-12)
    poses = PoseList(grid.poses(0, 10))          # an explicit list has no axes to reduce
    assert reduce_grid(model, poses) == (poses, 1)


@pytest.mark.scale
def test_local_cluster_equals_single_process(model):
    grid = _grid()
    single = gsil(model, grid, order="exact", check=False, progress=False)
    cluster, client = parallel.local_cluster(workers=2, threads_per_worker=1)
    try:
        res = distributed.gsil(model, grid, client, chunk=500, reduce=False, progress=False)
        assert res.settings["dask"]["tasks"] == -(-grid.size // 500) and res.settings["dask"]["workers"] == 2
        np.testing.assert_allclose(res.values, single.values, rtol=1e-12)
        par = distributed.gsil(model, grid, client, chunk=1000, worker_kernel="parallel", progress=False)
        assert par.settings["reduced_factor"] == 3 and par.settings["evaluated_poses"] == grid.size // 3
        np.testing.assert_allclose(par.values, single.values, rtol=1e-12)
        assert res.ranking == single.ranking
    finally:
        client.close()
        cluster.close()


def test_bad_options_are_one_line_errors(model):
    """The library names its arguments (chunk, worker_kernel); the command line names its options."""
    from fiveaxis.cli import to_command_line
    with pytest.raises(InputError, match="^chunk: expected") as exc:
        distributed.gsil(model, _grid(), client=None, chunk=0)
    assert to_command_line(str(exc.value), exc.value.key).startswith("--chunk: expected")
    with pytest.raises(InputError, match="^worker_kernel: expected") as exc:
        distributed.gsil(model, _grid(), client=None, worker_kernel="threads")
    assert to_command_line(str(exc.value), exc.value.key).startswith("--worker-kernel: expected")


@pytest.mark.scale
def test_cli_on_local_workers_matches_gsa(model, capsys):
    """`fiveaxis dask` (2 local worker processes) prints the same indices as `fiveaxis gsa --order exact`."""
    import json

    from conftest import run_cli
    axes = ["--axis", "X=-2500:2500:3", "--axis", "Y=-1000:1000:5", "--axis", "A=-30:30:5", "--axis", "B=-30:30:5"]
    assert run_cli("gsa", *axes, "--order", "exact", "--json", echo=True)[0] == 0
    ref = json.loads(capsys.readouterr().out)
    assert run_cli("dask", *axes, "--workers", "2", "--chunk", "100", "--json", "--no-progress", echo=True)[0] == 0
    got = json.loads(capsys.readouterr().out)
    assert got["ranking"] == ref["ranking"]
    for name, value in ref["indices"].items():
        assert got["indices"][name] == pytest.approx(value, rel=1e-12)
    assert got["settings"]["reduced_factor"] == 3 and got["settings"]["poses"] == ref["settings"]["poses"]
    assert run_cli("dask", "--chunk", "0", echo=True)[0] == 2
    assert "--chunk" in capsys.readouterr().err
