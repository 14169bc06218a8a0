"""PNG plots of the sensitivity analysis (matplotlib, Agg): pie charts of PL/PG (Fig. 10, 14), machining-error
maps on the cone's side surface (Fig. 12-13), contour maps of the average tool errors over two rotary axes
(Fig. 17-18), bar charts of the compensation experiments (Fig. 11, 16), and the share of the largest errors
along a toolpath.
Every file is written atomically (`fiveaxis.outputs`: a failed run never leaves half a PNG), with the permissions
of a new file under the umask (world-readable by default), and every function returns its path.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from ..outputs import write_with


#: Colours of the slices and bands: tab20 has 20 distinct colours, enough for the top 10 and more; "others"
#: is always grey, so it never takes the colour of a named error.
OTHERS_COLOUR = "#b0b0b0"


def _pyplot():
    import matplotlib   # optional heavy dependency: only where a figure is asked for
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt   # (as above)
    return plt


def _colours(n: int):
    plt = _pyplot()
    cmap = plt.get_cmap("tab20")
    order = list(range(0, 20, 2)) + list(range(1, 20, 2))     # the strong colours first, then the light ones
    return [cmap(order[i % 20]) for i in range(n)]


def _save(fig, path: Path) -> Path:
    """Write fig as a PNG atomically (`fiveaxis.outputs`), replacing an earlier plot of that name."""
    try:
        write_with(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight", pad_inches=0.25),
                   force=True, follow_links=False)
    finally:
        _pyplot().close(fig)
    return Path(path)


def pie(names, proportions, path, title: str, top: int = 10) -> Path:
    """Pie chart of the proportions (Eq. 15-16): the `top` largest by name, the rest as 'others' (grey)."""
    plt = _pyplot()
    p = np.asarray(proportions, dtype=float)
    order = np.argsort(-p, kind="stable")
    keep = order[:top]
    rest = float(p[order[top:]].sum())
    sizes = list(p[keep])
    labels = [f"{names[i]} {100 * p[i]:.1f}%" for i in keep]
    colours = _colours(len(keep))
    if rest > 0:
        sizes.append(rest)
        labels.append(f"others ({len(order) - top}) {100 * rest:.1f}%")
        colours.append(OTHERS_COLOUR)
    fig, ax = plt.subplots(figsize=(8.6, 6.0))
    wedges, _ = ax.pie(sizes, colors=colours, startangle=90, counterclock=False,
                       wedgeprops={"linewidth": 0.8, "edgecolor": "white"})
    ax.legend(wedges, labels, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=9, frameon=False,
              title="error: share of the sum", alignment="left")
    ax.set_title(title, fontsize=10)
    ax.set_aspect("equal")
    return _save(fig, path)


def cone_map(result: dict, path, title: str, vmax: float | None = None) -> Path:
    """Machining error |N . P_err| (mm) over azimuth and tool length (presets.cone_machining_error)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.4, 3.8))
    m = ax.pcolormesh(result["phi_deg"], result["L_mm"], result["map"].T, shading="gouraud", vmin=0, vmax=vmax)
    fig.colorbar(m, ax=ax, label="machining error |N . P_err| (mm)")
    ax.set_xlabel("azimuth on the cone (deg)")
    ax.set_ylabel("tool length L (mm)")
    ax.set_title(f"{title}\nmean {result['mean_mm']:.4f} mm", fontsize=10)
    return _save(fig, path)


def ab_contour(first_deg, second_deg, values, path, title: str, label: str, levels=None,
               axes: tuple[str, str] = ("A", "B")) -> Path:
    """Contour map over two rotary axes (values indexed [first, second]; the second on the x axis)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    cs = ax.contourf(second_deg, first_deg, values, levels=levels if levels is not None else 14)
    fig.colorbar(cs, ax=ax, label=label)
    ax.set_xlabel(f"{axes[1]} (deg)")
    ax.set_ylabel(f"{axes[0]} (deg)")
    ax.set_title(f"{title}\nmean {float(np.mean(values)):.4g}", fontsize=10)
    return _save(fig, path)


def bars(rows, path, title: str, quantity: str) -> Path:
    """Bar chart of a compensation experiment (Fig. 11, 16): the error left in each scenario, the part removed
    (where compensation helps) on top, the uncompensated level as a dashed line, the change in % above each bar;
    quantity: the y label with its unit."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.8, 4.4))
    x = np.arange(len(rows))
    value = np.array([r.value for r in rows])
    gain = np.array([max(r.improvement, 0.0) for r in rows])
    ref = rows[0].value
    c = _colours(2)
    ax.bar(x, value, color=c[0], label="error left")
    ax.bar(x, gain, bottom=value, color=c[1], alpha=0.55, label="removed by halving")
    ax.axhline(ref, color="0.3", linestyle="--", linewidth=0.8, label="no compensation")
    top = float(max(ref, value.max()))
    for xi, r in zip(x, rows):
        if r.scenario != "none":
            ax.annotate(f"{-r.improvement_pct:+.1f}%", (xi, max(ref, r.value)), xytext=(0, 3),
                        textcoords="offset points", ha="center", fontsize=8)
    ax.set_xticks(x, [f"{i + 1}: {r.scenario}" for i, r in enumerate(rows)], fontsize=9)
    ax.set_ylabel(quantity)
    ax.set_ylim(0, 1.15 * top)
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    return _save(fig, path)


def path_shares(names, per_pose, segment, path, title: str, top: int = 6) -> Path:
    """Stacked shares W_i / sum_j W_j of the `top` errors of the whole path (and the others, grey) at every pose
    along a toolpath; segment boundaries as thin vertical lines."""
    plt = _pyplot()
    W = np.asarray(per_pose, dtype=float)
    total = W.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(total[:, None] > 0, W / total[:, None], np.nan)
    mean = W.mean(axis=0)
    order = np.argsort(-mean, kind="stable")[:top]
    bands = [share[:, i] for i in order]
    rest = 1.0 - np.nansum(np.column_stack(bands), axis=1) if len(bands) else np.ones(len(W))
    rest = np.where(np.isnan(share[:, 0]), np.nan, rest)
    x = np.arange(1, len(W) + 1)
    fig, ax = plt.subplots(figsize=(9.0, 4.2))
    colours = _colours(len(order)) + [OTHERS_COLOUR]
    labels = [names[i] for i in order] + ["others"]
    if len(W) == 1:
        bottom = 0.0
        for b, c, lab in zip(bands + [rest], colours, labels):
            ax.bar(x, 100 * b, bottom=bottom, color=c, label=lab, width=0.6)
            bottom = bottom + 100 * b
    else:
        ax.stackplot(x, *[100 * b for b in bands + [rest]], colors=colours, labels=labels)
    seg = np.asarray(segment)
    starts = np.flatnonzero(np.diff(seg)) + 1.5
    if 0 < len(starts) <= 25:                      # more would hide the bands
        for s in starts:
            ax.axvline(s, color="white", linewidth=0.5, alpha=0.8)
    ax.set_xlim(x[0] - 0.5, x[-1] + 0.5)
    ax.set_ylim(0, 100)
    ax.set_xlabel(f"pose along the path (1-{len(W)}; {len(np.unique(seg))} segments)")
    ax.set_ylabel("share of the pose's W_i (%)")
    ax.set_title(title, fontsize=10)
    handles, labs = ax.get_legend_handles_labels()
    ax.legend(handles[::-1], labs[::-1], loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8,
              frameon=False, title="error")
    return _save(fig, path)
