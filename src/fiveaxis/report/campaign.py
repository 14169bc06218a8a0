"""The calibration campaign: who, what, where, when and with what a machine was calibrated, for the certificate.

A campaign file (TOML) or `--set KEY=VALUE` options give it; its schema is the table FIELDS below (key, kind,
required, meaning), which docs/report.md prints and every check reads: one source for both. Instruments are an
array of tables `[[instruments]]` with the keys of INSTRUMENT_FIELDS. Anything the schema does not know, a value
of the wrong kind or a missing required key is one InputError naming the file, the key and what was expected.

Kinds: text (non-empty, one line), date (YYYY-MM-DD), country (ISO 3166-1 alpha-2, e.g. DE), language (ISO 639-1,
e.g. en), location (where the calibration was performed: laboratory, customer, laboratoryBranch, customerBranch,
other), email, degC / K / percent / um / mm / ppm_per_K (a number in that unit, or [low, high] for a range over
the calibration).
"""
from __future__ import annotations

import datetime as _dt
import difflib
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..exceptions import InputError
from ..inputs import read_bytes

#: The largest campaign file read (bytes): a few kB of text in practice.
MAX_BYTES = 1_000_000


@dataclass(frozen=True)
class Field:
    key: str            # section.name
    kind: str           # see the module docstring
    required: bool
    what: str           # meaning, for people (docs/report.md, messages)


FIELDS = (
    Field("certificate.number", "text", True, "the certificate's unique identifier (e.g. FA-2025-0042)"),
    Field("certificate.issue_date", "date", False, "date of issue (default: the day the certificate is written)"),
    Field("certificate.country", "country", True, "country of the issuing laboratory (ISO 3166-1, e.g. DE)"),
    Field("certificate.language", "language", False, "language of the text (ISO 639-1; default en)"),
    Field("laboratory.name", "text", True, "the calibration laboratory (or the department that calibrates)"),
    Field("laboratory.accreditation", "text", False, "its accreditation code, e.g. D-K-12345-01"),
    Field("laboratory.street", "text", False, "street and number"),
    Field("laboratory.postcode", "text", False, "post code"),
    Field("laboratory.city", "text", True, "city"),
    Field("laboratory.email", "email", False, "contact e-mail"),
    Field("laboratory.phone", "text", False, "contact phone"),
    Field("customer.name", "text", True, "the customer (owner of the machine)"),
    Field("customer.contact", "text", False, "the customer's contact person"),
    Field("customer.street", "text", False, "street and number"),
    Field("customer.postcode", "text", False, "post code"),
    Field("customer.city", "text", True, "city"),
    Field("customer.country", "country", False, "country (ISO 3166-1)"),
    Field("customer.order", "text", False, "the customer's order or reference number"),
    Field("machine.manufacturer", "text", False, "manufacturer of the machine tool"),
    Field("machine.model", "text", False, "its type or model"),
    Field("machine.serial", "text", True, "its serial number"),
    Field("machine.inventory", "text", False, "the customer's inventory or asset number"),
    Field("machine.controller", "text", False, "the numerical control (e.g. LinuxCNC 2.9)"),
    Field("machine.description", "text", False, "what it is, in a few words (e.g. 5-axis machining centre, A/C "
                                                "trunnion table)"),
    Field("place.location", "location", False, "where the calibration was performed (default customer)"),
    Field("place.site", "text", False, "the site: hall, cell, address"),
    Field("dates.begin", "date", True, "first day of the measurements"),
    Field("dates.end", "date", False, "last day of the measurements (default: the first)"),
    Field("environment.air_temperature_degC", "degC", False, "air temperature near the machine during the test"),
    Field("environment.machine_temperature_degC", "degC", False, "temperature of the machine's structure or scale"),
    Field("environment.humidity_percent", "percent", False, "relative humidity"),
    Field("environment.note", "text", False, "anything else of the environment (warm-up, doors, sun)"),
    Field("iso230_9.u_device_um", "um", False, "standard uncertainty of the measuring device at the measured "
                                               "length (U/k of its certificate); as --u-device"),
    Field("iso230_9.temperature_deviation_K", "K", False, "deviation of the machine's temperature from 20 degC "
                                                         "during the test; as --temperature-deviation"),
    Field("iso230_9.expansion_ppm_per_K", "ppm_per_K", False, "half-width of the uncertainty of the machine's "
                                                              "expansion coefficient; as --expansion-ppm-per-K"),
    Field("iso230_9.misalignment_mm", "mm", False, "lateral walk of the beam over the measured length; as "
                                                   "--misalignment"),
    Field("iso230_9.drift_um", "um", False, "drift of the reading of the still axis over a test's duration; as "
                                            "--drift"),
    Field("procedure.name", "text", True, "the procedure followed (e.g. ISO 230-2:2014 positioning, R-test of the "
                                          "rotary axes, volumetric model identification)"),
    Field("procedure.reference", "text", False, "the laboratory's procedure document and revision"),
    Field("procedure.description", "text", False, "how the machine was measured, in a few sentences"),
    Field("operator.name", "text", True, "who performed the calibration"),
    Field("operator.role", "text", False, "their role (default: calibration engineer)"),
    Field("approval.name", "text", False, "who approved the certificate"),
    Field("approval.role", "text", False, "their role (e.g. head of the laboratory)"),
    Field("approval.date", "date", False, "date of approval"),
    Field("remarks.text", "text", False, "remarks printed on the certificate"),
)

#: The keys of each `[[instruments]]` table.
INSTRUMENT_FIELDS = (
    Field("name", "text", True, "the instrument (e.g. laser interferometer, R-test device, ballbar)"),
    Field("manufacturer", "text", False, "its manufacturer"),
    Field("model", "text", False, "its model"),
    Field("serial", "text", True, "its serial number"),
    Field("certificate", "text", True, "the number of its calibration certificate"),
    Field("certificate_issuer", "text", True, "who issued that certificate (laboratory, accreditation code)"),
    Field("calibration_date", "date", False, "date of that calibration"),
    Field("traceability", "text", True, "how its readings are traceable to the SI (e.g. to PTB's length standard "
                                        "via DAkkS-accredited calibration)"),
)

LOCATIONS = ("laboratory", "customer", "laboratoryBranch", "customerBranch", "other")
#: Units of the number kinds, as people read them.
UNITS = {"degC": "degC", "K": "K", "percent": "%", "um": "um", "mm": "mm", "ppm_per_K": "ppm/K"}
#: Physically sensible bounds of the number kinds (a typo or a unit slip beyond them is refused).
BOUNDS = {"degC": (-40.0, 80.0), "K": (-30.0, 30.0), "percent": (0.0, 100.0), "um": (0.0, 1000.0),
          "mm": (0.0, 100.0), "ppm_per_K": (0.0, 50.0)}
_BY_KEY = {f.key: f for f in FIELDS}


def _check(value, f: Field, where: str):
    """The value of one field, checked and normalised (dates as YYYY-MM-DD, numbers as float or [lo, hi])."""
    kind = f.kind
    expected = {"text": "a non-empty line of text", "date": "a date YYYY-MM-DD", "email": "an e-mail address",
                "country": "a two-letter ISO 3166-1 code (e.g. DE)", "language": "a two-letter ISO 639-1 code "
                                                                              "(e.g. en)",
                "location": f"one of {', '.join(LOCATIONS)}"}.get(
        kind, f"a number in {UNITS.get(kind)} or [low, high]")
    bad = InputError(f"{where}: expected {expected}, got {str(value)[:60]!r}")
    if kind in UNITS:
        vals = value if isinstance(value, list) else [value]
        if not 1 <= len(vals) <= 2 or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in vals):
            raise bad
        lo, hi = BOUNDS[kind]
        for v in vals:
            if not (math.isfinite(v) and lo <= v <= hi):
                raise InputError(f"{where}: {v!r} {UNITS[kind]} is outside {lo:g} to {hi:g} {UNITS[kind]} (a unit "
                                 f"slip?)")
        if len(vals) == 2 and vals[0] > vals[1]:
            raise InputError(f"{where}: a range [low, high] needs low <= high, got {vals}")
        return [float(v) for v in vals] if len(vals) == 2 else float(vals[0])
    if kind == "date":
        if isinstance(value, _dt.datetime):
            value = value.date()
        if isinstance(value, _dt.date):
            return value.isoformat()
        if not isinstance(value, str):
            raise bad
        try:
            return _dt.date.fromisoformat(value.strip()).isoformat()
        except ValueError:
            raise bad from None
    if not isinstance(value, str):
        raise bad
    text = " ".join(value.split())
    if not text or any(ord(c) < 32 for c in value if c not in "\t\n") or len(text) > 500:
        raise bad
    if kind == "country" and not re.fullmatch(r"[A-Z]{2}", text):
        raise bad
    if kind == "language" and not re.fullmatch(r"[a-z]{2}", text):
        raise bad
    if kind == "email" and not re.fullmatch(r"[^@\s]+@[^@\s]+\.[^@\s]+", text):
        raise bad
    if kind == "location" and text not in LOCATIONS:
        raise bad
    return text


def _near(key: str, known) -> str:
    close = difflib.get_close_matches(key, list(known), n=1)
    return f" (did you mean {close[0]}?)" if close else ""


def check(data: dict, source: str = "campaign") -> dict:
    """The campaign {section: {name: value}, "instruments": [{...}]} checked against FIELDS and INSTRUMENT_FIELDS:
    normalised values, the defaults filled in; InputError naming `source`, the key and what was expected."""
    if not isinstance(data, dict):
        raise InputError(f"{source}: expected tables of keys (see docs/report.md)")
    out: dict = {}
    for section, table in data.items():
        if section == "instruments":
            continue
        if not isinstance(table, dict):
            keys = [f.key for f in FIELDS if f.key.startswith(f"{section}.")]
            raise InputError(f"{source}: {section}: expected a table of keys" + (
                f" ({', '.join(keys[:4])}, ...)" if keys else _near(section, {f.key.split('.')[0] for f in FIELDS})))
        for name, value in table.items():
            key = f"{section}.{name}"
            f = _BY_KEY.get(key)
            if f is None:
                raise InputError(f"{source}: {key}: not a key of a campaign{_near(key, _BY_KEY)} (see docs/report.md)")
            out.setdefault(section, {})[name] = _check(value, f, f"{source}: {key}")
    insts = data.get("instruments", [])
    if isinstance(insts, dict):
        insts = [insts]
    if not isinstance(insts, list) or not all(isinstance(i, dict) for i in insts):
        raise InputError(f"{source}: instruments: expected [[instruments]] tables")
    known = {f.key: f for f in INSTRUMENT_FIELDS}
    out["instruments"] = []
    for k, inst in enumerate(insts, 1):
        entry = {}
        for name, value in inst.items():
            f = known.get(name)
            if f is None:
                raise InputError(f"{source}: instruments[{k}].{name}: not a key of an instrument"
                                 f"{_near(name, known)} (expected {', '.join(known)})")
            entry[name] = _check(value, f, f"{source}: instruments[{k}].{name}")
        for f in INSTRUMENT_FIELDS:
            if f.required and f.key not in entry:
                raise InputError(f"{source}: instruments[{k}].{f.key}: missing ({f.what})")
        out["instruments"].append(entry)
    for f in FIELDS:
        section, name = f.key.split(".")
        if f.required and name not in out.get(section, {}):
            raise InputError(f"{source}: {f.key}: missing ({f.what})")
    if not out["instruments"]:
        raise InputError(f"{source}: instruments: missing (at least one [[instruments]] table: the instrument the "
                         f"machine was measured with, its calibration certificate and traceability)")
    dates = out["dates"]
    dates.setdefault("end", dates["begin"])
    if dates["end"] < dates["begin"]:
        raise InputError(f"{source}: dates.end: {dates['end']} is before dates.begin {dates['begin']}")
    out["certificate"].setdefault("language", "en")
    out.setdefault("place", {}).setdefault("location", "customer")
    out["operator"].setdefault("role", "calibration engineer")
    return out


def parse_set(spec: str) -> tuple[str, object]:
    """`--set KEY=VALUE` -> (key, value): the value read as TOML when it is a number or a [list], else as text."""
    key, sep, raw = spec.partition("=")
    key = key.strip()
    if not sep or key not in _BY_KEY:
        raise InputError(f"--set {spec[:80]!r}: expected KEY=VALUE with a campaign key (e.g. customer.name=ACME; "
                         f"the keys: docs/report.md){_near(key, _BY_KEY) if key else ''}")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    if _BY_KEY[key].kind in ("text", "email", "country", "language", "location", "date") and not isinstance(
            value, str):
        value = raw
    return key, value


def load(path: Path | None = None, sets=()) -> dict | None:
    """The checked campaign of a TOML file and/or `--set KEY=VALUE` options (options override the file); None
    when neither is given."""
    if path is None and not sets:
        return None
    data: dict = {}
    source = "--set"
    if path is not None:
        path = Path(path)
        raw = read_bytes(path, "a campaign file (TOML)", MAX_BYTES)
        try:
            data = tomllib.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise InputError(f"{path}: not a TOML campaign file: {str(exc).splitlines()[0]}") from None
        source = str(path)
    for spec in sets:
        key, value = parse_set(spec)
        section, name = key.split(".")
        table = data.setdefault(section, {})
        if not isinstance(table, dict):
            raise InputError(f"{source}: {section}: expected a table of keys")
        table[name] = value
    return check(data, source)


def iso230_9(campaign: dict | None) -> dict:
    """The ISO 230-9 inputs of a campaign {u_device_um, ...} ({} without)."""
    return dict((campaign or {}).get("iso230_9", {}))
