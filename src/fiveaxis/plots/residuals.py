"""PNG of the fit residuals against each variable (and t), per kind of reading, before and after adding the top
candidate: um for tip and 1-D readings, urad for tool-axis readings."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import observations as ob
from .sensitivity import _pyplot, _save


def plot_residuals(dg, out_dir, name: str = "residuals.png") -> Path:
    """Scatter of the residual of every kind of reading (dx, dy, dz, di, dj, dk, du) against every variable:
    grey before, colour after adding the top candidate (each fit without its own outliers, which are left out of
    the plot and counted in its title)."""
    from .. import fit as F
    plt = _pyplot()
    prob = dg.fit.problem
    model, meas = prob.model, prob.meas
    sets = [("before", dg.fit, "0.65")]
    if dg.candidates:
        top = dg.candidates[0]["id"]
        res = F.fit(model, meas, list(prob.effects) + F.resolve_effects(model, [top]), fixed=prob.fixed)
        sets.append((f"after adding {top}", res, "tab:blue"))
    kinds = [k for k in ("dx", "dy", "dz", "di", "dj", "dk", "du") if (prob.obs.labels() == k).any()]
    cols = [(f"{v} ({'deg' if model.machine.axis(v).type == 'rotary' else 'mm'})", i)
            for i, v in enumerate(meas.variables)]
    if meas.t is not None:
        cols.append(("t (s)", None))
    fig, axes = plt.subplots(len(kinds), len(cols), figsize=(2.6 * len(cols) + 1.5, 2.1 * len(kinds) + 1.0),
                             sharey="row", squeeze=False)
    for label, res, colour in sets:
        obs = res.problem.obs
        labels = obs.labels()
        y = res.residual * np.where(obs.group == ob.ANGLE, 1e6, 1000.0)
        for c, (xlabel, i) in enumerate(cols):
            if i is None:
                x = meas.t[obs.row]
            else:
                x = meas.poses[obs.row, i]
                if model.machine.axis(meas.variables[i]).type == "rotary":
                    x = np.degrees(x)
            for r, kind in enumerate(kinds):
                sel = labels == kind
                axes[r, c].scatter(x[sel], y[sel], s=3, color=colour, label=label, rasterized=True)
    for r, kind in enumerate(kinds):
        axes[r, 0].set_ylabel(f"{kind} residual ({'urad' if kind in ('di', 'dj', 'dk') else 'um'})")
    for c, (xlabel, _) in enumerate(cols):
        axes[-1, c].set_xlabel(xlabel)
    after = ""
    if len(sets) > 1:
        after = f" -> {sets[1][1].rms_mm_without_outliers * 1000:.3g} um {sets[1][0]}"
    n_out = dg.fit.outliers.count if dg.fit.outliers is not None else 0
    fig.suptitle(f"Fit residual of {Path(str(meas.path)).name} against each variable: RMS "
                 f"{dg.rms_mm_without_outliers * 1000:.3g} um{after} (noise {dg.noise_mm * 1000:.3g} um)"
                 + (f"; {n_out} outlier reading(s) left out" if n_out else ""), fontsize=9)
    handles, names = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, names, loc="upper right", bbox_to_anchor=(1.0, 1.0), fontsize=7, markerscale=3,
               frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return _save(fig, Path(out_dir) / name)
