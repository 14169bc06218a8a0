"""PNG plots of the sensitivity analysis (matplotlib, Agg): pie charts of PL/PG (Fig. 10, 14), machining-error
maps on the cone's side surface (Fig. 12-13), contour maps of the average tool errors over A and B (Fig. 17-18).
Every file is written atomically (`fiveaxis.outputs`), so a failed run never leaves half a PNG.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path: Path) -> Path:
    """Write fig as a PNG atomically (`fiveaxis.outputs`), replacing an earlier plot of that name."""
    from ..outputs import write_with
    try:
        write_with(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight"), force=True)
    finally:
        _pyplot().close(fig)
    return Path(path)


def pie(names, proportions, path, title: str, top: int = 10) -> Path:
    """Pie chart of the proportions (Eq. 15-16): the `top` largest by name, the rest as 'others'."""
    plt = _pyplot()
    p = np.asarray(proportions, dtype=float)
    order = np.argsort(-p, kind="stable")
    keep = order[:top]
    sizes = list(p[keep]) + [float(p[order[top:]].sum())]
    labels = [f"{names[i]} {100 * p[i]:.1f}%" for i in keep] + [f"others {100 * sizes[-1]:.1f}%"]
    fig, ax = plt.subplots(figsize=(6.4, 6.4))
    ax.pie(sizes, labels=labels, startangle=90, counterclock=False, textprops={"fontsize": 8})
    ax.set_title(title)
    return _save(fig, path)


def cone_map(result: dict, path, title: str, vmax: float | None = None) -> Path:
    """Machining error |N . P_err| (mm) over azimuth and tool length (presets.cone_machining_error)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 3.6))
    m = ax.pcolormesh(result["phi_deg"], result["L_mm"], result["map"].T, shading="gouraud", vmin=0, vmax=vmax)
    fig.colorbar(m, ax=ax, label="machining error (mm)")
    ax.set_xlabel("azimuth on the cone (deg)")
    ax.set_ylabel("tool length L (mm)")
    ax.set_title(f"{title}\nmean {result['mean_mm']:.4f} mm")
    return _save(fig, path)


def ab_contour(A_deg, B_deg, values, path, title: str, label: str, levels=None) -> Path:
    """Contour map over the rotary axes A and B (values indexed [A, B])."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5.6, 4.6))
    cs = ax.contourf(B_deg, A_deg, values, levels=levels if levels is not None else 14)
    fig.colorbar(cs, ax=ax, label=label)
    ax.set_xlabel("B (deg)")
    ax.set_ylabel("A (deg)")
    ax.set_title(f"{title}\nmean {float(np.mean(values)):.4g}")
    return _save(fig, path)


def bars(rows, path, title: str, unit: str) -> Path:
    """Bar chart of a compensation experiment (Fig. 11, 16): the remaining error and the improvement."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 3.8))
    x = np.arange(len(rows))
    remain = [r.value for r in rows]
    gain = [r.improvement for r in rows]
    ax.bar(x, remain, label="remaining")
    ax.bar(x, gain, bottom=remain, label="improved", alpha=0.5)
    ax.set_xticks(x, [f"{i + 1}: {r.scenario}" for i, r in enumerate(rows)], fontsize=8)
    ax.set_ylabel(unit)
    ax.set_title(title)
    ax.legend()
    return _save(fig, path)
