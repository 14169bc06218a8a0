"""The plot of an ISO 230-3 thermal test, from its record (`fiveaxis.iso230.thermal.evaluate`): the drift of each
direction against time (um; the tilts in urad on their own panel), the temperature of every channel beside it on
the same time axis (degC), the spindle's running phases shaded; for a moving axis, the drift at each target and
the change of the distance between the end targets."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .sensitivity import _colours, _pyplot, _save

LINEAR = ("X", "Y", "Z")
TILTS = ("A", "B")


def _shade(ax, rec: dict):
    for p in rec["phases"]:
        if p["phase"] == "running":
            ax.axvspan(p["reference_min"] if p["reference_min"] < p["start_min"] else p["start_min"], p["end_min"],
                       color="0.88", zorder=0)


def thermal_figure(rec: dict):
    """The figure of a test record: drift panels over a temperature panel, time in min."""
    plt = _pyplot()
    s = rec["series"]
    t = np.asarray(s["t_min"], float)
    tilts = [k for k in TILTS if f"{k}_urad" in s]
    panels = 1 + (1 if tilts and rec["test"] != "axis" else 0) + (1 if rec["temperatures"] else 0)
    fig, axes = plt.subplots(panels, 1, figsize=(9.5, 2.8 * panels + 0.6), sharex=True, layout="constrained",
                             squeeze=False)
    axes = list(axes[:, 0])
    ax = axes[0]
    if rec["test"] == "axis":
        rows = np.asarray(s["rows"])
        colours = _colours(len(rec["targets"]) * 3)
        k = 0
        for tg in rec["targets"]:
            sel = np.isin(rows, tg["rows"])
            for d in LINEAR:
                if f"{d}_um" in s:
                    v = np.asarray(s[f"{d}_um"], float)[sel]
                    ax.plot(t[sel], v - v[0], ".-", color=colours[k], markersize=3, linewidth=1,
                            label=f"{d} at {rec['axis']} = {tg['position_mm']:g} mm")
                    k += 1
        e = rec.get("expansion")
        if e:
            ax.plot(e["series"]["t_min"], e["series"]["change_um"], "k--", linewidth=1.4,
                    label=f"change of the distance {e['from_mm']:g} to {e['to_mm']:g} mm")
        title = f"ISO 230-3 {rec['test_name']} ({rec['axis']})"
    else:
        for d, c in zip(LINEAR, ("tab:red", "tab:green", "tab:blue")):
            if f"{d}_um" in s:
                v = np.asarray(s[f"{d}_um"], float)
                fig_d = next(x for x in rec["directions"] if x["direction"] == d)
                ax.plot(t, v - v[0], color=c, linewidth=1.1,
                        label=f"{d}: max drift {fig_d['max_drift_um']:+.2f} um, range {fig_d['range_um']:.2f} um")
        title = f"ISO 230-3 {rec['test_name']}"
        _shade(ax, rec)
    ax.axhline(0.0, color="0.6", linewidth=0.8)
    ax.set_ylabel("drift (um)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=10)
    k = 1
    if tilts and rec["test"] != "axis":
        ax = axes[k]
        k += 1
        for d, c in zip(TILTS, ("tab:purple", "tab:orange")):
            if f"{d}_urad" in s:
                v = np.asarray(s[f"{d}_urad"], float)
                fig_d = next(x for x in rec["directions"] if x["direction"] == d)
                ax.plot(t, v - v[0], color=c, linewidth=1.1,
                        label=f"{d}: max drift {fig_d['max_drift_urad']:+.2f} urad, range "
                              f"{fig_d['range_urad']:.2f} urad")
        _shade(ax, rec)
        ax.axhline(0.0, color="0.6", linewidth=0.8)
        ax.set_ylabel("tilt (urad = um/m)")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.grid(alpha=0.3)
    if rec["temperatures"]:
        ax = axes[k]
        for c, colour in zip(rec["temperatures"], _colours(len(rec["temperatures"]))):
            v = np.array([np.nan if x is None else x for x in s[f"{c['channel']}_degC"]], float)
            ok = ~np.isnan(v)
            ax.plot(t[ok], v[ok], color=colour, linewidth=1.1,
                    label=f"{c['channel']}: {c['first_degC']:.2f} to {c['last_degC']:.2f} degC, range "
                          f"{c['range_degC']:.2f}")
        if rec["test"] != "axis":
            _shade(ax, rec)
        ax.set_ylabel("temperature (degC)")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time since the start of the test (min)" + ("; grey: spindle running" if any(
        p["phase"] == "running" for p in rec["phases"]) else ""))
    return fig


def write_thermal(rec: dict, folder) -> Path:
    """iso230-3_<test>.png in folder."""
    return _save(thermal_figure(rec), Path(folder) / f"iso230-3_{rec['test']}.png")
