"""PNG of the fit residuals against each variable (and t), per kind of reading, before and after adding the top
candidate: um for tool-tip and 1-D readings, urad for tool-axis readings."""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from .. import observations as ob
from .sensitivity import _pyplot, _save

#: Colours of the residual series, in order: grey for the first (before), then distinct colours.
SERIES_COLOURS = ("0.65", "tab:blue", "tab:orange", "tab:green")
KINDS = ("dx", "dy", "dz", "di", "dj", "dk", "du")


def variable_columns(model, meas, rows=None) -> list[tuple[str, np.ndarray]]:
    """(axis label with unit, values) of every pose variable in interface units (mm, degrees) and of t (s), at the
    pose rows `rows` (default: every pose)."""
    rows = np.arange(meas.n) if rows is None else rows
    cols = []
    for i, v in enumerate(meas.variables):
        x = meas.poses[rows, i]
        rotary = model.machine.axis(v).type == "rotary"
        cols.append((f"{v} ({'deg' if rotary else 'mm'})", np.degrees(x) if rotary else x))
    if meas.t is not None:
        cols.append(("t (s)", meas.t[rows]))
    return cols


def for_people(obs, residual: np.ndarray) -> np.ndarray:
    """Residuals per reading in um (mm readings) and urad (tool-axis readings)."""
    return residual * np.where(obs.group == ob.ANGLE, 1e6, 1e3)


def residual_figure(model, meas, obs, series, title: str):
    """Residuals of every kind of reading against every pose variable and time, one scatter series per entry of
    `series` [(label, residual per reading (m,) in um / urad)]; the legend and the title sit outside the data."""
    plt = _pyplot()
    cols = variable_columns(model, meas, obs.row)
    labels = obs.labels()
    kinds = [k for k in KINDS if (labels == k).any()]
    fig, axes = plt.subplots(len(kinds), len(cols), figsize=(2.7 * len(cols) + 0.8, 2.3 * len(kinds) + 0.9),
                             sharey="row", squeeze=False, layout="constrained")
    for c, (xlabel, x) in enumerate(cols):
        for r, kind in enumerate(kinds):
            ax = axes[r, c]
            sel = labels == kind
            for k, (label, res) in enumerate(series):
                ax.scatter(x[sel], res[sel], s=3, color=SERIES_COLOURS[k % len(SERIES_COLOURS)], label=label,
                           rasterized=True)
            ax.axhline(0.0, color="0.25", lw=0.6)
            ax.tick_params(labelsize=8)
            if c == 0:
                ax.set_ylabel(f"residual {kind} ({'urad' if kind in ('di', 'dj', 'dk') else 'um'})", fontsize=9)
            if r == 0:
                ax.set_title(f"against {xlabel.split(' ')[0]}", fontsize=9)
            if r == len(kinds) - 1:
                ax.set_xlabel(xlabel, fontsize=9)
    handles, names = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncol=max(1, len(series)), markerscale=4, fontsize=8,
               frameon=False)
    width = max(60, int(15 * fig.get_size_inches()[0]))
    fig.suptitle("\n".join(textwrap.wrap(title, width)), fontsize=10)
    return fig


def _rms_um(obs, res_people) -> float:
    lg = obs.group == ob.LENGTH
    return math.sqrt(np.mean(res_people[lg] ** 2)) if lg.any() else 0.0


def plot_residuals(dg, out_dir, name: str = "residuals.png") -> Path:
    """Scatter of the fit residual against every variable (and t): grey before, colour after the top candidate."""
    from .. import fit as F
    prob = dg.fit.problem
    model, meas, obs = prob.model, prob.meas, prob.obs
    before = for_people(obs, dg.fit.residual)
    series = [(f"model fitted (RMS {dg.rms_mm * 1000:.3g} um)", before)]
    after_text = ""
    if dg.candidates:
        top = dg.candidates[0]["id"]
        res = F.fit(model, meas, list(prob.effects) + F.resolve_effects(model, [top]), fixed=prob.fixed)
        after = for_people(obs, res.residual)
        rms_after = _rms_um(obs, after)
        series.append((f"after adding {top} (RMS {rms_after:.3g} um)", after))
        after_text = f", {rms_after:.3g} um after adding the top candidate {top}"
    title = (f"Fit residual (measured minus modelled reading; um, urad for the tool axis) of "
             f"{Path(str(meas.path)).name} against each axis position and time: RMS {dg.rms_mm * 1000:.3g} um"
             f"{after_text}; noise {dg.noise_mm * 1000:.3g} um")
    return _save(residual_figure(model, meas, obs, series, title), Path(out_dir) / name)
