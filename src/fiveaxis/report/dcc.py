"""The certificate as a PTB Digital Calibration Certificate (DCC, schema 3.3.0; quantities in D-SI 2.2).

`write(record)` turns the report's record with its certificate (`record["certificate"]`, see report.certificate)
into DCC XML: administrative data from the campaign (software, core data, the machine as the item, laboratory,
responsible persons, customer, statements), and the measurement results: the fitted errors (each a si:real with its
expanded uncertainty, k = 2), the quantities determined relative to others, the ISO 230-2 figures per axis with
the per-target table, the ISO 230-4 figures per circle and direction; the instruments as measuring equipment and
the environment as influence conditions. `read(xml)` reads the quantities back ({result name: {quantity name:
{value, unit, U, k}}}) for the tests and for anyone who wants the numbers without XML tooling.

Units in D-SI syntax: `\\micro\\metre`, `\\micro\\radian`, `\\milli\\metre`, `\\degreecelsius`, ratios with
`\\tothe{-1}`. Numbers are written as Python's shortest round-trip repr, so the values read back are the
record's, bit for bit. Only the standard library's ElementTree is used: the runtime does not need lxml.
"""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from .. import __version__

DCC = "https://ptb.de/dcc"
SI = "https://ptb.de/si"
SCHEMA_VERSION = "3.3.0"
ET.register_namespace("dcc", DCC)
ET.register_namespace("si", SI)

#: D-SI spellings of the units the record uses (prefix + unit; a ratio's denominator with \tothe{-1}).
_UNITS = {"um": r"\micro\metre", "mm": r"\milli\metre", "urad": r"\micro\radian", "rad": r"\radian",
          "deg": r"\degree", "s": r"\second", "degC": r"\degreecelsius", "K": r"\kelvin", "%": r"\percent",
          "1": r"\one"}


def dsi_unit(unit: str) -> str:
    """A record's unit (um, urad, urad/mm, um/deg, um/mm^2, degC, ...) in D-SI syntax."""
    num, _, den = unit.partition("/")
    if num not in _UNITS:
        raise ValueError(f"unit {unit!r}: no D-SI spelling")
    out = _UNITS[num]
    if den:
        base, _, power = den.partition("^")
        if base not in _UNITS:
            raise ValueError(f"unit {unit!r}: no D-SI spelling")
        out += _UNITS[base] + r"\tothe{" + f"-{int(power or 1)}" + "}"
    return out


def _el(parent, tag: str, text=None, ns: str = DCC, **attrs):
    e = ET.SubElement(parent, f"{{{ns}}}{tag}", {k: str(v) for k, v in attrs.items()})
    if text is not None:
        e.text = str(text)
    return e


def _text(parent, tag: str, content: str, lang: str):
    """A dcc:textType or richContentType element with one content in the certificate's language."""
    e = _el(parent, tag)
    _el(e, "content", content, lang=lang)
    return e


def _num(x) -> str:
    """A number as D-SI's decimal type spells it: the shortest repr that reads back to the same float."""
    return repr(float(x))


def _real(parent, value, unit: str, U=None, label: str | None = None, k: int = 2, p: float = 0.95):
    """si:real: [label,] value, unit[, the expanded uncertainty U (k, coverage probability)]."""
    r = _el(parent, "real", ns=SI)
    if label:
        _el(r, "label", label, ns=SI)
    _el(r, "value", _num(value), ns=SI)
    _el(r, "unit", dsi_unit(unit), ns=SI)
    if U is not None:
        mu = _el(_el(r, "measurementUncertaintyUnivariate", ns=SI), "expandedMU", ns=SI)
        _el(mu, "valueExpandedMU", _num(U), ns=SI)
        _el(mu, "coverageFactor", _num(k), ns=SI)
        _el(mu, "coverageProbability", _num(p), ns=SI)
    return r


def _quantity(parent, name: str, lang: str, value=None, unit: str = "", U=None, description: str | None = None,
              none: str | None = None):
    """dcc:quantity: a name, [a description,] and a si:real, or dcc:noQuantity with the reason (none)."""
    q = _el(parent, "quantity")
    _text(q, "name", name, lang)
    if description:
        _text(q, "description", description, lang)
    if value is not None and not spelled(unit):
        none = (f"{value:.6g} +- {U:.2g} in the fit's internal unit '{unit}': not a physical quantity, not stated"
                if U is not None else f"{value:.6g} in the fit's internal unit '{unit}': not stated")
        value = None
    if value is None:
        _text(q, "noQuantity", none or "not determined", lang)
    else:
        _real(q, value, unit, U)
    return q


def spelled(unit: str) -> bool:
    """Whether a record's unit has a D-SI spelling (what has not, e.g. a profile's 'scaled', is not a quantity the
    certificate can state)."""
    try:
        dsi_unit(unit)
    except ValueError:
        return False
    return True


def _real_list(parent, name: str, values, unit: str, lang: str):
    """dcc:quantity holding an si:realListXMLList (one unit for all values)."""
    q = _el(parent, "quantity")
    _text(q, "name", name, lang)
    rl = _el(q, "realListXMLList", ns=SI)
    _el(rl, "valueXMLList", " ".join(_num(v) for v in values), ns=SI)
    _el(rl, "unitXMLList", dsi_unit(unit), ns=SI)
    return q


def _contact(parent, tag: str, who: dict, lang: str):
    """dcc:contactType (name, e-mail, phone, location: city, country, post code, street; the city is required)."""
    c = _el(parent, tag)
    _text(c, "name", who["name"], lang)
    if who.get("email"):
        _el(c, "eMail", who["email"])
    if who.get("phone"):
        _el(c, "phone", who["phone"])
    loc = _el(c, "location")
    for key, tag_ in (("city", "city"), ("country", "countryCode"), ("postcode", "postCode"), ("street", "street")):
        if who.get(key):
            _el(loc, tag_, who[key])
    return c


def _identification(parent, issuer: str, value: str, name: str, lang: str):
    i = _el(parent, "identification")
    _el(i, "issuer", issuer)
    _el(i, "value", value)
    _text(i, "name", name, lang)


def _make_model_serial(e, part: dict, lang: str):
    """The manufacturer, model and serial number of an item or an instrument (in the schema's order); returns the
    identifications element for more."""
    if part.get("manufacturer"):
        _text(_el(e, "manufacturer"), "name", part["manufacturer"], lang)
    if part.get("model"):
        _el(e, "model", part["model"])
    ids = _el(e, "identifications")
    _identification(ids, "manufacturer", part["serial"], "serial number", lang)
    return ids


def _administrative(root, rec: dict, lang: str):
    c = rec["certificate"]
    h = c["certificate"]
    adm = _el(root, "administrativeData")
    sw = _el(_el(adm, "dccSoftware"), "software")
    _text(sw, "name", "fiveaxis", lang)
    _el(sw, "release", __version__)
    _el(sw, "type", "application")
    core = _el(adm, "coreData")
    _el(core, "countryCodeISO3166_1", h["country"])
    _el(core, "usedLangCodeISO639_1", lang)
    _el(core, "mandatoryLangCodeISO639_1", lang)
    _el(core, "uniqueIdentifier", h["number"])
    if c["customer"].get("order"):
        _identification(_el(core, "identifications"), "customer", c["customer"]["order"], "order", lang)
    _el(core, "beginPerformanceDate", c["dates"]["begin"])
    _el(core, "endPerformanceDate", c["dates"]["end"])
    _el(core, "performanceLocation", c["place"]["location"])
    _el(core, "issueDate", h["issue_date"])
    mach, m = c.get("machine", {}), rec["machine"]
    item = _el(_el(adm, "items"), "item")
    _text(item, "name", "machine tool " + (" ".join(mach[k] for k in ("manufacturer", "model") if mach.get(k))
                                           or m["title"]), lang)
    _text(item, "description", (mach["description"] + "; " if mach.get("description") else "")
          + f"kinematic model: machine file {m['name']} ({m['title']}, {m['convention']} convention)", lang)
    ids = _make_model_serial(item, mach, lang)
    if mach.get("inventory"):
        _identification(ids, "customer", mach["inventory"], "inventory number", lang)
    lab = c["laboratory"]
    cal = _el(adm, "calibrationLaboratory")
    if lab.get("accreditation"):
        _el(cal, "calibrationLaboratoryCode", lab["accreditation"])
    _contact(cal, "contact", dict(lab, country=h["country"]), lang)
    persons = _el(adm, "respPersons")
    for who, main in ((c["operator"], False), (c.get("approval"), True)):
        if who and who.get("name"):
            rp = _el(persons, "respPerson")
            _text(_el(rp, "person"), "name", who["name"], lang)
            if who.get("role"):
                _el(rp, "role", who["role"])
            _el(rp, "mainSigner", "true" if main else "false")
    _contact(adm, "customer", c["customer"], lang)
    st = _el(adm, "statements")
    s = _el(st, "statement")
    _text(s, "name", "Statement of uncertainty", lang)
    _text(s, "declaration", " ".join(c["uncertainty_statement"]), lang)
    s = _el(st, "statement")
    _text(s, "name", "Traceability", lang)
    _el(s, "traceable", "true")
    _text(s, "declaration", c["traceability"], lang)
    if (c.get("remarks") or {}).get("text"):
        s = _el(st, "statement")
        _text(s, "name", "Remarks", lang)
        _text(s, "declaration", c["remarks"]["text"], lang)


def _equipment(parent, rec: dict, lang: str):
    eq = _el(parent, "measuringEquipments")
    for i in rec["certificate"]["instruments"]:
        e = _el(eq, "measuringEquipment")
        _text(e, "name", i["name"], lang)
        _text(e, "description", f"calibration certificate {i['certificate']} by {i['certificate_issuer']}"
              + (f" of {i['calibration_date']}" if i.get("calibration_date") else "")
              + f"; traceability: {i['traceability']}", lang)
        ids = _make_model_serial(e, i, lang)
        _identification(ids, "other", i["certificate"], "calibration certificate", lang)


def _conditions(parent, rec: dict, lang: str):
    env = rec["certificate"]["environment"]
    items = []
    for key, name, unit in (("air_temperature_degC", "air temperature", "degC"),
                            ("machine_temperature_degC", "temperature of the machine", "degC"),
                            ("humidity_percent", "relative humidity", "%")):
        if key in env:
            v = env[key]
            items.append((name, [("lowest", v[0], unit), ("highest", v[1], unit)] if isinstance(v, list)
                          else [("stated", v, unit)]))
    for s in env["sensors"]:
        items.append((f"temperature channel {s['name']}", [("lowest", s["min_degC"], "degC"),
                                                            ("mean", s["mean_degC"], "degC"),
                                                            ("highest", s["max_degC"], "degC")]))
    if not items:
        return
    ic = _el(parent, "influenceConditions")
    for name, values in items:
        cond = _el(ic, "influenceCondition")
        _text(cond, "name", name, lang)
        data = _el(cond, "data")
        for label, v, unit in values:
            _quantity(data, f"{name}, {label}", lang, v, unit)


def _fit_result(results, rec: dict, lang: str):
    f = rec["fit"]
    r = _el(results, "result")
    _text(r, "name", "Fitted errors of the machine", lang)
    _text(r, "description", "geometric errors and effects of the final model, fitted by weighted least squares with "
                            "every error's prior (maximum a posteriori) on the exact kinematic chain; value with its expanded uncertainty U (k = 2); ISO 230 names "
                            "in brackets", lang)
    lst = _el(_el(r, "data"), "list")
    for p in f["parameters"]:
        name = f"{p['name']} ({p['iso']})" if p["iso"] else p["name"]
        if p["determined"]:
            _quantity(lst, name, lang, p["value"], p["unit"], p["u_k2"], p["description"] or None)
        else:
            _quantity(lst, name, lang, none=p["note"] or "not determined alone by this data",
                      description=p["description"] or None)
    if f["quantities"]:
        r = _el(results, "result")
        _text(r, "name", "Quantities determined relative to others", lang)
        _text(r, "description", "each determined together with the quantities named in its description", lang)
        lst = _el(_el(r, "data"), "list")
        for q in f["quantities"]:
            _quantity(lst, f"{q['name']} ({q['iso']})" if q["iso"] else q["name"], lang, q["value"], q["unit"],
                      q["u_k2"], f"{q['quantity']}, relative to {q['relative_to']}")
    for t in f.get("profiles", []):
        pu, eu = t["position_unit"], t["error_unit"]
        r = _el(results, "result")
        _text(r, "name", f"Per-position profile {t['id']}" + (f" ({t['iso']})" if t.get("iso") else ""), lang)
        _text(r, "description", f"{t['quantity']} at its {len(t['rows'])} knots, {t['datum']} (the datum knot); "
                                f"value with its expanded uncertainty U (k = 2)", lang)
        lst = _el(_el(r, "data"), "list")
        for row in t["rows"]:
            _quantity(lst, f"{t['axis']} = {row[f'position_{pu}']:g} {pu}", lang, row[f"error_{eu}"], eu,
                      row[f"U_k2_{eu}"], f"{t['quantity']} {t['datum']}")


_AXIS_FIGURES = ("E", "E_fwd", "E_bwd", "M", "B", "B_mean", "R", "R_fwd", "R_bwd", "A", "A_fwd", "A_bwd")
_TARGETS = (("P_i", "targets_mm", "mm"), ("mean x_i fwd", "mean_fwd_um", "um"), ("mean x_i bwd", "mean_bwd_um", "um"),
            ("s_i fwd", "s_fwd_um", "um"), ("s_i bwd", "s_bwd_um", "um"), ("R_i fwd", "R_i_fwd_um", "um"),
            ("R_i bwd", "R_i_bwd_um", "um"), ("B_i", "B_i_um", "um"),
            ("mean x_i bidirectional", "mean_bidirectional_um", "um"), ("R_i bidirectional", "R_i_um", "um"))


def _positioning(parent, r: dict, lang: str):
    mr = _el(parent, "measurementResult")
    _text(mr, "name", f"ISO 230-2 positioning of {r['axis']}" + (f" (setup {r['setup']})" if r["setup"] else ""), lang)
    _text(mr, "description", f"{r['targets']} targets over {r['measured_length_mm']:g} mm, {r['cycles']} cycles, "
                             f"both directions; {r['uncertainty']['statement']}", lang)
    m = _el(_el(mr, "usedMethods"), "usedMethod")
    _text(m, "name", "positioning accuracy and repeatability of a linear axis", lang)
    _el(m, "norm", "ISO 230-2:2014")
    if r["uncertainty"].get("U_um"):
        _el(m, "norm", "ISO/TR 230-9:2005")
    results = _el(mr, "results")
    res = _el(results, "result")
    _text(res, "name", "Axis figures", lang)
    lst = _el(_el(res, "data"), "list")
    U = r["uncertainty"].get("U_um", {})
    for k in _AXIS_FIGURES:
        _quantity(lst, k.replace("_", " "), lang, r[f"{k}_um"], "um", U.get(k))
    res = _el(results, "result")
    _text(res, "name", "Per target and approach direction", lang)
    lst = _el(_el(res, "data"), "list")
    for name, key, unit in _TARGETS:
        _real_list(lst, name, r[key], unit, lang)


def _circles(parent, rec: dict, lang: str):
    circ = rec["iso230"]["circles"]
    mr = _el(parent, "measurementResult")
    _text(mr, "name", "ISO 230-4 circular tests", lang)
    m = _el(_el(mr, "usedMethods"), "usedMethod")
    _text(m, "name", "circular tests for numerically controlled axes", lang)
    _el(m, "norm", "ISO 230-4:2005")
    results = _el(mr, "results")
    for c in circ["circles"]:
        res = _el(results, "result")
        _text(res, "name", f"Circle {c['plane']}" + (f" (setup {c['setup']})" if c["setup"] not in (None, c["plane"])
                                                    else ""), lang)
        _text(res, "description", f"radius {c['radius_mm']:g} mm, axes {'+'.join(c['axes'])}", lang)
        lst = _el(_el(res, "data"), "list")
        for run in c["runs"]:
            for key, name in (("G_um", "G"), ("G_mz_um", "G minimum zone"), ("F_max_um", "F max"),
                              ("F_min_um", "F min")):
                _quantity(lst, f"{name} {run['direction']}", lang, run[key], "um")
        if "H_um" in c:
            _quantity(lst, "H", lang, c["H_um"], "um")


def write(rec: dict) -> str:
    """The DCC XML (UTF-8 text) of a report record with a certificate."""
    if not rec.get("certificate"):
        raise ValueError("a DCC needs the certificate's record (report --campaign)")
    lang = rec["certificate"]["certificate"]["language"]
    root = ET.Element(f"{{{DCC}}}digitalCalibrationCertificate", {"schemaVersion": SCHEMA_VERSION})
    _administrative(root, rec, lang)
    results = _el(root, "measurementResults")
    model = _el(results, "measurementResult")
    _text(model, "name", "Volumetric error model of the machine", lang)
    _text(model, "description", rec["verdict"]["headline"], lang)
    m = _el(_el(model, "usedMethods"), "usedMethod")
    _text(m, "name", "identification of the geometric errors and effects from the measurements (fiveaxis: fit, "
                     "diagnosis rounds)", lang)
    _el(m, "norm", "ISO 230-1:2012")
    _el(m, "norm", "ISO 230-7:2015")
    _equipment(model, rec, lang)
    _conditions(model, rec, lang)
    _fit_result(_el(model, "results"), rec, lang)
    iso = rec.get("iso230") or {}
    for r in iso.get("positioning") or []:
        _positioning(results, r, lang)
    if iso.get("circles"):
        _circles(results, rec, lang)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


# -- reading back ----------------------------------------------------------------------------------------------
def _q(tag: str, ns: str = DCC) -> str:
    return f"{{{ns}}}{tag}"


def _content(e) -> str:
    c = e.find(_q("content")) if e is not None else None
    return "" if c is None or c.text is None else c.text


_UNIT_BACK = {v: k for k, v in _UNITS.items()}


def people_unit(dsi: str) -> str:
    """A D-SI unit of dsi_unit back in the record's spelling (\\micro\\radian\\milli\\metre\\tothe{-1} ->
    urad/mm); ValueError for one fiveaxis does not write."""
    m = re.fullmatch(r"(.*?)(?:\\tothe\{-(\d+)\})?", dsi)
    body, power = m.group(1), m.group(2)
    if power is None and body in _UNIT_BACK:
        return _UNIT_BACK[body]
    for i in (i for i, ch in enumerate(body) if ch == "\\" and i > 0):
        num, den = body[:i], body[i:]
        if power is not None and num in _UNIT_BACK and den in _UNIT_BACK:
            return _UNIT_BACK[num] + "/" + _UNIT_BACK[den] + ("" if power == "1" else f"^{power}")
    raise ValueError(f"unit {dsi!r}: not one fiveaxis writes")


def read(xml: str) -> dict:
    """The numbers of a DCC fiveaxis wrote: {"id": uniqueIdentifier, "results": {measurement result name:
    {result name: {quantity name: {"value", "unit" (record spelling), "U", "k"} or {"values", "unit"} for a list,
    or {"none": reason}}}}, "conditions": {name: {...}}}."""
    root = ET.fromstring(xml)
    out = {"id": root.findtext(f"{_q('administrativeData')}/{_q('coreData')}/{_q('uniqueIdentifier')}"),
           "results": {}, "conditions": {}}

    def quantities(container) -> dict:
        got = {}
        for q in container.iter(_q("quantity")):
            name = _content(q.find(_q("name")))
            real = q.find(_q("real", SI))
            lst = q.find(_q("realListXMLList", SI))
            if real is not None:
                mu = real.find(f"{_q('measurementUncertaintyUnivariate', SI)}/{_q('expandedMU', SI)}")
                got[name] = {"value": float(real.findtext(_q("value", SI))),
                             "unit": people_unit(real.findtext(_q("unit", SI))),
                             "U": None if mu is None else float(mu.findtext(_q("valueExpandedMU", SI))),
                             "k": None if mu is None else float(mu.findtext(_q("coverageFactor", SI)))}
            elif lst is not None:
                got[name] = {"values": [float(v) for v in lst.findtext(_q("valueXMLList", SI)).split()],
                             "unit": people_unit(lst.findtext(_q("unitXMLList", SI)))}
            else:
                got[name] = {"none": _content(q.find(_q("noQuantity")))}
        return got
    for mr in root.iter(_q("measurementResult")):
        name = _content(mr.find(_q("name")))
        out["results"][name] = {_content(r.find(_q("name"))): quantities(r) for r in mr.iter(_q("result"))}
        for cond in mr.iter(_q("influenceCondition")):
            out["conditions"][_content(cond.find(_q("name")))] = quantities(cond)
    return out
