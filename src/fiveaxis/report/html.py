"""The report as one self-contained HTML page: inline CSS, figures as base64 PNG, no script, nothing fetched.

`render(report)` builds the page from `Report.record` and `Report.figures` with Python string building (every
text escaped); the sections follow the reader's questions: is the machine explained (verdict), what was
measured (data), what the errors are (fit, with ISO 230 names and expanded uncertainties), where the model
fails (residuals), how the missing effects were found (diagnosis rounds), which errors matter most
(sensitivity), and what compensation would achieve.
"""
from __future__ import annotations

import base64
import re
from html import escape

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
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
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
footer { margin-top: 40px; color: var(--muted); font-size: 0.85em; border-top: 1px solid var(--line); padding-top: 8px; }
@media print {
  body { max-width: none; padding: 0; font-size: 11pt; }
  nav { display: none; }
  h2 { break-after: avoid; }
  figure, table, .verdict { break-inside: avoid; }
}
@page { size: A4; margin: 14mm 12mm; }
"""


def _e(text) -> str:
    return escape(str(text), quote=True)


def _t(text) -> str:
    """Escaped prose whose ASCII units (um, urad) are shown as people write them (µm, µrad)."""
    return _e(re.sub(r"(?<=[0-9] )u(m|rad)\b", "\u00b5\\1", str(text)))


def _unit(unit: str) -> str:
    """um -> µm, urad -> µrad for people (also inside 'urad/mm')."""
    return unit.replace("urad", "\u00b5rad").replace("um", "\u00b5m") if unit else ""


def _num(value, digits: int = 4) -> str:
    return "&ndash;" if value is None else f"{value:.{digits}g}"


def _name(name: str, iso_name) -> str:
    return f'<span class="code">{_e(name)}</span>' + (f' <span class="code">({_e(iso_name)})</span>'
                                                      if iso_name else "")


def _figure(figures: dict, key: str, alt: str, caption: str) -> str:
    if key not in figures:
        return ""
    data = base64.b64encode(figures[key]).decode("ascii")
    return (f'<figure id="fig-{_e(key)}"><img alt="{_e(alt)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{caption}</figcaption></figure>")


def _table(head: list[str], rows: list[list[str]], table_id: str = "", numeric=(), row_class=None) -> str:
    """A table from already escaped cells; columns in `numeric` are right-aligned."""
    ths = "".join(f'<th class="num">{h}</th>' if i in numeric else f"<th>{h}</th>" for i, h in enumerate(head))
    body = []
    for r, row in enumerate(rows):
        cls = f' class="{row_class[r]}"' if row_class and row_class[r] else ""
        tds = "".join(f'<td class="num">{c}</td>' if i in numeric else f"<td>{c}</td>" for i, c in enumerate(row))
        body.append(f"<tr{cls}>{tds}</tr>")
    ident = f' id="{table_id}"' if table_id else ""
    return f"<table{ident}><thead><tr>{ths}</tr></thead><tbody>{''.join(body)}</tbody></table>"


# -- sections -----------------------------------------------------------------------------------------------------
def _verdict(rec: dict) -> str:
    v = rec["verdict"]
    cls = "verdict ok" if v["explained"] else "verdict"
    ratio = "&ndash;" if v["ratio"] is None else f"{v['ratio']:.3g}"
    out = [f'<section id="verdict" class="{cls}"><p class="headline">{_t(v["headline"])}</p>',
           '<div class="numbers">',
           f"<div><b>{_num(v['rms_first_um'], 3)} &rarr; {_num(v['rms_um'], 3)} \u00b5m</b>"
           f"<span>residual RMS: geometric model &rarr; final model</span></div>",
           f"<div><b>{_num(v['noise_um'], 3)} \u00b5m</b><span>noise ({_e(v['noise_source'])})</span></div>",
           f"<div><b>{ratio}</b><span>residual / noise (1 = explained to the noise)</span></div>",
           f"<div><b>{len(v['effects_found'])}</b><span>effects found beyond the geometric errors</span></div>",
           "</div>"]
    if v["effects_found"]:
        out.append("<p><b>Effects found</b> (each lowered the residual and passed the decision test):</p><ul>")
        for f in v["effects_found"]:
            out.append(f"<li>{_name(f['id'], f['iso'])}: {_e(f['description'])}</li>")
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
    rows = [[_e(r["variable"]), _e(r["unit"]), _num(r["min"], 5), _num(r["max"], 5),
             f"{_num(r['stroke'][0], 5)} to {_num(r['stroke'][1], 5)}", f"{100 * r['coverage']:.0f} %"]
            for r in d["ranges"]]
    extra = [f"Tool length {_num(d['tool_length_mm'][0], 5)}"
             + (f" to {_num(d['tool_length_mm'][1], 5)}" if d["tool_length_mm"][1] != d["tool_length_mm"][0] else "")
             + " mm"]
    if d["time_s"] is not None:
        extra.append(f"time {_num(d['time_s'][0], 4)} to {_num(d['time_s'][1], 4)} s")
    extra.append("measurement uncertainty (sigma column) " + (f"{_num(d['sigma_um'], 3)} \u00b5m" if d["sigma_um"]
                                                               is not None else "not given"))
    return (f'<section id="data"><h2>The data</h2><p>{d["n"]} measured poses from <span class="code">'
            f"{_e(d['file'])}</span>. Instrument: {_e(d['instrument'])}. {_e('; '.join(extra))}.</p>"
            + _table(["axis", "unit", "lowest", "highest", "stroke", "stroke covered"], rows, "ranges",
                     numeric=(2, 3, 5))
            + _figure(figs, "coverage", "pose coverage",
                      "Each dot is a measured pose, projected on two axes; the dashed box is the stroke of the "
                      "machine file. Errors that change along an axis can only be found where the poses spread "
                      "along it.")
            + "</section>")


def _fit(rec: dict) -> str:
    f = rec["fit"]
    effects = ", ".join(f"{e} ({i})" if i else e for e, i in zip(f["effects"], f["effects_iso"])) or "none"
    out = ['<section id="fit"><h2>The fitted errors</h2>',
           f"<p>The final model (geometric errors + effects: {_e(effects)}) fitted by weighted least squares on "
           f"the exact kinematic chain: residual RMS {_num(f['rms_um'], 4)} \u00b5m; {f['n_parameters']} "
           f"parameters, of which the data determines {f['rank']} independent directions (condition number "
           f"{_num(f['condition'], 3)}). Uncertainty scale: {_e(f['sigma'])}"
           + (f", reduced chi\u00b2 {_num(f['reduced_chi2'], 3)}" if f["reduced_chi2"] is not None else "")
           + ". Values with an expanded uncertainty U (k = 2): first what the data determine alone, then what they "
             "determine relative to what they cannot separate it from; the parameters the data cannot determine "
             "alone are listed after, with the measurement that would separate them.</p>"]
    rows = []
    for p in f["parameters"]:
        if p["determined"]:
            rows.append([f'<span class="code">{_e(p["name"])}</span>', _e(p["iso"] or "\u2013"),
                         _e(p["description"]), _num(p["value"], 4), _num(p["u_k2"], 2), _e(_unit(p["unit"])),
                         _e(p["note"])])
    if rows:
        out.append(_table(["parameter", "ISO 230", "meaning", "value", "U (k = 2)", "unit", "note"], rows,
                          "parameters", numeric=(3, 4)))
    if f.get("quantities"):
        out.append("<h3>Determined relative to what the data cannot separate</h3><p>Each quantity is determined "
                   "together with the others named beside it (the locations of the rotary axes relative to the "
                   "axes' zero offsets, an axis's tilt relative to the artefacts' placement); the exact formula "
                   "is one click away.</p>")
        rows = [[f'<span class="code">{_e(q["name"])}</span>', _e(q["iso"] or "\u2013"), _e(q["quantity"]),
                 _num(q["value"], 4), _num(q["u_k2"], 2), _e(_unit(q["unit"])),
                 f'relative to {_e(q["relative_to"])}<details><summary>formula</summary>'
                 f'<span class="code">{_e(q["formula"])}</span></details>'] for q in f["quantities"]]
        out.append(_table(["quantity", "ISO 230", "meaning", "value", "U (k = 2)", "unit", "relative to"], rows,
                          "quantities", numeric=(3, 4)))
    if f.get("setups"):
        out.append("<h3>Setups: where the artefacts lay</h3><p>The unknown placement of each artefact or instrument "
                   "(offsets c, a length offset l of 1-D readings, rotations w), fitted beside the machine's errors; "
                   "these are not errors of the machine.</p>")
        rows, classes = [], []
        for p in f["setups"]:
            rows.append([_e(p["setup"]), f'<span class="code">{_e(p["name"])}</span>', _e(p["kind"]),
                         _num(p["value"], 4) if p["determined"] else "not determined",
                         _num(p["u_k2"], 2) if p["determined"] else "", _e(_unit(p["unit"])), _e(p["note"])])
            classes.append("" if p["determined"] else "undetermined")
        out.append(_table(["setup", "unknown", "kind", "value", "U (k = 2)", "unit", "note"], rows, "setups",
                          numeric=(3, 4), row_class=classes))
        for text in sorted({p["setup"] + " " + p["placement"] for p in f["setups"] if p["placement"]}):
            out.append(f"<p>{_e(text)}.</p>")
    if f["combinations"]:
        rows = [[f'<span class="code">{_e(c["formula"])}</span>', f'<span class="code">{_e(c["formula_iso"])}</span>',
                 _num(c["value"], 4), _num(c["u_k2"], 2), _e(_unit(c["unit"]))] for c in f["combinations"]]
        out.append(f"<details><summary>Every combination the data determine, as formulas ({len(rows)})</summary>"
                   + _table(["combination", "in ISO 230 names", "value", "U (k = 2)", "unit"], rows, "combinations",
                            numeric=(2, 3)) + "</details>")
    if f["groups"]:
        out.append("<h3>What the data cannot separate, and which measurement would</h3>")
        rows = []
        for g in f["groups"]:
            names = ", ".join(f"{n} ({i})" if i else n for n, i in zip(g["members"], g["iso"]))
            tips = "; ".join(f"{s['measure']}: determines {', '.join(s['determines'])}" if s.get("determines")
                             else f"{s['measure']}: could not be evaluated ({s.get('error', '')})"
                             for s in g["separate_by"])
            rows.append([_e(names), _e(g["why"]), _e(tips or "\u2013")])
        out.append(_table(["parameters", "why", "extra measurement that separates them"], rows, "groups"))
    if f["correlations"]:
        rows = [[_name(c["a"], c["a_iso"]), _name(c["b"], c["b_iso"]), f"{c['r']:+.3f}"] for c in f["correlations"]]
        out.append("<h3>Strongly correlated determined parameters</h3>"
                   + _table(["parameter", "parameter", "correlation r"], rows, "correlations", numeric=(2,)))
    out.append("</section>")
    return "".join(out)


def _residuals(rec: dict, figs: dict) -> str:
    r = rec["residuals"]
    changed = r["before"]["effects"] != r["after"]["effects"]
    text = (f"Grey: the residual of the model the diagnosis started from (RMS {_num(r['before']['rms_um'], 3)} "
            f"\u00b5m)." + (f" Blue: the final model with the effects found (RMS {_num(r['after']['rms_um'], 3)} "
                            f"\u00b5m)." if changed else " No effect was added."))
    return ('<section id="residuals"><h2>Residuals against each axis and time</h2>'
            "<p>A model that explains the data leaves residuals scattered evenly around zero, with no trend "
            "along any axis or in time. A slope, a curve or a step along a variable points at an effect that "
            "changes with it.</p>"
            + _figure(figs, "residuals", "residuals against each variable", _t(text)) + "</section>")


def _rounds(rec: dict, figs: dict) -> str:
    out = ['<section id="rounds"><h2>Diagnosis rounds</h2>',
           "<p>Each round fits the model, scores every candidate effect (each error and the tool length, changing "
           "linearly, quadratically or cubically along each axis or with time) by how much of the residual it "
           "explains, and decides with an extended BIC and cross-validation whether the best one is real. If it "
           "is, it is added and the next round starts.</p>",
           _figure(figs, "rounds", "RMS per round", "Residual RMS after each round against the noise level.")]
    for r in rec["rounds"]:
        model = "geometric errors" + "".join(f" + {a} ({i})" if i else f" + {a}"
                                             for a, i in zip(r["added"], r["added_iso"]))
        d = r["decision"]
        verdict = "an effect is missing" if r["missing_effect"] else "no missing effect"
        ratio = "" if r["ratio"] is None else f", ratio {r['ratio']:.3g}"
        out.append(f"<h3>Round {r['round']}: {_e(verdict)}</h3><p>Model: {_e(model)}. Residual RMS "
                   f"{_num(r['rms_um'], 4)} \u00b5m against noise {_num(r['noise_um'], 3)} \u00b5m{ratio}. "
                   f"Decision: best candidate &Delta;EBIC {_num(d.get('delta_ebic_best'), 4)} (must be &lt; 0), "
                   f"{d.get('cv_folds', '')}-fold cross-validation held-out error "
                   f"{_num(d.get('cv_sse_without'), 4)} &rarr; {_num(d.get('cv_sse_with'), 4)} (must fall).</p>")
        rows = []
        for k, c in enumerate(r["candidates"], 1):
            aliases = ", ".join(f"{a} ({i})" if i else a for a, i in zip(c["aliases"], c["aliases_iso"]))
            sep = "; ".join(f"{s['measure']} would separate " + " | ".join(", ".join(g) for g in s["separates"])
                            for s in c["separate_by"])
            rows.append([str(k), _name(c["id"], c["iso"]), _num(c["rms_um"], 4), f"{100 * c['explained']:.1f} %",
                         _e(c["description"]), _e(aliases + (f" ({sep})" if sep else "") or "\u2013")])
        out.append(_table(["#", "candidate effect", "RMS after (\u00b5m)", "explains", "meaning",
                           "indistinguishable on this data"], rows, f"candidates-{r['round']}", numeric=(0, 2, 3)))
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
        out.append('<section id="iso230-2"><h2>ISO 230-2: positioning of linear axes</h2>'
                   "<p>Per axis, from the readings along it: per target and approach direction the mean positional "
                   "deviation and its estimated standard uncertainty s over the cycles; the axis figures of ISO "
                   "230-2:2014 (&micro;m). E: systematic positional deviation (range of the mean deviations), M: mean "
                   "bidirectional systematic positional deviation, B: reversal value (largest reversal at a "
                   "target), R: repeatability (4 s, bidirectional with the reversal), A: accuracy (range of the mean "
                   "deviations &plusmn; 2 s). No uncertainty statement: the measuring device, temperature, "
                   "expansion, misalignment and drift were not stated (<span class=\"code\">fiveaxis iso230-2 "
                   "--u-device ...</span>).</p>")
        keys = [("E", "E"), ("M", "M"), ("B", "B"), ("B_mean", "B mean"), ("R", "R"), ("A", "A")]
        rows = []
        for r in iso["positioning"]:
            rows.append([_e(r["axis"]) + (f" ({_e(r['setup'])})" if r.get("setup") else ""), str(r["targets"]),
                         str(r["cycles"]), _num(r["measured_length_mm"], 5)]
                        + [_num(r[f"{k}_um"], 3) + (f" / {_num(r[f'{k}_fwd_um'], 3)} / {_num(r[f'{k}_bwd_um'], 3)}"
                                                    if f"{k}_fwd_um" in r else "") for k, _ in keys])
        out.append(_table(["axis", "targets", "cycles", "length (mm)"]
                          + [f"{label} (\u00b5m){' bi / fwd / bwd' if k in ('E', 'R', 'A') else ''}"
                             for k, label in keys], rows, "iso230-2-figures", numeric=tuple(range(1, 10))))
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
                   "(&micro;m).</p>")
        rows = []
        for c in circ["circles"]:
            for k, r in enumerate(c["runs"]):
                rows.append([_e(c["plane"]) + (f" ({_e(c['setup'])})" if c.get("setup") not in (None, c["plane"])
                                               else ""),
                             _num(c["radius_mm"], 6), _e(r["direction"]), _num(r["G_um"], 3), _num(r["G_mz_um"], 3),
                             _num(r["F_max_um"], 3), _num(r["F_min_um"], 3),
                             _num(c.get("H_um"), 3) if k == 0 else ""])
        out.append(_table(["circle", "radius (mm)", "direction", "G (\u00b5m)", "G min. zone (\u00b5m)",
                           "F max (\u00b5m)", "F min (\u00b5m)", "H (\u00b5m)"], rows, "iso230-4-figures",
                          numeric=(1, 3, 4, 5, 6, 7)))
        out.append(_figures_and_notes(figs, "iso230_4", circ["circles"], lambda c: (
            f"ISO 230-4 {c['plane']}", f"Circle {_e(c['plane'])}: the radial deviation of each direction's path "
                                       "from its least-squares circle, magnified.")))
        out.append("</section>")
    return "".join(out)


def _sensitivity(rec: dict, figs: dict) -> str:
    s = rec["sensitivity"]
    if s is None:
        return ""
    rows = [[str(k), _name(t["name"], t["iso"]), f"{100 * t['proportion']:.2f} %", _e(t["description"])]
            for k, t in enumerate(s["top"], 1)]
    return ('<section id="sensitivity"><h2>Which errors matter most on this machine</h2>'
            f"<p>Global sensitivity (GSIL) of the machine over its strokes ({s['points_per_axis']} points per axis, "
            f"tool length {_num(s['L0_mm'], 4)} mm, cutting length {_num(s['LE_mm'], 3)} mm), with "
            f"{_e(s['errors'])}: the errors whose share is large deserve the most careful measurement and "
            "compensation. This is a property of the machine's kinematics, independent of the data above.</p>"
            + _figure(figs, "sensitivity", "GSIL top errors", "Largest shares of the global sensitivity.")
            + _table(["rank", "error", "share PG_i", "meaning"], rows, "gsil", numeric=(0, 2)) + "</section>")


def _compensation(rec: dict, figs: dict) -> str:
    c = rec["compensation"]
    head = '<section id="compensation"><h2>Compensation</h2>'
    if c is None:
        return (head + '<p class="placeholder">No compensation was evaluated for this report. With '
                '<span class="code">--compensation DIR</span> (a folder holding summary.json with the predicted '
                "tool-tip error before and after compensation, and its maps) this section shows what the "
                "compensation achieves.</p></section>")
    ranged = any(st.get("range_k2") for st in c["stages"])
    rows = [[_e(st["label"]), _num(st["max"] * 1e3, 3), _num(st["rms"] * 1e3, 3), _num(st["p95"] * 1e3, 3)]
            + ([f"{_num(st['range_k2'][0] * 1e3, 3)} to {_num(st['range_k2'][1] * 1e3, 3)}"
                if st.get("range_k2") else "\u2013"] if ranged else [])
            for st in c["stages"]]
    head_row = ["", "largest (\u00b5m)", "RMS (\u00b5m)", "95th percentile (\u00b5m)"]
    if ranged:
        head_row.append("true RMS, k = 2 range (\u00b5m)")
    out = [head, f"<p>Predicted tool-tip error over the compensation's evaluation poses (from "
                 f"<span class=\"code\">{_e(c['folder'])}</span>)" + (f": {_e(c['method'])}" if c["method"] else "")
           + ".</p>", _table(head_row, rows, "compensation-summary", numeric=(1, 2, 3))]
    u = c.get("uncertainty") or {}
    if u:
        prior = u.get("prior") or {}
        text = (f"<p>What the prediction cannot know: the fit's uncertainty moves the tool tip by "
                f"{_num(u['fit_mm'] * 1e3, 3)} \u00b5m RMS, the {u['directions']} directions the data did not "
                f"determine by {_num(u['undetermined_mm'] * 1e3, 3)} \u00b5m (their size taken as that of the "
                f"determined errors: {_num(prior.get('linear_mm', 0.0) * 1e3, 3)} \u00b5m, "
                f"{_num(prior.get('angular_rad', 0.0) * 1e6, 3)} \u00b5rad). The last column is the range of the "
                f"true RMS error.")
        if u.get("measurement"):
            text += (f" The measurement that would determine the undetermined part: {_e(u['measurement'])} "
                     f"(<span class=\"code\">{_e(u['command'])}</span>).")
        if u.get("axis_note"):
            text += f" {_e(u['axis_note'][0].upper() + u['axis_note'][1:])}."
        out.append(text + "</p>")
    by = c.get("by_tool_length") or []
    if by:
        rows = [[_num(r["tool_length_mm"], 4) + (" (table)" if r["table_node"] else " (between)"),
                 _num(r["before"]["rms"] * 1e3, 3), _num(r["after_table"]["rms"] * 1e3, 3),
                 _num(r["after_exact_correction"]["rms"] * 1e3, 3), _num(r["after_table"]["max"] * 1e3, 3)]
                for r in by]
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
    """The ISO 230-3 section (`report --iso230-3 FILE`), built in its own module on this one's helpers."""
    from .iso230_3 import section_html   # imported here: that module imports this one's helpers
    return section_html(rec, figs)


def render(report) -> str:
    """The whole page as text (UTF-8)."""
    rec, figs = report.record, report.figures
    m = rec["machine"]
    nav = "".join(f'<a href="#{k}">{t}</a>' for k, t in (
        ("verdict", "Verdict"), ("terms", "Terms"), ("data", "Data"), ("fit", "Fitted errors"),
        ("residuals", "Residuals"), ("rounds", "Diagnosis rounds"), ("iso230-2", "ISO 230-2"),
        ("iso230-4", "ISO 230-4"), ("iso230-3", "ISO 230-3"), ("sensitivity", "Sensitivity"),
        ("compensation", "Compensation"))
        if (k != "sensitivity" or rec["sensitivity"] is not None) and _has_iso(rec, k))
    body = [f"<h1>{_e(rec['title'])}</h1>",
            f'<p class="meta">Machine <b>{_e(m["name"])}</b> ({_e(m["title"])}; file <span class="code">'
            f"{_e(m['file'])}</span>, {_e(m['convention'])} convention) &middot; data <span class=\"code\">"
            f"{_e(rec['data']['file'])}</span> &middot; {_e(rec['generated'])} &middot; fiveaxis "
            f"{_e(rec['fiveaxis_version'])}</p>",
            f"<nav>{nav}</nav>",
            _verdict(rec), _glossary(), _data(rec, figs), _fit(rec), _residuals(rec, figs), _rounds(rec, figs),
            _iso230(rec, figs), _iso230_3(rec, figs), _sensitivity(rec, figs), _compensation(rec, figs),
            "<footer>Made by fiveaxis from the measurement file and the machine file named above. Lengths in "
            "\u00b5m (mm in the data), angles in \u00b5rad (degrees for axis positions). Method: the project's "
            "docs/measurements.md and docs/iso230.md.</footer>"]
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{_e(rec['title'])}</title><style>{CSS}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")
