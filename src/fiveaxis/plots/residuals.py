"""PNG of the fit residuals against each variable (and t), per kind of reading, before and after adding the top
candidate: um for tool-tip and 1-D readings, urad for tool-axis readings. Each fit is plotted on its own readings
(a robust fit leaves its outliers out; before and after adding an effect they may differ)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from ..estimation import fit as F
from ..estimation.problem import resolve_effects
from ..measurement import observations as ob
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


def series_of(res, label: str):
    """A residual series of a fit: (label, its readings, residual in um / urad)."""
    obs = res.problem.obs
    return label, obs, for_people(obs, res.residual)


def residual_figure(model, meas, series, title: str):
    """Residuals of every kind of reading against every pose variable and time, one scatter series per entry of
    `series` [(label, observations, residual per reading in um / urad)]; legend and title outside the data."""
    plt = _pyplot()
    kinds = [k for k in KINDS if any((obs.labels() == k).any() for _, obs, _ in series)]
    names = [c[0] for c in variable_columns(model, meas, np.arange(0))]
    fig, axes = plt.subplots(len(kinds), len(names), figsize=(2.7 * len(names) + 0.8, 2.3 * len(kinds) + 0.9),
                             sharey="row", squeeze=False, layout="constrained")
    for k, (label, obs, res) in enumerate(series):
        labels = obs.labels()
        for c, (xlabel, x) in enumerate(variable_columns(model, meas, obs.row)):
            for r, kind in enumerate(kinds):
                sel = labels == kind
                axes[r, c].scatter(x[sel], res[sel], s=3, color=SERIES_COLOURS[k % len(SERIES_COLOURS)],
                                   label=label if (r, c) == (0, 0) else None, rasterized=True)
    for c, xlabel in enumerate(names):
        for r, kind in enumerate(kinds):
            ax = axes[r, c]
            ax.axhline(0.0, color="0.25", lw=0.6)
            ax.tick_params(labelsize=8)
            if c == 0:
                ax.set_ylabel(f"residual {kind} ({'urad' if kind in ('di', 'dj', 'dk') else 'um'})", fontsize=9)
            if r == 0:
                ax.set_title(f"against {xlabel.split(' ')[0]}", fontsize=9)
            if r == len(kinds) - 1:
                ax.set_xlabel(xlabel, fontsize=9)
    handles, labels_ = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels_, loc="outside lower center", ncol=max(1, len(series)), markerscale=4, fontsize=8,
               frameon=False)
    width = max(60, int(15 * fig.get_size_inches()[0]))
    fig.suptitle("\n".join(textwrap.wrap(title, width)), fontsize=10)
    return fig


def plot_residuals(dg, out_dir, name: str = "residuals.png") -> Path:
    """Scatter of the fit residual against every variable (and t): grey before, colour after the top candidate
    (each fit without its own outliers, which are left out of the plot and counted in its title)."""
    prob = dg.fit.problem
    model, meas = prob.model, prob.meas
    series = [series_of(dg.fit, f"model fitted (RMS {dg.rms_mm_without_outliers * 1000:.3g} um)")]
    after_text = ""
    if dg.candidates:
        top = dg.candidates[0]["id"]
        res = F.fit(model, meas, list(prob.effects) + resolve_effects(model, [top], poses=meas.poses), fixed=prob.fixed)
        rms_after = res.rms_mm_without_outliers * 1000
        series.append(series_of(res, f"after adding {top} (RMS {rms_after:.3g} um)"))
        after_text = f", {rms_after:.3g} um after adding the top candidate {top}"
    n_out = dg.fit.outliers.count if dg.fit.outliers is not None else 0
    title = (f"Fit residual (measured minus modelled reading; um, urad for the tool axis) of "
             f"{Path(str(meas.path)).name} against each axis position and time: RMS "
             f"{dg.rms_mm_without_outliers * 1000:.3g} um{after_text}; noise {dg.noise_mm * 1000:.3g} um"
             + (f"; {n_out} outlier reading(s) left out" if n_out else ""))
    return _save(residual_figure(model, meas, series, title), Path(out_dir) / name)
