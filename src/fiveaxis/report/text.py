"""Text for people, built from the JSON records of the estimators: the fit (`fiveaxis.estimation.result.to_json`)
and the diagnosis (`fiveaxis.diagnosis.diagnose.Diagnosis.to_json`). Values in um and urad, expanded uncertainties
(k = 2), in the manner of lmfit's fit_report; the records stay the one source of every number printed.
"""
from __future__ import annotations

import math

from ..compensation.prediction import STAGE_LABELS
from ..diagnosis import residual_tests as st
from ..effects import families as fx
from ..effects.families import TIME
from ..estimation.result import PLAUSIBLE, STRONG_CORRELATION, plausible
from ..units import human

#: More outliers than this fraction of the readings are suspicious: said so in the report.
OUTLIER_MANY = 0.01


def fit(j: dict) -> str:
    """A fit's record (`fiveaxis.estimation.result.to_json`) for people: um and urad, expanded uncertainty (k = 2)."""
    readings = ", ".join(f"{v} {k}" for k, v in j["readings"].items())
    lines = ["[[Fit]]",
             f"    file:            {j['file']} ({j['frame']} frame)",
             f"    poses:           {j['n']} ({readings} readings)",
             f"    parameters:      {j['n_parameters']} fitted, determined by this data: rank {j['rank']}"
             + (f"; held fixed: {', '.join(j['fixed'])}" if j["fixed"] else ""),
             f"    condition:       {j['condition']:.4g} (design with unit-norm columns)",
             f"    residual RMS:    {j['rms_mm_without_outliers'] * 1000:.4g} um "
             + (f"(exact model; first order {j['rms_first_order_mm'] * 1000:.4g} um, {j['iterations']} Gauss-Newton "
                f"steps)" if j["residual_model"] == "exact" else "(first-order model)")
             + (f"; tool axis {j['rms_rad'] * 1e6:.4g} urad" if "rms_rad" in j else "")
             + (f"; {j['rms_mm'] * 1000:.4g} um with the outliers" if j["outliers"] else "")]
    if j.get("note"):
        lines.append(f"    note:            {j['note']}")
    res = j.get("resolution")
    if res and (res["directions_below"] or res["columns_not_seen"]):
        lines.append(f"    resolution:      {res['directions_below']} direction(s) and {res['columns_not_seen']} "
                     f"parameter(s) within what the resolution of the poses can create: not determined (rule: "
                     f"{res['rule']})")
    lines += outlier_lines(j)
    if j["sigma"] == "sigma column":
        lines.append(f"    reduced chi2:    {j['reduced_chi2']:.4g} (weights from the sigma column)")
        if j["uncertainty_scale"] > 1:
            lines.append(f"    uncertainties:   scaled by sqrt(reduced chi2) = {j['uncertainty_scale']:.3g}: the fit is "
                         f"worse than the sigma column says")
    else:
        noise = []
        if "noise_mm" in j:
            noise.append(f"{j['noise_mm'] * 1000:.4g} um")
        if "noise_rad" in j:
            noise.append(f"{j['noise_rad'] * 1e6:.4g} urad (tool axis)")
        lines.append(f"    noise estimate:  {', '.join(noise)} (no sigma column: from the residual)")
    if j["effects"]:
        lines.append(f"    added effects:   {', '.join(j['effects'])}")
    for f in j.get("files", []):
        noise = ", ".join(human(f[k], u) for k, u in (("noise_mm", "mm"), ("noise_rad", "rad")) if k in f)
        rms = ", ".join(human(f[k], u) for k, u in (("rms_mm", "mm"), ("rms_rad", "rad")) if k in f)
        lines.append(f"    file:            {f['file']}: {f['n']} poses, {f['readings']} readings, residual RMS "
                     f"{rms}, noise {noise} ({f['sigma']})")
    lines += _prior_line(j)
    lines += _determined_lines(j)
    lines += _combination_lines(j)
    lines += profile_lines(j)
    held = [(n, p) for n, p in j["parameters"].items() if p.get("fixed")]
    if held:
        lines.append("[[Held fixed]]  (--fix or the machine file's [fit] fixed: not fitted)")
        for name, p in held:
            lines.append(f"    {_shown(name, p):18s} {human(p['value'], p['unit'])} (held)")
    if j["setups"]:
        lines.append("[[Setups: placement of the artefacts (not machine errors)]]  value +- expanded uncertainty "
                     "(k = 2)")
        for s in j["setups"]:
            vals = []
            for nm, p in s["parameters"].items():
                short = nm.split("[")[0]
                if not p["determined"]:
                    vals.append(f"{short} not determined alone")
                elif p.get("fixed"):
                    vals.append(f"{short} {human(p['value'], p['unit'])} (fixed)")
                else:
                    vals.append(f"{short} {human(p['value'], p['unit'])} +- {human(p['expanded_k2'], p['unit'])}")
            unseen = f"; not seen by its readings: {', '.join(n.split('[')[0] for n in s['not_seen_by_the_readings'])}" \
                if s["not_seen_by_the_readings"] else ""
            lines.append(f"    {s['id']} ({s['kind']}, {s['frame']} frame, {s['readings']} readings): "
                         f"{'; '.join(vals)}{unseen}")
            if "placement" in s and s["kind"] != "point":
                lines.append(f"        {s['id']} {s['placement']}")
    for g in j.get("not_separable", []):
        names = ", ".join(f"{n} ({i})" if i else n for n, i in zip(g["members"], g["members_iso"]))
        lines.append(f"[[Not separable from the placement of {', '.join(g['setups'])} by this data]]  {names}: the "
                     f"data see them only together with where the artefacts lay; their values are the prior's "
                     f"(below)")
    lines += _prior_decided_lines(j)
    placements = sum(1 for c in j["combinations"] if "[" in next(iter(c["terms"])))
    if j["unidentifiable"] or placements:
        count = sum(len(g) for g in j["unidentifiable"])
        lines.append(f"[[Not determined alone by this data]] {count} parameter(s) in {len(j['unidentifiable'])} "
                     f"group(s)" + (f"; {placements} combination(s) of the artefacts' placements" if placements
                                    else "")
                     + " (JSON: unidentifiable, combinations with their formulas; `fiveaxis report` says which "
                       "extra measurement would separate them)")
    if j["correlations"]:
        lines.append(f"[[Strong correlations (|r| >= {STRONG_CORRELATION})]]")
        for c in j["correlations"]:
            lines.append(f"    C({c['a']}, {c['b']}) = {c['r']:+.4f}")
    return "\n".join(lines)


def _shown(name: str, p: dict) -> str:
    return f"{name} ({p['iso']})" if p.get("iso") else name


def _value(value: float, std_k2: float, unit: str) -> str:
    """'12.3 um +- 0.4 um' (um, urad), or for a value beyond what a machine's error can be the words that say so
    (`fiveaxis.estimation.result.PLAUSIBLE`)."""
    return f"{human(value, unit)} +- {human(std_k2, unit)}"


IMPLAUSIBLE = (f"beyond {PLAUSIBLE['mm']:g} mm / {PLAUSIBLE['rad'] * 1e6:,.0f} urad: not an error of a machine tool "
               f"(check the file's units, its frame, and the model)")


def _prior_line(j: dict) -> list[str]:
    pr = j.get("prior") or {}
    if not pr:
        return []
    if not pr.get("used"):
        return [f"    prior:           none ({pr.get('note', '')})"]
    src = ", ".join(f"{k} {v}" for k, v in pr["sources"].items())
    d = pr["decided_by"]
    out = [f"    prior:           every error 0 +- the size of its ISO 230 class unless given ({src}); decided by "
           f"the data {d['data']}, by data and prior {d['data and prior']}, by the prior {d['prior']}"]
    if pr.get("conflicts"):
        worst = ", ".join(f"{c['name']} ({c['z']:+.0f})" for c in pr["conflicts"][:5])
        out.append(f"    warning:         {len(pr['conflicts'])} value(s) more than 5 prior sizes from their prior: "
                   f"{worst}; the prior is too tight for this machine (where the data see them weakly it pulls "
                   f"them): give a wider one (--prior CLASS=SIZE) or --prior none")
    return out


def _determined_lines(j: dict) -> list[str]:
    """The parameters the data determine alone, then the combinations that are one parameter but for dust."""
    rows = []
    for name, p in j["parameters"].items():
        if not p["determined"] or p.get("fixed") or p.get("data_share", 1.0) < 0.5:
            continue
        if p.get("plausible") is False:
            rows.append(f"    {_shown(name, p):18s} {IMPLAUSIBLE}")
            continue
        share = p.get("data_share", 1.0)
        note = "" if share >= 0.9 else f" (data {share:.0%}, prior {1 - share:.0%})"
        rows.append(f"    {_shown(name, p):18s} {_value(p['value'], p['expanded_k2'], p['unit'])}{note}"
                    + (f"   {p['description']}" if "description" in p else ""))
    for q in j["quantities"]:
        if q.get("alone"):
            shown = f"{q['lead']} ({q['iso']})" if q.get("iso") else q["lead"]
            rows.append(f"    {shown:18s} " + (IMPLAUSIBLE if q.get("plausible") is False else
                                              _value(q["value"], q["expanded_k2"], q["unit"])
                                              + f"   {q['quantity']} (its other members' share below 0.001)"))
    if not rows:
        return ["[[Determined by this data]]  none alone (see the combinations)"]
    return ["[[Determined by this data]]  value +- expanded uncertainty (k = 2); ISO 230 names in brackets"] + rows


def profile_lines(j: dict) -> list[str]:
    """The per-position profiles of a fit's record as tables (position, error relative to the datum knot, U)."""
    if not j.get("profiles"):
        return []
    out = ["[[Per-position profiles]]  error at each knot relative to the datum knot's, +- expanded uncertainty "
           "(k = 2); also with the slope removed"]
    for rec in j["profiles"]:
        out += fx.table_lines(rec)
    return out


def _in_profiles(j: dict) -> set:
    """The coefficient names of the fit's profiles (their tables state them)."""
    return {n for rec in j.get("profiles", []) for n in rec["names"]}


def _combination_lines(j: dict) -> list[str]:
    """What the data determine only together: printed as the combination (formula = value +- U); a profile's knots
    are in its table instead."""
    tabled = _in_profiles(j)
    qs = [q for q in j["quantities"] if not q.get("alone") and not (tabled and q["lead"] in tabled)]
    if not qs:
        return []
    out = ["[[Determined by this data only as combinations]]  formula (ISO 230 names) = value +- expanded "
           "uncertainty (k = 2); its members are not determined alone"]
    for q in qs:
        unit = q["unit"] if q["unit"] in ("mm", "rad") else ""
        if q.get("plausible") is False:
            value = IMPLAUSIBLE
        elif unit:
            value = _value(q["value"], q["expanded_k2"], unit)
        else:
            value = f"{q['value']:.6g} +- {q['expanded_k2']:.2g} (effect coefficients at the end of their range)"
        lead = f"{q['lead']}: " if q.get("iso") else ""
        out.append(f"    {q['formula_iso']} = {value}   ({lead}{q['quantity']})")
    return out


def _prior_decided_lines(j: dict) -> list[str]:
    """The parameters the data do not determine alone, at their posterior: the prior moved by the combinations."""
    tabled = _in_profiles(j)                    # a profile's knots: in its table, relative to its datum knot
    items = [(n, p) for n, p in j["parameters"].items() if not p["determined"] and "posterior" in p
             and n not in tabled]
    weak = [(n, dict(p, posterior={"value": p["value"], "expanded_k2": p["expanded_k2"]}))
            for n, p in j["parameters"].items()
            if p["determined"] and not p.get("fixed") and "prior" in p and p.get("data_share", 1.0) < 0.5
            and n not in tabled]
    items = weak + items
    if not items:
        return []
    moved = [(n, p) for n, p in items if p.get("data_share", 0.0) >= 0.1]
    still = [(n, p) for n, p in items if p.get("data_share", 0.0) < 0.1]
    out = [f"[[Decided by the prior]]  {len(items)} parameter(s) this data do not determine alone (or see less than "
           f"the prior does): the prior's value moved by the data, +- expanded uncertainty (k = 2); the prior (k = 2) "
           f"and the data's share in brackets"]
    for name, p in moved:
        q, pr = p["posterior"], p["prior"]
        value = IMPLAUSIBLE if not plausible(q["value"], p["unit"]) else _value(q["value"], q["expanded_k2"],
                                                                                  p["unit"])
        out.append(f"    {_shown(name, p):18s} {value} (prior {human(pr['value'], p['unit'], 3)} +- "
                   f"{human(2 * pr['std'], p['unit'], 3)}; data {p['data_share']:.0%})")
    if still:
        out.append(f"    at their prior (the data moved them by less than a tenth): "
                   + ", ".join(n for n, _ in still))
    return out


def outlier_lines(j: dict, limit: int = 12) -> list[str]:
    """Text lines on the outliers of a fit or diagnosis JSON record (empty without outliers)."""
    if not j.get("outliers"):
        return []
    items = []
    for o in j["outlier_readings"][:limit]:
        where = f"{o['file'].rsplit('/', 1)[-1]} " if "file" in o else ""
        items.append(f"{where}row {o['row']} {o['reading']} {human(o['residual'], o['unit'])}")
    more = len(j["outlier_readings"]) - limit
    many = len(j["outlier_readings"]) > OUTLIER_MANY * j["outlier_readings_of"]
    lines = [f"    outliers:        {len(j['outlier_readings'])} reading(s) in {len(j['outliers'])} data row(s) left "
             f"out of the fit: {', '.join(items)}" + (f", ... and {more} more (JSON: outlier_readings)"
                                                      if more > 0 else ""),
             f"                     rule: {j['outlier_rule']}"]
    if many:
        lines.append("                     that many: the model may be missing an effect whose largest deviations "
                     "look like outliers (fiveaxis diagnose tells the two apart)")
    return lines


def diagnosis(j: dict) -> str:
    """The text report of a diagnosis JSON record (Diagnosis.to_json)."""
    d = j["decision"]
    noise = j["noise_mm"]
    rms = j["rms_mm_without_outliers"]
    ratio = rms / noise if noise > 0 else math.inf
    lines = [f"[[Diagnosis]] {j['file']}: {j['n']} poses, {j['readings']} readings"
             + (f", model + {', '.join(j['added'])}" if j["added"] else ""),
             f"    residual RMS {rms * 1000:.4g} um against noise {noise * 1000:.4g} um "
             f"({j['noise_source']}): ratio {ratio:.3g}"
             + (f"; chi2 {d['chi2']:.5g} for {d['chi2_dof']} dof, p = {d['chi2_p']:.2g}" if "chi2" in d else "")]
    if j["outliers"]:
        lines.append(f"    residual RMS with the outliers: {j['rms_mm'] * 1000:.4g} um")
        lines += outlier_lines(j)
    lines += _structure_lines(j)
    fams = ", ".join(f"{f} {v['M']}" for f, v in d["families"].items())
    verdict = {"missing effect": "MISSING EFFECT", "no missing effect": "no missing effect found",
               "unexplained structure": "UNEXPLAINED STRUCTURE (" + (
                   "candidates pass, but structure remains after them" if d.get("passes") else
                   "the residual is above the noise; no candidate passes") + ")"}[j["verdict"]]
    what = (f"the set {' + '.join(d['accepted'])}" if len(d.get("accepted") or []) > 1
            else f"best candidate {d['best']}")
    lines.append(f"    decision: {verdict} "
                 f"({what}: delta EBIC {d['delta_ebic_best']:.1f} with penalty "
                 f"{d['penalty']:.1f}; trials per family: {fams}; {d['cv_folds']}-fold CV held-out SSE "
                 f"{d['cv_sse_without']:.4g} -> {d['cv_sse_with']:.4g})"
                 + ("; outliers left out of the decision" if j["outliers"] else ""))
    b = d.get("in_blocks")
    if b:
        lines.append(f"    in row blocks of {b['block_poses']:,} poses: every candidate screened on a sample of "
                     f"{b['sample_poses']:,} poses, the best {b['scored_on_all_readings']} decided on all "
                     f"{j['readings']:,} readings (structure tests on the sample)")
    lines += profile_lines(j)                   # the model's own profiles (--add), as tables
    lines.append("[[Candidates]] best first: RMS after adding it, share of the residual it explains")
    for k, c in enumerate(j["candidates"], 1):
        coef = "" if c["coefficient"] is None or not fx.family(c["family"]).RATE_SHOWN \
            else f"coef {c['coefficient']:.3g} {c['unit']}: "
        shown = f"{c['id']} ({c['iso']})" if c.get("iso") else c["id"]
        if c.get("plausible") is False and not c.get("implausible_rate"):     # a rate: its description says it
            lines.append(f"    {k:2d}. {shown:18s} -> {c['rms_mm'] * 1000:.4g} um ({c['explained']:.1%}) its size over "
                         f"the data: {IMPLAUSIBLE}")
            continue
        lines.append(f"    {k:2d}. {shown:18s} -> {c['rms_mm'] * 1000:.4g} um ({c['explained']:.1%}) "
                     f"{coef}{c['description']}")
        if c["aliases"]:
            lines.append(f"        aliases on this data: {', '.join(c['aliases'])}")
        for tip in c.get("separate_by", []):
            groups = " | ".join(", ".join(g) for g in tip["separates"])
            lines.append(f"        measuring with {tip['measure']} would separate: {groups}")
        if c["aliases"] and "separate_by" in c and not c["separate_by"]:
            lines.append("        neither another tool length nor wider axis ranges would tell these candidate effects apart "
                         "(their columns stay parallel); which fitted errors an extra measurement determines is "
                         "another question (fiveaxis report)")
    if j.get("hidden_by_placement"):
        hid = j["hidden_by_placement"]
        lines.append(f"[[Not visible with this placement]] {len(hid)} candidate(s) the setups' placement unknowns "
                     f"absorb (a machine error that looks like the artefact lying differently), e.g. "
                     f"{', '.join(h['id'] for h in hid[:4])} (setup {', '.join(sorted({s for h in hid for s in h['setups']}))})")
        tips = sorted({h["separate_by"] for h in hid if h["separate_by"]})
        for t in tips:
            lines.append(f"        {t}")
    if j.get("heat"):
        lines += _heat_lines(j["heat"])
    if j["verdict"] == "missing effect" and j["candidates"]:
        lines.append(f"    next: fiveaxis diagnose FILE --add {j['candidates'][0]['id']}")
    u = j.get("unexplained")
    if u:
        lines += _unexplained_lines(u)
    return "\n".join(lines)


def rounds(js: list[dict]) -> str:
    """The calibration loop (`fiveaxis.diagnosis.rounds`: diagnose, add the top candidate, again) from the rounds'
    diagnosis records: each round's diagnosis, then the residual's trail against the noise and what was found."""
    blocks = []
    for k, j in enumerate(js, 1):
        new = [a for a in j["added"] if a not in js[k - 2]["added"]] if k > 1 else []
        head = f"[[Round {k}]]" + (f" the model + {', '.join(new)} (the best candidate of round {k - 1})" if new
                                   else " the model as given")
        blocks.append(head + "\n" + diagnosis(j))
    first, last = js[0], js[-1]
    found = [a for a in last["added"] if a not in first["added"]]
    trail = " -> ".join(f"{j['rms_mm_without_outliers'] * 1000:.4g} um" for j in js)
    stop = ("" if last["verdict"] != "missing effect" else
            f" (stopped after {len(js)} rounds: next fiveaxis diagnose FILE --add {last['candidates'][0]['id']})"
            if last["candidates"] else "")
    blocks.append(f"[[Calibration loop]] residual RMS {trail} against noise {last['noise_mm'] * 1000:.4g} um; "
                  f"effects found: {', '.join(found) or 'none'}; verdict: {last['verdict']}{stop}")
    return "\n\n".join(blocks)


def _heat_lines(h: dict) -> list[str]:
    """The heat section of a diagnosis JSON record (`fiveaxis.diagnosis.heat.assess`), in words."""
    lines = ["[[Heat]] temperature channels: " + (", ".join(h["channels"]) or "none measured")]
    if h["accepted"]:
        lines.append(f"    accepted temperature effects: {', '.join(h['accepted'])}")
    s = h.get("sensors")
    if s:
        without = ", ".join(f"without {c} {v * 1000:.3g} um" for c, v in s["rms_without_mm"].items())
        lines.append(f"    sensors needed: {', '.join(s['smallest_set']) or 'none'} ({without}; {s['rule']})")
        for o in s["not_needed"]:
            lines.append(f"    not needed: {o['channel']}: {o['why']}")
    for c in h.get("confounded", []):
        lines.append(f"    confounded: {c['effect']} and {c['with']} (|cos| {c['cos']:.3f} of their columns)")
    if h.get("confounded"):
        lines.append(f"        {h['confounded_note']}")
    m = h.get("missing_sensor")
    if m:
        lines.append(f"    missing sensor: {m['note']}")
    return lines


_WHAT = {"trend": "a cubic trend", "order": "structure (von Neumann)", "direction": "a direction dependence"}


def _structure_line(t: dict, head: str) -> str:
    s = t.get("strongest")
    if not t["significant"] or s is None:
        return f"    {head}: none significant (p = {t['p']:.2g} over {t['tests']} tests)"
    return (f"    {head}: {_WHAT[s['test']]} of {s['reading']} along {s['var']} holds {s['share']:.0%} of its residual "
            f"(p = {t['p']:.2g} over {t['tests']} tests)")


def _structure_lines(j: dict) -> list[str]:
    """The residual-structure tests of a diagnosis JSON record, in words."""
    st_j = j["structure_test"]
    lines = []
    if st_j.get("after"):
        lines.append(_structure_line(st_j["fit"], "residual structure"))
        lines.append(_structure_line(st_j, f"after the effects the rule accepts ({', '.join(st_j['after'])})"))
    else:
        lines.append(_structure_line(st_j, "residual structure"))
        shares = sorted(((tok, max(v.values())) for tok, v in j["structure"].items() if v), key=lambda s: -s[1])
        if not st_j["significant"] and shares:
            lines[-1] = lines[-1][:-1] + "; largest share explained by a cubic: " + ", ".join(
                f"{tok} {share:.0%}" for tok, share in shares[:3]) + ")"
    if "noise_local_mm" in st_j and st_j["significant"] and j["verdict"] != "missing effect":
        lines.append(f"    noise of the readings along {st_j['strongest']['var']} with the structure removed "
                     f"(difference-based): {st_j['noise_local_mm'] * 1000:.4g} um; residual RMS / that noise "
                     f"{st_j.get('ratio_to_local_noise', math.inf):.3g}")
    return lines


def _unexplained_lines(u: dict) -> list[str]:
    if u.get("after"):
        lines = [f"[[Unexplained structure]] after the candidates the rule accepts ({', '.join(u['after'])}), "
                 f"structure remains: the vocabulary only approximates it"]
    else:
        lines = ["[[Unexplained structure]] the residual is above the noise and no candidate explains it"]
    if "variable" not in u:
        lines.append(f"    {u['note']}")
        return lines
    lines.append(f"    {u['reading']} along {u['axis']}: {u['share']:.0%} of the {u['reading']} residual "
                 f"(test: {u['test']}, p = {u['p']:.2g})")
    if u.get("profile"):
        unit = u["profile_unit"]
        parts = [f"{b['from']:.4g}..{b['to']:.4g}: {human(b['mean'], unit, 2)}" for b in u["profile"]]
        lines.append(f"    profile (mean residual by {u['variable']}): " + ", ".join(parts))
    if "direction" in u:
        dd = u["direction"]
        dep = "depends" if dd["p"] < st.ALPHA else "does not depend"
        lines.append(f"    direction: it {dep} on the approach direction of {dd['axis']} (dir_{dd['axis']}: "
                     f"p = {dd['p']:.2g}, {dd['share']:.0%} of the residual)")
    if "periodic" in u:
        pp = u["periodic"]
        lines.append(f"    periodicity: the best period along {u['variable']} ({pp['best']}) explains "
                     f"{pp['explained']:.1%} of the fit's residual")
    if "time" in u and u["time"]["p"] < st.ALPHA and u["variable"] != TIME:
        lines.append(f"    time: it also changes with t (p = {u['time']['p']:.2g}, {u['time']['share']:.0%})")
    if u.get("candidates_on_variable"):
        lines.append(f"    closest candidates along {u['variable']}: {', '.join(u['candidates_on_variable'])} "
                     + ("(they pass the decision but leave this structure)" if u.get("after")
                        else "(not accepted by the decision)"))
    lines.append("    a custom effect to fill in (machine file; then fiveaxis diagnose FILE --machine EDITED.toml):")
    lines += [f"        {t}" for t in u["template"].splitlines()]
    return lines


#: Below this (urad), a model's tool-axis error is the arithmetic's, not the machine's: printed as 0.
AXIS_DUST_URAD = 1e-3


def _urad(rad: float) -> str:
    """A tool-axis error (rad) in urad, 3 significant figures; 0 below AXIS_DUST_URAD (no 9.7e-15 urad printed)."""
    v = 1e6 * rad
    return "0" if abs(v) < AXIS_DUST_URAD else f"{v:.3g}"


def compensation(rec: dict, folder: str = "") -> str:
    """The text of a compensation (um, urad), built from its record (`compensation.record.summary`, what
    summary.json holds); folder: where it was written, for the last line."""
    tab, lc, mod = rec["table"], rec["linuxcnc"], rec["kinematics_module"]
    tip, ax = rec["predicted_tip_error_mm"], rec["predicted_axis_error_rad"]
    counts = [tab["nodes"][v]["count"] for v in tab["variables"]]
    lengths = tab.get("tool_lengths_mm")
    grid = " x ".join(str(c) for c in ([len(lengths)] if lengths else []) + counts)
    dims = ("L (mm)",) * (lengths is not None) + tuple(tab["variables"])
    lines = [f"fiveaxis compensate: machine {rec['machine']['name']} ({rec['convention']}), tool length "
             f"{rec['tool_length_mm']:g} mm",
             f"  table: {grid} = {tab['size']} nodes over the strokes ({', '.join(dims)}); exact-model residual at "
             f"the nodes <= {tab['nodes_max_tip_residual_mm']:.1e} mm",
             f"  predicted tool-tip error over {rec['workspace']['poses']} random poses (um):   max      RMS      p95"
             + ("   RMS after the part's set-up" if "predicted_tip_error_setup_removed_mm" in rec else "")]
    setup = rec.get("predicted_tip_error_setup_removed_mm", {})
    what = lc["kinematics"] + " + " if lc.get("kinematics") else ""
    rows = [("before", "before"),
            (f"after LinuxCNC ({what}{len(lc['comp_files'])} comp files)", "after_linuxcnc"),
            ("after LinuxCNC with the kinematics module", "after_kinematics_module"),
            ("after the volumetric table (multilinear)", "after_table"),
            ("after the exact correction (Newton)", "after_exact_correction")]
    for label, key in rows:
        if key in tip:
            s = tip[key]
            lines.append(f"    {label:56s} {1e3 * s['max']:8.3f} {1e3 * s['rms']:8.3f} {1e3 * s['p95']:8.3f}"
                         + (f" {1e3 * setup[key]['rms']:28.3f}" if key in setup else ""))
    lines.append(f"  tool-axis error RMS (urad, model estimates): before {_urad(ax['before']['rms'])}, after the "
                 f"table {_urad(ax['after_table']['rms'])} (damping {tab['damping']:g} near singular poses)")
    warm = rec.get("predicted_at_temperatures")
    if warm:
        temps = ", ".join(f"{k} {v:g} degC (reference {warm['references_degC'][k]:g})"
                          for k, v in warm["temperatures_degC"].items())
        lines.append(f"  at {temps}: predicted tool-tip error RMS (um):")
        for label, key in rows:
            if key in warm["tip_error_mm"]:
                lines.append(f"    {label:56s} {1e3 * warm['tip_error_mm'][key]['rms']:8.3f}")
        lines.append(f"  {rec['not_compensated']['temperature_note']}")
    lines += prediction_lines(rec.get("prediction_uncertainty", {}), rec.get("prediction_warnings", []))
    if lengths is not None:
        lines.append(f"  tool lengths (mm) {', '.join(f'{x:g}' for x in lengths)} (first grid dimension); "
                     f"predicted tool-tip error by tool length (um):")
        lines.append(f"    {'L (mm)':>10s} {'':6s} {'before RMS':>11s} {'after table RMS':>16s} {'max':>9s} "
                     f"{'after exact RMS':>16s}")
        for r in rec.get("predicted_by_tool_length", []):
            b, a, e = (r["tip_error_mm"][k] for k in ("before", "after_table", "after_exact_correction"))
            lines.append(f"    {r['tool_length_mm']:10.3f} {'node' if r['table_node'] else 'mid':6s} "
                         f"{1e3 * b['rms']:11.3f} {1e3 * a['rms']:16.3f} {1e3 * a['max']:9.3f} "
                         f"{1e3 * e['rms']:16.3f}")
    lines += [f"  warning: {w}" for w in rec.get("warnings", [])]
    if lc.get("kinematics"):
        pins = ", ".join(f"{k} {v:+.4f}" for k, v in lc["trt_pins_mm"].items())
        o = lc["workpiece_origin_g54_mm"]
        lines.append(f"  LinuxCNC {lc['kinematics']} (mm): {pins}; G54 X{o[0]:+.4f} Y{o[1]:+.4f} Z{o[2]:+.4f}")
    if mod.get("folder"):
        lines += [f"  kinematics module: {line}" for line in mod["left_out"]]
    else:
        lines.append(f"  no kinematics module: {mod['note']}")
    if folder:
        vol = f", {mod['folder']}/ (the kinematics module and a simulated configuration)" if mod.get("folder") else ""
        lines.append(f"  wrote {folder}/table.csv, table.parquet, summary.json, linuxcnc/{vol}")
    return "\n".join(lines)


def prediction_lines(unc: dict, warnings: list) -> list[str]:
    """The prediction's uncertainty (summary.json's `prediction_uncertainty`, mm and rad) and its warnings
    (`prediction_warnings`) as lines of the compensation's text (um, urad)."""
    if not unc:
        return ["  the prediction's uncertainty: unknown (the model file has no covariance: fit it again with this "
                "version)"]
    p, parts = unc.get("prior"), unc["tip_parts_rms_mm"]
    setup = unc.get("part_setup") or {}
    span = (lambda r: f"{1e3 * r[0]:.3f} to {1e3 * r[1]:.3f}")
    lines = [f"  the true machine's RMS tool-tip error over the workspace, k = 2 range (um):  {'raw':22s} after the "
             f"part's set-up"]
    for key, s in unc["tip_error_mm"].items():
        sr = s.get("setup_removed")
        lines.append(f"    {STAGE_LABELS.get(key, key):72s} {span(s['range_k2']):22s} "
                     f"{span(sr['range_k2']) if sr else ''}".rstrip())
    if setup:
        lines.append(f"    (the part's set-up: a work offset and the alignment about {setup['axis']}, fitted over the "
                     f"workspace: what probing the part sets anyway)")
    if unc.get("lower_end"):
        lines.append(f"    (lower end: {unc['lower_end']}; upper end: {unc['upper_end']})")
    if unc.get("prior_note"):
        lines.append(f"  {unc['prior_note']}")
    noise = unc.get("noise_mm")
    reads = [f"{STAGE_LABELS.get(k, k)} {1e3 * s['remeasured_range_k2'][0]:.3g} to "
             f"{1e3 * s['remeasured_range_k2'][1]:.3g}" for k, s in unc["tip_error_mm"].items()
             if s.get("remeasured_range_k2")]
    if noise and reads:
        lines.append(f"  a tip measurement over the workspace with {1e3 * noise:.2g} um noise would read (raw, um): "
                     + "; ".join(reads))
    sr = parts.get("setup_removed", parts)
    lines.append(f"  what the range holds (RMS at the tip after the part's set-up): the fit's uncertainty "
                 f"{1e3 * sr['fit']:.3g} um, the {unc['undetermined_directions']} undetermined directions "
                 f"{1e3 * math.hypot(sr['undetermined'], sr['undetermined_best_value']):.3g} um "
                 + (f"(their size taken as the determined ones': {1e3 * p['linear_mm']:.3g} um, "
                    f"{1e6 * p['angular_rad']:.3g} urad)" if p else "(what the fit's priors allow there)"))
    ax = unc["axis_error_rad"]
    if "after_table" in ax:
        lo, hi = ax["after_table"]["range_k2"]
        lines.append(f"  tool-axis error after the table (model estimate): {1e6 * lo:.3g} to {1e6 * hi:.3g} urad RMS "
                     f"(k = 2)")
    best = (unc.get("determining") or {}).get("best")
    if best:
        lines.append(f"  to determine the undetermined part ({100 * best['determines_share']:.0f} % of it): "
                     f"{best['measurement']}: {best['command']}")
    lines += [f"  WARNING: {w}" for w in warnings]
    return lines
