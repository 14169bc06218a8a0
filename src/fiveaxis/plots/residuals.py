"""PNG of the fit residuals against each variable (and t), per kind of reading, before and after adding the top
candidate: um for tip and 1-D readings, urad for tool-axis readings."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import observations as ob
from .sensitivity import _pyplot, _save


def plot_residuals(dg, out_dir, name: str = "residuals.png") -> Path:
    """Scatter of the residual of every kind of reading (dx, dy, dz, di, dj, dk, du) against every variable:
    grey before, colour after adding the top candidate."""
    from .. import fit as F
    plt = _pyplot()
    prob = dg.fit.problem
    model, meas, obs = prob.model, prob.meas, prob.obs
    labels = obs.labels()
    kinds = [k for k in ("dx", "dy", "dz", "di", "dj", "dk", "du") if (labels == k).any()]
    scale = np.where(obs.group == ob.ANGLE, 1e6, 1000.0)
    before = dg.fit.residual * scale
    after, label = None, None
    if dg.candidates:
        top = dg.candidates[0]["id"]
        res = F.fit(model, meas, list(prob.effects) + F.resolve_effects(model, [top]), fixed=prob.fixed)
        after, label = res.residual * scale, f"after adding {top}"
    cols = []
    for i, v in enumerate(meas.variables):
        x = meas.poses[obs.row, i]
        rotary = model.machine.axis(v).type == "rotary"
        cols.append((f"{v} ({'deg' if rotary else 'mm'})", np.degrees(x) if rotary else x))
    if meas.t is not None:
        cols.append(("t (s)", meas.t[obs.row]))
    fig, axes = plt.subplots(len(kinds), len(cols), figsize=(2.6 * len(cols) + 1.5, 2.1 * len(kinds) + 1.0),
                             sharey="row", squeeze=False)
    for c, (xlabel, x) in enumerate(cols):
        for r, kind in enumerate(kinds):
            ax = axes[r, c]
            sel = labels == kind
            ax.scatter(x[sel], before[sel], s=3, color="0.65", label="before", rasterized=True)
            if after is not None:
                ax.scatter(x[sel], after[sel], s=3, color="tab:blue", label=label, rasterized=True)
            if c == 0:
                unit = "urad" if kind in ("di", "dj", "dk") else "um"
                ax.set_ylabel(f"{kind} residual ({unit})")
            if r == len(kinds) - 1:
                ax.set_xlabel(xlabel)
    lg = obs.group == ob.LENGTH
    rms_after = "" if after is None or not lg.any() else \
        f" -> {math.sqrt(np.mean(after[lg] ** 2)):.3g} um {label}"
    fig.suptitle(f"Fit residual of {Path(str(meas.path)).name} against each variable: RMS "
                 f"{dg.rms_mm * 1000:.3g} um{rms_after} (noise {dg.noise_mm * 1000:.3g} um)", fontsize=9)
    handles, names = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, names, loc="upper right", bbox_to_anchor=(1.0, 1.0), fontsize=7, markerscale=3,
               frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return _save(fig, Path(out_dir) / name)
