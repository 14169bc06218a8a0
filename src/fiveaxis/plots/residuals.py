"""PNG of the residuals (dx, dy, dz in um) against each variable, before and after adding the top candidate."""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from .sensitivity import _pyplot, _save

#: Colours of the residual series, in order: grey for the first (before), then distinct colours.
SERIES_COLOURS = ("0.65", "tab:blue", "tab:orange", "tab:green")


def variable_columns(model, meas) -> list[tuple[str, np.ndarray]]:
    """(axis label with unit, values) of every pose variable in interface units (mm, degrees) and of t (s)."""
    cols = []
    for i, v in enumerate(meas.variables):
        x = meas.poses[:, i]
        rotary = model.machine.axis(v).type == "rotary"
        cols.append((f"{v} ({'deg' if rotary else 'mm'})", np.degrees(x) if rotary else x))
    if meas.t is not None:
        cols.append(("t (s)", meas.t))
    return cols


def residual_figure(model, meas, series, title: str):
    """Residual components dx, dy, dz (um) against every pose variable and time, one scatter series per entry of
    `series` [(label, residual (n, 3) um)]; the legend and the title sit outside the data."""
    plt = _pyplot()
    cols = variable_columns(model, meas)
    fig, axes = plt.subplots(3, len(cols), figsize=(2.7 * len(cols) + 0.8, 7.4), sharey="row", squeeze=False,
                             layout="constrained")
    for c, (xlabel, x) in enumerate(cols):
        for r, comp in enumerate(("dx", "dy", "dz")):
            ax = axes[r, c]
            for k, (label, res) in enumerate(series):
                ax.scatter(x, res[:, r], s=3, color=SERIES_COLOURS[k % len(SERIES_COLOURS)], label=label,
                           rasterized=True)
            ax.axhline(0.0, color="0.25", lw=0.6)
            ax.tick_params(labelsize=8)
            if c == 0:
                ax.set_ylabel(f"residual {comp} (um)", fontsize=9)
            if r == 0:
                ax.set_title(f"against {xlabel.split(' ')[0]}", fontsize=9)
            if r == 2:
                ax.set_xlabel(xlabel, fontsize=9)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=max(1, len(series)), markerscale=4, fontsize=8,
               frameon=False)
    width = max(60, int(15 * fig.get_size_inches()[0]))
    fig.suptitle("\n".join(textwrap.wrap(title, width)), fontsize=10)
    return fig


def plot_residuals(dg, out_dir, name: str = "residuals.png") -> Path:
    """Scatter of the fit residual against every variable (and t): grey before, colour after the top candidate."""
    from .. import fit as F
    prob = dg.fit.problem
    model, meas = prob.model, prob.meas
    before = dg.fit.residual.reshape(-1, 3) * 1000
    series = [(f"model fitted (RMS {dg.rms_mm * 1000:.3g} um)", before)]
    after_text = ""
    if dg.candidates:
        top = dg.candidates[0]["id"]
        res = F.fit(model, meas, list(prob.effects) + F.resolve_effects(model, [top]))
        after = res.residual.reshape(-1, 3) * 1000
        rms_after = math.sqrt(np.mean(after ** 2))
        series.append((f"after adding {top} (RMS {rms_after:.3g} um)", after))
        after_text = f", {rms_after:.3g} um after adding the top candidate {top}"
    title = (f"Fit residual (measured minus modelled tool-tip deviation, um) of {Path(str(meas.path)).name} "
             f"against each axis position and time: RMS {dg.rms_mm * 1000:.3g} um{after_text}; "
             f"noise {dg.noise_mm * 1000:.3g} um")
    return _save(residual_figure(model, meas, series, title), Path(out_dir) / name)
