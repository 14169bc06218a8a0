"""Edits of machine files (`fiveaxis model add`): structural, through tomlkit, so that comments, layout and every
way TOML allows to write the `model` table (`[model]`, `model = { effects = [] }`, `model.effects = [...]`) are
kept; the result is read back with the machine-file checks before it is written atomically (`fiveaxis.outputs`).
"""
from __future__ import annotations

import tomllib
from pathlib import Path

from .. import outputs
from ..exceptions import InputError
from ..inputs import read_text
from .machine import MAX_MACHINE_BYTES, Machine, parse_machine

COMMENT = "Effects added to the geometric model (fiveaxis model add)"


def with_model_effects(text: str, path, effects) -> str:
    """The machine file text with the list `model.effects` set to effects (ids or custom effect names)."""
    import tomlkit   # optional heavy dependency: only `fiveaxis model add` edits machine files
    from tomlkit.exceptions import TOMLKitError   # (as above)
    try:
        doc = tomlkit.parse(text)
    except TOMLKitError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    array = tomlkit.array()
    array.extend(list(effects))
    model = doc.get("model")
    if model is None:
        table = tomlkit.table()
        table.add("effects", array)
        doc.add(tomlkit.nl())
        doc.add(tomlkit.comment(COMMENT))
        doc.append("model", table)
    elif hasattr(model, "keys"):          # a [model] table, an inline table or dotted keys
        model["effects"] = array
    else:
        raise InputError(f"{path}: model: expected a table such as [model] effects = [\"ex_x:x1\"]")
    return tomlkit.dumps(doc)


def write_model_effects(machine: Machine, effects, output=None, force: bool = False) -> Path:
    """Write the machine file with `[model] effects = effects`; returns the file written.

    output None rewrites the machine file itself (a symbolic link is followed: its target is rewritten, the
    link stays); otherwise output is a new file, replaced only with force=True."""
    source = Path(machine.path)
    text = read_text(source, "a machine file (TOML)", MAX_MACHINE_BYTES)
    if output is not None and Path(output).resolve() == source.resolve():
        raise InputError(f"{output}: is the machine file itself (in_place=True rewrites it)", key="in_place")
    target = source if output is None else Path(output)
    new = with_model_effects(text, source, effects)
    parse_machine(tomllib.loads(new), target)          # the new file must read back
    return outputs.write_with(target, lambda tmp: tmp.write_text(new, encoding="utf-8"),
                              force=force or output is None)
