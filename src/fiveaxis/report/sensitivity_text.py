"""The sensitivity commands' text (gsa, lsa, sobol, dask), built from their JSON records: `SensitivityResult.to_json`
({indices, ranking, settings}) with what the commands add to it (compensation, segments), and the Sobol' record.
Proportions in %, errors in mm and rad as the records hold them. Each function returns the lines of one block.
"""
from __future__ import annotations

import numpy as np


def ranking(rec: dict, iso: dict, top: int, title: str) -> list[str]:
    """The largest proportions of a sensitivity record with each error's ISO 230 name (iso: {error: name or None})."""
    p = rec["indices"]
    lines = [title, f"{'rank':>4}  {'error':<6} {'ISO 230':<9} {'proportion':>10}"]
    prev = None
    for r, name in enumerate(rec["ranking"][:top], 1):
        v = p[name]
        tie = "  (tied: same J)" if prev is not None and abs(v - prev) <= 1e-12 * max(abs(v), 1e-300) else ""
        lines.append(f"{r:>4}  {name:<6} {iso.get(name) or '-':<9} {100 * v:>9.2f}%{tie}")
        prev = v
    return lines


def settings(s: dict) -> list[str]:
    """The settings of a run: machine, tool lengths, quadrature, poses; the workspace where it has one."""
    q = s["quadrature"]
    rule = "exact integral over L" if q["order"] == "exact" else f"Gauss-Legendre order {q['order']}"
    line = (f"settings: {s['machine']} ({s['convention']} convention), L0 {s['L0_mm']:g} mm, LE {s['LE_mm']:.4g} mm, "
            f"{rule}")
    if "max_abs_change_of_proportion" in q:
        line += (f" (vs Gauss-Legendre order {q['check_order']}: largest change of a proportion "
                 f"{q['max_abs_change_of_proportion']:.1e})")
    left = (f"{s['skipped_poses']} poses" if "skipped_poses" in s else f"{s['skipped_nodes']} nodes")
    line += f", {s['poses']} poses, {left} left out (|P_err| ~ 0)"
    return [line] + ([f"workspace: {s['workspace']}"] if "workspace" in s else [])


def error_notes(s: dict) -> list[str]:
    """What became of a fitted model's values (settings' errors_undetermined_kept, errors_left_out_parameters)."""
    lines = []
    kept, left = s.get("errors_undetermined_kept"), s.get("errors_left_out_parameters")
    if kept:
        lines.append(f"errors: {len(kept)} undetermined in the fitted model keep the machine file's values: "
                     f"{', '.join(kept)}")
    if left:
        lines.append(f"errors: fitted parameters that are not geometric errors are left out: {', '.join(left)}")
    return lines


def compensation(rows: list[dict], title: str, unit: str, paper: dict | None = None) -> list[str]:
    """A compensation experiment's rows ({scenario, value, improvement, improvement_pct}; value in `unit`), with
    the paper's figures beside them when given."""
    lines = [title, f"  {'':2}{'scenario':<15} {unit:>12} {'improvement':>12} {'%':>6}"]
    for i, r in enumerate(rows, 1):
        lines.append(f"  {i:<2}{r['scenario']:<15} {r['value']:>12.5g} {r['improvement']:>12.5g} "
                     f"{r['improvement_pct']:>6.1f}")
    if paper:
        lines.append("  paper: " + ", ".join(f"{k} {v}" for k, v in paper.items()))
    return lines


def segments(segs: list[dict], shown: int) -> list[str]:
    """The three largest PL_i of `shown` segments spread evenly over a path (the record's `segments`)."""
    picked = range(len(segs)) if len(segs) <= shown else \
        sorted(set(np.linspace(0, len(segs) - 1, shown).round().astype(int).tolist()))
    every = "each of" if len(picked) == len(segs) else f"{len(picked)} evenly spread of"
    lines = [f"per segment (which errors matter where): the three largest PL_i of {every} {len(segs)} segments"]
    for s in (segs[i] for i in picked):
        if s["indices"] is None:
            top = "all indices zero"
        else:
            top = ", ".join(f"{n} {100 * s['indices'][n]:.1f}%" for n in s["ranking"][:3])
        span = f"poses {s['first_pose'] + 1}-{s['last_pose'] + 1}"
        lines.append(f"  {s['label']:<14} {span:<16} {top}")
    if len(picked) < len(segs):
        lines.append(f"  ({len(segs) - len(picked)} more segments in --json; --segments N lists N of them)")
    return lines


def sobol(rec: dict, gsil: dict, top: int) -> list[str]:
    """Sobol' total indices (the sobol record: indices, ST_conf, ranking, settings, comparison) beside the GSIL
    record of the same workspace."""
    s = rec["settings"]
    rank_g = {n: i + 1 for i, n in enumerate(gsil["ranking"])}
    lines = [f"Sobol' total indices of mean |P_err| over the workspace ({s['evaluations']} evaluations), "
             f"with the GSIL rank",
             f"{'rank':>4}  {'error':<6} {'S_T':>7} {'+-95%':>7}   {'PG_i':>7} {'GSIL rank':>9}"]
    for r, n in enumerate(rec["ranking"][:top], 1):
        lines.append(f"{r:>4}  {n:<6} {rec['indices'][n]:>7.3f} {rec['ST_conf'][n]:>7.3f}   "
                     f"{100 * gsil['indices'][n]:>6.2f}% {rank_g[n]:>9}")
    cmp = rec["comparison"]
    lines.append(f"Spearman rank correlation of S_T and GSIL: {cmp['spearman']:.3f}; top 4 in common: "
                 f"{', '.join(cmp['top4_common'])}")
    lines.append(f"workspace: {s['workspace']}")
    return lines


def dask(s: dict) -> list[str]:
    """How a Dask run went (settings' dask, evaluated_poses, reduced_factor, seconds)."""
    d = s["dask"]
    return [f"dask: {d['workers']} workers, {d['threads']} threads, {d['tasks']} tasks of {d['chunk']} poses, "
            f"{s['evaluated_poses']} poses evaluated (x{s['reduced_factor']}), {s['seconds']} s; peak memory of "
            f"the workers {d['worker_peak_rss_mb']} MB"]
