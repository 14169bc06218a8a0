"""The plots practitioners know for ISO 230-2 and ISO 230-4, from the evaluations' JSON records
(`fiveaxis.iso230.positioning.to_json`, `fiveaxis.iso230.circular.to_json`):

- positioning: the mean positional deviation per target, forward and backward, with the +-2 s band of each
  direction and the mean bidirectional deviation (um against the target position, mm); the axis figures in the
  title;
- circle: the polar plot of a circle's actual path, both directions, its radial deviation from the least-squares
  circle magnified (um per division of the radial scale), G, G (minimum zone), F and H in the title.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .sensitivity import _pyplot, _save

COLOURS = {"fwd": "tab:blue", "bwd": "tab:red", "ccw": "tab:blue", "cw": "tab:red"}


def positioning_figure(rec: dict):
    """The ISO 230-2 plot of an evaluation record: x̄_i fwd / bwd +- 2 s_i against P_i."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(9, 4.8), layout="constrained")
    P = np.asarray(rec["targets_mm"])
    for d, label in (("fwd", "forward (approach in +)"), ("bwd", "backward (approach in -)")):
        m = np.asarray(rec[f"mean_{d}_um"])
        s = np.asarray(rec[f"s_{d}_um"])
        ax.plot(P, m, "o-", color=COLOURS[d], label=f"mean deviation, {label}")
        ax.fill_between(P, m - 2 * s, m + 2 * s, color=COLOURS[d], alpha=0.18, label=f"+-2 s, {label}")
        xs = [p for p, cyc in zip(P, rec["readings_um"][d]) for _ in cyc]
        ys = [v for cyc in rec["readings_um"][d] for v in cyc]
        ax.plot(xs, ys, ".", color=COLOURS[d], alpha=0.35, markersize=3)
    ax.plot(P, rec["mean_bidirectional_um"], "--", color="0.3", label="mean bidirectional deviation")
    ax.axhline(0.0, color="0.6", linewidth=0.8)
    ax.set_xlabel(f"target position {rec['axis']} (mm)")
    ax.set_ylabel("positional deviation (um)")
    ax.set_title(f"ISO 230-2 positioning of {rec['axis']}: A {rec['A_um']:.2f} um, E {rec['E_um']:.2f} um, "
                 f"M {rec['M_um']:.2f} um, B {rec['B_um']:.2f} um, R {rec['R_um']:.2f} um "
                 f"({rec['targets']} targets, {rec['cycles']} cycles)", fontsize=10)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.grid(alpha=0.3)
    return fig


def circle_figure(circle: dict):
    """The polar plot of a circle record: each direction's path, radial deviation from its least-squares circle,
    magnified; the reference circle at the middle of the radial scale."""
    plt = _pyplot()
    fig = plt.figure(figsize=(6.2, 6.6), layout="constrained")
    ax = fig.add_subplot(projection="polar")
    devs = [np.asarray(r["path"]["deviation_um"]) for r in circle["runs"]]
    span = max(max((float(np.max(np.abs(d))) for d in devs), default=1.0), 0.5)
    div = _nice(span / 2)                                   # um per division; 4 divisions inside, 4 outside
    base = 4 * div
    for r, d in zip(circle["runs"], devs):
        th = np.radians(np.asarray(r["path"]["theta_deg"]))
        o = np.argsort(th)
        th, dd = np.append(th[o], th[o][0] + 2 * math.pi), np.append(d[o], d[o][0])
        ax.plot(th, base + dd, color=COLOURS.get(r["direction"], "k"), linewidth=1.2,
                label=f"{r['direction']}: G {r['G_um']:.2f} um (LSQ), {r['G_mz_um']:.2f} um (MZ)")
    ring = np.linspace(0, 2 * math.pi, 361)
    ax.plot(ring, np.full_like(ring, base), color="0.5", linewidth=0.8, linestyle="--")
    ax.set_ylim(0, 2 * base)
    ticks = base + div * np.arange(-4, 5)
    ax.set_yticks(ticks)
    ax.set_yticklabels([f"{t - base:+.3g}" if k % 2 == 0 else "" for k, t in enumerate(ticks)], fontsize=7)
    a, b = circle["axes"]
    ax.set_xticks(np.radians([0, 90, 180, 270]))
    ax.set_xticklabels([f"+{a}", f"+{b}", f"-{a}", f"-{b}"])
    H = f", H {circle['H_um']:.2f} um" if circle.get("H_um") is not None else ""
    setup = circle.get("setup")
    ax.set_title(f"ISO 230-4 circle {circle['plane']}" + (f" ({setup})" if setup not in (None, circle["plane"]) else "")
                 + f", radius {circle['radius_mm']:g} mm{H}\nradial deviation from the least-squares circle, "
                 f"{div:.3g} um per division", fontsize=10)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.06))
    return fig


def _nice(x: float) -> float:
    """1, 2 or 5 times a power of ten, at least x."""
    e = 10.0 ** math.floor(math.log10(x))
    return next(m * e for m in (1, 2, 5, 10) if m * e >= x)


def write_positioning(rec: dict, folder) -> Path:
    """iso230-2_<axis>[_<setup>].png in folder."""
    name = f"iso230-2_{rec['axis']}" + (f"_{_safe(rec['setup'])}" if rec.get("setup") else "") + ".png"
    return _save(positioning_figure(rec), Path(folder) / name)


def write_circle(circle: dict, folder) -> Path:
    """iso230-4_<plane>[_<setup>].png in folder."""
    setup = circle.get("setup")
    name = f"iso230-4_{circle['plane']}" + (f"_{_safe(setup)}" if setup not in (None, circle["plane"]) else "") + ".png"
    return _save(circle_figure(circle), Path(folder) / name)


def _safe(text) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in str(text))
