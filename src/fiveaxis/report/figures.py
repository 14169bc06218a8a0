"""The report's figures as PNG bytes (matplotlib, Agg): pose coverage, RMS per diagnosis round, GSIL bars.

The residual scatter comes from `fiveaxis.plots.residuals.residual_figure`. Every figure has a title with the
quantity and its unit; legends sit outside the data; layouts are constrained so that nothing is clipped.
"""
from __future__ import annotations

import io
import itertools

import numpy as np

from ..plots.sensitivity import _pyplot

DPI = 100


def png(fig) -> bytes:
    """The figure as PNG bytes (closed afterwards)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight")
    _pyplot().close(fig)
    return buf.getvalue()


def _interface(model, meas, name):
    """Values of a pose variable in interface units (mm, degrees), its stroke and unit."""
    ax = model.machine.axis(name)
    x = meas.poses[:, list(meas.variables).index(name)]
    if ax.type == "rotary":
        return np.degrees(x), ax.stroke, "deg"
    return x, ax.stroke, "mm"


def coverage(model, meas) -> tuple[bytes, str]:
    """Where the measured poses lie, and the caption that says what the figure shows: pairs of linear axes and the
    rotary axes as dots against the strokes; when at most one axis moves (a laser run along one axis), the poses
    along that axis as bars; tool length or time as bars."""
    plt = _pyplot()
    moving = [v for v in meas.variables if np.ptp(meas.poses[:, list(meas.variables).index(v)]) > 0]
    linear = [v for v in meas.variables if model.machine.axis(v).type == "linear"]
    rotary = [v for v in meas.variables if model.machine.axis(v).type == "rotary"]
    pairs = list(itertools.combinations(linear, 2))[:3]
    if len(rotary) >= 2:
        pairs.append((rotary[0], rotary[1]))
    elif rotary:
        pairs.append((linear[0] if linear else rotary[0], rotary[0]))
    one = moving[0] if len(moving) == 1 else None
    if len(moving) <= 1:
        pairs = []
    extra = "L" if meas.has_L else ("t" if meas.t is not None else None)
    n = len(pairs) + (one is not None) + (extra is not None)
    if n == 0:
        extra = "none"
        n = 1
    fig, axes = plt.subplots(1, n, figsize=(3.3 * n, 3.5), squeeze=False, layout="constrained")
    k = 0
    for a, b in pairs:
        ax = axes[0, k]
        k += 1
        xa, (lo_a, hi_a), ua = _interface(model, meas, a)
        xb, (lo_b, hi_b), ub = _interface(model, meas, b)
        ax.scatter(xa, xb, s=3, color="tab:blue", alpha=0.6, rasterized=True, label="measured pose")
        ax.plot([lo_a, hi_a, hi_a, lo_a, lo_a], [lo_b, lo_b, hi_b, hi_b, lo_b], "--", color="0.3", lw=0.8,
                label="stroke")
        ax.set_xlabel(f"{a} ({ua})", fontsize=9)
        ax.set_ylabel(f"{b} ({ub})", fontsize=9)
        ax.set_title(f"poses in {a}-{b}", fontsize=9)
        ax.tick_params(labelsize=8)
    if one is not None:
        ax = axes[0, k]
        k += 1
        x, (lo, hi), u = _interface(model, meas, one)
        ax.hist(x, bins=min(60, max(10, len(np.unique(x)) * 3)), color="tab:blue", alpha=0.8, label="measured pose")
        for end in (lo, hi):
            ax.axvline(end, ls="--", color="0.3", lw=0.8, label="stroke" if end == lo else None)
        ax.set_xlabel(f"{one} ({u})", fontsize=9)
        ax.set_ylabel("poses", fontsize=9)
        ax.set_title(f"poses along {one}", fontsize=9)
        ax.tick_params(labelsize=8)
    if extra in ("L", "t"):
        ax = axes[0, k]
        vals, label = (meas.L, "tool length L (mm)") if extra == "L" else (meas.t, "time t (s)")
        ax.hist(vals, bins=30, color="tab:blue", alpha=0.8)
        ax.set_xlabel(label, fontsize=9)
        ax.set_ylabel("poses", fontsize=9)
        ax.set_title(f"poses over {label.split(' (')[0]}", fontsize=9)
        ax.tick_params(labelsize=8)
    elif extra == "none":
        axes[0, 0].text(0.5, 0.5, "all poses at one position", ha="center", va="center", fontsize=9)
        axes[0, 0].set_axis_off()
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncol=2, fontsize=8, frameon=False, markerscale=3)
    fig.suptitle(f"Coverage of the workspace by the {meas.n} measured poses (dashed: the machine's strokes)",
                 fontsize=10)
    parts = []
    if pairs:
        parts.append("Each dot is a measured pose, projected on two axes "
                     f"({', '.join(f'{a}-{b}' for a, b in pairs)}); the dashed box is the stroke of the machine file.")
    if one is not None:
        parts.append(f"Only {one} moves in this file: the bars count the measured poses along {one}; the dashed "
                     f"lines are its stroke.")
    elif not moving:
        parts.append("All poses lie at one position of the axes.")
    if extra in ("L", "t"):
        parts.append(f"The bars of the last panel count the poses over the "
                     f"{'tool length' if extra == 'L' else 'time of the measurement'}.")
    parts.append("Errors that change along an axis can only be found where the poses spread along it.")
    return png(fig), " ".join(parts)


def rounds(rows: list[dict]) -> bytes:
    """Residual RMS (um) of each diagnosis round against the noise level."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(max(4.5, 1.6 * len(rows) + 2), 3.4), layout="constrained")
    x = np.arange(len(rows))
    rms = [r["rms_um"] for r in rows]
    ax.bar(x, rms, color="tab:blue", width=0.6, label="residual RMS")
    ax.plot([-0.5, len(rows) - 0.5], [rows[-1]["noise_um"]] * 2, "--", color="tab:red", lw=1.2,
            label=f"noise ({rows[-1]['noise_um']:.3g} um)")
    ax.set_xticks(x, [("base model" if i == 0 else f"+ {r['added'][-1]}") for i, r in enumerate(rows)], fontsize=8)
    for xi, v in zip(x, rms):
        ax.annotate(f"{v:.3g}", (xi, v), ha="center", va="bottom", fontsize=8, xytext=(0, 2),
                    textcoords="offset points")
    ax.set_ylabel("residual RMS (um)", fontsize=9)
    ax.set_ylim(0, max(rms + [rows[-1]["noise_um"]]) * 1.18)
    ax.set_title("Residual RMS (um) per diagnosis round: the model, then each effect added", fontsize=10)
    fig.legend(loc="outside lower center", ncol=2, fontsize=8, frameon=False)
    return png(fig)


def sensitivity(top: list[dict]) -> bytes:
    """Horizontal bars of the largest GSIL proportions PG_i (%)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 0.32 * len(top) + 1.4), layout="constrained")
    labels = [f"{t['name']} ({t['iso']})" if t["iso"] else t["name"] for t in top]
    values = [100 * t["proportion"] for t in top]
    y = np.arange(len(top))[::-1]
    ax.barh(y, values, color="tab:blue", height=0.65)
    ax.set_yticks(y, labels, fontsize=8)
    for yi, v in zip(y, values):
        ax.annotate(f"{v:.1f}%", (v, yi), va="center", fontsize=8, xytext=(3, 0), textcoords="offset points")
    ax.set_xlim(0, max(values) * 1.2 if values else 1)
    ax.set_xlabel("share of the global sensitivity PG_i (%)", fontsize=9)
    ax.set_title("Largest global sensitivity indices (GSIL, Eq. 14-16), % of the total", fontsize=10)
    return png(fig)
