"""The record of a compensation (summary.json): what was written, the predicted account and what is not compensated,
explicit keys with their units (mm, rad, degrees as the keys say); no NaN, no null numbers. The text for people is
built from it (fiveaxis.report.text.compensation).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import prediction
from .folder import VOLUMETRIC
from .pipeline import Compensation
from .table import INTERPOLATION, INTERPOLATION_L
from ..effects.families import TIME
from ..linuxcnc import configuration as lx
from ..linuxcnc import kinematics as lk
from ..linuxcnc.volumetric import files as volumetric_files


def summary(comp: Compensation, model_path: str = "") -> dict:
    """The record of summary.json: explicit keys, mm, rad and degrees as the keys say; no NaN, no null numbers."""
    fm, tab = comp.fm, comp.table
    units = {v: ("deg" if r else "mm") for v, r in zip(tab.variables, tab.rotary)}
    nodes = {}
    for v, r, a in zip(tab.variables, tab.rotary, tab.nodes):
        f = np.degrees if r else np.asarray
        nodes[v] = {"min": float(f(a[0])), "max": float(f(a[-1])), "count": int(len(a)), "unit": units[v]}
    tip, axis = comp.account["tip_error_mm"], comp.account["axis_error_rad"]
    time_effects = [e.id for e in fm.effects if e.var == TIME]
    heat = [e.id for e in fm.effects if e.var in fm.scales and fm.scales[e.var].unit == "degC"]
    dims = (["L"] if tab.tool_lengths is not None else []) + list(tab.variables)
    out = {
        "format": "fiveaxis compensation", "version": 1,
        "machine": {"name": fm.machine, "file": str(Path(comp.model.machine.path).resolve()),
                    "sha256": fm.machine_sha256},
        "convention": fm.convention, "model_file": str(model_path), "tool_length_mm": comp.tool_length,
        "table": {"files": ["table.csv", "table.parquet"], "variables": list(tab.variables), "units": units,
                  "nodes": nodes, "size": int(tab.size), "interpolation": INTERPOLATION,
                  "columns": dims + [f"c_{v}" for v in tab.variables],
                  "damping": comp.damping,
                  "solver": "Gauss-Newton on the exact chain with the identified errors, Jacobian by central "
                            "differences, tip weighted to be exact, rotary corrections penalised by "
                            "damping^2 (Jo^T Jo)^(-1/2) where the rotary axes hardly turn the tool axis",
                  "nodes_max_tip_residual_mm": float(np.max(comp.nodes.tip_residual)),
                  "nodes_converged": bool(np.all(comp.nodes.converged)),
                  "nodes_iterations": int(comp.nodes.iterations)},
        "workspace": {"poses": comp.account["poses"], "seed": comp.account["seed"],
                      "sampling": "uniform within the strokes; approach directions random per joint"},
        "predicted_tip_error_mm": tip,
        "predicted_tip_error_setup_removed_mm": comp.account["tip_error_setup_removed_mm"],
        "part_setup": comp.account["part_setup"],
        "predicted_axis_error_rad": axis,
        "predicted_axis_error_note": "model estimates: the tool axis is known only as far as the data had tool-axis "
                                     "readings or several tool lengths (prediction_uncertainty.axis_error_rad)",
        "prediction_uncertainty": comp.account.get("uncertainty", {}),
        "prediction_warnings": prediction.warnings(comp.account.get("uncertainty", {})),
        "linuxcnc": dict(lx.describe(comp.lc), folder="linuxcnc"),
        "kinematics_module": module_summary(comp),
        "not_compensated": {
            "time_effects": time_effects,
            "time_effects_note": "the table and LinuxCNC's files are static: time effects are taken at t = 0",
            **({"temperature_effects": heat,
                "temperature_note": "the table and LinuxCNC's compensation files cannot hold a temperature: they are "
                                    "at the reference temperatures (the model's references, degC); only the "
                                    "kinematics module reads temperature sensors (its temp pins)"}
               if heat else {}),
            "reversal_note": "the table is direction-independent (reversal effects at their mean); LinuxCNC's "
                             "forward and reverse trims carry them",
            "undetermined": list(fm.undetermined),
            "undetermined_note": "their values are the fit's prior moved by what the data determine; the tip error "
                                 "at the measured tool lengths does not depend on them, the tool axis and other tool "
                                 "lengths may",
            "tool_axis_note": "where the rotary axes hardly turn the tool axis (a trunnion near A = 0) its error "
                              "is corrected only partly (damping); the tip is corrected everywhere",
            "kinematics_module": list(comp.module.left_out) if comp.module is not None else [comp.module_note]},
    }
    if "at_temperatures" in comp.account:
        at = comp.account["at_temperatures"]
        out["predicted_at_temperatures"] = dict(at, references_degC={
            k: float(fm.scales[k].centre) for k in at["temperatures_degC"]},
            note="the same poses with the machine at these temperatures (a steady state): the table and LinuxCNC's "
                 "comp files at the references, the kinematics module with its sensors at these temperatures")
    out["warnings"] = list(comp.account.get("warnings", []))   # the table's: a better file; a tool length's account
    if tab.tool_lengths is None:
        out["not_compensated"]["tool_length_note"] = (
            f"the table is for the tool length {comp.tool_length:g} mm only; other tools get a correction wrong by "
            f"about the angular errors times the difference in length (compensate --tool-lengths)")
        return out
    t = out["table"]
    t["tool_lengths_mm"] = [float(x) for x in tab.tool_lengths]
    t["dimensions"] = dims
    t["interpolation"] = INTERPOLATION_L
    t["tool_length_note"] = ("L (mm) is the first grid dimension and the first column (rows of one tool length "
                             "are contiguous); outside the table's lengths the nearest length's values are held")
    out["predicted_by_tool_length"] = comp.account.get("by_tool_length", [])
    return out


def module_summary(comp: Compensation) -> dict:
    """summary.json's `kinematics_module`: the LinuxCNC kinematics module written to linuxcnc/volumetric/."""
    if comp.module is None:
        return {"folder": None, "note": comp.module_note}
    v, acc = comp.module, comp.account.get("kinematics_module", {})
    return {"folder": f"linuxcnc/{VOLUMETRIC}", "component": v.component,
            "files": sorted(volumetric_files(comp.model, v, "").keys()),
            "joints": list(comp.model.variables),
            "world_coordinates": "the tool tip in the workpiece frame (mm; plus the G43 tool offset on z) and the "
                                 "rotary angles (degrees), as xyzac-trt-kins; no G54",
            "error_values": len(v.errors), "effects": [s.id for s in v.slots], "left_out": list(v.left_out),
            "tool_length_mm": v.tool_length, "damping": v.damping,
            "inverse": {"method": "Newton with the nominal Jacobian from the nominal inverse",
                        "max_iterations": lk.MAX_ITER, "step_tolerance_mm": lk.TOL_MM,
                        "step_tolerance_rad": lk.TOL_RAD,
                        "account_converged": bool(acc.get("converged", False)),
                        "account_max_iterations": int(acc.get("max_iterations", 0))}}
