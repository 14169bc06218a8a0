"""The predicted tool-tip error map of `fiveaxis compensate --plot`: before, after LinuxCNC, after the table.

Over the two rotary axes (a grid over their strokes); at each cell the RMS of the tip error over the nine linear-axis
positions of the corners and the centre of the linear strokes. Micrometres, one colour scale for all panels.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..compensation.chain import actual_tool
from ..compensation.correction import fitted_errors
from ..compensation.table import compensated_commands
from ..linuxcnc.configuration import linuxcnc_commands
from .sensitivity import _pyplot, _save


def figure(comp, path) -> Path:
    """The error map of a compensation (`fiveaxis.compensation.pipeline.Compensation`) as a PNG at path."""
    return error_map(comp.model, fitted_errors(comp.fm, comp.model), comp.table, comp.lc, path)


def error_map(model, errors_fn, table, lc, path, cells: int = 41) -> Path:
    """PNG of the predicted tip error (um) over the rotary axes: before / after LinuxCNC / after the table."""
    machine = model.machine
    variables = list(model.variables)
    rot = [v for v in variables if machine.axis(v).type == "rotary"][:2]
    lin = [v for v in variables if v not in rot]
    grids = [np.linspace(*machine.axis(v).model_stroke, cells) for v in rot]
    G1, G2 = np.meshgrid(*grids, indexing="ij")
    corners = []
    for k in range(2 ** len(lin)):
        corners.append([machine.axis(v).model_stroke[(k >> i) & 1] for i, v in enumerate(lin)])
    corners.append([0.5 * sum(machine.axis(v).model_stroke) for v in lin])
    q = np.zeros((G1.size * len(corners), len(variables)))
    for i, v in enumerate(lin):
        q[:, variables.index(v)] = np.tile([c[i] for c in corners], G1.size)
    q[:, variables.index(rot[0])] = np.repeat(G1.ravel(), len(corners))
    q[:, variables.index(rot[1])] = np.repeat(G2.ravel(), len(corners))
    P0, _ = model.ideal_tool(q, model.tool_lengths(None, len(q)))

    def rms_map(positions):
        E, dL = errors_fn(positions, None)
        P, _ = actual_tool(model, positions, E, dL)
        e = np.sum((P - P0) ** 2, axis=1).reshape(G1.size, len(corners))
        return 1e3 * np.sqrt(e.mean(axis=1)).reshape(G1.shape)

    panels = [("before", rms_map(q))]
    if lc is not None:
        panels.append(("after LinuxCNC", rms_map(linuxcnc_commands(lc, model, q, 1.0))))
    if table is not None:
        panels.append(("after the table", rms_map(compensated_commands(table, q, machine.tool_length))))
    vmax = max(float(np.max(p)) for _, p in panels)
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 4.2), squeeze=False)
    ext = [np.degrees(grids[1][0]), np.degrees(grids[1][-1]), np.degrees(grids[0][0]), np.degrees(grids[0][-1])]
    for ax, (title, data) in zip(axes[0], panels):
        im = ax.imshow(data, origin="lower", extent=ext, aspect="auto", vmin=0, vmax=vmax, cmap="viridis")
        ax.set_title(f"{title}: RMS {np.sqrt(np.mean(data ** 2)):.3g} um")
        ax.set_xlabel(f"{rot[1]} (deg)")
        ax.set_ylabel(f"{rot[0]} (deg)")
    fig.colorbar(im, ax=list(axes[0]), label="predicted tool-tip error, RMS over X Y Z corners (um)")
    fig.suptitle(f"{machine.name}: predicted tool-tip error over {rot[0]} and {rot[1]}")
    return _save(fig, Path(path))
