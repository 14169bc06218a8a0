"""The folder `fiveaxis compensate` writes (table, LinuxCNC's files, the kinematics module, README.txt, summary.json
last with the SHA-256 of every other file) and its readers: the table, what LinuxCNC was given, and the commands
either makes of nominal poses. Units: mm and rad in Python; mm and degrees in the files.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from .table import INTERPOLATION, INTERPOLATION_L, Table, compensated_commands, read_table, table_frame
from ..exceptions import InputError
from ..inputs import read_json, regular_file
from ..linuxcnc import configuration as lx
from ..linuxcnc.configuration import linuxcnc_commands
from ..linuxcnc.volumetric import files as volumetric_files
from ..model.machine import check_made_for
from ..outputs import write_set


#: The folder of the kinematics module and its simulated configuration, under DIR/linuxcnc/.
VOLUMETRIC = "volumetric"


def volumetric_folder(folder) -> Path:
    return Path(folder) / "linuxcnc" / VOLUMETRIC


README = """fiveaxis compensate: the files in this folder

table.csv, table.parquet  the volumetric compensation table. One row per node of a full grid over the strokes
    (the last variable varies fastest). Columns: {lcol}the machine's variables (the nominal command: mm for linear
    axes, degrees for rotary axes), then c_<variable>: the correction to ADD to the command (mm, degrees), so that
    the machine with the identified errors puts the tool tip and the tool axis where the nominal machine would.
    Interpolation a controller is expected to use: {interpolation}.
summary.json  machine, table grid, predicted tool-tip error over the workspace (mm: before, after LinuxCNC, after
    the table, after the exact correction), tool-axis error (rad), what LinuxCNC was given, what is not compensated.
linuxcnc/  for LinuxCNC 2.9: joint<N>-<axis>.comp (COMP_FILE_TYPE = 1: nominal, forward trim, reverse trim per
    line, machine units), fiveaxis.ini (lines to merge into the machine's INI), fiveaxis-trt.hal (trunnions: the
    kinematics parameters). LinuxCNC's stock kinematics and comp files take only part of the model: see
    summary.json, predicted_tip_error_mm (after_linuxcnc).
linuxcnc/volumetric/  the whole model in LinuxCNC: the kinematics module <machine>_kins (source, build with
    halcompile) and a complete simulated configuration around it; its own README.txt has the commands.
    Predicted: summary.json, predicted_tip_error_mm (after_kinematics_module). Use it instead of the files above,
    not with them.
error_map.png  (with --plot) the predicted tool-tip error over the rotary axes.
"""


#: The record of a compensate folder, written last, and its key of the other files' SHA-256.
SUMMARY = "summary.json"
MANIFEST = "files_sha256"
#: The keys of summary.json a reader checks before using any (key, type, required); the numbers inside are
#: checked where they are read (fiveaxis.report.compensation).
SUMMARY_SCHEMA = (("machine", dict, True), ("table", dict, True), ("predicted_tip_error_mm", dict, True),
                  ("predicted_axis_error_rad", dict, False), ("linuxcnc", dict, False),
                  ("not_compensated", dict, False), ("warnings", list, False),
                  ("predicted_by_tool_length", list, False), (MANIFEST, dict, True))
_KIND_NAMES = {dict: "an object", list: "a list"}


def outputs(folder, plot: bool = False) -> list:
    """Paths compensate writes into folder."""
    folder = Path(folder)
    out = [folder / n for n in ("table.csv", "table.parquet", "summary.json", "README.txt")]
    if plot:
        out.append(folder / "error_map.png")
    return out


def write(comp, folder, record: dict, force: bool = False, figure=None, model_path: str = "") -> list:
    """Write a Compensation (compensation.pipeline) into an existing folder: its table, summary.json (the record,
    compensation.record.summary), README.txt, linuxcnc/ (with the kinematics module's files in
    linuxcnc/volumetric/ where there is one) and error_map.png (drawn by figure(comp, path) when given:
    `fiveaxis.plots.compensation.figure`); nothing is replaced unless force (checked for
    every file before the first is written). The folder is written as one set (fiveaxis.outputs.write_set):
    summary.json last, with the SHA-256 of every other file (files_sha256), which every reader checks
    (read_summary): a run killed mid-way never leaves a mixed folder that is used."""

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: output folder not found")
    lcdir = folder / "linuxcnc"
    lfiles = lx.files(comp.lc, f"fitted model {model_path}" if model_path else "")
    frame = table_frame(comp.table)
    has_L = comp.table.tool_lengths is not None
    lcol = ("L (the tool length, mm; the slowest-varying: each tool length is a contiguous block), " if has_L
            else "")
    readme = README.format(interpolation=INTERPOLATION_L if has_L else INTERPOLATION, lcol=lcol)
    heat = record.get("not_compensated", {})
    if heat.get("temperature_effects"):
        readme += (f"\nTemperature effects ({', '.join(heat['temperature_effects'])}): "
                   f"{heat['temperature_note']}. summary.json, predicted_at_temperatures: the error at a warm state.\n")

    def text(t):
        return lambda tmp: tmp.write_text(t, encoding="utf-8")
    files = [(folder / "table.csv", lambda tmp: frame.to_csv(tmp, index=False, float_format="%.10g")),
             (folder / "table.parquet", lambda tmp: frame.to_parquet(tmp, index=False))]
    files += [(lcdir / name, text(t)) for name, t in lfiles.items()]
    files.append((folder / "README.txt", text(readme)))
    if comp.module is not None:
        source = f"fitted model {model_path}" if model_path else ""
        vol = volumetric_folder(folder)
        files += [(vol / name, text(t)) for name, t in
                  volumetric_files(comp.model, comp.module, comp.module_source, source).items()]
    if figure is not None:
        files.append((folder / "error_map.png", lambda tmp: figure(comp, tmp)))

    def seal(hashes):
        sealed = dict(record, **{MANIFEST: {p.relative_to(folder).as_posix(): h for p, h in hashes.items()}})
        return json.dumps(sealed, indent=1, allow_nan=False) + "\n"
    return write_set(files, folder / SUMMARY, seal, force=force)


def read_summary(folder) -> dict:
    """The summary.json of a compensate folder, after checking that every file it vouches for (files_sha256) is
    there as written: InputError naming the file otherwise (a run killed mid-way, a file edited or replaced)."""

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: compensation folder not found (write one with `fiveaxis compensate`)")
    path = folder / SUMMARY
    if not path.exists():
        raise InputError(f"{path}: not found (a compensate output folder has summary.json; a run killed before "
                         f"it finished leaves none: run compensate again)")
    data = read_json(path, "the summary.json of `fiveaxis compensate`")
    if not isinstance(data, dict):
        raise InputError(f"{path}: expected a JSON object (the summary.json of `fiveaxis compensate`)")
    for key, kind, required in SUMMARY_SCHEMA:
        if key not in data:
            if required:
                raise InputError(f"{path}: key {key}: missing (expected the summary.json of `fiveaxis compensate`)")
            continue
        if not isinstance(data[key], kind):
            raise InputError(f"{path}: key {key}: expected {_KIND_NAMES[kind]}, got {type(data[key]).__name__}")
    mach = data.get("machine")
    if not all(isinstance(mach.get(k), str) for k in ("name", "sha256")):
        raise InputError(f"{path}: key machine: expected {{\"name\": ..., \"sha256\": ...}} (strings)")
    manifest = data.get(MANIFEST)
    if not isinstance(manifest, dict) or not manifest or not all(isinstance(v, str) for v in manifest.values()):
        raise InputError(f"{path}: key {MANIFEST}: missing (written by an older fiveaxis, or not by compensate): "
                         f"run compensate again")
    for rel, sha in manifest.items():
        f = folder / rel
        if ".." in Path(rel).parts or Path(rel).is_absolute():
            raise InputError(f"{path}: key {MANIFEST}: {rel!r} is not a file of the folder")
        try:
            with open(regular_file(f, "a file summary.json vouches for"), "rb") as fh:
                digest = hashlib.sha256()
                for block in iter(lambda: fh.read(1 << 20), b""):
                    digest.update(block)
        except OSError as exc:
            raise InputError(f"{f}: {exc.strerror or exc} (summary.json lists it: an incomplete compensation folder; "
                             f"run compensate again)") from None
        if digest.hexdigest() != sha:
            raise InputError(f"{f}: not the file summary.json vouches for (its SHA-256 differs: {_changed(f, data)}); "
                             f"run compensate again (with --force over this folder)")
    return data


def _changed(f: Path, data: dict) -> str:
    """What differs in a table file that no longer matches summary.json, for the message: a missing column, the
    first cell that is not a finite number, or numbers edited; other files: edited or left by a killed run."""
    if f.name not in ("table.csv", "table.parquet"):
        return "the file edited, or a compensate run killed mid-way"
    import pandas as pd          # pandas: heavy, loaded only for this message
    try:
        df = pd.read_parquet(f) if f.suffix == ".parquet" else pd.read_csv(f)
    except Exception:            # pandas/pyarrow raise many types for damaged files
        return "not a readable table any more"
    want = [c for c in data.get("table", {}).get("columns", []) if isinstance(c, str)]
    missing = [c for c in want if c not in df.columns]
    if missing:
        return f"column(s) {', '.join(missing)} missing"
    values = df[want or list(df.columns)].apply(pd.to_numeric, errors="coerce").to_numpy(dtype=float)
    bad = np.argwhere(~np.isfinite(values))
    if len(bad):
        row, col = bad[0]
        return f"data row {row + 1}, column {(want or list(df.columns))[col]}: not a finite number"
    return "its numbers were edited after compensate wrote them"


def summary_for(folder, model) -> dict:
    """The summary.json of a compensate folder (read_summary), checked to be for the model's machine file."""
    info = read_summary(folder)
    check_made_for(model.machine, info["machine"]["name"], info["machine"]["sha256"], str(folder), "compensation")
    return info


def load_table(folder, model) -> Table:
    """The table of a `compensate` output folder, checked against the model's machine file and against
    summary.json's hashes (read_summary)."""

    folder = Path(folder)
    info = summary_for(folder, model)
    path = folder / "table.parquet"
    if "table.parquet" not in info[MANIFEST]:
        path = folder / "table.csv"
    return read_table(path, model.machine)


def command_function(folder, model, table: Table | None = None):
    """(poses, L=None, dirs=None) -> compensated commands (mm, rad) with the table of a compensate output folder (or
    the table given): at each pose's own tool length L (mm; (n,) or scalar; None: the machine's L0) when the table
    has a tool-length dimension; the table does not depend on the approach directions dirs."""
    table = load_table(folder, model) if table is None else table
    L0 = model.machine.tool_length
    return lambda poses, L=None, dirs=None: compensated_commands(table, poses, L0 if L is None else L)


def load_linuxcnc(folder, model):
    """What LinuxCNC was given in a compensate output folder, as a linuxcnc.LinuxCNCCompensation: the per-joint
    compensation files (linuxcnc/joint<N>-<axis>.comp, read as LinuxCNC reads them) and, for a trunnion, the
    kinematics pins, the workpiece origin (G54) and the tool length of summary.json; checked against the model's
    machine file."""

    folder = Path(folder)
    info = summary_for(folder, model).get("linuxcnc", {})
    machine = model.machine
    variables = tuple(model.variables)
    rotary = tuple(machine.axis(v).type == "rotary" for v in variables)
    comps = []
    for j, v in enumerate(variables):
        path = folder / "linuxcnc" / f"joint{j}-{v}.comp"
        if path.exists():
            nominal, fwd, rev = lx.read_comp_file(path)
            comps.append(lx.JointComp(j, v, "deg" if rotary[j] else "mm", nominal, fwd, rev))
    if not comps:
        raise InputError(f"{folder}/linuxcnc: no compensation file joint<N>-<axis>.comp for {machine.name}")
    trt = None
    kind = lx.trt_kind(machine)
    if kind is not None:
        pins = info.get("trt_pins_mm") or {}
        origin = info.get("workpiece_origin_g54_mm")
        try:
            trt = lx.TrtParameters(kind, float(pins["x-rot-point"]), float(pins["y-rot-point"]),
                                   float(pins["z-rot-point"]), float(pins[lx.TrtParameters(kind).offset_pin]),
                                   float(pins["z-offset"]), tuple(float(x) for x in origin))
        except (KeyError, TypeError, ValueError):
            raise InputError(f"{folder}/summary.json: linuxcnc: expected trt_pins_mm and workpiece_origin_g54_mm of "
                             f"{kind}-trt-kins") from None
    L0 = float(info.get("tool_length_mm", machine.tool_length))
    return lx.LinuxCNCCompensation(machine.name, variables, rotary, L0, tuple(comps), trt)


def linuxcnc_function(folder, model):
    """(poses, L=None, dirs=None) -> the positions the axes go to under LinuxCNC with the files of a compensate
    output folder (kinematics, then the compensation files' forward or reverse trims by the approach direction:
    dirs {axis: (n,) +1/-1}, missing axes forward), mm and rad."""
    lc = load_linuxcnc(folder, model)

    def commands(poses, L=None, dirs=None):
        q = np.atleast_2d(np.asarray(poses, float))
        D = np.ones_like(q)
        for j, v in enumerate(model.variables):
            if dirs and v in dirs:
                D[:, j] = np.asarray(dirs[v], float)
        return linuxcnc_commands(lc, model, q, D, L)
    return commands
