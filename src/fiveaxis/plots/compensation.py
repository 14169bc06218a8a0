"""The predicted tool-tip error map of `fiveaxis compensate --plot`: before, after LinuxCNC, after the table.

Over the two rotary axes (a grid over their strokes); at each cell the RMS of the tip error over the nine linear-axis
positions of the corners and the centre of the linear strokes. Micrometres, one colour scale for all panels. A
machine with fewer than two rotary axes: over its first two axes, or along its only axis (curves).
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
    """PNG of the predicted tip error (um) before / after LinuxCNC / after the table: over the two rotary axes (the
    RMS over the corners and the centre of the linear strokes); a machine with fewer rotary axes: over its first two
    axes (the others at the corners and centre of their strokes), or along its one axis as curves."""
    machine = model.machine
    variables = list(model.variables)
    rot = [v for v in variables if machine.axis(v).type == "rotary"][:2]
    shown = rot if len(rot) == 2 else (rot + [v for v in variables if v not in rot])[:2]
    rest = [v for v in variables if v not in shown]
    grids = [np.linspace(*machine.axis(v).model_stroke, cells) for v in shown]
    G = np.meshgrid(*grids, indexing="ij")
    corners = []
    for k in range(2 ** len(rest)):
        corners.append([machine.axis(v).model_stroke[(k >> i) & 1] for i, v in enumerate(rest)])
    corners.append([0.5 * sum(machine.axis(v).model_stroke) for v in rest])
    size = G[0].size
    q = np.zeros((size * len(corners), len(variables)))
    for i, v in enumerate(rest):
        q[:, variables.index(v)] = np.tile([c[i] for c in corners], size)
    for g, v in zip(G, shown):
        q[:, variables.index(v)] = np.repeat(g.ravel(), len(corners))
    P0, _ = model.ideal_tool(q, model.tool_lengths(None, len(q)))

    def rms_map(positions):
        E, dL = errors_fn(positions, None)
        P, _ = actual_tool(model, positions, E, dL)
        e = np.sum((P - P0) ** 2, axis=1).reshape(size, len(corners))
        return 1e3 * np.sqrt(e.mean(axis=1)).reshape(G[0].shape)

    panels = [("before", rms_map(q))]
    if lc is not None:
        panels.append(("after LinuxCNC", rms_map(linuxcnc_commands(lc, model, q, 1.0))))
    if table is not None:
        panels.append(("after the table", rms_map(compensated_commands(table, q, machine.tool_length))))
    plt = _pyplot()
    units = [np.degrees if machine.axis(v).type == "rotary" else np.asarray for v in shown]
    labels = [f"{v} ({'deg' if machine.axis(v).type == 'rotary' else 'mm'})" for v in shown]
    over = " and ".join(shown)
    if len(shown) == 1:                         # a one-axis machine: the error along its stroke
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        x = units[0](grids[0])
        for title, data in panels:
            ax.plot(x, data, label=f"{title}: RMS {np.sqrt(np.mean(data ** 2)):.3g} um")
        ax.set_xlabel(labels[0])
        ax.set_ylabel("predicted tool-tip error (um)")
        ax.legend()
    else:
        vmax = max(float(np.max(p)) for _, p in panels)
        fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 4.2), squeeze=False)
        ext = [*units[1](grids[1][[0, -1]]), *units[0](grids[0][[0, -1]])]
        for ax, (title, data) in zip(axes[0], panels):
            im = ax.imshow(data, origin="lower", extent=ext, aspect="auto", vmin=0, vmax=vmax, cmap="viridis")
            ax.set_title(f"{title}: RMS {np.sqrt(np.mean(data ** 2)):.3g} um")
            ax.set_xlabel(labels[1])
            ax.set_ylabel(labels[0])
        what = f"RMS over {' '.join(rest)} corners" if rest else "at each pose"
        fig.colorbar(im, ax=list(axes[0]), label=f"predicted tool-tip error, {what} (um)")
    fig.suptitle(f"{machine.name}: predicted tool-tip error over {over}")
    return _save(fig, Path(path))
