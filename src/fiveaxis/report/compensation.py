"""What a compensation run leaves for the report: DIR/summary.json and the PNG maps it names.

summary.json (lengths in mm):

    {
      "machine": "li2018",                                  optional; must match the report's machine
      "method": "per-axis LinuxCNC comp tables from the fit", optional, one line for people
      "before_mm": {"max": 0.0123, "rms": 0.0045, "p95": 0.0089},   required: predicted tool-tip error
      "after_mm":  {"max": 0.0021, "rms": 0.0008, "p95": 0.0015},   required: ... with the compensation applied
      "maps": [{"file": "before.png", "caption": "predicted |P_err| (um) over X-Y, before"}, ...],  optional
      "files": ["x.comp", "y.comp"]                         optional: files written for the controller
    }

max, rms and p95 are the largest, root-mean-square and 95th-percentile length of the predicted tool-tip error
over the compensation's evaluation poses. Any problem is an InputError naming the file and the key.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

from ..errors import InputError

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


def read(folder, machine_name: str | None = None) -> dict:
    """The compensation summary of a folder, checked; maps come back as {"caption", "file", "png": bytes}."""
    folder = Path(folder)
    path = folder / SUMMARY
    if not folder.is_dir():
        raise InputError(f"{folder}: compensation folder not found")
    if not path.is_file():
        raise InputError(f"{path}: not found (a compensation folder holds summary.json with before_mm and after_mm)")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: line {exc.lineno} column {exc.colno}: invalid JSON ({exc.msg})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text file") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a JSON object with before_mm and after_mm")
    if machine_name is not None and "machine" in data and data["machine"] != machine_name:
        raise InputError(f"{path}: machine: the compensation is for '{data['machine']}', the report for "
                         f"'{machine_name}'")
    out = {"folder": str(folder), "method": str(data.get("method", "")),
           "before_mm": _stats(path, data, "before_mm"), "after_mm": _stats(path, data, "after_mm"),
           "files": [str(f) for f in data.get("files", [])], "maps": []}
    maps = data.get("maps", [])
    if not isinstance(maps, list):
        raise InputError(f"{path}: maps: expected a list of {{\"file\", \"caption\"}}")
    for i, m in enumerate(maps):
        if not isinstance(m, dict) or not isinstance(m.get("file"), str):
            raise InputError(f"{path}: maps[{i}]: expected {{\"file\": \"<name>.png\", \"caption\": \"...\"}}")
        f = folder / m["file"]
        if not f.is_file():
            raise InputError(f"{path}: maps[{i}].file: {f} not found")
        png = f.read_bytes()
        if not png.startswith(PNG_MAGIC):
            raise InputError(f"{path}: maps[{i}].file: {f} is not a PNG image")
        out["maps"].append({"file": m["file"], "caption": str(m.get("caption", m["file"])), "png": png})
    return out
