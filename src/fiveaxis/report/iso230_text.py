"""The ISO 230 evaluations as text, built from their JSON records: ISO 230-2 positioning
(`fiveaxis.iso230.positioning.to_json`) in the layout of the standard's table, ISO 230-4 circles with the ballbar's
diagnostic list (`fiveaxis.iso230.circular.to_json`). um in the text, as in the records; the records stay the one
source of every number printed (the text only adds the table rows the standard prints: 2 s_i, mean +- 2 s_i).
"""
from __future__ import annotations

import numpy as np

#: ISO 230-2: the approach directions of the record's per-target arrays.
DIRECTIONS = ("fwd", "bwd")

#: ISO 230-2 axis figures: (label, record key without _um, meaning), in the order a laser's report prints them.
AXIS_FIGURES = (("E fwd", "E_fwd", "unidirectional systematic positional deviation, forward"),
                ("E bwd", "E_bwd", "unidirectional systematic positional deviation, backward"),
                ("E", "E", "bidirectional systematic positional deviation"),
                ("M", "M", "mean bidirectional systematic positional deviation"),
                ("B", "B", "reversal value (largest |B_i|)"),
                ("B mean", "B_mean", "mean reversal value"),
                ("R fwd", "R_fwd", "unidirectional repeatability, forward"),
                ("R bwd", "R_bwd", "unidirectional repeatability, backward"),
                ("R", "R", "bidirectional repeatability"),
                ("A fwd", "A_fwd", "unidirectional accuracy, forward"),
                ("A bwd", "A_bwd", "unidirectional accuracy, backward"),
                ("A", "A", "bidirectional accuracy"))


#: The figures the slope changes (B and R do not: the line is removed from both directions alike).
SLOPE_FIGURES = ("E_fwd", "E_bwd", "E", "M", "A_fwd", "A_bwd", "A")


def _cells(values, width=8, digits=1) -> list[str]:
    return [f"{v:{width}.{digits}f}" if v is not None else " " * (width - 1) + "-" for v in values]


def target_rows(rec: dict) -> dict:
    """The per-target rows of the standard's table from a positioning record (um): {name: (fwd, bwd) arrays} for
    the unidirectional rows and {name: array} for the bidirectional ones, in the table's order."""
    um = {k: np.asarray(rec[f"{k}_um"]) for k in ("mean_fwd", "mean_bwd", "s_fwd", "s_bwd", "R_i_fwd", "R_i_bwd",
                                                    "B_i", "mean_bidirectional", "R_i")}
    return {"mean x_i": ((um["mean_fwd"], um["mean_bwd"]), 1),
            "s_i": ((um["s_fwd"], um["s_bwd"]), 2),
            "2 s_i": ((2 * um["s_fwd"], 2 * um["s_bwd"]), 2),
            "mean x_i + 2 s_i": ((um["mean_fwd"] + 2 * um["s_fwd"], um["mean_bwd"] + 2 * um["s_bwd"]), 1),
            "mean x_i - 2 s_i": ((um["mean_fwd"] - 2 * um["s_fwd"], um["mean_bwd"] - 2 * um["s_bwd"]), 1),
            "R_i = 4 s_i": ((um["R_i_fwd"], um["R_i_bwd"]), 1),
            "B_i": (um["B_i"], 1),
            "mean x_i bidirectional": (um["mean_bidirectional"], 1),
            "R_i bidirectional": (um["R_i"], 1)}


def positioning(rec: dict, per_block: int = 5) -> str:
    """An ISO 230-2 record as text in the layout of the standard's table (targets across, each with its forward and
    backward column; blocks of `per_block` targets), then the axis figures (um) with their expanded uncertainty."""
    targets = rec["targets_mm"]
    m = len(targets)
    head = f"ISO 230-2:2014 positioning of {rec['axis']}" + (f" (setup {rec['setup']})" if rec["setup"] else "") + \
        f": {rec['file']}, {m} targets over {rec['measured_length_mm']:g} mm, {rec['cycles']} cycles, both " \
        f"directions (um)"
    lines = [head]
    x = rec["readings_um"]
    ncyc = max(len(a) for dname in DIRECTIONS for a in x[dname])
    rows = target_rows(rec)
    label_w = 22
    for start in range(0, m, per_block):
        ks = range(start, min(m, start + per_block))

        def row(name, vals_f, vals_b, digits=1):
            cells = []
            for k in ks:
                cells += _cells([vals_f[k], vals_b[k]], 8, digits)
            return f"  {name:{label_w}s}" + " ".join(cells)

        def row_bi(name, vals, digits=1):
            cells = []
            for k in ks:
                cells += _cells([vals[k]], 17, digits)
            return f"  {name:{label_w}s}" + " ".join(cells)
        lines.append("")
        lines.append(f"  {'target position i':{label_w}s}" + " ".join(f"{k + 1:>17d}" for k in ks))
        lines.append(f"  {'P_i (mm)':{label_w}s}" + " ".join(f"{targets[k]:17.3f}" for k in ks))
        lines.append(f"  {'approach direction':{label_w}s}" + " ".join(f"{'fwd':>8s} {'bwd':>8s}" for _ in ks))
        for j in range(ncyc):
            vf = [x["fwd"][k][j] if j < len(x["fwd"][k]) else None for k in range(m)]
            vb = [x["bwd"][k][j] if j < len(x["bwd"][k]) else None for k in range(m)]
            lines.append(row(f"x_i{j + 1} (cycle {j + 1})", vf, vb))
        for name, (vals, digits) in rows.items():
            lines.append(row(name, *vals, digits) if isinstance(vals, tuple) else row_bi(name, vals, digits))
    uncertainty = rec.get("uncertainty")
    U = (uncertainty or {}).get("U_um", {})

    def fig(name, key, what):
        u = U.get(key)
        tail = f"U (k=2) {u:6.2f}" if u is not None else ""
        return f"  {name:9s} {rec[f'{key}_um']:9.2f}   {tail:14s}   {what}"
    lines += ["", "  axis figures (um)"]
    lines += [fig(*f) for f in AXIS_FIGURES]
    if uncertainty is not None:
        lines.append(f"  uncertainty: {uncertainty['statement']}")
    flat = rec.get("slope_removed")
    if flat:
        lines += ["", f"  with the slope removed (not ISO 230-2's figures): slope {flat['slope_um_per_m']:.4g} um/m, "
                      f"{flat['line']} (um)",
                  f"  {'P_i (mm)':22s}" + " ".join(f"{p:9.3f}" for p in targets),
                  f"  {'mean bidirectional':22s}" + " ".join(f"{v:9.2f}" for v in flat["mean_bidirectional_um"])]
        lines += [f"  {name:9s} {flat[f'{key}_um']:9.2f}   {'':14s}   {what}, slope removed"
                  for name, key, what in AXIS_FIGURES if key in SLOPE_FIGURES]
    for note in rec["notes"]:
        lines.append(f"  note: {note}")
    return "\n".join(lines)


def circles(record: dict) -> str:
    """An ISO 230-4 record (circles, and the ballbar's diagnostic list when it has one) as text, um."""
    lines = []
    for c in record["circles"]:
        feed = f", feed {c['feed_mm_per_min']:g} mm/min" if "feed_mm_per_min" in c else ""
        lines.append(f"ISO 230-4 circle {c['plane']} ({'+'.join(c['axes'])})"
                     + (f", setup {c['setup']}" if c["setup"] not in (None, c["plane"]) else "")
                     + f": radius {c['radius_mm']:.3f} mm, pivot {np.round(c['centre_mm'], 3).tolist()} mm{feed}")
        lines.append(f"  {'direction':10s} {'points':>6s} {'arc':>6s} {'G (LSQ)':>9s} {'G (MZ)':>9s} {'F max':>9s} "
                     f"{'F min':>9s}   centre offset (um)")
        for r in c["runs"]:
            lines.append(f"  {r['direction']:10s} {r['points']:6d} {r['arc_deg']:5.0f}d {r['G_um']:9.2f} "
                         f"{r['G_mz_um']:9.2f} {r['F_max_um']:9.2f} {r['F_min_um']:9.2f}   "
                         f"{r['centre_offset_um'][0]:+.2f}, {r['centre_offset_um'][1]:+.2f}")
        if "H_um" in c:
            lines.append(f"  circular hysteresis H ({' / '.join(c['H_pair'])}): {c['H_um']:.2f} um")
        for n in c["notes"]:
            lines.append(f"  note: {n}")
    diag = record.get("diagnostics")
    if diag:
        lines.append("Ballbar diagnosis (from the fit and diagnosis of all circles; size with its standard "
                     "uncertainty; * = accepted by the diagnosis' decision)")
        for w in diag["warnings"]:
            lines.append(f"  warning: {w}")
        for d in diag["items"]:
            size = "-" if "size" not in d else f"{d['size']:.3g} +- {d['std']:.2g} {d['unit']}"
            star = "*" if d.get("found") else " "
            lines.append(f"  {star} {d['term']:28s} {size:24s} {d['effect']}"
                         + (f" ({d['iso']})" if d.get("iso") else "") + (f": {d['note']}" if d.get("note") else ""))
    return "\n".join(lines)
