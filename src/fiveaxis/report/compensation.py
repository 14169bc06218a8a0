"""What a compensation run (`fiveaxis compensate MODEL -o DIR`) leaves for the report: DIR/summary.json, written by
`fiveaxis.compensation.record.summary`, and the map PNG beside it.

The report reads from summary.json: the machine (`machine.name`, must match the report's), the predicted tool-tip
error over the workspace (`predicted_tip_error_mm`: `before`, `after_linuxcnc`, `after_kinematics_module`,
`after_table`, each {max, rms, p95} in mm: the largest, root-mean-square and 95th-percentile length over the
evaluation poses), for a table over tool lengths the same per tool length (`predicted_by_tool_length`) and its
`warnings`, what the prediction cannot know (`prediction_uncertainty`: per stage the k = 2 range of the true RMS,
the parts, the measurement that would determine the undetermined part; `prediction_warnings`), what is not
compensated, and the files for the controller (the table, `linuxcnc/`). Any problem is an InputError naming the
file and the key.
"""
from __future__ import annotations

import math
from pathlib import Path

from ..compensation.folder import read_summary
from ..exceptions import InputError

SUMMARY = "summary.json"
STATS = ("max", "rms", "p95")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _stats(path, data, key) -> dict:
    block = data.get(key)
    if not isinstance(block, dict):
        raise InputError(f"{path}: {key}: missing (expected {{\"max\": ..., \"rms\": ..., \"p95\": ...}} in mm)")
    out = {}
    for s in STATS:
        v = block.get(s)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise InputError(f"{path}: {key}.{s}: expected a length >= 0 in mm, got {v!r}")
        out[s] = float(v)
    return out


def _by_tool_length(path, data) -> list:
    """Rows of `predicted_by_tool_length` (a table with a tool-length dimension, `compensate --tool-lengths`):
    tool length (mm), whether it is a table node, and the tip error stages {max, rms, p95} (mm)."""
    rows = []
    for i, entry in enumerate(data.get("predicted_by_tool_length") or []):       # a list (read_summary)
        key = f"predicted_by_tool_length[{i}]"
        L = entry.get("tool_length_mm") if isinstance(entry, dict) else None
        if isinstance(L, bool) or not isinstance(L, (int, float)) or not math.isfinite(L) or L <= 0:
            raise InputError(f"{path}: {key}.tool_length_mm: expected a tool length > 0 in mm, got {L!r}")
        tip = entry.get("tip_error_mm")
        if not isinstance(tip, dict):
            raise InputError(f"{path}: {key}.tip_error_mm: missing")
        rows.append({"tool_length_mm": float(L), "table_node": bool(entry.get("table_node")),
                     **{k: _stats(path, tip, k) for k in ("before", "after_table", "after_exact_correction")}})
    return rows


def _range(path, unc: dict, key: str):
    """[lo, hi] mm: the k = 2 range of the true RMS tool-tip error of a stage (prediction_uncertainty), or None."""
    r = ((unc.get("tip_error_mm") or {}).get(key) or {}).get("range_k2")
    if r is None:
        return None
    if not (isinstance(r, list) and len(r) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                        and math.isfinite(x) and x >= 0 for x in r)):
        raise InputError(f"{path}: prediction_uncertainty.tip_error_mm.{key}.range_k2: expected [low, high] in mm")
    return [float(x) for x in r]


def _uncertainty(unc: dict) -> dict:
    """What the report says of the prediction's uncertainty: the parts (mm), the prior, the measurement that
    determines the undetermined part, the note on the tool axis; {} without it."""
    if not unc:
        return {}
    best = (unc.get("determining") or {}).get("best") or {}
    parts = unc.get("tip_parts_rms_mm") or {}
    return {"fit_mm": float(parts.get("fit", 0.0)),
            "undetermined_mm": float(math.hypot(parts.get("undetermined", 0.0),
                                                parts.get("undetermined_best_value", 0.0))),
            "directions": int(unc.get("undetermined_directions", 0)),
            "prior": dict(unc.get("prior") or {}), "measurement": str(best.get("measurement", "")),
            "command": str(best.get("command", "")), "axis_note": str(unc.get("axis_note", "")),
            "lower_end": str(unc.get("lower_end", "")), "upper_end": str(unc.get("upper_end", "")),
            "prior_note": str(unc.get("prior_note", ""))}


#: The stages of summary.json's predicted_tip_error_mm the report shows, in order, with their labels.
STAGES = (("before", "before compensation"), ("after_linuxcnc", "after what LinuxCNC takes (comp files, trunnion "
                                                                 "kinematics)"),
          ("after_kinematics_module", "after LinuxCNC with the kinematics module"),
          ("after_table", "after the volumetric table"))
MAP = ("error_map.png", "predicted tool-tip error over the workspace before and after the table (um)")


def read(folder, machine_name: str | None = None) -> dict:
    """The compensation summary of a folder, checked; maps come back as {"caption", "file", "png": bytes}."""
    folder = Path(folder)
    path = folder / SUMMARY
    data = read_summary(folder)                   # every file it vouches for checked against its SHA-256
    if not isinstance(data.get("predicted_tip_error_mm"), dict):
        raise InputError(f"{path}: predicted_tip_error_mm: missing (expected the summary.json of `fiveaxis "
                         f"compensate`)")
    mach = data.get("machine")
    name = mach.get("name") if isinstance(mach, dict) else mach
    if machine_name is not None and name is not None and name != machine_name:
        raise InputError(f"{path}: machine.name: the compensation is for '{name}', the report for '{machine_name}'")
    tip = data["predicted_tip_error_mm"]
    unc = data.get("prediction_uncertainty") or {}
    stages = []
    for key, label in STAGES:
        if key in tip:
            stages.append(dict(_stats(path, tip, key), key=key, label=label,
                               range_k2=_range(path, unc, key)))
    if not stages or stages[0]["key"] != "before":
        raise InputError(f"{path}: predicted_tip_error_mm.before: missing")
    table = data.get("table")
    listed = table.get("files", []) if isinstance(table, dict) else None
    if not isinstance(listed, list):
        raise InputError(f"{path}: table.files: expected a list of file names")
    files = [str(f) for f in listed]
    lc = folder / "linuxcnc"
    if lc.is_dir():
        files += [f"linuxcnc/{p.name}" for p in sorted(lc.iterdir())]
    out = {"folder": str(folder), "stages": stages, "files": files, "maps": [],
           "by_tool_length": _by_tool_length(path, data),
           "warnings": [str(w) for w in data.get("warnings", [])] + [str(w) for w in
                                                                      data.get("prediction_warnings", [])],
           "uncertainty": _uncertainty(unc),
           "not_compensated": data.get("not_compensated", {}),
           "method": "volumetric table solved on the exact model" + (" and LinuxCNC files" if lc.is_dir() else "")}
    f = folder / MAP[0]
    if f.is_file():
        png = f.read_bytes()
        if not png.startswith(PNG_MAGIC):
            raise InputError(f"{f}: not a PNG image")
        out["maps"].append({"file": MAP[0], "caption": MAP[1], "png": png})
    return out
