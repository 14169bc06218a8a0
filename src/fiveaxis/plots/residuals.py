"""PNG of the residuals (dx, dy, dz in um) against each variable, before and after adding the top candidate."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .sensitivity import _pyplot, _save


def plot_residuals(dg, out_dir, name: str = "residuals.png") -> Path:
    """Scatter of the fit residual against every variable (and t): grey before, colour after the top candidate."""
    from .. import fit as F
    plt = _pyplot()
    prob = dg.fit.problem
    model, meas = prob.model, prob.meas
    before = dg.fit.residual.reshape(-1, 3) * 1000
    after, label = None, None
    if dg.candidates:
        top = dg.candidates[0]["id"]
        res = F.fit(model, meas, list(prob.effects) + F.resolve_effects(model, [top]))
        after, label = res.residual.reshape(-1, 3) * 1000, f"after adding {top}"
    cols = []
    for i, v in enumerate(meas.variables):
        x = meas.poses[:, i]
        rotary = model.machine.axis(v).type == "rotary"
        cols.append((f"{v} ({'deg' if rotary else 'mm'})", np.degrees(x) if rotary else x))
    if meas.t is not None:
        cols.append(("t (s)", meas.t))
    fig, axes = plt.subplots(3, len(cols), figsize=(2.6 * len(cols), 6.4), sharey="row", squeeze=False)
    for c, (xlabel, x) in enumerate(cols):
        for r, comp in enumerate(("dx", "dy", "dz")):
            ax = axes[r, c]
            ax.scatter(x, before[:, r], s=3, color="0.7", label="before", rasterized=True)
            if after is not None:
                ax.scatter(x, after[:, r], s=3, color="tab:blue", label=label, rasterized=True)
            if c == 0:
                ax.set_ylabel(f"{comp} residual (um)")
            if r == 2:
                ax.set_xlabel(xlabel)
    rms_after = "" if after is None else f" -> {math.sqrt(np.mean(after ** 2)):.3g} um {label}"
    fig.suptitle(f"{Path(str(meas.path)).name}: residual RMS {dg.rms_mm * 1000:.3g} um{rms_after} "
                 f"(noise {dg.noise_mm * 1000:.3g} um)", fontsize=9)
    axes[0, 0].legend(fontsize=7, markerscale=3, loc="upper right")
    return _save(fig, Path(out_dir) / name)
