"""The report's record: run the diagnosis rounds, the fit and the sensitivity, and keep what a reader needs.

`build(data, machine, ...)` returns a `Report`: `record`, a plain JSON-able dict (values for people in um and urad,
every key with its unit), and `figures`, PNG bytes by name. The record is made from the documents the analyses
already produce (`fit.to_json`, `Diagnosis.to_json`, `SensitivityResult`, the compensation summary), so the HTML
never reaches into the analyses' objects:

- fit.to_json: rms_mm, rank, n_parameters, condition, sigma, effects, parameters {name: {value, std, unit,
  note?, description?}} (mm, rad; effect coefficients per unit of their variable), unidentifiable [[names]],
  combinations [{formula, terms, value, std}], correlations [{a, b, r}];
- Diagnosis.to_json: rms_mm, noise_mm, noise_source, missing_effect, added, decision, candidates [{id, aliases,
  rms_mm, explained, description, separate_by?}];
- compensation.read: stages (before, after LinuxCNC, after the table: {max, rms, p95} mm), maps, files.
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field

import numpy as np

from .. import __version__
from ..diagnosis import rounds as loop
from ..diagnosis import separation as sep
from ..effects.families import describe_param
from ..estimation.problem import machine_effects, resolve_effects
from ..estimation.result import to_json as fit_json
from ..estimation.solver import formula
from ..iso230 import uncertainty as U
from ..measurement import observations as ob
from ..measurement.files import join, read
from ..model import iso_names as iso
from ..model.error_model import load
from ..plots.residuals import residual_figure, series_of
from ..sensitivity.grid import Grid
from ..sensitivity.indices import gsil
from ..units import human
from . import text
from . import compensation as C
from . import certificate, figures, iso230
from ..diagnosis import preconditions
from ..estimation import design_size

#: Rounds of diagnose -> add the top candidate, at most (the calibration loop: fiveaxis.diagnosis.rounds).
MAX_ROUNDS = loop.MAX_ROUNDS
#: Candidates kept per round.
TOP = 5
#: GSIL grid: points per axis over the strokes (X of li2018 is reduced exactly: it appears in no J_i).
GSIL_POINTS = 9
#: Largest GSIL proportions listed.
GSIL_TOP = 10


@dataclass
class Report:
    """The record (JSON-able) and its figures (PNG bytes by name)."""
    record: dict
    figures: dict = field(default_factory=dict)


def people(value, unit: str):
    """A value in mm or rad (or per unit of a variable: 'rad/mm') in um or urad for people; None stays None."""
    head, sep, rest = unit.partition("/")
    factor, new = {"mm": (1e3, "um"), "rad": (1e6, "urad")}.get(head, (1.0, head))
    return (None if value is None else value * factor), new + sep + rest


def _iso_formula(obj, terms: dict) -> str:
    return formula({(iso.name(obj, n) or n): c for n, c in terms.items()})


def _machine_record(model) -> dict:
    m = model.machine
    return {"name": m.name, "title": m.title, "file": str(m.path), "convention": model.convention,
            "tool_length_mm": m.tool_length,
            "axes": [{"name": a.name, "type": a.type, "direction": list(a.direction), "stroke": list(a.stroke),
                      "unit": "deg" if a.type == "rotary" else "mm",
                      "chain": "tool" if a in m.tool_chain else "workpiece"} for a in m.axes]}


def _data_record(model, meas) -> dict:
    ranges = []
    for i, v in enumerate(meas.variables):
        ax = model.machine.axis(v)
        vals = meas.poses[:, i]
        if ax.type == "rotary":
            vals = np.degrees(vals)
        lo, hi = ax.stroke
        ranges.append({"variable": v, "unit": "deg" if ax.type == "rotary" else "mm",
                       "min": float(vals.min()), "max": float(vals.max()), "stroke": [lo, hi],
                       "coverage": float((vals.max() - vals.min()) / (hi - lo))})
    return {"file": str(meas.path), "n": meas.n, "variables": list(meas.variables), "ranges": ranges,
            "instrument": _readings_text(model, meas),
            "setups": list(meas.setups),
            "tool_length_mm": [float(meas.L.min()), float(meas.L.max())],
            "time_s": None if meas.t is None else [float(meas.t.min()), float(meas.t.max())],
            "sigma_um": None if meas.sigma is None or np.isnan(meas.sigma).all()
            else float(np.sqrt(np.nanmean(meas.sigma ** 2)) * 1e3)}


def _readings_text(model, meas) -> str:
    """What the file measures, in words: the kinds of readings, their frame and the setups."""
    obs = ob.build(meas, model.machine)
    kinds = {ob.TIP: "tool-tip deviations (dx, dy, dz; mm, actual minus nominal)",
             ob.AXIS: "tool-axis deviations (di, dj, dk)",
             ob.LINE: "1-D deviations du along a direction (mm; ballbar, interferometer or tracker)"}
    parts = [f"{int(np.sum(obs.kind == k))} {text}" for k, text in kinds.items() if (obs.kind == k).any()]
    text = "; ".join(parts) + f", in the {meas.frame} frame, at {meas.n} poses"
    if meas.setups:
        text += (f"; {len(meas.setups)} setup(s) whose placement is fitted beside the machine's errors "
                 f"({', '.join(meas.setups[:6])}{', ...' if len(meas.setups) > 6 else ''})")
    return text


def _round_record(obj, k: int, j: dict) -> dict:
    cands = []
    for c in j["candidates"]:
        cands.append({"id": c["id"], "iso": iso.name(obj, c["id"]), "aliases": list(c["aliases"]),
                      "aliases_iso": [iso.name(obj, a) for a in c["aliases"]],
                      "rms_um": c["rms_mm"] * 1e3, "explained": c["explained"], "description": c["description"],
                      "separate_by": c.get("separate_by", [])})
    return {"round": k, "added": list(j["added"]), "added_iso": [iso.name(obj, a) for a in j["added"]],
            "rms_um": j["rms_mm"] * 1e3, "noise_um": j["noise_mm"] * 1e3, "noise_source": j["noise_source"],
            "ratio": j["rms_mm"] / j["noise_mm"] if j["noise_mm"] > 0 else None,
            "missing_effect": j["missing_effect"], "verdict": j["verdict"], "decision": j["decision"],
            "candidates": cands, "unexplained": j.get("unexplained")}


def _fit_record(model, j: dict, groups_advice) -> dict:
    placed = model.machine.with_convention(model.convention)
    params = []
    for name, p in j["parameters"].items():
        value, unit = people(p.get("value"), p["unit"])
        std, _ = people(p.get("std"), p["unit"])
        entry = iso.names(model).get(name)
        shown = p["determined"] and p.get("plausible", True)
        note = p.get("note", "") if p.get("plausible", True) else text.IMPLAUSIBLE
        if p.get("fixed"):
            note = "held (--fix or [fit] fixed)"
        elif p.get("decided_by") in ("prior", "data and prior") and "posterior" in p:
            note = (f"{note}; posterior {human(p['posterior']['value'], p['unit'])} +- "
                    f"{human(p['posterior']['expanded_k2'], p['unit'])} (k = 2), the prior's moved by the "
                    f"combinations ({p['data_share']:.0%} data)")
        params.append({"name": name, "iso": iso.name(model, name),
                       "kind": entry.kind if entry else "effect coefficient",
                       "description": p.get("description") or (describe_param(placed, name) if entry else ""),
                       "value": value if shown else None, "u_k2": None if std is None or not shown else 2 * std,
                       "unit": unit, "determined": shown, "note": note,
                       "decided_by": p.get("decided_by", "data")})
    combos = []
    for c in j["combinations"]:
        value, unit = people(c["value"], c["unit"])
        std, _ = people(c["std"], c["unit"])
        combos.append({"formula": c["formula"], "formula_iso": _iso_formula(model, c["terms"]), "value": value,
                       "u_k2": 2 * std, "unit": unit, "note": c.get("note", "")})
    tabled = {n for t in j.get("profiles", []) for n in t["names"]}    # a profile's knots: in its table
    quantities = []
    for q in j["quantities"]:
        value, unit = people(q["value"], q["unit"])
        std, _ = people(q["std"], q["unit"])
        if q.get("plausible") is False or q["lead"] in tabled:
            continue
        quantities.append({"name": q["lead"], "iso": q["iso"], "quantity": q["quantity"],
                           "relative_to": q["relative_to"] or "nothing else (the other members' share is below "
                                                             "0.001)",
                           "value": value, "u_k2": 2 * std, "unit": unit,
                           "formula": q["formula_iso"]})
    setups = []
    for su_ in j.get("setups", []):
        for name, p in su_["parameters"].items():
            value, unit = people(p.get("value"), p["unit"])
            std, _ = people(p.get("std"), p["unit"])
            setups.append({"setup": su_["id"], "kind": su_["kind"], "frame": su_["frame"], "name": name,
                           "value": value, "u_k2": None if std is None else 2 * std, "unit": unit,
                           "determined": p["determined"], "note": p.get("note", ""),
                           "placement": su_.get("placement", "")})
    leads = {q["name"] for q in quantities}
    groups = [dict(g, relative=[m for m in g["members"] if m in leads]) for g in groups_advice]
    return {"rms_um": j["rms_mm"] * 1e3, "rms_first_order_um": j["rms_first_order_mm"] * 1e3, "rank": j["rank"],
            "setups": setups,
            "n_parameters": j["n_parameters"], "condition": j["condition"], "sigma": j["sigma"],
            "reduced_chi2": j.get("reduced_chi2"), "effects": j["effects"],
            "effects_iso": [iso.name(model, e) for e in j["effects"]], "parameters": params,
            "combinations": combos, "quantities": quantities, "groups": groups,
            "profiles": [dict(t) for t in j.get("profiles", [])],
            "correlations": [dict(c, a_iso=iso.name(model, c["a"]), b_iso=iso.name(model, c["b"]))
                             for c in j["correlations"]]}


def _sensitivity(model) -> tuple[dict, list]:
    grid = Grid.from_strokes(model.machine, {v: GSIL_POINTS for v in model.variables})
    res = gsil(model, grid, check=False, progress=False)
    p = res.proportions
    index = {n: i for i, n in enumerate(res.names)}
    placed = model.machine.with_convention(model.convention)
    top = [{"name": n, "iso": iso.name(model, n), "proportion": float(p[index[n]]),
            "description": describe_param(placed, n)} for n in res.ranking[:GSIL_TOP]]
    return {"kind": "GSIL", "top": top, "points_per_axis": GSIL_POINTS, "poses": grid.size,
            "grid": grid.describe(model.machine.rotary), "L0_mm": res.settings["L0_mm"],
            "LE_mm": res.settings["LE_mm"], "errors": "the machine file's error values"}, top


def _verdict(obj, rounds: list[dict], fit: dict, max_rounds: int) -> dict:
    """The report's verdict: the last round's diagnosis verdict (the one `fiveaxis diagnose` prints), in words."""
    last = rounds[-1]
    base = set(rounds[0]["added"])
    found = [a for a in last["added"] if a not in base]
    known = last["noise_source"] == "sigma column"
    ratio = last["ratio"]
    verdict = last["verdict"]
    explained = verdict == "no missing effect"
    unexplained = []
    if verdict == "missing effect":
        best = last["candidates"][0] if last["candidates"] else None
        unexplained.append(f"an effect is still missing after {len(rounds)} rounds (the limit is {max_rounds})"
                           + (f"; the best candidate is {best['id']}: {best['description']}" if best else ""))
    elif verdict == "unexplained structure":
        u = last.get("unexplained") or {}
        where = (f" ({u['reading']} along {u['axis']}: {u['share']:.0%} of its residual)" if "axis" in u else "")
        unexplained.append(f"the residual ({last['rms_um']:.3g} um) is above the noise ({last['noise_um']:.3g} um) "
                           f"and holds structure{where} that no effect of the vocabulary explains: the cause may "
                           f"lie outside the model (instrument setup, an effect of another form; see the last round)")
    if not known:
        unexplained.append("the data has no sigma column: the noise is estimated from the residual itself; the "
                           "verdict rests on the candidate test and the residual-structure tests")
    if fit["groups"]:
        relative = sum(len(g["relative"]) for g in fit["groups"])
        unexplained.append(f"{len(fit['groups'])} groups of parameters cannot be told apart by this data (their "
                           f"combinations are determined; see the fit)"
                           + (f"; {relative} of these parameters {'is' if relative == 1 else 'are'} stated relative "
                              f"to the others of {'its' if relative == 1 else 'their'} group" if relative else ""))
    if explained:
        headline = (f"The model explains the measurements to the noise level: residual RMS {last['rms_um']:.3g} um "
                    f"against noise {last['noise_um']:.3g} um"
                    + (f", after adding {len(found)} effect(s) the data showed." if found else "."))
    else:
        headline = (f"The model does not yet explain the measurements: residual RMS {last['rms_um']:.3g} um against "
                    f"noise {last['noise_um']:.3g} um ({verdict}).")
    return {"explained": explained, "verdict": verdict, "headline": headline, "rms_um": last["rms_um"],
            "noise_um": last["noise_um"], "noise_source": last["noise_source"], "ratio": ratio,
            "rms_first_um": rounds[0]["rms_um"],
            "effects_found": [_found(obj, a, fit) for a in found],
            "unexplained": unexplained}


def _found(obj, effect_id: str, fit: dict) -> dict:
    """An effect the rounds added, as the final fit has it (one size per effect: the final model's, never a
    round's): its parameters' names in the fit's table and the description of its first parameter."""
    names = [p["name"] for p in fit["parameters"] if p["name"] == effect_id or p["name"].startswith(effect_id + "@")]
    first = next((p for p in fit["parameters"] if names and p["name"] == names[0]), None)
    return {"id": effect_id, "iso": iso.name(obj, effect_id), "parameters": names,
            "description": first["description"] if first else ""}


def build(data, machine="li2018", convention: str = "equations", added=(), compensation=None,
          max_rounds: int = MAX_ROUNDS, sensitivity: bool = True, title: str | None = None,
          frame: str | None = None, campaign: dict | None = None, uncertainty: U.Statement | None = None,
          today: _dt.date | None = None, references: dict | None = None, progress=None) -> Report:
    """Run the analyses of a measurement file (or of several: one joint fit, `measurement.files.join`) and collect
    the report's record and figures.

    added: effect ids added to the model before the first round (project or ISO names); compensation: a folder
    with summary.json (see report.compensation) or None. Rounds: diagnose, add the top candidate, repeat while
    the decision says an effect is missing, at most max_rounds diagnoses; frame: of the readings (None: the
    file's, else workpiece). campaign: a checked campaign (`report.campaign.load`): the record becomes a
    calibration certificate (`record["certificate"]`); uncertainty: the ISO 230-9 statement of the ISO 230-2
    figures (default: the campaign's iso230_9 keys, else none); today: the issue date when the campaign gives
    none; references: stated reference temperatures of the channels (`Measurements.with_references`); progress:
    None, or called with a line of text after each round and as each later step starts (a report takes seconds)."""
    say = progress or (lambda text: None)
    if uncertainty is None:
        uncertainty = U.Statement(**{k: v for k, v in (campaign or {}).get("iso230_9", {}).items()})
    U.check(uncertainty)
    model = load(machine, convention)
    comp = C.read(compensation, model.machine.name) if compensation is not None else None
    paths = list(data) if isinstance(data, (list, tuple)) else [data]
    meas = join([read(p, model.machine, min_rows=2 if len(paths) == 1 else 1, frame=frame) for p in paths],
                model.machine)
    if references:
        meas = meas.with_references(references)
    effects = resolve_effects(model, machine_effects(model) + list(added), poses=meas.poses)
    design_size.check(model, meas, effects)
    preconditions.check(meas)
    diags = loop.rounds(model, meas, effects, max_rounds, top=TOP, fixed=dict(model.machine.fixed) or None,
                        progress=lambda *done: say(loop.round_line(*done)))
    rounds = [_round_record(model, k, dg.to_json()) for k, dg in enumerate(diags, 1)]
    final = diags[-1]
    j = fit_json(final.fit)
    advice = sep.parameters(model, meas, final.fit.problem.effects, j["unidentifiable"],
                            list(final.fit.problem.names))
    fit = _fit_record(model, j, advice)
    record = {
        "title": title or (f"Calibration certificate {campaign['certificate']['number']}: {model.machine.title}"
                           if campaign else f"Calibration report: {model.machine.title}"),
        "generated": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "fiveaxis_version": _version(),
        "machine": _machine_record(model), "data": _data_record(model, meas), "rounds": rounds, "fit": fit,
        "residuals": {"before": {"effects": rounds[0]["added"], "rms_um": rounds[0]["rms_um"]},
                      "after": {"effects": rounds[-1]["added"], "rms_um": rounds[-1]["rms_um"]}},
        "sensitivity": None, "compensation": None}
    record["verdict"] = _verdict(model, rounds, fit, max_rounds)
    say("figures")
    figs = {"rounds": figures.rounds(rounds)}
    figs["coverage"], record["data"]["coverage_caption"] = figures.coverage(model, meas)
    series = [series_of(diags[0].fit, f"{_model_label(rounds[0]['added'])} (RMS {rounds[0]['rms_um']:.3g} um)")]
    if len(diags) > 1:
        series.append(series_of(final.fit, f"{_model_label(rounds[-1]['added'])} (RMS {rounds[-1]['rms_um']:.3g} "
                                           f"um)"))
    figs["residuals"] = figures.png(residual_figure(
        model, meas, series, "Fit residual (measured minus modelled reading, um; urad for "
                                                    "the tool axis) against each axis "
                             "position and time" + (", before and after the effects found" if len(diags) > 1 else "")))
    record["iso230"], iso_figs = iso230.sections(model, meas, uncertainty)
    figs.update(iso_figs)
    record["certificate"] = (certificate.block(campaign, meas, record["iso230"], fit["sigma"], today)
                             if campaign else None)
    if sensitivity:
        say("sensitivity of the machine's errors (GSIL)")
        record["sensitivity"], top = _sensitivity(model)
        figs["sensitivity"] = figures.sensitivity(top)
    if comp is not None:
        record["compensation"] = {k: v for k, v in comp.items() if k != "maps"}
        record["compensation"]["maps"] = [{"file": m["file"], "caption": m["caption"]} for m in comp["maps"]]
        for i, m in enumerate(comp["maps"]):
            figs[f"compensation_{i}"] = m["png"]
    _check_finite(record)
    return Report(record, figs)


def _model_label(added) -> str:
    return "geometric model" + (f" + {', '.join(added)}" if added else "")


def _version() -> str:
    return __version__


def _check_finite(obj, where="record"):
    """No NaN or inf where a number is promised (the HTML and the JSON would carry it silently)."""
    if isinstance(obj, float) and not math.isfinite(obj):
        if ".decision" in where:         # the decision's statistics are shown as computed (an inf is meaningful)
            return
        raise ValueError(f"report: {where} is {obj}")
    if isinstance(obj, dict):
        for k, v in obj.items():
            _check_finite(v, f"{where}.{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _check_finite(v, f"{where}[{i}]")
