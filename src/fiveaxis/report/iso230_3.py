"""ISO 230-3 thermal tests for people, built from the evaluation's record (`fiveaxis.iso230.thermal.evaluate`):
the text of `fiveaxis iso230-3`, and the section of `fiveaxis report --iso230-3 FILE` (record, figure, HTML)."""
from __future__ import annotations

import math

from ..iso230 import thermal as T
from ..plots.thermal import thermal_figure
from .figures import png
from .markup import escape as _e, figure as _figure, get as _get, number as _v, table as _table

#: The rows of a direction's figures: key, label.
ROWS = (("max_drift", "maximum drift"), ("max_drift_t_min", "  at (min)"), ("range", "range (max - min)"),
        ("change", "change, start to end"), ("last_hour_change", "change in the last hour"))
WIDTH = 10


def _cell(v, digits=2) -> str:
    return f"{v:{WIDTH}.{digits}f}" if v is not None else " " * (WIDTH - 1) + "-"


def _value(d: dict, key: str):
    return d.get(key if key.endswith("_min") else f"{key}_{d['unit']}")


def _decimals(res) -> int:
    return 3 if not res or res <= 0 else int(min(3, max(0, math.ceil(-math.log10(res) - 1e-9))))


def digits(rec: dict) -> dict:
    """Decimals to print per direction and temperature channel: those of its resolution as the file gives it (0.1
    um: 1; a tilt from sensors at 0.1 um 100 mm apart, 1 urad: 0; 0.01 degC: 2), at most 3."""
    out = {e["direction"]: _decimals(e.get(f"resolution_{e['unit']}")) for e in rec["directions_read"]}
    out.update({c["channel"]: _decimals(c.get("resolution_degC")) for c in rec["temperatures"]})
    return out


def _figure_rows(dirs: list, places: dict, indent="    ", extra=()) -> list[str]:
    lines = []
    for key, label in (*extra, *ROWS):
        if key == "last_hour_change" and all(_value(d, key) is None for d in dirs):
            continue
        lines.append(f"{indent}{label:28s}" + "".join(
            _cell(_value(d, key), 1 if key.endswith("_min") else places[d["direction"]]) for d in dirs))
    return lines


def _head(dirs: list) -> str:
    return f"    {'':28s}" + "".join(f"{d['direction'] + ' (' + d['unit'] + ')':>{WIDTH}s}" for d in dirs)


def _phase_label(p: dict) -> str:
    speed = ""
    if p["speed_rpm"]:
        lo, hi = p["speed_rpm"]
        speed = f", {lo:g} rpm" if lo == hi else f", {lo:g} to {hi:g} rpm"
    return f"{p['phase']} {p['start_min']:g} to {p['end_min']:g} min{speed} (from the reading at " \
           f"{p['reference_min']:g} min)"


def text(rec: dict) -> str:
    """The evaluation as text: the test, its phases, the figures per direction (um, urad) over the test and per
    phase (per target for a moving axis), the temperatures (degC) and the notes."""
    lines = [f"{rec['standard']} {rec['test_name']}: {rec['file']}",
             f"  {rec['readings']} readings over {rec['duration_min']:.4g} min (every {rec['interval_s']:g} s)"]
    reads = ", ".join(f"{d['direction']} to {d['resolution_' + d['unit']]:.3g} {d['unit']}"
                      if d["resolution_" + d["unit"]] is not None else f"{d['direction']} (binary numbers: "
                      f"resolution not written)" for d in rec["directions_read"])
    lines.append(f"  directions read: {reads}" + (f"; tilts from sensor pairs {rec['spacing_mm']:g} mm apart"
                                                    if rec["spacing_mm"] else ""))
    sp = rec.get("spindle")
    if sp:
        lines.append(f"  spindle: {sp['source']}" + (f", {sp['speed_rpm']:g} rpm" if sp.get("speed_rpm") else ""))
    lines.append("  drift: a reading minus the reference reading (the first of the test, or the last before a "
                 "phase); um, tilts in urad (= um/m)")
    places = digits(rec)
    if rec["test"] == "axis":
        lines += _axis_text(rec, places)
    else:
        dirs = rec["directions"]
        lines += ["", _head(dirs), "  over the test"]
        extra = (("ETVE", "ETVE (range over the test)"),) if rec["test"] == "etve" else ()
        lines += _figure_rows(dirs, places, extra=extra)
        lines.append(f"    {'noise (estimated)':28s}" + "".join(
            _cell(e.get(f"noise_{e['unit']}"), places[e["direction"]] + 1) for e in rec["directions_read"]))
        if len(rec["phases"]) > 1:
            for p in rec["phases"]:
                lines += ["", f"  {_phase_label(p)}"] + _figure_rows(p["directions"], places)
                lines.append(f"    {'from the start of the test':28s}" + "".join(
                    _cell(d[f"from_start_{d['unit']}"], places[d["direction"]]) for d in p["directions"]))
    if rec["temperatures"]:
        lines += ["", f"  {'temperature (degC)':22s}{'first':>9s}{'last':>9s}{'min':>9s}{'max':>9s}{'range':>9s}"
                      f"{'change':>9s}{'readings':>10s}"]
        for c in rec["temperatures"]:
            lines.append(f"    {c['channel']:20s}" + "".join(f"{c[k]:9.{places[c['channel']]}f}" for k in (
                "first_degC", "last_degC", "min_degC", "max_degC", "range_degC", "change_degC"))
                + f"{c['readings']:10d}")
        if len(rec["phases"]) > 1:
            lines.append(f"    {'change per phase':20s}" + "".join(f"{p['phase']:>12s}" for p in rec["phases"]))
            for c in rec["temperatures"]:
                cells = []
                for p in rec["phases"]:
                    f = next((t for t in p["temperatures"] if t["channel"] == c["channel"]), None)
                    cells.append(f"{f['change_degC']:12.{places[c['channel']]}f}" if f else f"{'-':>12s}")
                lines.append(f"    {c['channel']:20s}" + "".join(cells))
    for n in rec["notes"]:
        lines.append(f"  note: {n}")
    return "\n".join(lines)


def _axis_text(rec: dict, places: dict) -> list[str]:
    lines = [f"  axis {rec['axis']}: {len(rec['targets'])} targets"]
    for tg in rec["targets"]:
        dirs = tg["directions"]
        lines += ["", f"  target {rec['axis']} = {tg['position_mm']:g} mm ({tg['readings']} readings)", _head(dirs)]
        lines += _figure_rows(dirs, places)
    e = rec.get("expansion")
    if e:
        k = places.get(rec["axis"], 2)
        lines += ["", f"  change of the distance from {rec['axis']} = {e['from_mm']:g} to {e['to_mm']:g} mm "
                      f"({e['length_mm']:g} mm, {e['cycles']} cycles)",
                  f"    {'maximum change':28s}{e['max_drift_um']:{WIDTH}.{k}f} um at {e['max_drift_t_min']:.1f} min "
                  f"({e['max_drift_um_per_m']:.{k}f} um/m)",
                  f"    {'range (max - min)':28s}{e['range_um']:{WIDTH}.{k}f} um",
                  f"    {'change, start to end':28s}{e['change_um']:{WIDTH}.{k}f} um"]
    return lines


def section(file, test=None, spindle=None, spacing_mm=None) -> tuple[dict, dict]:
    """The report's ISO 230-3 section of a test file (arguments as `fiveaxis.iso230.thermal.evaluate_file`): its
    record and figure."""
    rec = T.evaluate_file(file, test, spindle, spacing_mm)
    return rec, {"iso230_3": png(thermal_figure(rec))}


def _people(unit: str) -> str:
    return {"um": "\u00b5m", "urad": "\u00b5rad"}.get(unit, unit)


def section_html(rec: dict, figs: dict) -> str:
    """The HTML of the report's ISO 230-3 section (empty without one): the figures with the decimals of the
    readings' resolution, as the text prints them."""
    th = rec.get("iso230_3")
    if not th:
        return ""
    places = digits(th)
    out = [f'<section id="iso230-3"><h2>ISO 230-3: {_e(th["test_name"])}</h2>',
           f"<p>From <span class=\"code\">{_e(th['file'])}</span>: {_v(rec, 'iso230_3.readings', 'd')} readings "
           f"over {_v(rec, 'iso230_3.duration_min')} min. The drift of a direction is its reading minus the reference "
           f"reading (the first of the test; for a phase, the last reading before it), \u00b5m; tilts in \u00b5rad "
           f"(= \u00b5m/m).</p>"]
    keys = [k for k, _ in ROWS if k != "max_drift_t_min"]
    head = ["direction"] + [label for k, label in ROWS if k != "max_drift_t_min"]
    numeric = tuple(range(1, len(head)))

    def rows_of(base):
        """The rows of the directions at `base` (a key of the record); every number the record's (report.markup.number)."""
        rows = []
        for n, d in enumerate(_get(rec, base)):
            fmt = f".{places[d['direction']]}f"
            rows.append([_e(d["direction"]) + f" ({_people(d['unit'])})"]
                        + [_v(rec, f"{base}.{n}.{k if k.endswith('_min') else k + '_' + d['unit']}", fmt)
                           if _value(d, k) is not None else "\u2013" for k in keys])
        return rows
    if th["test"] == "axis":
        for i, tg in enumerate(th["targets"]):
            out.append(f"<p>Target {_e(th['axis'])} = {_v(rec, f'iso230_3.targets.{i}.position_mm', 'g')} mm</p>"
                       + _table(head, rows_of(f"iso230_3.targets.{i}.directions"), "", numeric=numeric))
        e = th.get("expansion")
        if e:
            f = f".{places.get(th['axis'], 2)}f"
            out.append(f"<p>Change of the distance between {_v(rec, 'iso230_3.expansion.from_mm', 'g')} and "
                       f"{_v(rec, 'iso230_3.expansion.to_mm', 'g')} mm: largest "
                       f"{_v(rec, 'iso230_3.expansion.max_drift_um', f)} \u00b5m "
                       f"({_v(rec, 'iso230_3.expansion.max_drift_um_per_m', f)} \u00b5m/m), range "
                       f"{_v(rec, 'iso230_3.expansion.range_um', f)} \u00b5m.</p>")
    else:
        out.append(_table(head, rows_of("iso230_3.directions"), "iso230-3-figures", numeric=numeric))
        if th["test"] == "etve":
            etve = []
            for n, d in enumerate(th["directions"]):
                key, fmt = f"iso230_3.directions.{n}.ETVE_{d['unit']}", f".{places[d['direction']]}f"
                etve.append(f"{_e(d['direction'])} {_v(rec, key, fmt)} {_people(d['unit'])}")
            out.append("<p>ETVE per direction (range over the test): " + ", ".join(etve) + ".</p>")
        for j, p in enumerate(th["phases"] if len(th["phases"]) > 1 else []):
            out.append(f"<p>{_e(_phase_label(p))}</p>" + _table(head, rows_of(f"iso230_3.phases.{j}.directions"), "",
                                                                numeric=numeric))
    if th["temperatures"]:
        out.append(_table(["temperature", "first (\u00b0C)", "last (\u00b0C)", "min (\u00b0C)", "max (\u00b0C)",
                           "range (\u00b0C)", "change (\u00b0C)"],
                          [[_e(c["channel"])] + [_v(rec, f"iso230_3.temperatures.{i}.{k}", f".{places[c['channel']]}f")
                                                 for k in ("first_degC", "last_degC", "min_degC", "max_degC",
                                                           "range_degC", "change_degC")]
                           for i, c in enumerate(th["temperatures"])], "iso230-3-temperatures",
                          numeric=(1, 2, 3, 4, 5, 6)))
    out.append(_figure(figs, "iso230_3", f"ISO 230-3 {th['test']}", "Drift of each direction and the temperatures "
                                                                     "over the test."))
    out += [f'<p class="note">{_e(n)}</p>' for n in th["notes"]]
    out.append("</section>")
    return "".join(out)
