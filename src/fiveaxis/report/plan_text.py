"""The text for people of a measurement plan and of a program's check, built from their records
(`fiveaxis.planning.plan.to_json`, `fiveaxis.planning.safety.CheckResult`): what the plan will determine and what
it cannot, before any measurement; the worst value of each limit of a program and where. um and urad for people.
"""
from __future__ import annotations

import math

import numpy as np

from ..planning.plan import PlanResult, to_json, worth
from ..planning.recommend import WORKSPACE_POSES, Recommendation
from ..planning.safety import MAX_LISTED, MIN_SAMPLES, SPARSE, STEP_DEG, STEP_MM, CheckResult
from ..units import human

#: The kinematics modes in words (the report).
KINEMATICS_TEXT = {"joint": "identity kinematics: the words are the machine file's axis positions",
                   "tcp": "TCP: the words are the tool tip in the workpiece frame and the rotary angles, as "
                          "xyzac/xyzbc-trt-kins"}


def _fmt_D(D: float, rank: int, r: int) -> str:
    return f"{D:.2f}" if math.isfinite(D) else f"not reached (rank {rank} of {r})"


def plan(res: PlanResult) -> str:
    """What the plan will determine and what it cannot, before any measurement; um and urad for people."""
    j = to_json(res)
    pred = res.predicted
    setups = list(j["setups"])
    lengths = ", ".join(f"{L:g}" for L in res.lengths)
    lines = [f"[[Plan]] {res.instrument} on {j['machine']}: {res.n} poses, {j['readings']} readings, "
             f"{len(setups)} setup(s), tool length(s) {lengths} mm, seed {res.seed}",
             f"    criterion:   D = {_fmt_D(res.D, res.rank, res.r)}: log det of the information about the {res.r} "
             f"directions {res.instrument} data can determine (noise {res.design.ref.noise_mm * 1000:g} um"
             + (f", {res.design.ref.noise_rad * 1e6:g} urad" if res.plan.reads == "tip+axis" else "")
             + "; docs/plan.md)",
             f"    chosen from: {j['candidates']} candidates (greedy D-optimal selection, then "
             f"{res.passes} exchange pass(es))",
             f"    program:     {res.kinematics} kinematics ({KINEMATICS_TEXT[res.kinematics]}; docs/plan.md); "
             f"every pose and move keeps {res.strokes.text()} from the ends of the strokes"]
    if res.random_D:
        lines.insert(2, f"    random plan: D = {_fmt_D(res.random_median, min(res.random_rank), res.r)} for "
                        f"{res.n} random poses (median of {len(res.random_D)})"
                     + (f"; random plans would need about {worth(res):.0f} poses to match this one" if worth(res)
                        else ""))
    for note in res.notes:
        lines.append(f"    note:        {note}")
    if res.effect_std:
        lines.append("[[Effects to detect]]  predicted standard uncertainty of the change at the end of the stroke: "
                     "this plan / a random plan of the same size")
        for nm, v in res.effect_std.items():
            txt = [("not determined" if x is None else human(x, v["unit"])) for x in (v["plan"], v["random"])]
            lines.append(f"    {nm:14s} {txt[0]} / {txt[1]}")
    coefs = {nm for e in res.effects for nm in e.names}
    items = [f"{nm} {human(v['std'], v['unit'])}" for nm, v in pred["determined"].items()
             if not nm.endswith("]") and nm not in coefs]
    lines.append(f"[[Determined by this plan]]  {len(items)} machine errors alone; predicted standard uncertainty "
                 f"(k = 1)")
    for i in range(0, len(items), 4):
        lines.append("    " + ";  ".join(items[i:i + 4]))
    if pred["combinations"]:
        lines.append("[[Combinations determined (members not determined alone)]]  predicted standard uncertainty")
        for c in pred["combinations"]:
            unit = c["unit"] if c["unit"] in ("mm", "rad") else ""
            lines.append(f"    {c['formula']}  +- {human(c['std'], unit) if unit else format(c['std'], '.2g')}")
    if pred["unidentifiable"]:
        lines.append("[[Not determined by this plan]]")
        unseen = set(pred["unseen"])
        if unseen:
            lines.append(f"    not seen at all: {', '.join(n for n in pred['unseen'])}")
        for g in pred["unidentifiable"]:
            rest = [n for n in g if n not in unseen]
            if rest:
                lines.append(f"    {', '.join(rest)}")
    if setups:
        lines.append("[[Setups]]  unknowns estimated with the machine's errors")
        for s in setups:
            count = int(np.sum(res.plan.setup == s))
            lines.append(f"    {s} ({count} poses): {j['setups'][s]}")
    return "\n".join(lines)


def check(res: CheckResult) -> str:
    """The check for people: the kinematics assumed, the worst value of each limit and where, the strokes, the
    setup changes, the measuring poses, the verdict."""
    out = [f"[[Check]] {res.path}: {res.instrument} on {res.machine}, {res.kinematics} kinematics (from "
           f"{res.kinematics_source}); {res.moves} moves sampled at {res.samples} points (every {STEP_MM:g} mm / "
           f"{STEP_DEG:g} deg, {SPARSE * STEP_MM:g} mm / {SPARSE * STEP_DEG:g} deg with nothing mounted, at least "
           f"{MIN_SAMPLES} per move) on the nominal chain"]
    for w in res.worst:
        lim = w.limit
        rel = "at most" if lim.bound == "max" else "at least"
        if w.value is None:
            out.append(f"    {lim.name}: no sample applies (limit: {rel} {lim.limit:g} {lim.unit})")
        else:
            out.append(f"    {lim.name}: worst {w.value:.4g} {lim.unit} at line {w.line} (limit: {rel} "
                       f"{lim.limit:g} {lim.unit}){'' if w.ok else f'  EXCEEDED in {w.violations} move(s)'}")
    margins = f"{res.margin_mm:g} mm, {res.margin_deg:g} deg"
    if res.stroke_excess > 1e-6:
        out.append(f"    strokes: {res.stroke_violations} move(s) outside; worst {res.stroke_axis} "
                   f"{res.stroke_excess:.4g} {res.stroke_unit} beyond its stroke at line {res.stroke_line}")
    elif res.margin_violations:
        out.append(f"    strokes: {res.margin_violations} move(s) within the margins ({margins}) of a stroke end; "
                   f"smallest margin {max(0.0, -res.stroke_excess):.4g} {res.stroke_unit} ({res.stroke_axis}, line "
                   f"{res.stroke_line})")
    else:
        out.append(f"    strokes: every sample at least the margins ({margins}) from the ends; smallest margin "
                   f"{max(0.0, -res.stroke_excess):.4g} {res.stroke_unit} ({res.stroke_axis}, line "
                   f"{res.stroke_line})")
    if res.start_lines:
        out.append(f"    start: line(s) {', '.join(map(str, res.start_lines))} from wherever the machine is (not "
                   f"sampled: not every axis word given yet), the first `{res.start_first}`")
    for r in res.retracts:
        out.append(f"    exit retract at line {r['line']}: {r.get('measured', 0.0):.4g} mm along the tool axis "
                   f"(stated {r['stated']:g} mm)")
    out.append(f"    setup changes: {res.setup_changes} (tool, mount, unmount)")
    pc = res.pose_check
    if pc is not None:
        if "max_line_offset_mm" in pc:              # probed: the plan's poses are the sphere centres
            out.append(f"    measuring poses: {pc['marked']} of {pc['poses']} marked; probing lines within "
                       f"{pc['max_line_offset_mm']:.2g} mm of the planned sphere centres, rotary axes within "
                       f"{pc['max_rotary_deg']:.2g} deg of the plan")
        else:
            out.append(f"    measuring poses: {pc['marked']} of {pc['poses']} marked; largest difference from the "
                       f"plan {pc['max_linear_mm']:.2g} mm, {pc['max_rotary_deg']:.2g} deg")
        if pc["missing"]:
            out.append(f"    not measured: pose(s) {', '.join(map(str, pc['missing']))}")
    for ln, text in res.problems[:MAX_LISTED]:
        out.append(f"    line {ln}: {text}")
    out.append("    verdict: " + ("every move keeps the instrument within its limits and the axes within their "
                                  "strokes" if res.ok else "REFUSED"))
    return "\n".join(out)


def recommendation(r: Recommendation, tool_length: float) -> str:
    """Which instrument next: what each one's typical plan would leave of the tool tip's uncertainty over the
    workspace (um, k = 2)."""
    counts = {}
    for _, src in r.prior.values():
        key = src.split(" (")[0]
        counts[key] = counts.get(key, 0) + 1
    sources = [f"{'its ISO 230 class size' if k == 'class' else k} for {n} error(s)" for k, n in counts.items()]
    out = [f"[[Next instrument]] on {r.machine}, from {r.source}: the tool tip's uncertainty over the workspace a plan "
           f"of each instrument would leave (k = 2, RMS over {WORKSPACE_POSES} random poses at L = {tool_length:g} mm; "
           f"the machine's constant errors, each with the estimator's prior: {', '.join(sources)})",
           f"    before: {r.before_um:.4g} um"]
    best = r.best
    for o in r.options:
        if not o.n:
            out.append(f"    {o.instrument:15s} no plan: {o.note}")
            continue
        out.append(f"    {o.instrument:15s} {o.n} poses, determines {o.directions} direction(s): leaves "
                   f"{o.after_um:.4g} um" + ("   <- recommended" if o is best else ""))
    return "\n".join(out)

