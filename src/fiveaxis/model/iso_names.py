"""ISO 230 names of a machine's geometric errors, derived from the machine file: axis, direction and error kind.

The project names its 41 errors as the paper does (`ex_x`, `dy_B`, `Sxy`, `dXOB`, ...). People who calibrate
machines speak ISO 230; this module derives, for every error of a machine (and convention), the ISO name:

- ISO 230-1 error motions of a linear axis X: E_XX (positioning), E_YX, E_ZX (straightness), E_AX, E_BX, E_CX
  (angular: about x, y, z). The paper's `d<c>_<axis>` is the translation along c, `e<c>_<axis>` the rotation
  about c, so `dx_x` = E_XX, `ex_x` = E_AX, `ez_x` = E_CX.
- ISO 230-7 error motions of a rotary axis C: E_XC, E_YC (radial), E_ZC (axial), E_AC, E_BC (tilt), E_CC
  (angular positioning). The paper's PD of a rotary axis lives in the frame that rotates with the axis; ISO's
  error motions are along the fixed machine axes. The two agree at C = 0 (in general
  dx_C = cos C * E_XC + sin C * E_YC); each entry says which frame the project's value is in (`frame`).
- ISO 230-7 location errors of a rotary axis C: E_X0C, E_Y0C (position of the axis line), E_A0C, E_B0C
  (orientation). The name follows the machine file's kind (`rz` is a rotation about z), not the paper's
  symbol: li2018's `SAOB` is a rotation about z, so its ISO name is E_C0B.
- ISO 230-1 squareness of linear axes: a rotation about z placed before the Y axis turns Y towards X:
  E_C(0X)Y ("Y to X, about z"); likewise E_B(0X)Z and E_A(0Y)Z. The short spelling E_C0Y is accepted too.

Signs: ISO values are along / about the machine file's +x, +y, +z, except the positioning error of an axis
(E_XX for X, E_CC for C), which ISO measures in the axis' own sense: for an axis that moves along -z
(tilting_head's Z) E_ZZ = -dz_Z. `sign` of each entry gives ISO value = sign * project value.

No ISO name (iso is None, with a note) where ISO 230 has none: an axis whose direction is not along x, y or z
(a nutating head), an axis whose name is not the ISO 841 letter of its direction (a linear axis named B), and
position-independent errors that are not location errors of their axis (a translation before a linear axis).

Units: errors in mm (translations) and rad (rotations), as everywhere in the model.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

from ..exceptions import InputError
from .machine import Machine

#: Direction letters of ISO 230 (translations along x, y, z) and rotation letters (about x, y, z).
TRANSLATION = "XYZ"
ROTATION = "ABC"
#: ISO 841 axis letters by direction index: linear axes along x, y, z; rotary axes about x, y, z.
LINEAR_LETTERS = ("XUP", "YVQ", "ZWR")
ROTARY_LETTERS = ("A", "B", "C")


@dataclass(frozen=True)
class IsoName:
    """One error of a machine with its ISO 230 name (None where ISO 230 has none, see `note`)."""
    error: str          # project name, e.g. ex_x, SAOB
    iso: str | None     # ISO 230 name, e.g. E_AX, E_C0B, E_C(0X)Y
    axis: str           # the joint the error belongs to (a PIGE: the joint it is placed before)
    kind: str           # PDGE prefix ex ey ez dx dy dz, or PIGE kind rx ry rz tx ty tz
    unit: str           # mm (translation) or rad (rotation)
    standard: str       # which ISO 230 definition the name comes from
    sign: int           # ISO value = sign * project value
    frame: str          # the frame the project's value is expressed in
    note: str = ""      # frame caveat, or why there is no ISO name

    def to_json(self) -> dict:
        return asdict(self)


def _direction(vec) -> tuple[int, int] | None:
    """(index 0-2, sign +-1) of a direction along x, y or z; None for any other direction."""
    nonzero = [i for i, v in enumerate(vec) if v != 0]
    if len(nonzero) != 1:
        return None
    i = nonzero[0]
    return i, (1 if vec[i] > 0 else -1)


def _frame(rotated: list[str]) -> str:
    """The frame a joint's errors are expressed in: the machine axes, or a frame turned by the rotary axes passed."""
    return "machine axes" if not rotated else "rotating with " + " and ".join(rotated)


def _at_zero(rotated: list[str]) -> str:
    return " = ".join(rotated) + " = 0"


def _unnamed_reason(axis) -> str:
    """Why an axis has no ISO 230 names, or '' if it has them."""
    along = _direction(axis.direction)
    if along is None:
        how = "turns about" if axis.type == "rotary" else "moves along"
        return (f"axis {axis.name} {how} {list(axis.direction)}, not along x, y or z: ISO 230 names only axes "
                f"along the machine axes")
    letters = ROTARY_LETTERS[along[0]] if axis.type == "rotary" else LINEAR_LETTERS[along[0]]
    if axis.name not in letters:
        which = "about" if axis.type == "rotary" else "along"
        return (f"a {axis.type} axis {which} {'xyz'[along[0]]} is named {' or '.join(letters)} in ISO 841, "
                f"not {axis.name}: no ISO 230 name")
    return ""


def _pdge(axis, rotated: list[str], own_rotation_only: bool) -> list[IsoName]:
    """The six error motions of an axis (ISO 230-1 for linear, ISO 230-7 for rotary axes)."""
    reason = _unnamed_reason(axis)
    along = _direction(axis.direction)
    frame = _frame(rotated)
    rotary = axis.type == "rotary"
    standard = "ISO 230-7 error motion of a rotary axis" if rotary else "ISO 230-1 error motion of a linear axis"
    out = []
    for name in axis.pdge:
        prefix = name.split("_", 1)[0]
        comp = "xyz".index(prefix[1])
        angular = prefix[0] == "e"
        unit = "rad" if angular else "mm"
        if reason:
            out.append(IsoName(name, None, axis.name, prefix, unit, "", 1, frame, reason))
            continue
        letter = (ROTATION if angular else TRANSLATION)[comp]
        own = comp == along[0]
        # The positioning error (translation along a linear axis, rotation about a rotary one) is measured in the
        # axis' own sense; everything else along / about the machine's +x, +y, +z.
        positioning = own and (angular == rotary)
        sign = along[1] if positioning else 1
        note = ""
        if rotated:
            if own and own_rotation_only:
                note = f"along the axis {axis.name} itself: the same in the rotating and the fixed frame"
            else:
                note = (f"the project's value is along the axes of the frame {frame}; ISO's error motion is along "
                        f"the fixed machine axes: the two agree where {_at_zero(rotated)}")
        if positioning and sign < 0:
            note = (note + "; " if note else "") + (f"{axis.name} moves in -{'xyz'[comp]}: its positioning error "
                                                    f"is counted in the axis' own sense")
        out.append(IsoName(name, f"E_{letter}{axis.name}", axis.name, prefix, unit, standard, sign, frame, note))
    return out


def _pige(axis, rotated: list[str]) -> list[IsoName]:
    """Position-independent errors placed before an axis: location errors (rotary) or squareness (linear)."""
    reason = _unnamed_reason(axis)
    frame = _frame(rotated)
    along = _direction(axis.direction)
    out = []
    for name, kind in axis.pige.items():
        angular = kind[0] == "r"
        unit = "rad" if angular else "mm"
        comp = "xyz".index(kind[1])
        if reason:
            out.append(IsoName(name, None, axis.name, kind, unit, "", 1, frame, reason))
            continue
        note = f"in the frame {frame}: ISO's reference position is where {_at_zero(rotated)}" if rotated else ""
        if axis.type == "rotary":
            letter = (ROTATION if angular else TRANSLATION)[comp]
            iso = f"E_{letter}0{axis.name}"
            standard = "ISO 230-7 location error of a rotary axis"
            if comp == along[0]:
                extra = (f"zero position of {axis.name} (a rotation about its own line)" if angular else
                         f"axial position of {axis.name}'s line, which only shifts the chain after it")
            elif kind[0] == "t":
                extra = (f"a translation before {axis.name}: it moves {axis.name}'s line and, unlike ISO's position "
                         f"of the line, also the chain after it (a constant offset)")
            else:
                extra = ""
            note = "; ".join(x for x in (note, extra) if x)
            out.append(IsoName(name, iso, axis.name, kind, unit, standard, 1, frame, note))
            continue
        if not angular:
            out.append(IsoName(name, None, axis.name, kind, unit, "", 1, frame,
                               f"a translation before the linear axis {axis.name} only shifts the chain after it; "
                               f"ISO 230 gives the line of a linear axis no position"))
            continue
        if comp == along[0]:
            out.append(IsoName(name, None, axis.name, kind, unit, "", 1, frame,
                               f"a rotation about the linear axis {axis.name}'s own direction is not a squareness "
                               f"of {axis.name}"))
            continue
        ref = 3 - comp - along[0]
        iso = f"E_{ROTATION[comp]}(0{TRANSLATION[ref]}){axis.name}"
        out.append(IsoName(name, iso, axis.name, kind, unit, "ISO 230-1 squareness of linear axes", 1, frame,
                           note or f"{axis.name} to {TRANSLATION[ref]}, a rotation about {kind[1]}"))
    return out


def _chain_end(machine: Machine, error: str, rotated: dict) -> IsoName:
    """A location error after the last joint of a chain (the spindle in its head, the workpiece holder): ISO 230
    names location errors of axes, not of these."""
    kind = getattr(machine, "pige_kinds", {}).get(error, "")
    place = machine.pige_place(error) if hasattr(machine, "pige_place") else ""
    what = {"tool": "the spindle", "workpiece": "the workpiece holder"}.get(place, "the end of a chain")
    unit = "rad" if machine.is_angular(error) else "mm"
    return IsoName(error, None, place, kind, unit, "", 1, _frame(rotated.get(place, [])),
                   f"a location error of {what} after the last axis of its chain, not of an axis: no ISO 230 name")


def table(machine: Machine, convention: str | None = "equations") -> dict[str, IsoName]:
    """ISO names of every error of a machine (in a convention of its file), by project name, in model order."""
    m = machine.with_convention(convention)
    entries, ends = {}, {}
    for place, chain in (("tool", m.tool_chain), ("workpiece", m.workpiece_chain)):
        rotated: list[str] = []
        for axis in chain:
            for e in _pige(axis, list(rotated)):
                entries[e.error] = e
            before = list(rotated)
            if axis.type == "rotary":
                rotated.append(axis.name)
            for e in _pdge(axis, list(rotated), own_rotation_only=not before):
                entries[e.error] = e
        ends[place] = rotated
    return {n: entries[n] if n in entries else _chain_end(m, n, ends) for n in m.error_names}


def _machine_and_convention(obj, convention):
    """A Machine or a loaded Model (which knows its convention)."""
    machine = getattr(obj, "machine", obj)
    return machine, convention or getattr(obj, "convention", "equations")


def names(obj, convention: str | None = None) -> dict[str, IsoName]:
    """table() of a Machine (equations convention unless given) or of a loaded Model (its convention)."""
    return table(*_machine_and_convention(obj, convention))


def name(obj, error: str, convention: str | None = None) -> str | None:
    """The ISO name of one error (None where ISO 230 has none); an effect id `ex_x:x1` gives `E_AX:x1`."""
    param, sep, rest = error.partition(":")
    entry = names(obj, convention).get(param)
    if entry is None or entry.iso is None:
        return None
    return entry.iso + sep + rest


def label(obj, error: str, convention: str | None = None) -> str:
    """'ex_x (E_AX)' for people; the project name alone where there is no ISO name (L, custom effects)."""
    iso = name(obj, error, convention)
    return f"{error} ({iso})" if iso else error


def spellings(entry: IsoName) -> tuple[str, ...]:
    """Every accepted spelling of an ISO name: E_AX and EAX; for squareness also E_C0Y and EC0Y."""
    if entry.iso is None:
        return ()
    out = [entry.iso, entry.iso.replace("_", "", 1)]
    if "(" in entry.iso:
        short = entry.iso[:3] + "0" + entry.iso[-len(entry.axis):]
        out += [short, short.replace("_", "", 1)]
    return tuple(out)


_LOOKUPS: dict = {}


def _lookup(machine: Machine, convention: str | None) -> dict[str, str]:
    """Accepted ISO spelling -> project name; with no convention given, those of every convention of the file
    that do not contradict each other. Kept per machine record (they are immutable)."""
    key = (id(machine), convention)
    hit = _LOOKUPS.get(key)
    if hit is not None and hit[0] is machine:
        return hit[1]
    convs = [convention] if convention else ["equations", *machine.conventions]
    found: dict[str, set] = {}
    for conv in convs:
        for entry in table(machine, conv).values():
            for s in spellings(entry):
                found.setdefault(s, set()).add(entry.error)
    out = {s: next(iter(errs)) for s, errs in found.items() if len(errs) == 1}
    _LOOKUPS[key] = (machine, out)
    return out


def canonical(obj, error: str, convention: str | None = None, where: str = "error name") -> str:
    """The project name of an error given by its project name or its ISO 230 name (E_AX, E_C0B, E_C(0X)Y).

    obj: a Machine or a loaded Model. Any other name is an InputError listing both spellings of every error."""
    machine, conv = _machine_and_convention(obj, convention)
    error = error.strip()
    if error in machine.error_names:
        return error
    project = _lookup(machine, convention or getattr(obj, "convention", None)).get(error)
    if project is not None:
        return project
    raise InputError(f"{where}: unknown error name '{error}' for machine {machine.name} (expected a project or an "
                     f"ISO 230 name: {_pairs(machine, conv)})")


def _pairs(machine: Machine, convention: str) -> str:
    """'ex_x=E_AX, ..., SAOB=E_C0B': every error in both spellings, for error messages."""
    return ", ".join(f"{e.error}={e.iso}" if e.iso else e.error for e in table(machine, convention).values())


def canonical_keys(obj, values: dict, convention: str | None = None, where: str = "errors") -> dict:
    """A dict keyed by project or ISO names, keyed by project names; one error named twice is an InputError."""
    out, given = {}, {}
    for key, value in values.items():
        error = canonical(obj, key, convention, where)
        if error in out:
            raise InputError(f"{where}: '{key}' and '{given[error]}' name the same error {error}")
        out[error], given[error] = value, key
    return out


def canonical_effect(obj, effect_id: str, convention: str | None = None, where: str = "effect") -> str:
    """An effect id with its parameter in the project's spelling: `E_AX:x1` -> `ex_x:x1`.

    Ids whose parameter is a project name or L, and ids without ':' (custom effects), come back unchanged; a
    parameter that is neither a project nor an ISO name is an InputError listing both spellings."""
    text = effect_id.strip()
    param, sep, rest = text.rpartition(":")
    if not sep or param == "L":
        return effect_id
    machine, conv = _machine_and_convention(obj, convention)
    if param in machine.error_names:
        return effect_id
    project = _lookup(machine, convention or getattr(obj, "convention", None)).get(param)
    if project is None:
        raise InputError(f"{where}: '{text}': unknown parameter '{param}' (expected L for the tool length or an error "
                         f"of {machine.name}, by its project or ISO 230 name: {_pairs(machine, conv)})")
    return project + sep + rest


def to_json(obj, convention: str | None = None, describe=None) -> dict:
    """The `fiveaxis names --json` document: {machine, convention, names: [{error, iso, ...}, ...]}.

    describe: optional function error name -> plain-language description (added as `description`)."""
    machine, conv = _machine_and_convention(obj, convention)
    rows = []
    for e in table(machine, conv).values():
        row = e.to_json()
        if describe is not None:
            row["description"] = describe(e.error)
        rows.append(row)
    return {"machine": machine.name, "convention": conv, "names": rows}


__all__ = ["IsoName", "canonical", "canonical_keys", "canonical_effect", "label", "name", "names", "spellings",
           "table", "to_json"]
