"""Error values from the user: NAME=VALUE specs, files of such lines, JSON objects, fitted model files.

`read(model, specs)` starts from the machine file's values and applies each spec in turn:

* `NAME=VALUE` (mm for translations, rad for rotations);
* a text file of `NAME=VALUE` or `NAME VALUE` lines (`#` comments);
* a JSON object `{NAME: VALUE, ...}`;
* a fitted model file (`fiveaxis fit ... -o model.json`): a JSON object with "machine" (a name, or the record
  {"name", "file", "sha256"} that `fit -o` writes: name and SHA-256 must be those of the machine file of the run),
  "convention" and an "errors_mm_rad" table (the full error vector; used when present; the coefficients of its
  "effects" are reported as left out) or a "parameters" table
  {NAME: {"value": number or null, "std": ...}}. A model fitted for another machine, or under another
  convention (the same name then means a different error), is refused. In a "parameters" table, null marks a
  parameter the data could not determine: that error keeps its previous value (the machine file's unless an
  earlier spec set it), and the names so kept are reported; parameters that are not geometric errors of the
  machine (an added effect's coefficients, the tool length) do not enter a sensitivity run and are reported as
  left out.

Values must be finite JSON numbers (not booleans, not null outside "parameters", not strings). Every problem is
an InputError naming the file and the line or key.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from ..exceptions import InputError
from . import iso_names as iso
from .machine import check_made_for
from ..inputs import read_text


@dataclass
class ErrorValues:
    """Error values (mm, rad) by name in model order, and what the reading noted (kept, left out, sources)."""
    values: dict[str, float]
    sources: list[str] = field(default_factory=list)
    kept: list[str] = field(default_factory=list)          # undetermined in a fitted model: previous value kept
    left_out: list[str] = field(default_factory=list)      # fitted parameters that are not errors of the model

    def label(self):
        """For the settings of a run: 'machine file defaults' or the sources in order."""
        return "machine file defaults" if not self.sources else list(self.sources)


#: Largest error value accepted (mm for translations, rad for rotations): beyond, no machine tool; the products of
#: the sensitivity integrals would overflow (1e200).
MAX_VALUE = {"mm": 1e3, "rad": 1.0}


def _number(raw, where: str, name: str, unit: str | None = None) -> float:
    if isinstance(raw, bool) or raw is None or isinstance(raw, (list, dict)):
        shown = json.dumps(raw)
        raise InputError(f"{where}: value of {name} must be a number (mm or rad), got {shown}")
    try:
        v = float(raw)
    except (TypeError, ValueError):
        raise InputError(f"{where}: value of {name} must be a number (mm or rad), got {_short(raw)!r}") from None
    if not math.isfinite(v):
        raise InputError(f"{where}: value of {name} must be finite, got {_short(raw)!r}")
    if unit is not None and abs(v) > MAX_VALUE[unit]:
        raise InputError(f"{where}: value of {name} must be within +-{MAX_VALUE[unit]:g} {unit} (an error of a "
                         f"machine tool), got {_short(raw)!r}")
    return v


def _short(raw, n: int = 40):
    s = str(raw)
    return s if len(s) <= n else s[:n] + "..."


class _Reader:
    def __init__(self, model):
        self.model = model
        defaults = model.machine.default_errors()
        self.out = ErrorValues({n: float(defaults[n]) for n in model.errors})
        self.known = set(model.errors)

    def put(self, name, raw, where):
        name = iso.canonical(self.model, _short(str(name).strip(), 200), where=where)   # project or ISO 230 name
        unit = "rad" if self.model.machine.is_angular(name) else "mm"
        self.out.values[name] = _number(raw, where, name, unit)

    def spec(self, spec: str):
        spec = str(spec)
        if "=" in spec and not Path(spec).exists():
            name, _, raw = spec.partition("=")
            self.put(name, raw, f"--errors {_short(spec)}")
            self.out.sources.append(spec)
            return
        path = Path(spec)
        if not path.exists():
            raise InputError(f"errors {spec!r}: not NAME=VALUE and no such file (expected NAME=VALUE, e.g. "
                             f"ex_x=1e-5, or a file of them, a JSON object or a fitted model file)", key="errors")
        text = read_text(path, "NAME=VALUE lines, a JSON object or a fitted model file")
        if not text.strip():
            raise InputError(f"{path}: empty (expected NAME=VALUE lines, a JSON object or a fitted model file)")
        if text.lstrip()[:1] in ("{", "["):
            self.json_file(path, text)
        else:
            self.lines(path, text)
        self.out.sources.append(str(path))

    def lines(self, path, text):
        for i, line in enumerate(text.splitlines(), 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            name, sep, raw = line.partition("=")
            if not sep:
                parts = line.split()
                if len(parts) != 2:
                    raise InputError(f"{path}: line {i}: expected NAME=VALUE, got {_short(line)!r}")
                name, raw = parts
            self.put(name, raw, f"{path}: line {i}")

    def json_file(self, path, text):
        try:
            data = json.loads(text, parse_constant=lambda c: c)     # NaN/Infinity stay strings: refused below
        except json.JSONDecodeError as exc:
            raise InputError(f"{path}: line {exc.lineno} column {exc.colno}: invalid JSON ({exc.msg})") from None
        except RecursionError:
            raise InputError(f"{path}: invalid JSON (nested too deeply)") from None
        if not isinstance(data, dict):
            raise InputError(f"{path}: expected a JSON object of error values, got a {type(data).__name__}")
        if "errors_mm_rad" in data or "parameters" in data:
            self.model_file(path, data)
            return
        for name, raw in data.items():
            self.put(name, raw, f"{path}: key {_short(name)}")

    def model_file(self, path, data):
        machine = data.get("machine")
        if isinstance(machine, dict):                 # a model file of `fit -o`: {"name", "file", "sha256"}
            self.fitted_machine(path, machine)
        elif machine is not None and machine != self.model.machine.name:
            raise InputError(f"{path}: key machine: a model of {_short(machine)!r}, not of {self.model.machine.name}")
        conv = data.get("convention")
        if conv is not None and conv != self.model.convention:
            raise InputError(f"{path}: key convention: fitted under the {_short(conv)!r} convention, this run uses "
                             f"{self.model.convention!r} (the same error name sits elsewhere)")
        if "errors_mm_rad" in data:
            table = data["errors_mm_rad"]
            if not isinstance(table, dict):
                raise InputError(f"{path}: key errors_mm_rad: expected an object {{name: value}}")
            for name, raw in table.items():
                self.put(name, raw, f"{path}: key errors_mm_rad.{_short(name)}")
            effects = data.get("effects", [])
            for e in effects if isinstance(effects, list) else ():
                coefs = e.get("coefficients_mm_rad") if isinstance(e, dict) else None
                self.out.left_out.extend(str(n) for n in (coefs if isinstance(coefs, dict) else ()))
            return
        table = data["parameters"]
        if not isinstance(table, dict):
            raise InputError(f"{path}: key parameters: expected an object {{name: {{\"value\": ...}}}}")
        for name, entry in table.items():
            where = f"{path}: key parameters.{_short(name)}"
            if not isinstance(entry, dict) or not ("value" in entry or entry.get("determined") is False):
                raise InputError(f"{where}: expected an object with a \"value\" (number or null) or "
                                 f"\"determined\": false")
            if name not in self.known:
                self.out.left_out.append(str(name))
                continue
            if entry.get("value") is None:
                self.out.kept.append(name)
                continue
            self.put(name, entry["value"], f"{where}.value")


    def fitted_machine(self, path, machine: dict):
        """The "machine" record of a `fit -o` model file must name this machine file (name and SHA-256)."""
        check_made_for(self.model.machine, machine.get("name"), machine.get("sha256"), str(path))


def read(model, specs=()) -> ErrorValues:
    """The machine file's error values with the specs applied in order (see the module docstring)."""
    r = _Reader(model)
    for spec in specs or ():
        r.spec(spec)
    return r.out
