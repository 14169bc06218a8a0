"""The predicted tool-tip error map of `fiveaxis compensate --plot`: before, after LinuxCNC, after the table, and
what the true machine may show after the table (the k = 2 band).

Over the two rotary axes (a grid over their strokes); at each cell the RMS of the tip error over the nine linear-axis
positions of the corners and the centre of the linear strokes. The first panels are the fitted model's own view
(raw), titled with the workspace's k = 2 range of the true machine (summary.json's prediction_uncertainty); the last
panel the k = 2 upper bound per cell of the true machine after the table with the part's set-up taken out
(compensation.prediction.local_upper). Micrometres, one colour scale for all panels. A machine with fewer than two
rotary axes: over its first two axes (the others at their corners and centres), or along its only axis (curves).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..compensation.chain import actual_tool
from ..compensation.correction import fitted_errors
from ..compensation.prediction import PRIOR_DECIDES, local_upper
from ..compensation.table import compensated_commands
from ..linuxcnc.configuration import linuxcnc_commands
from .sensitivity import _pyplot, _save


def figure(comp, path) -> Path:
    """The error map of a compensation (`fiveaxis.compensation.pipeline.Compensation`) as a PNG at path."""
    return error_map(comp.model, fitted_errors(comp.fm, comp.model), comp.table, comp.lc, path, fm=comp.fm,
                     uncertainty=comp.account.get("uncertainty") or {})


def error_map(model, errors_fn, table, lc, path, cells: int = 41, fm=None, uncertainty=None) -> Path:
    """PNG of the predicted tip error (um) over the rotary axes: before / after LinuxCNC / after the table; with the
    fitted model fm (covariance), also the k = 2 upper bound of the true machine after the table (part's set-up
    taken out), and with its uncertainty record (compensation.prediction.band) the workspace ranges in the titles."""
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

    def errors(positions):
        E, dL = errors_fn(positions, None)
        P, _ = actual_tool(model, positions, E, dL)
        return P - P0

    def rms_map(e):
        return 1e3 * np.sqrt(np.sum(e ** 2, axis=1).reshape(size, len(corners)).mean(axis=1)).reshape(G[0].shape)

    tips = (uncertainty or {}).get("tip_error_mm", {})

    def title(what, key, data):
        band = (tips.get(key) or {}).get("setup_removed") or {}
        head = f"{what} (fitted model): RMS {np.sqrt(np.mean(data ** 2)):.3g} um"
        decided = band.get("prior_share", 0.0) >= PRIOR_DECIDES
        return head if "range_k2" not in band else (f"{head}\nthe true machine after the part's set-up:\n"
                                                    f"{1e3 * band['range_k2'][0]:.3g} to "
                                                    f"{1e3 * band['range_k2'][1]:.3g} um RMS (k = 2)"
                                                    + ("\n(upper end: the priors' sizes for what the data cannot "
                                                       "see)" if decided else ""))

    panels = [("before", "before", rms_map(errors(q)))]
    if lc is not None:
        panels.append(("after LinuxCNC", "after_linuxcnc", rms_map(errors(linuxcnc_commands(lc, model, q, 1.0)))))
    if table is not None:
        after = errors(compensated_commands(table, q, machine.tool_length))
        panels.append(("after the table", "after_table", rms_map(after)))
        upper = None if fm is None else local_upper(fm, model, q, None, after, len(corners))
        if upper is not None:
            panels.append(("upper", None, 1e3 * upper.reshape(G[0].shape)))
    upper_title = "after the table, the true machine after the part's set-up: k = 2 upper bound"
    plt = _pyplot()
    unit = [np.degrees if machine.axis(v).type == "rotary" else np.asarray for v in shown]
    label = [f"{v} ({'deg' if machine.axis(v).type == 'rotary' else 'mm'})" for v in shown]
    if len(shown) == 1:                          # a one-axis machine: the error along its stroke, as curves
        fig, ax = plt.subplots(figsize=(7.0, 4.6))
        x = unit[0](grids[0])
        for what, key, data in panels:
            ax.plot(x, data, label=(title(what, key, data) if key else
                                    f"{upper_title} (RMS {np.sqrt(np.mean(data ** 2)):.3g} um)").replace("\n", " "))
        ax.set_xlabel(label[0])
        ax.set_ylabel("tool-tip error (um)")
        ax.legend(fontsize=7)
        fig.suptitle(f"{machine.name}: predicted tool-tip error along {shown[0]}")
        return _save(fig, Path(path))
    vmax = max(float(np.max(p)) for _, _, p in panels)
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 5.0), squeeze=False)
    ext = [*unit[1](grids[1][[0, -1]]), *unit[0](grids[0][[0, -1]])]
    for ax, (what, key, data) in zip(axes[0], panels):
        im = ax.imshow(data, origin="lower", extent=ext, aspect="auto", vmin=0, vmax=vmax, cmap="viridis")
        ax.set_title(title(what, key, data) if key else "after the table, the true machine after the part's\n"
                     f"set-up: k = 2 upper bound per cell\n(RMS {np.sqrt(np.mean(data ** 2)):.3g} um)", fontsize=8)
        ax.set_xlabel(label[1])
        ax.set_ylabel(label[0])
    fig.subplots_adjust(left=0.05, right=0.9, top=0.78, wspace=0.3)
    over = f"RMS over {' '.join(rest)} corners" if rest else "at each pose"
    fig.colorbar(im, cax=fig.add_axes([0.92, 0.11, 0.012, 0.67]), label=f"tool-tip error, {over} (um)")
    fig.suptitle(f"{machine.name}: predicted tool-tip error over {shown[0]} and {shown[1]}", y=0.99)
    return _save(fig, Path(path))
