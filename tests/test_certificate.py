"""The calibration certificate (issue 32 points 1-2): the campaign file and its checks, one record behind the HTML,
the PDF and the DCC XML (every number of the page is the JSON record's at the key it names; the DCC reads back with
the record's numbers; its structure is the schema's), the contradictions of the old report fixed, and the DCC
validated against PTB's XSD where the schema is at hand."""
import json
import os
import re
import warnings
import xml.etree.ElementTree as ET
from html.parser import HTMLParser
from pathlib import Path

import pytest

from fiveaxis.exceptions import InputError
from fiveaxis.report import campaign as CP
from fiveaxis.report import dcc, html, record

from conftest import ROOT, run_cli

CAMPAIGN = ROOT / "examples" / "campaign.toml"


# -- the campaign ------------------------------------------------------------------------------------------------
def _toml(tmp_path, text: str) -> Path:
    p = tmp_path / "c.toml"
    p.write_text(text)
    return p


def _example_without(*keys) -> str:
    """The example campaign's text without the lines of the given keys (`name = ...` inside their sections)."""
    out, section = [], ""
    for line in CAMPAIGN.read_text().splitlines():
        m = re.match(r"\[+([a-z_0-9]+)\]+", line)
        if m:
            section = m.group(1)
        key = line.split("=")[0].strip()
        if f"{section}.{key}" not in keys:
            out.append(line)
    return "\n".join(out) + "\n"


def test_the_example_campaign_loads_with_its_defaults():
    c = CP.load(CAMPAIGN)
    assert c["certificate"]["number"] == "FA-2025-0042" and c["certificate"]["language"] == "en"
    assert c["dates"] == {"begin": "2025-03-10", "end": "2025-03-11"}
    assert c["environment"]["air_temperature_degC"] == [20.1, 21.4] and c["environment"]["humidity_percent"] == 45.0
    assert c["instruments"][0]["calibration_date"] == "2024-11-02" and c["operator"]["role"] == "calibration engineer"
    assert CP.iso230_9(c) == {"u_device_um": 0.4, "temperature_deviation_K": 0.6, "expansion_ppm_per_K": 2.0,
                              "misalignment_mm": 0.5, "drift_um": 0.2}
    c = CP.load(CAMPAIGN, ["customer.name=ACME Tools", "environment.air_temperature_degC=[19.5, 20.5]",
                           "dates.end=2025-03-12"])
    assert c["customer"]["name"] == "ACME Tools" and c["environment"]["air_temperature_degC"] == [19.5, 20.5]
    assert c["dates"]["end"] == "2025-03-12"


@pytest.mark.parametrize("text, message", [
    ("[customer]\nnam = 'x'\n", "customer.nam: not a key of a campaign (did you mean customer.name?)"),
    ("[custmer]\nname = 'x'\n", "custmer.name: not a key of a campaign"),
    ("[dates]\nbegin = '2025-13-01'\n", "dates.begin: expected a date YYYY-MM-DD, got '2025-13-01'"),
    ("[certificate]\ncountry = 'Germany'\n", "certificate.country: expected a two-letter ISO 3166-1 code"),
    ("[environment]\nair_temperature_degC = 2050\n", "environment.air_temperature_degC: 2050 degC is outside -40 to 80"),
    ("[environment]\nhumidity_percent = [60, 40]\n", "needs low <= high"),
    ("[place]\nlocation = 'garage'\n", "place.location: expected one of laboratory, customer"),
    ("[operator]\nname = ''\n", "operator.name: expected a non-empty line of text"),
    ("[dates]\nend = 2025-03-01\n", "dates.end: 2025-03-01 is before dates.begin 2025-03-10"),
])
def test_a_bad_campaign_is_one_line_naming_the_key(tmp_path, text, message):
    base = _example_without(*(f"{s}.{line.split('=')[0].strip()}" for s, line in
                              re.findall(r"\[([a-z_]+)\]\n([^\n]*)", text)))
    merged = base
    for section, line in re.findall(r"\[([a-z_]+)\]\n([^\n]*)", text):
        if f"[{section}]" in merged:
            merged = merged.replace(f"[{section}]\n", f"[{section}]\n{line}\n", 1)
        else:
            merged += f"\n[{section}]\n{line}\n"
    with pytest.raises(InputError) as exc:
        CP.load(_toml(tmp_path, merged))
    assert message in str(exc.value) and "\n" not in str(exc.value), str(exc.value)
    assert str(exc.value).startswith(str(tmp_path / "c.toml"))


@pytest.mark.parametrize("key", ["certificate.number", "machine.serial", "dates.begin", "operator.name",
                                 "customer.name", "laboratory.city"])
def test_a_required_key_missing_is_named(tmp_path, key):
    with pytest.raises(InputError, match=re.escape(f"{key}: missing (")):
        CP.load(_toml(tmp_path, _example_without(key)))


def test_instruments_need_their_certificate_and_traceability(tmp_path):
    with pytest.raises(InputError, match=r"instruments\[1\]\.traceability: missing"):
        CP.load(_toml(tmp_path, _example_without("instruments.traceability")))
    text = "\n".join(line for line in CAMPAIGN.read_text().splitlines()
                     if not line.startswith(("[[instruments]]", "name = \"laser", "manufacturer = \"Example Optics",
                                             "model = \"LI", "serial = \"LI", "certificate", "calibration_date",
                                             "traceability")))
    with pytest.raises(InputError, match="instruments: missing"):
        CP.load(_toml(tmp_path, text))
    with pytest.raises(InputError, match="not a TOML campaign file"):
        CP.load(_toml(tmp_path, "[certificate\n"))
    with pytest.raises(InputError, match=r"--set 'customer\.nme=x'.*did you mean customer\.name"):
        CP.load(CAMPAIGN, ["customer.nme=x"])


def test_docs_list_every_campaign_key():
    """docs/report.md prints the schema: every key with its kind, from the same table the checks read."""
    text = (ROOT / "docs" / "report.md").read_text()
    for f in CP.FIELDS:
        assert re.search(rf"`{re.escape(f.key)}`\s*\|\s*{re.escape(f.kind)}\s*\|\s*{'yes' if f.required else 'no'}",
                         text), f.key
    for f in CP.INSTRUMENT_FIELDS:
        assert re.search(rf"`instruments\.{re.escape(f.key)}`\s*\|\s*{f.kind}\s*\|", text), f.key


# -- every number of the page is the record's -------------------------------------------------------------------
class _Numbers(HTMLParser):
    """Every <data> of a page (key, value attribute, format, scale, text) and the text of the numeric cells outside
    them."""

    def __init__(self):
        super().__init__()
        self.data, self.stray = [], []
        self._data = None
        self._cell = 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "data":
            self._data = [a["data-k"], float(a["value"]), a["data-f"], float(a.get("data-x", 1.0)), ""]
        elif tag == "td" and "num" in (a.get("class") or "").split():
            self._cell += 1

    def handle_endtag(self, tag):
        if tag == "data" and self._data is not None:
            self.data.append(tuple(self._data))
            self._data = None
        elif tag == "td" and self._cell:
            self._cell -= 1

    def handle_data(self, text):
        if self._data is not None:
            self._data[4] += text
        elif self._cell:
            self.stray.append(text)


def _at(rec, key):
    obj = rec
    for part in key.split("."):
        obj = obj[int(part)] if isinstance(obj, list) else obj[part]
    return obj


def check_numbers(page: str, rec: dict) -> set:
    """Every number the page shows from the record is the JSON record's value at the key it names, formatted as it
    says; numeric table cells hold nothing else. Returns the top-level sections the numbers came from."""
    printed = json.loads(json.dumps(rec))          # the record as `report --json` prints it
    p = _Numbers()
    p.feed(page)
    assert len(p.data) > 20
    for key, value, fmt, scale, text in p.data:
        truth = _at(printed, key)
        assert isinstance(truth, (int, float)) and float(truth) == value, (key, truth, value)
        assert text == format(truth * scale if scale != 1.0 else truth, fmt), (key, truth, fmt, text)
    for text in p.stray:
        assert not re.search(r"\d", text), f"a number in a numeric cell that is not the record's: {text!r}"
    return {key.split(".")[0] for key, *_ in p.data}


# -- a synthetic certificate record (fast): the DCC's structure and read-back --------------------------------------
def _synthetic():
    """A small record with every part a certificate has (what record.build makes, in its shape)."""
    camp = CP.load(CAMPAIGN)
    from fiveaxis.report import certificate
    pos = {"axis": "X", "setup": "laser-X", "file": "x.csv", "standard": "ISO 230-2:2014", "targets": 3, "cycles": 5,
           "measured_length_mm": 800.0, "targets_mm": [-400.0, 0.0, 400.0],
           "readings_um": {"fwd": [[1.0] * 5] * 3, "bwd": [[2.0] * 5] * 3}, "rows": {"fwd": [], "bwd": []},
           "notes": [], "uncertainty": {"U_um": {"E": 1.3, "M": 1.3, "B": 0.23}, "statement": "U (k = 2) ..."}}
    for k in ("E", "E_fwd", "E_bwd", "M", "B", "B_mean", "R", "R_fwd", "R_bwd", "A", "A_fwd", "A_bwd"):
        pos[f"{k}_um"] = 3.25
    for k in ("mean_fwd", "mean_bwd", "s_fwd", "s_bwd", "R_i_fwd", "R_i_bwd", "B_i", "mean_bidirectional", "R_i"):
        pos[f"{k}_um"] = [0.1, -2.5e-7, 12.345678901234]
    iso = {"positioning": [pos], "circles": None, "skipped": {}}
    params = [{"name": "ex_x", "iso": "E_AX", "kind": "rx", "description": "the roll of X", "value": -1.25e-3,
               "u_k2": 0.012, "unit": "urad", "determined": True, "note": ""},
              {"name": "ex_x:x1", "iso": "E_AX:x1", "kind": "effect coefficient", "description": "roll along X",
               "value": 0.00799673472538, "u_k2": 5.7e-05, "unit": "urad/mm", "determined": True, "note": ""},
              {"name": "dx_x:x2", "iso": "E_XX:x2", "kind": "effect coefficient", "description": "lead",
               "value": 6.1e-05, "u_k2": 1.3e-06, "unit": "um/mm^2", "determined": True, "note": ""},
              {"name": "SAOC", "iso": "E_A0C", "kind": "rx", "description": "location", "value": None, "u_k2": None,
               "unit": "urad", "determined": False, "note": "not determined alone"}]
    rec = {"machine": {"name": "ac_trunnion", "title": "A/C trunnion", "convention": "equations"},
           "verdict": {"headline": "The model explains the measurements to the noise level."},
           "fit": {"parameters": params, "sigma": "sigma column",
                   "quantities": [{"name": "SAOC", "iso": "E_A0C", "quantity": "location of C", "relative_to": "E_AX",
                                   "value": -20.3386986073946, "u_k2": 0.5, "unit": "urad", "formula": "SAOC - ex_x"}]},
           "iso230": iso}
    rec["certificate"] = certificate.block(camp, None, iso, "sigma column")
    rec["certificate"]["environment"]["sensors"] = [{"name": "temp_spindle", "readings": 40, "min_degC": 20.02,
                                                     "mean_degC": 21.5, "max_degC": 23.37}]
    return rec


#: The order of the children the DCC 3.3.0 and D-SI 2.2 schemas prescribe for the elements fiveaxis writes (a
#: sequence: each child at most where listed; * = may repeat; ! = required), transcribed from dcc.xsd and
#: SI_Format.xsd for this test, independently of the writer.
ORDER = {
    "digitalCalibrationCertificate": ["administrativeData!", "measurementResults!", "comment", "document",
                                      "Signature*"],
    "software": ["name!", "release!", "type", "description"],
    "coreData": ["countryCodeISO3166_1!", "usedLangCodeISO639_1!*", "mandatoryLangCodeISO639_1!*",
                 "uniqueIdentifier!", "identifications", "receiptDate", "beginPerformanceDate!", "endPerformanceDate!",
                 "performanceLocation!", "issueDate", "reportAmendedSubstituted", "previousReport"],
    "item": ["name!", "equipmentClass*", "description", "owner", "installedSoftwares", "manufacturer", "model",
             "identifications!", "itemQuantities", "subItems"],
    "identification": ["issuer!", "value!", "name"],
    "calibrationLaboratory": ["calibrationLaboratoryCode", "contact!", "cryptElectronicSeal",
                              "cryptElectronicSignature", "cryptElectronicTimeStamp"],
    "contact": ["name!", "eMail", "phone", "fax", "link", "location!", "descriptionData"],
    "customer": ["name!", "eMail", "phone", "fax", "link", "location!", "descriptionData"],
    "respPerson": ["person!", "description", "role", "mainSigner", "cryptElectronicSeal", "cryptElectronicSignature",
                   "cryptElectronicTimeStamp"],
    "statement": ["name", "description", "countryCodeISO3166_1*", "convention", "traceable", "norm*", "reference*",
                  "link*", "declaration", "valid", "date", "period", "respAuthority", "conformity", "data",
                  "nonSIDefinition", "nonSIUnit", "location"],
    "measurementResults": ["usedMethods", "usedSoftware", "measuringEquipments", "influenceConditions",
                           "measurementMetaData", "measurementResult!*"],
    "measurementResult": ["name!", "description", "usedMethods", "usedSoftware", "measuringEquipments",
                          "influenceConditions", "results!", "measurementMetaData"],
    "usedMethod": ["name!", "description", "norm*", "reference*", "link*", "usedMethodQuantities"],
    "measuringEquipment": ["name!", "equipmentClass*", "description", "certificate", "manufacturer", "model",
                           "identifications", "measuringEquipmentQuantities", "installedSoftware"],
    "influenceCondition": ["name!", "description", "status", "certificate", "data!"],
    "result": ["name!", "description", "data!"],
    "quantity": ["name", "description", "noQuantity|real|realListXMLList!", "relativeUncertainty", "usedMethods",
                 "usedSoftware", "measuringEquipments", "influenceConditions", "measurementMetaData"],
    "real": ["label", "quantityTypeQUDT", "value!", "unit!", "significantDigit", "dateTime",
             "measurementUncertaintyUnivariate|expandedUnc|coverageInterval"],
    "expandedMU": ["valueExpandedMU!", "coverageFactor!", "coverageProbability!", "distribution"],
    "realListXMLList": ["labelXMLList", "quantityTypeXMLList", "valueXMLList!", "unitXMLList!"],
}
#: D-SI units: prefixes and units of the SI brochure as D-SI writes them (the ones a machine tool needs and more).
DSI_PREFIX = "deca|hecto|kilo|mega|giga|deci|centi|milli|micro|nano|pico"
DSI_UNIT = "metre|kilogram|second|ampere|kelvin|mole|candela|radian|degree|degreecelsius|one|percent|hertz"
DSI = re.compile(rf"(?:(?:\\(?:{DSI_PREFIX}))?\\(?:{DSI_UNIT})(?:\\tothe\{{-?\d+\}})?)+")
DECIMAL = re.compile(r"[-+]?((\d*\.\d+)|(\d+\.\d*)|(\d+\.?))([Ee][-+]?\d+)?")


def check_structure(xml: str):
    """The elements fiveaxis writes in the order, and with the required children, the schema prescribes; numbers in
    D-SI's decimal spelling, units in D-SI syntax, k >= 1, probabilities in [0, 1]."""
    root = ET.fromstring(xml)
    assert root.tag == "{https://ptb.de/dcc}digitalCalibrationCertificate" and root.get("schemaVersion") == "3.3.0"
    seen = set()
    for el in root.iter():
        local = el.tag.split("}")[1]
        if local in ORDER and not (local == "name" or el.tag.startswith("{https://ptb.de/si}") and local not in
                                   ("real", "expandedMU", "realListXMLList")):
            seen.add(local)
            slots = [s.rstrip("!*") for s in ORDER[local]]
            positions = []
            for child in el:
                c = child.tag.split("}")[1]
                k = next((i for i, s in enumerate(slots) if c in s.split("|")), None)
                assert k is not None, f"{local}: child {c} is not one the schema allows"
                positions.append(k)
            assert positions == sorted(positions), f"{local}: children out of the schema's order"
            for i, s in enumerate(ORDER[local]):
                assert not (s.endswith("!") or "!" in s) or i in positions, f"{local}: required {s} missing"
                if "*" not in s:
                    assert positions.count(i) <= 1, f"{local}: {s} twice"
        if el.tag == "{https://ptb.de/si}unit" or el.tag == "{https://ptb.de/si}unitXMLList":
            assert DSI.fullmatch(el.text), el.text
        if el.tag in ("{https://ptb.de/si}value", "{https://ptb.de/si}valueExpandedMU"):
            assert DECIMAL.fullmatch(el.text), el.text
        if el.tag == "{https://ptb.de/si}valueXMLList":
            assert all(DECIMAL.fullmatch(v) for v in el.text.split()), el.text
        if el.tag == "{https://ptb.de/si}coverageFactor":
            assert float(el.text) >= 1
        if el.tag == "{https://ptb.de/si}coverageProbability":
            assert 0 <= float(el.text) <= 1 and "e" not in el.text.lower()
    assert {"coreData", "item", "respPerson", "measurementResult", "result", "quantity", "real"} <= seen


def check_read_back(xml: str, rec: dict):
    """The DCC's numbers are the record's: every fitted error (value, U, unit), every ISO 230-2 figure and U, every
    per-target value, every temperature."""
    got = dcc.read(xml)
    assert got["id"] == rec["certificate"]["certificate"]["number"]
    fitted = got["results"]["Volumetric error model of the machine"]["Fitted errors of the machine"]
    for p in rec["fit"]["parameters"]:
        q = fitted[f"{p['name']} ({p['iso']})" if p["iso"] else p["name"]]
        if p["determined"] and dcc.spelled(p["unit"]):
            assert (q["value"], q["U"], q["k"], q["unit"]) == (p["value"], p["u_k2"], 2.0, p["unit"]), p["name"]
        else:
            assert "none" in q
    for r in (rec.get("iso230") or {}).get("positioning") or []:
        res = next(v for k, v in got["results"].items() if k.startswith(f"ISO 230-2 positioning of {r['axis']}"))
        for k in ("E", "M", "B", "R", "A", "E_fwd", "B_mean"):
            q = res["Axis figures"][k.replace("_", " ")]
            assert q["value"] == r[f"{k}_um"] and q["unit"] == "um" and q["U"] == r["uncertainty"]["U_um"].get(k)
        table = res["Per target and approach direction"]
        assert table["P_i"] == {"values": r["targets_mm"], "unit": "mm"}
        assert table["B_i"]["values"] == r["B_i_um"] and table["s_i fwd"]["values"] == r["s_fwd_um"]
    env = rec["certificate"]["environment"]
    for s in env["sensors"]:
        c = got["conditions"][f"temperature channel {s['name']}"]
        assert c[f"temperature channel {s['name']}, mean"] == {"value": s["mean_degC"], "unit": "degC", "U": None,
                                                              "k": None}
    if isinstance(env.get("air_temperature_degC"), list):
        lo = got["conditions"]["air temperature"]["air temperature, lowest"]["value"]
        assert lo == env["air_temperature_degC"][0]


def test_dcc_of_a_synthetic_certificate_is_the_schemas_and_reads_back():
    rec = _synthetic()
    xml = dcc.write(rec)
    check_structure(xml)
    check_read_back(xml, rec)
    assert r"\micro\radian\milli\metre\tothe{-1}" in xml and r"\micro\metre\milli\metre\tothe{-2}" in xml
    assert "<si:valueExpandedMU>5.7e-05</si:valueExpandedMU>" in xml and r"\degreecelsius" in xml
    with pytest.raises(ValueError, match="certificate"):
        dcc.write(dict(rec, certificate=None))
    odd = json.loads(json.dumps(rec))
    odd["fit"]["quantities"][0]["unit"] = "scaled"       # a profile's combination in the fit's own unit
    q = dcc.read(dcc.write(odd))["results"]["Volumetric error model of the machine"][
        "Quantities determined relative to others"]["SAOC (E_A0C)"]
    assert "not a physical quantity, not stated" in q["none"]


def test_structure_check_bites():
    """The independent check refuses what the schema refuses: children out of order, a required one missing, a
    unit not in D-SI syntax."""
    xml = dcc.write(_synthetic())
    swapped = xml.replace("<dcc:countryCodeISO3166_1>DE</dcc:countryCodeISO3166_1>\n      <dcc:usedLangCodeISO639_1>"
                          "en</dcc:usedLangCodeISO639_1>", "<dcc:usedLangCodeISO639_1>en</dcc:usedLangCodeISO639_1>"
                          "\n      <dcc:countryCodeISO3166_1>DE</dcc:countryCodeISO3166_1>")
    assert swapped != xml
    for bad in (swapped, re.sub(r"<dcc:uniqueIdentifier>.*?</dcc:uniqueIdentifier>", "", xml),
                xml.replace(r"\micro\metre", "um", 1)):
        with pytest.raises(AssertionError):
            check_structure(bad)


# -- the DCC against PTB's schema --------------------------------------------------------------------------------
def schema_folder() -> Path | None:
    """The DCC 3.3.0 schema: $FIVEAXIS_DCC_SCHEMA or ~/.cache/fiveaxis/dcc-3.3.0/, a folder with dcc.xsd (PTB's, as
    published), si/SI_Format.xsd (D-SI 2.2) and optionally d-sig/xmldsig-core-schema.xsd (else xmlschema's copy)."""
    folder = Path(os.environ.get("FIVEAXIS_DCC_SCHEMA") or Path.home() / ".cache" / "fiveaxis" / "dcc-3.3.0")
    return folder if (folder / "dcc.xsd").is_file() and (folder / "si" / "SI_Format.xsd").is_file() else None


def validator():
    """An xmlschema validator of PTB's dcc.xsd with its imports mapped to the local copies (nothing fetched). The
    D-SI schema imports a QUDT vocabulary for the optional si:quantityTypeQUDT, which fiveaxis does not write:
    where it is not at hand, that element's type stays open (xmlschema's lax build) and everything else is strict."""
    folder = schema_folder()
    if folder is None:
        pytest.skip("the DCC 3.3.0 XSDs are not here (set FIVEAXIS_DCC_SCHEMA to a folder with dcc.xsd and "
                    "si/SI_Format.xsd, or put them in ~/.cache/fiveaxis/dcc-3.3.0/)")
    xmlschema = pytest.importorskip("xmlschema", reason="xmlschema is not installed (pip install -e .[test])")
    dsig = folder / "d-sig" / "xmldsig-core-schema.xsd"
    if not dsig.is_file():
        dsig = Path(xmlschema.__file__).parent / "schemas" / "DSIG" / "xmldsig-core-schema.xsd"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")            # the QUDT import that cannot be fetched
        schema = xmlschema.XMLSchema(str(folder / "dcc.xsd"), validation="lax", allow="local",
                                     locations=[("https://ptb.de/si", str(folder / "si" / "SI_Format.xsd")),
                                                ("http://www.w3.org/2000/09/xmldsig#", str(dsig))])
    assert schema.version == "3.3.0" and "{https://ptb.de/si}real" in schema.maps.elements
    assert all("qudt" in str(e).lower() for e in schema.all_errors), schema.all_errors[:2]
    return schema


def test_dcc_validates_against_ptbs_schema():
    schema = validator()
    xml = dcc.write(_synthetic())
    errors = list(schema.iter_errors(xml))
    assert errors == [], str(errors[0])[:500]
    bad = xml.replace("<dcc:performanceLocation>customer</dcc:performanceLocation>",
                      "<dcc:performanceLocation>garage</dcc:performanceLocation>")
    assert list(schema.iter_errors(bad)), "the validator does not bite"


# -- real certificates: a laser run (ISO 230-2), an R-test, a ballbar (ISO 230-4) ---------------------------------
def _simulate(tmp, name, *argv):
    from conftest import run_cli
    path = tmp / name
    assert run_cli("simulate", *map(str, argv), "-o", str(path))[0] == 0
    return path


@pytest.fixture(scope="module")
def laser(tmp_path_factory):
    """`fiveaxis report` of an ISO 230-2 laser run of X on the A/C trunnion (9 targets, 5 cycles, a 25 um reversal,
    readings at 0.1 um) with the example campaign and a customer set on the command line: HTML, PDF, DCC, JSON."""
    import shutil
    from fiveaxis.report.pdf import browser
    d = tmp_path_factory.mktemp("laser")
    data = _simulate(d, "laser.csv", "--machine", "ac_trunnion", "--instrument", "interferometer", "--axes", "X",
                     "--targets", "9", "--effect", "dx_x:xr=0.0125", "--seed", "3", "--temperature", "air=air:amp=0.4",
                     "--temperature", "bed=bed:rise=0.8")
    out = d / "cert.html"
    argv = ["report", data, "--machine", "ac_trunnion", "--rounds", "2", "--campaign", CAMPAIGN,
            "--set", "customer.name=ACME Tools", "--u-device", "0.3", "-o", out, "--dcc", "--json"]
    pdf = browser() is not None and shutil.which("chromium") is not None
    return d, data, out, argv + (["--pdf"] if pdf else []), pdf


@pytest.fixture(scope="module")
def laser_run(laser, capsys_module):
    d, data, out, argv, pdf = laser
    rc, stdout, err = capsys_module(*argv)
    assert rc == 0, err
    return json.loads(stdout), out, pdf, err


@pytest.fixture(scope="module")
def capsys_module():
    """Run the command line in-process and catch what it prints (a module-scoped capsys)."""
    from conftest import run_cli
    return run_cli


@pytest.mark.slow
def test_a_laser_certificate_writes_html_pdf_and_dcc_from_one_record(laser_run):
    rec, out, pdf, err = laser_run
    page = out.read_text(encoding="utf-8")
    xml = out.with_suffix(".xml").read_text(encoding="utf-8")
    assert "wrote" in err and f"{out.with_suffix('.xml')}" in err
    if pdf:
        assert out.with_suffix(".pdf").read_bytes().startswith(b"%PDF")
    cert = rec["certificate"]
    assert cert["customer"]["name"] == "ACME Tools" and cert["machine"]["serial"] == "SN 123456"
    sensors = {s["name"]: s for s in cert["environment"]["sensors"]}
    assert set(sensors) == {"temp_air", "temp_bed"} and all(s["readings"] > 80 for s in sensors.values())
    assert all(15 < s["min_degC"] <= s["mean_degC"] <= s["max_degC"] < 30 for s in sensors.values())
    sections = check_numbers(page, rec)
    assert {"certificate", "verdict", "data", "fit", "rounds", "iso230", "residuals", "sensitivity"} <= sections
    for part in ('id="certificate"', 'id="instruments"', 'id="environment"', 'id="uncertainty"', 'id="signatures"',
                 "SN 123456", "ACME Tools", "DAkkS 12345-2024", 'id="iso230-2-targets-0"', "Approved by"):
        assert part in page, part
    # ISO 230-2: --u-device wins over the campaign's 0.4 um, the rest of its budget stays; U of E, M and B
    pos = rec["iso230"]["positioning"][0]
    assert pos["uncertainty"]["inputs"]["u_device_um"] == 0.3 and pos["uncertainty"]["inputs"]["drift_um"] == 0.2
    assert set(pos["uncertainty"]["U_um"]) == {"E", "M", "B"}
    assert "no uncertainty statement" not in page.lower()
    # the DCC: the schema's structure, the record's numbers
    check_structure(xml)
    check_read_back(xml, rec)


@pytest.mark.slow
def test_the_laser_dcc_validates_against_ptbs_schema(laser_run):
    schema = validator()
    rec, out, _, _ = laser_run
    errors = list(schema.iter_errors(out.with_suffix(".xml").read_text(encoding="utf-8")))
    assert errors == [], str(errors[0])[:500]


@pytest.mark.slow
def test_outputs_are_checked_before_the_work_and_all_or_nothing(laser, laser_run, capsys_module, tmp_path):
    d, data, out, argv, _ = laser
    before = out.read_bytes()
    rc, _, err = capsys_module(*argv[:-1] if argv[-1] == "--pdf" else argv)
    assert rc == 2 and err.count("\n") == 1 and "--force" in err and out.read_bytes() == before
    rc, _, err = capsys_module("report", data, "--machine", "ac_trunnion", "-o", tmp_path / "a.html", "--dcc")
    assert rc == 2 and "--dcc: a Digital Calibration Certificate needs the campaign" in err
    assert not (tmp_path / "a.html").exists()
    rc, _, err = capsys_module("report", data, "--machine", "ac_trunnion", "-o", tmp_path / "a.html", "--campaign",
                               CAMPAIGN, "--set", "environment.air_temperature_degC=2000")
    assert rc == 2 and err.count("\n") == 1 and "environment.air_temperature_degC" in err
    assert not list(tmp_path.iterdir())
    rc, _, err = capsys_module("report", data, "--machine", "ac_trunnion", "-o", tmp_path / "a.html", "--dcc",
                               tmp_path / "a.txt", "--campaign", CAMPAIGN)
    assert rc == 2 and "expected a .xml file" in err


@pytest.fixture(scope="module")
def rtest(tmp_path_factory):
    """The report of an R-test on the A/C trunnion (3 sphere placements) with a hidden radial motion of C, at the
    controller's resolution, as a certificate."""
    d = tmp_path_factory.mktemp("rtest")
    data = _simulate(d, "r.csv", "--machine", "ac_trunnion", "--instrument", "rtest", "--n", "200", "--effect",
                     "dx_C:C1=0.01", "--seed", "2", "--with-sigma")
    return record.build(data, "ac_trunnion", max_rounds=2, sensitivity=False, campaign=CP.load(CAMPAIGN))


@pytest.mark.slow
def test_an_r_test_certificate(rtest):
    rec = rtest.record
    page = html.render(rtest)
    sections = check_numbers(page, rec)
    assert {"certificate", "fit", "verdict", "rounds"} <= sections
    xml = dcc.write(rec)
    check_structure(xml)
    check_read_back(xml, rec)
    got = dcc.read(xml)["results"]["Volumetric error model of the machine"]
    rel = got["Quantities determined relative to others"]
    for q in rec["fit"]["quantities"]:
        got_q = rel[f"{q['name']} ({q['iso']})" if q["iso"] else q["name"]]
        assert got_q["value"] == q["value"] if dcc.spelled(q["unit"]) else "not stated" in got_q["none"]


@pytest.mark.slow
def test_a_quantity_stated_relative_to_others_is_said_so_in_its_group(rtest):
    """Issue 32.2: SBOA/SCOA appeared with values and also under "cannot separate": a group member that is stated
    relative to the others says so in its group, and the verdict counts them."""
    fit = rtest.record["fit"]
    leads = {q["name"] for q in fit["quantities"]}
    assert leads
    page = html.render(rtest)
    for g in fit["groups"]:
        assert g["relative"] == [m for m in g["members"] if m in leads]
        for m in g["relative"]:
            assert f"{m}: stated above relative to the others of this group" in page or \
                re.search(rf"{re.escape(m)}(, [^:<]+)*: stated above relative", page)
    n = sum(len(g["relative"]) for g in fit["groups"])
    assert f"{n} of these parameters {'is' if n == 1 else 'are'} stated relative to the others of " \
           f"{'its' if n == 1 else 'their'} group" in " ".join(rtest.record["verdict"]["unexplained"])


@pytest.mark.slow
def test_a_ballbar_report_and_one_axis_coverage(tmp_path):
    """ISO 230-4's numbers are the record's; a laser file (one axis moves) says its coverage figure is bars."""
    ball = _simulate(tmp_path, "b.csv", "--machine", "li2018", "--instrument", "ballbar", "--n", "300", "--effect",
                     "dx_x:xr=0.003", "--seed", "3")
    rep = record.build(ball, "li2018", max_rounds=1, sensitivity=False)
    assert "iso230" in check_numbers(html.render(rep), rep.record)
    assert "Each dot is a measured pose" in rep.record["data"]["coverage_caption"]
    laser = _simulate(tmp_path, "l.csv", "--machine", "ac_trunnion", "--instrument", "interferometer", "--axes", "X",
                      "--targets", "6", "--cycles", "2", "--seed", "1")
    rep = record.build(laser, "ac_trunnion", max_rounds=1, sensitivity=False)
    cap = rep.record["data"]["coverage_caption"]
    assert "Only X moves" in cap and "bars" in cap and "Each dot" not in cap
    assert cap in html.render(rep)


def test_compensation_numbers_are_the_records_and_not_false_precision():
    """Issue 32.2: the kinematics module's predicted 2.84e-10 um beside a k = 2 range of 0 to 44.3 um: the page
    shows the model's predictions to 0.01 um, says what they are, and every number is the record's."""
    rec = _synthetic_report_record()
    page = html.render(record.Report(rec, {}))
    assert "compensation" in check_numbers(page, rec)
    shown = re.sub(r"<[^>]+>", "", page)          # what a reader sees (the exact value stays in <data value=...>)
    assert "2.84e" not in shown and ">0.00</data>" in page
    assert "leaves nothing by construction" in page and "lies in the last column" in page


def _synthetic_report_record() -> dict:
    """A report record of the shape record.build makes, small, with a compensation section."""
    rec = {"title": "t", "generated": "g", "fiveaxis_version": "v",
           "machine": {"name": "li2018", "title": "Li", "file": "li2018.toml", "convention": "equations"},
           "data": {"file": "m.csv", "n": 100, "variables": ["X"], "instrument": "tip", "setups": [],
                    "ranges": [{"variable": "X", "unit": "mm", "min": -10.5, "max": 20.25, "stroke": [-100, 100],
                                "coverage": 0.15375}], "tool_length_mm": [200.0, 200.0], "time_s": None,
                    "sigma_um": None, "coverage_caption": "c"},
           "rounds": [{"round": 1, "added": [], "added_iso": [], "rms_um": 1.25, "noise_um": 1.0, "ratio": 1.25,
                       "noise_source": "estimated", "missing_effect": False, "verdict": "no missing effect",
                       "decision": {"delta_ebic_best": 3.5, "cv_folds": 5, "cv_sse_without": 1.0,
                                    "cv_sse_with": 1.1}, "candidates": []}],
           "fit": {"rms_um": 1.25, "rms_first_order_um": 1.25, "rank": 10, "n_parameters": 41, "condition": 12.5,
                   "sigma": "estimated from the residual", "reduced_chi2": None, "effects": [], "effects_iso": [],
                   "parameters": [], "combinations": [], "quantities": [], "groups": [], "setups": [],
                   "correlations": []},
           "residuals": {"before": {"effects": [], "rms_um": 1.25}, "after": {"effects": [], "rms_um": 1.25}},
           "sensitivity": None, "iso230": None, "certificate": None,
           "verdict": {"explained": True, "verdict": "no missing effect", "headline": "h", "rms_um": 1.25,
                       "noise_um": 1.0, "noise_source": "estimated", "ratio": 1.25, "rms_first_um": 1.25,
                       "effects_found": [], "unexplained": []}}
    stages = [("before", 0.0312, 0.0213, 0.0301, [0.018, 0.025]),
              ("after_kinematics_module", 2.84e-13, 1.1e-13, 2.0e-13, [0.0, 0.0443]),
              ("after_table", 0.00427, 0.00211, 0.0036, [0.0005, 0.0443])]
    rec["compensation"] = {
        "folder": "comp", "method": "m", "files": ["table.csv"], "maps": [], "warnings": [], "not_compensated": {},
        "stages": [{"key": k, "label": k, "max": a, "rms": b, "p95": c, "range_k2": r} for k, a, b, c, r in stages],
        "uncertainty": {"fit_mm": 0.00041, "undetermined_mm": 0.0123, "directions": 4,
                        "prior": {"linear_mm": 0.005, "angular_rad": 2.5e-5}, "measurement": "", "command": "",
                        "axis_note": ""},
        "by_tool_length": [{"tool_length_mm": 150.0, "table_node": True,
                            **{k: {"max": 0.002, "rms": 0.00123, "p95": 0.0019}
                               for k in ("before", "after_table", "after_exact_correction")}}]}
    return rec


def test_effects_found_carry_the_final_models_size():
    """Issue 32.2: the verdict said `dx_x:t1 ... by 1.2 um` (round 1), the table `by -6.5 um` (the final model): the
    effects found are described by the final fit, and their value is the table's."""
    fit = {"parameters": [{"name": "dx_x:t1", "description": "final: by -6.5 um", "value": -6.5, "u_k2": 0.2,
                           "unit": "um", "determined": True},
                          {"name": "dx_x:xk100@-400", "description": "a profile", "determined": False},
                          {"name": "dx_x:xk100@0", "description": "a profile", "determined": False}]}
    from fiveaxis.model.machine import load_machine
    m = load_machine("li2018")
    f = record._found(m, "dx_x:t1", fit)
    assert f["description"] == "final: by -6.5 um" and f["parameters"] == ["dx_x:t1"] and f["iso"] == "E_XX:t1"
    assert record._found(m, "dx_x:xk100", fit)["parameters"] == ["dx_x:xk100@-400", "dx_x:xk100@0"]


def test_ini_speaks_of_pins_and_g54_only_where_the_machine_has_them():
    """Issue 32.2: the INI said "never use the comp files without the pins and G54" on a machine with neither."""
    from fiveaxis.linuxcnc import configuration as lx
    plain = lx.LinuxCNCCompensation("li2018", ("X", "Y", "Z", "B", "A"), (False,) * 3 + (True,) * 2, 200.0, ())
    text = lx.ini_text(plain)
    assert "G54" not in text and "pins" not in text and "comp files alone" in text


def test_diagnose_text_says_which_separation_question_it_answers():
    """Issue 32.2: diagnose's "neither another tool length nor wider axis ranges would separate them" (candidates)
    read beside the report's "another tool length determines ..." (fitted errors) as one question."""
    from fiveaxis.report import text
    src = Path(text.__file__).read_text()
    assert "would tell these candidate effects apart" in src and "fitted errors an extra measurement determines" in src
    page_src = Path(html.__file__).read_text()
    assert "Fitted errors the data cannot determine alone" in page_src
    assert "candidates this data cannot tell apart from it" in page_src


@pytest.mark.slow
def test_a_certificate_of_a_log_as_a_laser_writes_it(tmp_path):
    """A log of X as a laser's software writes it (positions at 0.001 mm jittering around irregular targets, readings
    at 0.1 um; tests/test_iso230_2.laser_log): the certificate's per-target table and the DCC's equal the standard's
    formulas evaluated independently (test_iso230_2.reference) to the printed decimals (0.01 um) and to 1e-9 um."""
    import fiveaxis
    from test_iso230_2 import laser_log, reference
    model = fiveaxis.load("ac_trunnion")
    path, df = laser_log(model, tmp_path, jitter_mm=0.004)
    ref, mean, s, B, targets = reference(df, 9)
    rep = record.build(path, "ac_trunnion", max_rounds=1, sensitivity=False, campaign=CP.load(CAMPAIGN))
    page = html.render(rep)
    check_numbers(page, rep.record)
    body = re.search(r'<table id="iso230-2-targets-0">.*?<tbody>(.*?)</tbody>', page, re.S).group(1)
    rows = [[float(re.sub(r"<[^>]+>", "", c)) for c in re.findall(r"<td[^>]*>(.*?)</td>", r)[1:]]
            for r in re.findall(r"<tr[^>]*>(.*?)</tr>", body)]
    import numpy as np
    got = np.array(rows)
    assert np.allclose(got[:, 0], targets, atol=5e-4 + 1e-9)                       # P_i, 3 decimals (mm)
    assert np.allclose(got[:, 1:3], mean, atol=5e-3 + 1e-9)                        # mean fwd, bwd (um)
    assert np.allclose(got[:, 3:5], s, atol=5e-3 + 1e-9) and np.allclose(got[:, 7], B, atol=5e-3 + 1e-9)
    table = dcc.read(dcc.write(rep.record))["results"]["ISO 230-2 positioning of X (setup laser-X)"]
    t = table["Per target and approach direction"]
    assert np.allclose(t["mean x_i fwd"]["values"], mean[:, 0], atol=1e-9)
    assert np.allclose(t["B_i"]["values"], B, atol=1e-9)
    figs = table["Axis figures"]
    for k in ("E", "M", "B", "R", "A"):
        assert figs[k]["value"] == pytest.approx(ref[k], abs=1e-9)
        assert (figs[k]["U"] is not None) == (k in ("E", "M", "B"))
