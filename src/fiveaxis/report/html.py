"""The report as one self-contained HTML page: inline CSS, figures as base64 PNG, no script, nothing fetched.

`render(report)` builds the page from `Report.record` and `Report.figures` with Python string building (every
text escaped); the sections follow the reader's questions: is the machine explained (verdict), what was
measured (data), what the errors are (fit, with ISO 230 names and expanded uncertainties), where the model
fails (residuals), how the missing effects were found (diagnosis rounds), which errors matter most
(sensitivity), and what compensation would achieve.
"""
from __future__ import annotations

from .iso230_3 import section_html
from .markup import (code_name as _name, escape as _e, figure as _figure, get as _get, number as _v, prose as _t,
                     table as _table, unit as _unit)


CSS = """
:root { --ink: #1d232a; --muted: #5b6570; --line: #d5dbe1; --ok: #1f7a3a; --warn: #a05a00; --bg-soft: #f4f6f8; }
* { box-sizing: border-box; }
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif; color: var(--ink);
       margin: 0 auto; max-width: 1180px; padding: 24px 28px 60px; line-height: 1.45; font-size: 15px; }
h1 { font-size: 1.7em; margin: 0 0 4px; }
h2 { font-size: 1.3em; margin: 34px 0 8px; padding-top: 8px; border-top: 2px solid var(--line); }
h3 { font-size: 1.05em; margin: 20px 0 6px; }
p, li { max-width: 78em; }
.meta { color: var(--muted); font-size: 0.92em; margin: 0 0 14px; }
nav { font-size: 0.92em; margin: 8px 0 18px; }
nav a { margin-right: 14px; color: #1f5aa6; text-decoration: none; }
.verdict { border-left: 6px solid var(--warn); background: #fff6ea; padding: 12px 18px; border-radius: 4px; }
.verdict.ok { border-left-color: var(--ok); background: #edf7ef; }
.verdict .headline { font-size: 1.15em; font-weight: 600; margin: 0 0 6px; }
.numbers { display: flex; flex-wrap: wrap; gap: 10px 28px; margin: 8px 0; }
.numbers div { min-width: 150px; }
.numbers b { display: block; font-size: 1.25em; }
.numbers span { color: var(--muted); font-size: 0.85em; }
table { border-collapse: collapse; margin: 8px 0 14px; font-size: 0.9em; }
th, td { border-bottom: 1px solid var(--line); padding: 4px 9px; text-align: left; vertical-align: top; }
th { background: var(--bg-soft); font-weight: 600; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; }
td.num { white-space: nowrap; }
td.code, span.code { font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 0.95em; white-space: nowrap; }
tr.undetermined td { color: var(--muted); }
figure { margin: 12px 0 20px; }
figure img { max-width: 100%; height: auto; display: block; border: 1px solid var(--line); }
figcaption { color: var(--muted); font-size: 0.88em; margin-top: 4px; max-width: 78em; }
dl.glossary { display: grid; grid-template-columns: max-content 1fr; gap: 4px 16px; font-size: 0.92em; }
dl.glossary dt { font-weight: 600; }
dl.glossary dd { margin: 0; }
.note { color: var(--muted); font-size: 0.9em; }
.placeholder { border: 1px dashed var(--line); background: var(--bg-soft); padding: 10px 14px; border-radius: 4px; }
.kind { font-size: 1.25em; font-weight: 600; letter-spacing: 0.04em; text-transform: uppercase; margin: 4px 0 10px; }
dl.admin { display: grid; grid-template-columns: 14em 1fr; gap: 5px 16px; margin: 8px 0 14px; }
dl.admin dt { font-weight: 600; }
dl.admin dd { margin: 0; }
.signatures { display: flex; flex-wrap: wrap; gap: 20px 60px; margin: 30px 0 10px; }
.sign { min-width: 260px; }
.sign .role { font-weight: 600; margin: 0 0 38px; }
.sign .line { border-bottom: 1px solid var(--ink); width: 260px; margin-bottom: 4px; }
footer { margin-top: 40px; color: var(--muted); font-size: 0.85em; border-top: 1px solid var(--line); padding-top: 8px; }
@media print {
  body { max-width: none; padding: 0; font-size: 11pt; }
  nav { display: none; }
  h2 { break-after: avoid; }
  figure, table, .verdict, .signatures, dl.admin { break-inside: avoid; }
  table { font-size: 8.5pt; }
  th, td { padding: 3px 5px; }
}
@page { size: A4; margin: 14mm 12mm; }
"""


# -- sections -----------------------------------------------------------------------------------------------------
def _verdict(rec: dict) -> str:
    v = rec["verdict"]
    cls = "verdict ok" if v["explained"] else "verdict"
    params = {p["name"]: i for i, p in enumerate(rec["fit"]["parameters"])}
    out = [f'<section id="verdict" class="{cls}"><p class="headline">{_t(v["headline"])}</p>',
           '<div class="numbers">',
           f"<div><b>{_v(rec, 'verdict.rms_first_um', '.3g')} &rarr; {_v(rec, 'verdict.rms_um', '.3g')} \u00b5m</b>"
           f"<span>residual RMS: geometric model &rarr; final model</span></div>",
           f"<div><b>{_v(rec, 'verdict.noise_um', '.3g')} \u00b5m</b><span>noise ({_e(v['noise_source'])})</span></div>",
           f"<div><b>{_v(rec, 'verdict.ratio', '.3g')}</b><span>residual / noise (1 = explained to the noise)</span>"
           f"</div>",
           f"<div><b>{len(v['effects_found'])}</b><span>effects found beyond the geometric errors</span></div>",
           "</div>"]
    if v["effects_found"]:
        out.append("<p><b>Effects found</b> (each lowered the residual and passed the decision test; the sizes are "
                   "the final model's, as in the fitted errors below):</p><ul>")
        for f in v["effects_found"]:
            size = ""
            if len(f["parameters"]) == 1:
                i = params[f["parameters"][0]]
                if rec["fit"]["parameters"][i]["determined"]:
                    size = (f" Fitted: {_v(rec, f'fit.parameters.{i}.value')} &plusmn; "
                            f"{_v(rec, f'fit.parameters.{i}.u_k2', '.2g')} "
                            f"{_e(_unit(rec['fit']['parameters'][i]['unit']))} (U, k = 2).")
            elif f["parameters"]:
                size = f" Fitted as {len(f['parameters'])} parameters (see the fitted errors)."
            out.append(f"<li>{_name(f['id'], f['iso'])}: {_t(f['description'])}.{size}</li>")
        out.append("</ul>")
    else:
        out.append("<p><b>Effects found:</b> none beyond the model's geometric errors"
                   + (" and the effects it was given" if rec["rounds"][0]["added"] else "") + ".</p>")
    if v["unexplained"]:
        out.append("<p><b>Still open:</b></p><ul>" + "".join(f"<li>{_t(u)}</li>" for u in v["unexplained"]) + "</ul>")
    out.append("</section>")
    return "".join(out)


GLOSSARY = [
    ("pose", "one position of the machine's axes (X, Y, Z in mm; rotary axes in degrees) at which the tool tip "
             "was measured."),
    ("deviation", "measured minus nominal tool-tip position (dx, dy, dz), relative to the workpiece; a 1-D "
                  "instrument (ballbar, interferometer, tracker) reads it along one direction (du)."),
    ("setup", "one placement of an artefact or instrument (a sphere, a ballbar circle, a test part): its unknown "
              "position (and orientation) is fitted beside the machine's errors and reported apart."),
    ("geometric errors", "the small errors of the machine's kinematic chain (41 for the paper's machine, Li et al. "
                         "2018): for each axis six "
                         "error motions (three translations, three rotations, changing along the axis), and the "
                         "location and squareness errors between axes (constants). Lengths in \u00b5m, angles in "
                         "\u00b5rad (1 \u00b5rad = 1 \u00b5m per m)."),
    ("ISO 230 name", "the name of an error in ISO 230-1 / ISO 230-7, shown beside the project's name: E_XX is the "
                     "positioning error of X, E_AX its roll (rotation about x), E_C0B the orientation of the B axis "
                     "about z, E_C(0X)Y the squareness of Y to X. The project's errors of a rotary axis turn with "
                     "it; ISO's are along the fixed axes; they agree at the zero position."),
    ("effect", "an error that changes along an axis or with time, beyond the constant part the model has: "
               "ex_x:x1 is the roll of X changing linearly along X (a twisted guideway), L:t1 the tool length "
               "growing with time (warm-up)."),
    ("residual", "deviation minus what the fitted model predicts: what the model does not explain. RMS is its "
                 "root-mean-square over all poses and directions."),
    ("noise", "the measuring instrument's scatter: from the data's sigma column when it has one, else estimated "
              "from the residual. A residual near the noise means the model explains all that can be seen."),
    ("expanded uncertainty U", "k = 2 times the standard uncertainty of a fitted value (about 95 % coverage "
                               "for normal errors): the true value lies within value \u00b1 U."),
    ("not separable", "errors that move the tool tip in the same way at every measured pose: the data fixes "
                      "their combination (shown as a formula) but not each alone."),
    ("GSIL", "global sensitivity index: how much each error contributes to the tool's volumetric error over "
             "the whole workspace (Li et al. 2018, Eq. 14-16), as a share of the total."),
]


def _glossary() -> str:
    items = "".join(f"<dt>{_e(t)}</dt><dd>{d}</dd>" for t, d in GLOSSARY)
    return f'<section id="terms"><h2>How to read this report</h2><dl class="glossary">{items}</dl></section>'


def _data(rec: dict, figs: dict) -> str:
    d = rec["data"]
    rows = [[_e(r["variable"]), _e(r["unit"]), _v(rec, f"data.ranges.{i}.min", ".5g"),
             _v(rec, f"data.ranges.{i}.max", ".5g"),
             f"{_v(rec, f'data.ranges.{i}.stroke.0', '.5g')} to {_v(rec, f'data.ranges.{i}.stroke.1', '.5g')}",
             f"{_v(rec, f'data.ranges.{i}.coverage', '.0f', 100.0)} %"]
            for i, r in enumerate(d["ranges"])]
    extra = [f"Tool length {_v(rec, 'data.tool_length_mm.0', '.5g')}"
             + (f" to {_v(rec, 'data.tool_length_mm.1', '.5g')}" if d["tool_length_mm"][1] != d["tool_length_mm"][0]
                else "") + " mm"]
    if d["time_s"] is not None:
        extra.append(f"time {_v(rec, 'data.time_s.0')} to {_v(rec, 'data.time_s.1')} s")
    extra.append("measurement uncertainty (sigma column) " + (f"{_v(rec, 'data.sigma_um', '.3g')} \u00b5m"
                                                               if d["sigma_um"] is not None else "not given"))
    return (f'<section id="data"><h2>The data</h2><p>{_v(rec, "data.n", "d")} measured poses from <span class="code">'
            f"{_e(d['file'])}</span>. Instrument: {_e(d['instrument'])}. {'; '.join(extra)}.</p>"
            + _table(["axis", "unit", "lowest", "highest", "stroke", "stroke covered"], rows, "ranges",
                     numeric=(2, 3, 4, 5))
            + _figure(figs, "coverage", "pose coverage", _e(d["coverage_caption"]))
            + "</section>")


def _fit(rec: dict) -> str:
    f = rec["fit"]
    effects = ", ".join(f"{e} ({i})" if i else e for e, i in zip(f["effects"], f["effects_iso"])) or "none"
    out = ['<section id="fit"><h2>The fitted errors</h2>',
           f"<p>The final model (geometric errors + effects: {_e(effects)}) fitted by weighted least squares with "
           f"every error's prior (maximum a posteriori) on the exact kinematic chain: residual RMS {_v(rec, 'fit.rms_um')} \u00b5m; {_v(rec, 'fit.n_parameters', 'd')} "
           f"parameters, of which the data determines {_v(rec, 'fit.rank', 'd')} independent directions (condition "
           f"number {_v(rec, 'fit.condition', '.3g')}). Uncertainty scale: {_e(f['sigma'])}"
           + (f", reduced chi\u00b2 {_v(rec, 'fit.reduced_chi2', '.3g')}" if f["reduced_chi2"] is not None else "")
           + ". Values with an expanded uncertainty U (k = 2): first what the data determine alone, then what they "
             "determine relative to what they cannot separate it from; the parameters the data cannot determine "
             "alone are listed after, with the measurement that would separate them.</p>"]
    rows = []
    for i, p in enumerate(f["parameters"]):
        if p["determined"]:
            rows.append([f'<span class="code">{_e(p["name"])}</span>', _e(p["iso"] or "\u2013"),
                         _e(p["description"]), _v(rec, f"fit.parameters.{i}.value"),
                         _v(rec, f"fit.parameters.{i}.u_k2", ".2g"), _e(_unit(p["unit"])), _e(p["note"])])
    if rows:
        out.append(_table(["parameter", "ISO 230", "meaning", "value", "U (k = 2)", "unit", "note"], rows,
                          "parameters", numeric=(3, 4)))
    out += [_profile(rec, i) for i in range(len(f.get("profiles", [])))]
    if f.get("quantities"):
        out.append("<h3>Determined relative to what the data cannot separate</h3><p>Each quantity is determined "
                   "together with the others named beside it (the locations of the rotary axes relative to the "
                   "axes' zero offsets, an axis's tilt relative to the artefacts' placement); the exact formula "
                   "is one click away. Each of them is also a member of a group below: alone, the data cannot "
                   "determine it; relative to the others named, they can.</p>")
        rows = [[f'<span class="code">{_e(q["name"])}</span>', _e(q["iso"] or "\u2013"), _e(q["quantity"]),
                 _v(rec, f"fit.quantities.{i}.value"), _v(rec, f"fit.quantities.{i}.u_k2", ".2g"),
                 _e(_unit(q["unit"])),
                 f'relative to {_e(q["relative_to"])}<details><summary>formula</summary>'
                 f'<span class="code">{_e(q["formula"])}</span></details>'] for i, q in enumerate(f["quantities"])]
        out.append(_table(["quantity", "ISO 230", "meaning", "value", "U (k = 2)", "unit", "relative to"], rows,
                          "quantities", numeric=(3, 4)))
    if f.get("setups"):
        out.append("<h3>Setups: where the artefacts lay</h3><p>The unknown placement of each artefact or instrument "
                   "(offsets c, a length offset l of 1-D readings, rotations w), fitted beside the machine's errors; "
                   "these are not errors of the machine.</p>")
        rows, classes = [], []
        for i, p in enumerate(f["setups"]):
            rows.append([_e(p["setup"]), f'<span class="code">{_e(p["name"])}</span>', _e(p["kind"]),
                         _v(rec, f"fit.setups.{i}.value") if p["determined"] else "not determined",
                         _v(rec, f"fit.setups.{i}.u_k2", ".2g") if p["determined"] else "", _e(_unit(p["unit"])),
                         _e(p["note"])])
            classes.append("" if p["determined"] else "undetermined")
        out.append(_table(["setup", "unknown", "kind", "value", "U (k = 2)", "unit", "note"], rows, "setups",
                          numeric=(3, 4), row_class=classes))
        for text in sorted({p["setup"] + " " + p["placement"] for p in f["setups"] if p["placement"]}):
            out.append(f"<p>{_e(text)}.</p>")
    if f["combinations"]:
        rows = [[f'<span class="code">{_e(c["formula"])}</span>', f'<span class="code">{_e(c["formula_iso"])}</span>',
                 _v(rec, f"fit.combinations.{i}.value"), _v(rec, f"fit.combinations.{i}.u_k2", ".2g"),
                 _e(_unit(c["unit"]))] for i, c in enumerate(f["combinations"])]
        out.append(f"<details><summary>Every combination the data determine, as formulas ({len(rows)})</summary>"
                   + _table(["combination", "in ISO 230 names", "value", "U (k = 2)", "unit"], rows, "combinations",
                            numeric=(2, 3)) + "</details>")
    if f["groups"]:
        out.append("<h3>Fitted errors the data cannot determine alone, and which measurement would</h3>"
                   "<p>The question here is about the fit's parameters (which of them these poses cannot tell "
                   "apart); which candidate effects the diagnosis could not tell apart is said in the rounds "
                   "below.</p>")
        rows = []
        for g in f["groups"]:
            names = ", ".join(f"{n} ({i})" if i else n for n, i in zip(g["members"], g["iso"]))
            tips = "; ".join(f"{s['measure']}: determines {', '.join(s['determines'])}" if s.get("determines")
                             else f"{s['measure']}: could not be evaluated ({s.get('error', '')})"
                             for s in g["separate_by"])
            rel = (f" {', '.join(g['relative'])}: stated above relative to the others of this group."
                   if g.get("relative") else "")
            rows.append([_e(names), _e(g["why"]) + _e(rel), _e(tips or "\u2013")])
        out.append(_table(["parameters", "why", "extra measurement that separates them"], rows, "groups"))
    if f["correlations"]:
        rows = [[_name(c["a"], c["a_iso"]), _name(c["b"], c["b_iso"]), _v(rec, f"fit.correlations.{i}.r", "+.3f")]
                for i, c in enumerate(f["correlations"])]
        out.append("<h3>Strongly correlated determined parameters</h3>"
                   + _table(["parameter", "parameter", "correlation r"], rows, "correlations", numeric=(2,)))
    out.append("</section>")
    return "".join(out)


def _profile(rec: dict, i: int) -> str:
    """A per-position profile as its table: position, error relative to the datum knot, U (k = 2), and the same
    with the slope removed (the fit's `profiles` record)."""
    t = rec["fit"]["profiles"][i]
    pu, eu = t["position_unit"], t["error_unit"]
    per = "m" if pu == "mm" else "deg"
    iso = f" ({t['iso']})" if t.get("iso") else ""
    shown = _e(_unit(eu))
    head = (f'<h3>Per-position profile <span class="code">{_e(t["id"])}</span>{_e(iso)}</h3><p>{_e(t["quantity"])} '
            f'at its {len(t["rows"])} knots, {_e(t["datum"])} (the datum knot), with its expanded uncertainty U '
            f'(k = 2); slope removed: {_e(t["slope_removed"])}, slope {_v(rec, f"fit.profiles.{i}.slope_{eu}_per_{per}")}'
            f' {shown}/{per} +- {_v(rec, f"fit.profiles.{i}.U_k2_slope_{eu}_per_{per}", ".2g")} {shown}/{per}'
            f' (k = 2).</p>')
    pre = f"fit.profiles.{i}.rows"
    rows = [[_v(rec, f"{pre}.{r}.position_{pu}", ".6g"), _v(rec, f"{pre}.{r}.error_{eu}"),
             _v(rec, f"{pre}.{r}.U_k2_{eu}", ".2g"), _v(rec, f"{pre}.{r}.error_slope_removed_{eu}"),
             _v(rec, f"{pre}.{r}.U_k2_slope_removed_{eu}", ".2g")] for r in range(len(t["rows"]))]
    return head + _table([f"{_e(t['axis'])} ({_e(pu)})", f"error ({shown})", f"U (k = 2, {shown})",
                          f"slope removed ({shown})", f"U (k = 2, {shown})"], rows, f"profile-{i}",
                         numeric=(0, 1, 2, 3, 4))


def _residuals(rec: dict, figs: dict) -> str:
    r = rec["residuals"]
    changed = r["before"]["effects"] != r["after"]["effects"]
    text = (f"Grey: the residual of the model the diagnosis started from (RMS "
            f"{_v(rec, 'residuals.before.rms_um', '.3g')} \u00b5m)."
            + (f" Blue: the final model with the effects found (RMS {_v(rec, 'residuals.after.rms_um', '.3g')} "
               f"\u00b5m)." if changed else " No effect was added."))
    return ('<section id="residuals"><h2>Residuals against each axis and time</h2>'
            "<p>A model that explains the data leaves residuals scattered evenly around zero, with no trend "
            "along any axis or in time. A slope, a curve or a step along a variable points at an effect that "
            "changes with it.</p>"
            + _figure(figs, "residuals", "residuals against each variable", text) + "</section>")


def _rounds(rec: dict, figs: dict) -> str:
    out = ['<section id="rounds"><h2>Diagnosis rounds</h2>',
           "<p>Each round fits the model, scores every candidate effect (each error and the tool length, changing "
           "linearly, quadratically or cubically along each axis or with time) by how much of the residual it "
           "explains, and decides with an extended BIC and cross-validation whether the best one is real. If it "
           "is, it is added and the next round starts.</p>",
           _figure(figs, "rounds", "RMS per round", "Residual RMS after each round against the noise level.")]
    for n, r in enumerate(rec["rounds"]):
        model = "geometric errors" + "".join(f" + {a} ({i})" if i else f" + {a}"
                                             for a, i in zip(r["added"], r["added_iso"]))
        d = r["decision"]
        verdict = "an effect is missing" if r["missing_effect"] else "no missing effect"
        ratio = "" if r["ratio"] is None else f", ratio {_v(rec, f'rounds.{n}.ratio', '.3g')}"
        dk = f"rounds.{n}.decision"
        out.append(f"<h3>Round {r['round']}: {_e(verdict)}</h3><p>Model: {_e(model)}. Residual RMS "
                   f"{_v(rec, f'rounds.{n}.rms_um')} \u00b5m against noise {_v(rec, f'rounds.{n}.noise_um', '.3g')} "
                   f"\u00b5m{ratio}. Decision: best candidate &Delta;EBIC "
                   f"{_v(rec, f'{dk}.delta_ebic_best') if 'delta_ebic_best' in d else '&ndash;'} (must be &lt; 0), "
                   f"{_v(rec, f'{dk}.cv_folds', 'd') if 'cv_folds' in d else ''}-fold cross-validation held-out "
                   f"error {_v(rec, f'{dk}.cv_sse_without') if 'cv_sse_without' in d else '&ndash;'} &rarr; "
                   f"{_v(rec, f'{dk}.cv_sse_with') if 'cv_sse_with' in d else '&ndash;'} (must fall).</p>")
        rows = []
        for k, c in enumerate(r["candidates"]):
            aliases = ", ".join(f"{a} ({i})" if i else a for a, i in zip(c["aliases"], c["aliases_iso"]))
            sep = "; ".join(f"{s['measure']} would separate " + " | ".join(", ".join(g) for g in s["separates"])
                            for s in c["separate_by"])
            rows.append([f"{k + 1}.", _name(c["id"], c["iso"]), _v(rec, f"rounds.{n}.candidates.{k}.rms_um"),
                         f"{_v(rec, f'rounds.{n}.candidates.{k}.explained', '.1f', 100.0)} %",
                         _e(c["description"]), _e(aliases + (f" ({sep})" if sep else "") or "\u2013")])
        out.append(_table(["#", "candidate effect", "RMS after (\u00b5m)", "explains", "meaning",
                           "candidates this data cannot tell apart from it (and what would)"], rows,
                          f"candidates-{r['round']}", numeric=(2, 3)))
    out.append("</section>")
    return "".join(out)


def _figures_and_notes(figs: dict, prefix: str, records: list, words) -> str:
    """Figure `<prefix>_<i>` of each record with its notes; words(record) -> (alt text, caption)."""
    out = []
    for i, r in enumerate(records):
        alt, caption = words(r)
        out.append(_figure(figs, f"{prefix}_{i}", alt, caption))
        out += [f'<p class="note">{_t(n)}</p>' for n in r["notes"]]
    return "".join(out)


def _iso230(rec: dict, figs: dict) -> str:
    """The ISO 230-2 and ISO 230-4 sections (only when the data holds such readings)."""
    iso = rec.get("iso230")
    if not iso:
        return ""
    out = []
    if iso["positioning"]:
        stated = [r for r in iso["positioning"] if r["uncertainty"].get("U_um")]
        out.append('<section id="iso230-2"><h2>ISO 230-2: positioning of linear axes</h2>'
                   "<p>Per axis, from the readings along it: per target and approach direction the mean positional "
                   "deviation and its estimated standard uncertainty s over the cycles; the axis figures of ISO "
                   "230-2:2014 (\u00b5m). E: systematic positional deviation (range of the mean deviations), M: mean "
                   "bidirectional systematic positional deviation, B: reversal value (largest reversal at a "
                   "target), R: repeatability (4 s, bidirectional with the reversal), A: accuracy (range of the mean "
                   "deviations &plusmn; 2 s). "
                   + ("The expanded uncertainties U (k = 2) of E, M and B follow ISO 230-9's simplified budget from "
                      "what the test states (below each axis)." if stated else
                      "No uncertainty statement: the measuring device, temperature, expansion, misalignment and drift "
                      "were not stated (<span class=\"code\">--u-device ...</span>, or the campaign's iso230_9).")
                   + "</p>")
        for a, r in enumerate(iso["positioning"]):
            out.append(_axis_figures(rec, a))
            out.append(_targets(rec, a))
            out.append(f'<p class="note">{_t(r["uncertainty"]["statement"])}.</p>')
        out.append(_figures_and_notes(figs, "iso230_2", iso["positioning"], lambda r: (
            f"ISO 230-2 {r['axis']}", f"Mean positional deviation of {_e(r['axis'])} per target, forward and "
                                      "backward, with the &plusmn;2 s bands; the dots are the single readings.")))
        out.append("</section>")
    circ = iso.get("circles")
    if circ:
        out.append('<section id="iso230-4"><h2>ISO 230-4: circular tests</h2>'
                   "<p>Per circle and direction: the circular deviation G (about the least-squares centre, and about "
                   "the minimum-zone centre), the radial deviation F (largest and smallest, against the nominal "
                   "radius, least-squares centre), and the circular hysteresis H between the two directions "
                   "(\u00b5m).</p>")
        rows = []
        for ci, c in enumerate(circ["circles"]):
            for k, r in enumerate(c["runs"]):
                rk = f"iso230.circles.circles.{ci}.runs.{k}"
                rows.append([_e(c["plane"]) + (f" ({_e(c['setup'])})" if c.get("setup") not in (None, c["plane"])
                                               else ""),
                             _v(rec, f"iso230.circles.circles.{ci}.radius_mm", ".6g"), _e(r["direction"]),
                             _v(rec, f"{rk}.G_um", ".3g"), _v(rec, f"{rk}.G_mz_um", ".3g"),
                             _v(rec, f"{rk}.F_max_um", ".3g"), _v(rec, f"{rk}.F_min_um", ".3g"),
                             (_v(rec, f"iso230.circles.circles.{ci}.H_um", ".3g") if "H_um" in c else "&ndash;")
                             if k == 0 else ""])
        out.append(_table(["circle", "radius (mm)", "direction", "G (\u00b5m)", "G min. zone (\u00b5m)",
                           "F max (\u00b5m)", "F min (\u00b5m)", "H (\u00b5m)"], rows, "iso230-4-figures",
                          numeric=(1, 3, 4, 5, 6, 7)))
        out.append(_figures_and_notes(figs, "iso230_4", circ["circles"], lambda c: (
            f"ISO 230-4 {c['plane']}", f"Circle {_e(c['plane'])}: the radial deviation of each direction's path "
                                       "from its least-squares circle, magnified.")))
        out.append("</section>")
    return "".join(out)


#: ISO 230-2's axis figures as a laser's report lists them: (figure, record key prefix, meaning).
AXIS_FIGURES = (("E", "E", "systematic positional deviation"), ("M", "M", "mean bidirectional systematic positional "
                                                                          "deviation"),
                ("B", "B", "reversal value (largest |B_i|)"), ("B mean", "B_mean", "mean reversal value"),
                ("R", "R", "repeatability"), ("A", "A", "accuracy"))


def _axis_figures(rec: dict, a: int) -> str:
    """The a-th axis's ISO 230-2 figures, one row each: bidirectional, forward, backward, U (k = 2) where ISO
    230-9's budget gives one (um)."""
    r = rec["iso230"]["positioning"][a]
    k0 = f"iso230.positioning.{a}"
    U = r["uncertainty"].get("U_um", {})
    rows = [[f"<b>{name}</b>", _v(rec, f"{k0}.{key}_um", ".2f"),
             _v(rec, f"{k0}.{key}_fwd_um", ".2f") if f"{key}_fwd_um" in r else "",
             _v(rec, f"{k0}.{key}_bwd_um", ".2f") if f"{key}_bwd_um" in r else "",
             _v(rec, f"{k0}.uncertainty.U_um.{key}", ".2f") if key in U else "&ndash;", _e(what)]
            for name, key, what in AXIS_FIGURES]
    return (f"<h3>{_e(r['axis'])}" + (f" ({_e(r['setup'])})" if r.get("setup") else "")
            + f": {_v(rec, f'{k0}.targets', 'd')} targets over {_v(rec, f'{k0}.measured_length_mm', '.5g')} mm, "
              f"{_v(rec, f'{k0}.cycles', 'd')} cycles</h3>"
            + _table(["figure", "bidirectional (\u00b5m)", "forward (\u00b5m)", "backward (\u00b5m)",
                      "U, k = 2 (\u00b5m)", "meaning"], rows, f"iso230-2-figures-{a}", numeric=(1, 2, 3, 4)))


#: The per-target table of ISO 230-2 (the standard's table, transposed): (heading, record key, format).
TARGET_COLUMNS = (("P_i", "targets_mm", ".3f"), ("mean x_i fwd", "mean_fwd_um", ".2f"),
                  ("mean x_i bwd", "mean_bwd_um", ".2f"), ("s_i fwd", "s_fwd_um", ".2f"), ("s_i bwd", "s_bwd_um", ".2f"),
                  ("R_i fwd", "R_i_fwd_um", ".2f"), ("R_i bwd", "R_i_bwd_um", ".2f"), ("B_i", "B_i_um", ".2f"),
                  ("mean x_i bidir.", "mean_bidirectional_um", ".2f"), ("R_i bidir.", "R_i_um", ".2f"))


def _targets(rec: dict, a: int) -> str:
    """The per-target table of the a-th ISO 230-2 evaluation: per target P_i and approach direction the mean
    deviation, s, R_i = 4 s, the reversal B_i and the bidirectional mean and R_i (um)."""
    r = rec["iso230"]["positioning"][a]
    k0 = f"iso230.positioning.{a}"
    rows = [[f"{i + 1}."] + [_v(rec, f"{k0}.{key}.{i}", fmt) for _, key, fmt in TARGET_COLUMNS]
            for i in range(len(r["targets_mm"]))]
    head = ["i"] + [h for h, _, _ in TARGET_COLUMNS]
    return (f"<p>{_e(r['axis'])} per target and approach direction (\u00b5m; P_i in mm):</p>"
            + _table(head, rows, f"iso230-2-targets-{a}", numeric=tuple(range(1, 11))))


def _sensitivity(rec: dict, figs: dict) -> str:
    s = rec["sensitivity"]
    if s is None:
        return ""
    rows = [[f"{k + 1}.", _name(t["name"], t["iso"]), f"{_v(rec, f'sensitivity.top.{k}.proportion', '.2f', 100.0)} %",
             _e(t["description"])] for k, t in enumerate(s["top"])]
    return ('<section id="sensitivity"><h2>Which errors matter most on this machine</h2>'
            f"<p>Global sensitivity (GSIL) of the machine over its strokes ({_v(rec, 'sensitivity.points_per_axis', 'd')} "
            f"points per axis, tool length {_v(rec, 'sensitivity.L0_mm')} mm, cutting length "
            f"{_v(rec, 'sensitivity.LE_mm', '.3g')} mm), with "
            f"{_e(s['errors'])}: the errors whose share is large deserve the most careful measurement and "
            "compensation. This is a property of the machine's kinematics, independent of the data above.</p>"
            + _figure(figs, "sensitivity", "GSIL top errors", "Largest shares of the global sensitivity.")
            + _table(["rank", "error", "share PG_i", "meaning"], rows, "gsil", numeric=(2,)) + "</section>")


def _compensation(rec: dict, figs: dict) -> str:
    c = rec["compensation"]
    head = '<section id="compensation"><h2>Compensation</h2>'
    if c is None:
        return (head + '<p class="placeholder">No compensation was evaluated for this report. With '
                '<span class="code">--compensation DIR</span> (a folder holding summary.json with the predicted '
                "tool-tip error before and after compensation, and its maps) this section shows what the "
                "compensation achieves.</p></section>")
    ranged = any(st.get("range_k2") for st in c["stages"])
    um = ".2f"            # predicted errors to 0.01 um: what the model predicts, not what a machine resolves

    def stage(i, what):
        return _v(rec, f"compensation.stages.{i}.{what}", um, 1e3)
    rows = [[_e(st["label"]), stage(i, "max"), stage(i, "rms"), stage(i, "p95")]
            + ([f"{stage(i, 'range_k2.0')} to {stage(i, 'range_k2.1')}" if st.get("range_k2") else "\u2013"]
               if ranged else [])
            for i, st in enumerate(c["stages"])]
    head_row = ["", "largest (\u00b5m)", "RMS (\u00b5m)", "95th percentile (\u00b5m)"]
    if ranged:
        head_row.append("true RMS, k = 2 range (\u00b5m)")
    out = [head, f"<p>Predicted tool-tip error over the compensation's evaluation poses (from "
                 f"<span class=\"code\">{_e(c['folder'])}</span>)" + (f": {_e(c['method'])}" if c["method"] else "")
           + ". The largest, RMS and 95th-percentile columns are what the fitted model itself predicts: a stage "
             "that applies the model exactly (the kinematics module computes it) leaves nothing by construction. "
           + ("What the machine will show lies in the last column's range (k = 2), which adds what the model "
              "does not know." if ranged else "What the model does not know is not in these numbers.")
           + "</p>", _table(head_row, rows, "compensation-summary", numeric=(1, 2, 3, 4) if ranged else (1, 2, 3))]
    u = c.get("uncertainty") or {}
    if u:
        prior = u.get("prior") or {}
        text = (f"<p>What the prediction cannot know: the fit's uncertainty moves the tool tip by "
                f"{_v(rec, 'compensation.uncertainty.fit_mm', '.3g', 1e3)} \u00b5m RMS, the "
                f"{_v(rec, 'compensation.uncertainty.directions', 'd')} directions the data did not determine by "
                f"{_v(rec, 'compensation.uncertainty.undetermined_mm', '.3g', 1e3)} \u00b5m"
                + (f" (their size taken as that of the determined errors: "
                   f"{_v(rec, 'compensation.uncertainty.prior.linear_mm', '.3g', 1e3)} \u00b5m, "
                   f"{_v(rec, 'compensation.uncertainty.prior.angular_rad', '.3g', 1e6)} \u00b5rad)"
                   if "linear_mm" in prior and "angular_rad" in prior else "")
                + ". The last column is the range of the true RMS error"
                + (f" (its lower end: {_e(u['lower_end'])}; its upper end: {_e(u['upper_end'])})"
                   if u.get("lower_end") else "") + ".")
        if u.get("prior_note"):
            text += f" {_e(u['prior_note'][0].upper() + u['prior_note'][1:])}."
        if u.get("measurement"):
            text += (f" The measurement that would determine the undetermined part: {_e(u['measurement'])} "
                     f"(<span class=\"code\">{_e(u['command'])}</span>).")
        if u.get("axis_note"):
            text += f" {_e(u['axis_note'][0].upper() + u['axis_note'][1:])}."
        out.append(text + "</p>")
    by = c.get("by_tool_length") or []
    if by:
        def at(i, key):
            return _v(rec, f"compensation.by_tool_length.{i}.{key}", um, 1e3)
        rows = [[_v(rec, f"compensation.by_tool_length.{i}.tool_length_mm")
                 + (" (table)" if r["table_node"] else " (between)"),
                 at(i, "before.rms"), at(i, "after_table.rms"), at(i, "after_exact_correction.rms"),
                 at(i, "after_table.max")] for i, r in enumerate(by)]
        out.append("<p>The table has a tool-length dimension: the predicted tool-tip error at each of its tool "
                   "lengths and between them (RMS over random poses at that length).</p>"
                   + _table(["tool length (mm)", "before, RMS (\u00b5m)", "after the table, RMS (\u00b5m)",
                             "exact correction, RMS (\u00b5m)", "after the table, largest (\u00b5m)"], rows,
                            "compensation-by-tool-length", numeric=(1, 2, 3, 4)))
    for w in c.get("warnings") or []:
        out.append(f'<p class="warning">{_e(w)}</p>')
    for i, m in enumerate(c["maps"]):
        out.append(_figure(figs, f"compensation_{i}", m["caption"], _e(m["caption"])))
    if c["files"]:
        out.append("<p>Files for the controller: " + ", ".join(f'<span class="code">{_e(f)}</span>'
                                                               for f in c["files"]) + "</p>")
    out.append("</section>")
    return "".join(out)


# -- the certificate (only with a campaign) ------------------------------------------------------------------------
LOCATION_WORDS = {"laboratory": "in the calibration laboratory", "customer": "at the customer's premises",
                  "laboratoryBranch": "at a branch of the calibration laboratory",
                  "customerBranch": "at a branch of the customer", "other": "elsewhere"}


def _address(part: dict) -> str:
    return ", ".join(_e(part[k]) for k in ("street", "postcode", "city", "country") if part.get(k))


def _dl(items) -> str:
    """A definition list of (term, already escaped value) pairs, empty values left out."""
    return '<dl class="admin">' + "".join(f"<dt>{_e(t)}</dt><dd>{v}</dd>" for t, v in items if v) + "</dl>"


def _cert_head(rec: dict) -> str:
    c = rec["certificate"]
    h, lab, cus, mach = c["certificate"], c["laboratory"], c["customer"], c.get("machine", {})
    place, dates, proc, op = c["place"], c["dates"], c["procedure"], c["operator"]
    m = rec["machine"]
    item = " ".join(_e(mach[k]) for k in ("manufacturer", "model") if mach.get(k)) or _e(m["title"])
    return ('<section id="certificate"><p class="kind">Calibration certificate</p>'
            + _dl([("Certificate number", f'<b>{_e(h["number"])}</b>'), ("Date of issue", _e(h["issue_date"])),
                   ("Calibration laboratory", _e(lab["name"]) + (f" (accreditation {_e(lab['accreditation'])})"
                                                                 if lab.get("accreditation") else "")
                    + f"<br>{_address(lab)}"
                    + "".join(f"<br>{_e(lab[k])}" for k in ("email", "phone") if lab.get(k))),
                   ("Customer", _e(cus["name"]) + (f", {_e(cus['contact'])}" if cus.get("contact") else "")
                    + f"<br>{_address(cus)}" + (f"<br>order {_e(cus['order'])}" if cus.get("order") else "")),
                   ("Item calibrated", f"machine tool {item}" + (f": {_e(mach['description'])}"
                                                                 if mach.get("description") else "")
                    + f"<br>serial number <b>{_e(mach['serial'])}</b>"
                    + (f"; inventory number {_e(mach['inventory'])}" if mach.get("inventory") else "")
                    + (f"; control {_e(mach['controller'])}" if mach.get("controller") else "")
                    + f"<br>kinematic model: machine file <span class=\"code\">{_e(m['name'])}</span> "
                      f"({_e(m['title'])}, {_e(m['convention'])} convention)"),
                   ("Place of calibration", _e(LOCATION_WORDS[place["location"]])
                    + (f": {_e(place['site'])}" if place.get("site") else "")),
                   ("Date of calibration", _e(dates["begin"]) + (f" to {_e(dates['end'])}"
                                                                 if dates["end"] != dates["begin"] else "")),
                   ("Procedure", _e(proc["name"]) + (f" ({_e(proc['reference'])})" if proc.get("reference") else "")
                    + (f"<br>{_e(proc['description'])}" if proc.get("description") else "")),
                   ("Performed by", f"{_e(op['name'])}, {_e(op['role'])}")])
            + "</section>")


def _cert_instruments(rec: dict) -> str:
    rows = []
    for i in rec["certificate"]["instruments"]:
        rows.append([_e(i["name"]), _e(" ".join(i[k] for k in ("manufacturer", "model") if i.get(k)) or "\u2013"),
                     _e(i["serial"]),
                     _e(i["certificate"]) + f"<br>{_e(i['certificate_issuer'])}"
                     + (f", {_e(i['calibration_date'])}" if i.get("calibration_date") else ""),
                     _e(i["traceability"])])
    return ('<section id="instruments"><h2>Measuring instruments and traceability</h2>'
            + _table(["instrument", "manufacturer, model", "serial number", "calibration certificate",
                      "traceability"], rows, "instruments")
            + f"<p>{_e(rec['certificate']['traceability'])}</p></section>")


def _range(rec: dict, key: str, unit: str, fmt: str = ".1f") -> str:
    """A stated value or [low, high] range of the record, with its unit."""
    if isinstance(_get(rec, key), list):
        return f"{_v(rec, key + '.0', fmt)} to {_v(rec, key + '.1', fmt)} {unit}"
    return f"{_v(rec, key, fmt)} {unit}"


def _cert_environment(rec: dict) -> str:
    env = rec["certificate"]["environment"]
    k0 = "certificate.environment"
    stated = [(label, _range(rec, f"{k0}.{key}", unit, fmt)) for label, key, unit, fmt in (
        ("Air temperature", "air_temperature_degC", "\u00b0C", ".4g"),
        ("Temperature of the machine", "machine_temperature_degC", "\u00b0C", ".4g"),
        ("Relative humidity", "humidity_percent", "%", ".3g")) if key in env]
    if env.get("note"):
        stated.append(("Note", _e(env["note"])))
    out = ['<section id="environment"><h2>Environment</h2>']
    if stated:
        out.append(_dl(stated))
    if env["sensors"]:
        rows = [[f'<span class="code">{_e(s["name"])}</span>', _v(rec, f"{k0}.sensors.{i}.readings", "d"),
                 _v(rec, f"{k0}.sensors.{i}.min_degC", ".2f"), _v(rec, f"{k0}.sensors.{i}.mean_degC", ".2f"),
                 _v(rec, f"{k0}.sensors.{i}.max_degC", ".2f")] for i, s in enumerate(env["sensors"])]
        out.append("<p>Temperatures read during the measurement (the temperature columns of the measurement "
                   "file):</p>" + _table(["channel", "readings", "lowest (\u00b0C)", "mean (\u00b0C)",
                                          "highest (\u00b0C)"], rows, "temperatures", numeric=(1, 2, 3, 4)))
    if not stated and not env["sensors"]:
        out.append("<p>No temperature was stated or measured: ISO 230-2 asks for the temperatures of the machine "
                   "and of the air during the test to be stated.</p>")
    out.append("</section>")
    return "".join(out)


def _cert_statements(rec: dict) -> str:
    c = rec["certificate"]
    out = ['<section id="uncertainty"><h2>Statement of uncertainty</h2>']
    out += [f"<p>{_t(line)}</p>" for line in c["uncertainty_statement"]]
    if (c.get("remarks") or {}).get("text"):
        out.append(f"<h3>Remarks</h3><p>{_e(c['remarks']['text'])}</p>")
    out.append("</section>")
    return "".join(out)


def _cert_signatures(rec: dict) -> str:
    c = rec["certificate"]
    op, ap = c["operator"], c.get("approval") or {}
    place = c["laboratory"]["city"]

    def block(title, name, role, date):
        return (f'<div class="sign"><p class="role">{_e(title)}</p><div class="line"></div>'
                f"<p>{_e(name) if name else '&nbsp;'}<br>{_e(role) if role else '&nbsp;'}</p>"
                f"<p class=\"note\">{_e(place)}, {_e(date) if date else '(date)'}</p></div>")
    return ('<section id="signatures"><h2>Signatures</h2><div class="signatures">'
            + block("Calibrated by", op["name"], op["role"], c["dates"]["end"])
            + block("Approved by", ap.get("name"), ap.get("role"), ap.get("date") or c["certificate"]["issue_date"])
            + "</div><p class=\"note\">This certificate may only be reproduced in full. Its results relate only to "
              "the item calibrated, at the time and under the conditions stated. A Digital Calibration "
              "Certificate (PTB DCC 3.3.0, XML) issued with it carries the same numbers.</p></section>")


def _has_iso(rec: dict, key: str) -> bool:
    """Whether the nav entry `key` has a section (the ISO 230 sections only when the data holds such readings)."""
    iso = rec.get("iso230") or {}
    if key == "iso230-2":
        return bool(iso.get("positioning"))
    if key == "iso230-4":
        return bool(iso.get("circles"))
    if key == "iso230-3":
        return bool(rec.get("iso230_3"))
    return True


def _iso230_3(rec: dict, figs: dict) -> str:
    """The ISO 230-3 section (`report --iso230-3 FILE`), built in its own module on the same pieces (`markup`)."""
    return section_html(rec, figs)


def render(report) -> str:
    """The whole page as text (UTF-8)."""
    rec, figs = report.record, report.figures
    m = rec["machine"]
    cert = rec.get("certificate")
    sections = (("certificate", "Certificate"), ("instruments", "Instruments"), ("environment", "Environment"),
                ("verdict", "Verdict"), ("terms", "Terms"), ("data", "Data"), ("fit", "Fitted errors"),
                ("residuals", "Residuals"), ("rounds", "Diagnosis rounds"), ("iso230-2", "ISO 230-2"),
                ("iso230-4", "ISO 230-4"), ("iso230-3", "ISO 230-3"), ("sensitivity", "Sensitivity"),
                ("compensation", "Compensation"), ("uncertainty", "Uncertainty"), ("signatures", "Signatures"))
    only_cert = {"certificate", "instruments", "environment", "uncertainty", "signatures"}
    nav = "".join(f'<a href="#{k}">{t}</a>' for k, t in sections
                  if (k != "sensitivity" or rec["sensitivity"] is not None) and _has_iso(rec, k)
                  and (cert or k not in only_cert))
    body = [f"<h1>{_e(rec['title'])}</h1>",
            f'<p class="meta">Machine <b>{_e(m["name"])}</b> ({_e(m["title"])}; file <span class="code">'
            f"{_e(m['file'])}</span>, {_e(m['convention'])} convention) &middot; data <span class=\"code\">"
            f"{_e(rec['data']['file'])}</span> &middot; {_e(rec['generated'])} &middot; fiveaxis "
            f"{_e(rec['fiveaxis_version'])}</p>",
            f"<nav>{nav}</nav>"]
    if cert:
        body += [_cert_head(rec), _cert_instruments(rec), _cert_environment(rec)]
    body += [_verdict(rec), _glossary(), _data(rec, figs), _fit(rec), _residuals(rec, figs), _rounds(rec, figs),
             _iso230(rec, figs), _iso230_3(rec, figs), _sensitivity(rec, figs), _compensation(rec, figs)]
    if cert:
        body += [_cert_statements(rec), _cert_signatures(rec)]
    body.append("<footer>Made by fiveaxis from the measurement file and the machine file named above. Lengths in "
                "\u00b5m (mm in the data), angles in \u00b5rad (degrees for axis positions). Method: the project's "
                "docs/measurements.md and docs/iso230.md.</footer>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{_e(rec['title'])}</title><style>{CSS}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")
