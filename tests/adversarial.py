"""An adversarial corpus over every command (issue 19, point 4): hostile G-code, model, machine and measurement
files, absurd numbers, NaN/Inf/huge values, malformed JSON/TOML/CSV/Parquet, symbolic links, kill -9 mid-write,
options out of range. Round 4 (issue 28, issue 34; `round4()`): hostile file names reaching LinuxCNC's files and the
kinematics module, links planted inside an output folder, programs that never end, unit slips, one-axis machines
and the options and columns whose messages did not name them; its checks: "inject", "kins", "hint", "clean".

Every trial is a row of data: an id, a command line (with `{f}` the trial's hostile file, `{out}` a fresh output
folder, `{m}` a marker path, `{base}` the folder of base files), the file it needs (a MAKERS entry and its
content), what is expected (REFUSE: exit 2 and one line; OK: exit 0; EITHER), the names a refusal should say
(file, key, option) and, for kill -9 trials, when to kill. `trials()` builds the rows from the tables below; a new
command (iso230-2, iso230-4) is covered by adding rows to COMMANDS_READING (files it reads), OPTION_TRIALS
(its options) and WRITERS (its outputs).

Each trial runs `python -m fiveaxis.cli ...` as a subprocess in its own folder, under a memory limit (prlimit
--as) and a timeout, with HOME, TMPDIR and FIVEAXIS_CACHE in the work folder. It is classified automatically:
  code-execution  a marker file appeared (a payload ran);
  traceback       "Traceback" on stderr, or the process died of a signal;
  hang            the timeout;
  silent          exit 0 where a refusal was expected, or an output holding a non-finite or implausible number,
                  or (kill -9) a mixed or partial output that a reader accepts;
  vague           a refusal whose message names neither the file/row/key/option nor what was expected;
  refused-valid   a harmless variant refused;
  ok              anything else.

    python tests/adversarial.py                      # the full corpus (`make fuzz`), totals per class
    python tests/adversarial.py --pythonpath DIR     # the same against another tree (e.g. the base commit)
    python tests/adversarial.py --only lsa --list    # the trials of one command
    python tests/adversarial.py --again results.json # the trials that were not ok in an earlier --json
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MACHINES = ROOT / "machines"
DATA = Path(__file__).resolve().parent / "data"
REFUSE, OK, EITHER = "refuse", "ok", "either"
CLASSES = ("code-execution", "traceback", "hang", "silent", "vague", "refused-valid", "ok")
MEMORY_LIMIT = 3 * 2 ** 30
TIMEOUT = 240.0
#: Phrases that say what was expected (a refusal with one of them is not vague even without a name).
EXPECTED = re.compile(r"expected|expect|must|needs?|at least|at most|more than|beyond|not a |not found|no such|"
                      r"unknown|exists|refus|cannot|invalid|did you mean|limit|out of memory", re.IGNORECASE)
NOT_FINITE = re.compile(r"(?<![A-Za-z_])[-+]?(nan|inf|infinity)(?![A-Za-z_])", re.IGNORECASE)


@dataclass
class Trial:
    """One command line and what is known of its outcome (see the module docstring)."""
    id: str
    command: str
    argv: list
    expect: str = EITHER
    names: tuple = ()                  # at least one must be in a refusal (or an EXPECTED phrase)
    file: tuple | None = None          # (maker, content) for {f}
    timeout: float = TIMEOUT
    kill: str | None = None            # kill -9 trials: "write" (when the outputs start to change)
    check: str | None = None           # "comp": also check the corrections' magnitudes
    reader: list | None = None         # kill trials: a command that reads the outputs afterwards
    suffix: str = ""                   # of {f}
    together: tuple = ()               # kill trials: the files that must come from one run (globs in {out})
    filename: str | None = None        # the name of {f} (default hostile<suffix>): hostile names of round 4


# -- base files, made once per run ------------------------------------------------------------------------------------
def make_base(base: Path, run) -> None:
    """The files trials start from, made by the code under test: measurements, a fitted model, a compensation."""
    base.mkdir(parents=True, exist_ok=True)
    steps = [
        (["simulate", "--n", "200", "--seed", "1", "-o", "{base}/meas.csv"], "meas.csv"),
        (["simulate", "--n", "120", "--no-time", "--seed", "2", "-o", "{base}/meas_nt.csv"], "meas_nt.csv"),
        (["fit", "{base}/meas.csv", "-o", "{base}/model.json"], "model.json"),
        (["compensate", "{base}/model.json", "-o", "{base}/comp", "--nodes", "X=2,Y=2,Z=2", "--poses", "200",
          "--comp-points", "9"], "comp/summary.json"),
        (["plan", "--n", "12", "-o", "{base}/plan.csv"], "plan.csv"),
        (["simulate", "--instrument", "interferometer", "--n", "200", "--seed", "3", "--effect", "dx_x:x1=0.005",
          "-o", "{base}/iso2.csv"], "iso2.csv"),
        (["simulate", "--instrument", "ballbar", "--n", "200", "--seed", "4", "-o", "{base}/iso4.csv"], "iso4.csv"),
        (["simulate", "--iso230-3", "spindle", "-o", "{base}/iso3.csv", "--hours", "4", "--seed", "5"], "iso3.csv"),
    ]
    (base / "comp").mkdir(exist_ok=True)
    (base / "stage42.toml").write_text(STAGE)
    (base / "nocut.toml").write_text(STAGE.replace('name = "stage42"', 'name = "nocut"').replace("length = 50.0",
                                                                                              "length = 0.0"))
    steps += [(["fit", "{base}/meas_nt.csv", "--add", "dx_x:xp800", "-o", "{base}/model_p.json"], "model_p.json"),
              (["simulate", "--machine", "{base}/stage42.toml", "--instrument", "interferometer", "--n", "60",
                "--no-time", "--seed", "4", "--noise", "0.0001", "--effect", "dx_x:x1=0.003", "--effect",
                "dx_x:xr=0.00032", "-o", "{base}/stage_mm.csv"], "stage_mm.csv"),
              (["fit", "{base}/stage_mm.csv", "--machine", "{base}/stage42.toml", "--add", "dx_x:x1", "--add",
                "dx_x:xr", "-o", "{base}/stage_mm.json"], "stage_mm.json"),
              (_stage_files, "stage_um.csv"),
              (["fit", "{base}/stage_um.csv", "--machine", "{base}/stage42.toml", "--add", "dx_x:x1", "--add",
                "dx_x:xr", "-o", "{base}/stage_um.json"], "stage_um.json")]
    for argv, made in steps:
        if not (base / made).exists():
            if callable(argv):
                argv(base)
                continue
            rc, out, err = run([a.format(base=base) for a in argv])
            if rc != 0:
                raise SystemExit(f"adversarial: making {made} failed: {err.strip()[-300:]}")
    shutil.copy(ROOT / "examples" / "ac_trunnion_sphere.ngc", base / "good.ngc")
    shutil.copy(DATA / "planar.toml", base / "planar.toml")
    shutil.copy(MACHINES / "li2018.toml", base / "li2018.toml")


#: A 42 mm stage measured with a laser (round 4: the unit slip of issue 28, point 6; a one-axis machine).
STAGE = (DATA / "stage42.toml").read_text()


def _stage_files(base: Path) -> None:
    """stage_um.csv: the laser readings written in um into the mm column; stage3.csv: X, dir_X, du only."""
    import pandas as pd
    df = pd.read_csv(base / "stage_mm.csv")
    df.assign(du=df["du"] * 1000.0).to_csv(base / "stage_um.csv", index=False)
    df[["X", "dir_X", "du"]].to_csv(base / "stage3.csv", index=False)


# -- hostile files ------------------------------------------------------------------------------------------------------
def _write(path: Path, content) -> Path:
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def _huge(path: Path, n: int) -> Path:
    with open(path, "wb") as fh:
        fh.truncate(n)
    return path


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _symlink(path: Path, target) -> Path:
    path.symlink_to(target)
    return path


def _folder(path: Path) -> Path:
    path.mkdir()
    return path


#: How a trial's file is made: maker(path, content, base) -> path. Content may hold {m} (the marker) and {base}.
MAKERS = {
    "text": lambda p, c, b: _write(p, c),
    "bytes": lambda p, c, b: _write(p, c),
    "huge": lambda p, c, b: _huge(p, c),
    "fifo": lambda p, c, b: _fifo(p),
    "symlink": lambda p, c, b: _symlink(p, c.format(base=b)),
    "folder": lambda p, c, b: _folder(p),
    "copy": lambda p, c, b: Path(shutil.copy(Path(c.format(base=b)), p)),
    "json-edit": lambda p, c, b: _write(p, json.dumps(c[1](json.loads((b / c[0]).read_text())))),
    "csv-edit": lambda p, c, b: _csv_edit(p, b / c[0], c[1]),
    "parquet": lambda p, c, b: _parquet(p, b / c[0], c[1]),
    "toml-edit": lambda p, c, b: _write(p, _changed((b / c[0]).read_text(), c[1])),
}


def _changed(text: str, edit) -> str:
    """edit(text), which must change it (a trial whose edit no longer applies is the corpus' bug)."""
    new = edit(text)
    if new == text:
        raise ValueError("the edit did not change the file")
    return new


def _csv_edit(path: Path, src: Path, edit) -> Path:
    import pandas as pd
    df = edit(pd.read_csv(src))
    if isinstance(df, (str, bytes)):
        return _write(path, df)
    df.to_csv(path, index=False)
    return path


def _parquet(path: Path, src: Path, edit) -> Path:
    import pandas as pd
    edit(pd.read_csv(src)).to_parquet(path, index=False)
    return path


def make_file(trial_dir: Path, name: str, spec, base: Path, marker: Path) -> Path:
    """The trial's file; {m} (the marker), {d} (its folder) and {base} in a text file are replaced. A payload.py
    in the marker's folder creates the marker (for `(pyrun,{d}/payload.py)`)."""
    maker, content = spec
    (marker.parent / "payload.py").write_text(f"open({str(marker)!r}, 'w')\n")
    path = MAKERS[maker](trial_dir / name, content, base)
    if not path.is_symlink() and path.is_file() and path.stat().st_size < 2 ** 24:
        data = path.read_bytes()
        if b"{m}" in data or b"{d}" in data or b"{base}" in data:
            data = (data.replace(b"{m}", str(marker).encode()).replace(b"{d}", str(marker.parent).encode())
                    .replace(b"{base}", str(base).encode()))
            path.write_bytes(data)
    return path


# -- G-code ---------------------------------------------------------------------------------------------------------------
_PY = ["{c}import os)", "{c}class K: __class_getitem__=os.system)", "{c}K['touch {m}'])"]
_HEAD = "G21 G90 F100\nG0 X0 Y0 Z200 A-20 C0\n"


def _py(opening: str, same_line: bool = False) -> str:
    lines = [p.replace("{c}", opening) for p in _PY]
    if same_line:
        lines = [f"G1 X{i + 1} {line}" for i, line in enumerate(lines)]
    return _HEAD + "\n".join(lines) + "\nG1 X5\nM2\n"


GCODE = {   # name -> (maker, content, expect)
    "py": ("text", _py("(py,"), REFUSE), "PY": ("text", _py("(PY,"), REFUSE),
    "( py": ("text", _py("( py,"), REFUSE), "tab py": ("text", _py("(\tpy,"), REFUSE),
    "Py mixed": ("text", _py("(Py,"), REFUSE), "py on G lines": ("text", _py("(py,", True), REFUSE),
    "py blank comma": ("text", _py("(py ,"), REFUSE), "pyrun": ("text", _py("(pyrun,"), REFUSE),
    "pyrun file": ("text", _HEAD + "(pyrun,{d}/payload.py)\nG1 X5\nM2\n", REFUSE),
    "pyreload": ("text", _HEAD + "(pyreload)\nG1 X5\nM2\n", REFUSE),
    ";py,": ("text", _HEAD + ";py,open('{m}','w')\nG1 X5\nM2\n", REFUSE),
    ";PY,": ("text", _HEAD + ";PY,open('{m}','w')\nG1 X5\nM2\n", REFUSE),
    "G ;py,": ("text", _HEAD + "G1 X2 ;py,open('{m}','w')\nG1 X5\nM2\n", EITHER),
    "py in sub": ("text", _HEAD + "o<s> sub\n" + "\n".join(p.replace("{c}", "(py,") for p in _PY)
                  + "\no<s> endsub\no<s> call\nM2\n", REFUSE),
    "o<$(shell)>": ("text", _HEAD + "o<$(touch${IFS}{m})> call\nM2\n", REFUSE),
    "o<`shell`>": ("text", _HEAD + "o<`touch${IFS}{m}`> call\nM2\n", REFUSE),
    "o<$(shell)> sub": ("text", _HEAD + "o<$(touch${IFS}{m})> call\no<$(touch${IFS}{m})> sub\nG1 X1\n"
                        "o<$(touch${IFS}{m})> endsub\nM2\n", REFUSE),
    "o<abs path>": ("text", _HEAD + "o</etc/passwd> call\nM2\n", REFUSE),
    "o<~home>": ("text", _HEAD + "o<~/x> call\nM2\n", REFUSE),
    "o<undefined>": ("text", _HEAD + "o<elsewhere> call\nM2\n", REFUSE),
    "o100 undefined": ("text", _HEAD + "o100 call\nM2\n", REFUSE),
    "o[computed]": ("text", _HEAD + "#1=100\no[#1] call\nM2\n", REFUSE),
    "o-name comment": ("text", _HEAD + "o<a(py,import os)b> call\nM2\n", REFUSE),
    "logopen": ("text", _HEAD + "(logopen,{m})\n(log,x)\n(logclose)\nG1 X5\nM2\n", OK),
    "print canon": ("text", _HEAD + "(print,  9 N..... STRAIGHT_FEED[999])\nG1 X5\nM2\n", OK),
    "msg debug": ("text", _HEAD + "(msg,hello)\n(debug,#1)\nG1 X5\nM2\n", OK),
    "abort": ("text", _HEAD + "(abort,stop)\nG1 X5\nM2\n", REFUSE),
    "NUL": ("bytes", (_HEAD + "G1 X1\0 Y5\nM2\n").encode(), REFUSE),
    "ESC": ("bytes", (_HEAD + "G1 X1 \x1b[2J\nM2\n").encode(), REFUSE),
    "form feed": ("bytes", (_HEAD + "G1 X1\x0cG1 X99\nM2\n").encode(), REFUSE),
    "nested comment": ("text", _HEAD + "G1 X1 (a (b) c)\nM2\n", REFUSE),
    "unclosed comment": ("text", _HEAD + "G1 X1 (open\nM2\n", REFUSE),
    "endless loop": ("text", _HEAD + "o100 while [1]\nG1 X1\nG1 X2\no100 endwhile\nM2\n", REFUSE),
    "silent loop": ("text", _HEAD + "o100 while [1]\n#1=[#1+1]\no100 endwhile\nM2\n", REFUSE),
    "recursion": ("text", _HEAD + "o<r> sub\no<r> call\no<r> endsub\no<r> call\nM2\n", REFUSE),
    "huge coordinate": ("text", _HEAD + "G1 X1e300\nM2\n", REFUSE),
    "nan word": ("text", _HEAD + "G1 X[0/0]\nM2\n", REFUSE),
    "long line": ("text", _HEAD + "G1 X1 " + "(" + "c" * 5000 + ")\nM2\n", EITHER),
    "CRLF": ("bytes", (_HEAD + "G1 X5\nM2\n").replace("\n", "\r\n").encode(), OK),
    "binary": ("bytes", bytes(range(256)) * 8, REFUSE),
    "latin-1": ("bytes", (_HEAD + "(caf\xe9)\nG1 X5\nM2\n").encode("latin-1"), REFUSE),
    "empty": ("text", "", REFUSE),
    "no end": ("text", _HEAD + "G1 X5\n", REFUSE),
    "probe": ("text", _HEAD + "G38.2 Z-10 F10\nM2\n", REFUSE),
    "fifo": ("fifo", None, REFUSE),
    "dev zero": ("symlink", "/dev/zero", REFUSE),
    "folder": ("folder", None, REFUSE),
    "huge file": ("huge", 300 * 2 ** 20, EITHER),
    "good": ("copy", "{base}/good.ngc", OK),
}


# -- model files (fit -o) -------------------------------------------------------------------------------------------------
def _edit(*keys, value):
    def edit(d):
        x = d
        for k in keys[:-1]:
            x = x[k]
        x[keys[-1]] = value
        return d
    return edit


def _coef(value):
    def edit(d):
        d["errors_mm_rad"] = {k: (value if k == "ex_x" else v) for k, v in d["errors_mm_rad"].items()}
        return d
    return edit


MODEL_FILES = {   # name -> (maker, content, expect for compensate, expect for --errors)
    "dev zero machine": ("json-edit", ("model.json", _edit("machine", "file", value="/dev/zero")), EITHER, EITHER),
    "shadow machine": ("json-edit", ("model.json", _edit("machine", "file", value="../" * 12 + "etc/shadow")),
                       EITHER, EITHER),
    "foreign machine file": ("json-edit", ("model.json", lambda d: dict(_edit("machine", "file",
                             value="planar.toml")(d), machine=dict(d["machine"], name="mine"))), REFUSE, REFUSE),
    "absolute machine, no shipped": ("json-edit", ("model.json", lambda d: dict(d, machine=dict(
        d["machine"], name="mine", file="/etc/passwd.toml"))), REFUSE, REFUSE),
    "error 1e6 mm": ("json-edit", ("model.json", _edit("errors_mm_rad", "dx_x", value=1e6)), REFUSE, EITHER),
    "error 3 rad": ("json-edit", ("model.json", _edit("errors_mm_rad", "ex_y", value=3.0)), REFUSE, EITHER),
    "error 1e200": ("json-edit", ("model.json", _coef(1e200)), REFUSE, EITHER),
    "error 1e308": ("json-edit", ("model.json", _coef(1e308)), REFUSE, EITHER),
    "error string": ("json-edit", ("model.json", _coef("big")), REFUSE, REFUSE),
    "error null": ("json-edit", ("model.json", _coef(None)), REFUSE, REFUSE),
    "error true": ("json-edit", ("model.json", _coef(True)), REFUSE, REFUSE),
    "error list": ("json-edit", ("model.json", _coef([1])), REFUSE, REFUSE),
    "NaN literal": ("text", '{"format": "fiveaxis fitted model", "version": 1, "errors_mm_rad": {"ex_x": NaN}}',
                    REFUSE, REFUSE),
    "Infinity literal": ("text", '{"errors_mm_rad": {"ex_x": Infinity}, "machine": "li2018"}', REFUSE, REFUSE),
    "unknown error": ("json-edit", ("model.json", _edit("errors_mm_rad", "bogus", value=1e-5)), REFUSE, REFUSE),
    "wrong format": ("json-edit", ("model.json", _edit("format", value="something")), REFUSE, EITHER),
    "wrong version": ("json-edit", ("model.json", _edit("version", value=99)), REFUSE, EITHER),
    "machine a list": ("json-edit", ("model.json", _edit("machine", value=[1])), REFUSE, REFUSE),
    "other machine": ("json-edit", ("model.json", _edit("machine", "name", value="ac_trunnion")), REFUSE, REFUSE),
    "sha256 wrong": ("json-edit", ("model.json", _edit("machine", "sha256", value="0" * 64)), REFUSE, REFUSE),
    "convention wrong": ("json-edit", ("model.json", _edit("convention", value="printed")), EITHER, REFUSE),
    "scales bad": ("json-edit", ("model.json", _edit("scales", value={"x": {"variable": "X", "centre_mm": 0,
                                                                             "half_range_mm": 0}})), EITHER, EITHER),
    "effects garbage": ("json-edit", ("model.json", _edit("effects", value=[{"id": "x"}])), REFUSE, EITHER),
    "effect coef 1e200": ("json-edit", ("model.json", _edit("effects", value=[
        {"id": "ex_x:x1", "kind": "polynomial", "param": "ex_x", "variable": "x", "degree": 1,
         "coefficients_mm_rad": {"ex_x:x1": 1e200}}])), REFUSE, EITHER),
    "deep JSON": ("text", "[" * 100000 + "]" * 100000, REFUSE, REFUSE),
    "deep object": ("text", '{"a":' * 50000 + "1" + "}" * 50000, REFUSE, REFUSE),
    "truncated": ("text", '{"format": "fiveaxis fitted model", "vers', REFUSE, REFUSE),
    "empty": ("text", "", REFUSE, REFUSE),
    "binary": ("bytes", b"\x89PNG\r\n\x1a\n" + bytes(range(256)), REFUSE, REFUSE),
    "a list": ("text", "[1, 2, 3]", REFUSE, REFUSE),
    "fifo": ("fifo", None, REFUSE, REFUSE),
    "dev zero": ("symlink", "/dev/zero", REFUSE, REFUSE),
    "folder": ("folder", None, REFUSE, REFUSE),
    "huge": ("huge", 40 * 2 ** 20, REFUSE, REFUSE),
    "good": ("copy", "{base}/model.json", OK, OK),
}


# -- machine files --------------------------------------------------------------------------------------------------------
LI = (MACHINES / "li2018.toml").read_text()
MACHINE_FILES = {   # name -> (maker, content); every one is refused
    "dev zero": ("symlink", "/dev/zero"), "fifo": ("fifo", None), "folder": ("folder", None),
    "huge": ("huge", 5 * 2 ** 20), "binary": ("bytes", bytes(range(256)) * 4), "empty": ("text", ""),
    "truncated": ("text", LI[: len(LI) // 2] + "\n[[["),
    "deep tables": ("text", "a = " + "[" * 5000 + "]" * 5000 + "\n"),
    "nan stroke": ("toml-edit", ("li2018.toml", lambda t: re.sub(r"stroke = \[[^\]]*\]", "stroke = [nan, 1]", t,
                                                                 count=1))),
    "inf length": ("toml-edit", ("li2018.toml", lambda t: t.replace("length = 200.0", "length = inf", 1))),
    "huge length": ("toml-edit", ("li2018.toml", lambda t: t.replace("length = 200.0", "length = 1e300", 1))),
    "bad direction": ("toml-edit", ("li2018.toml", lambda t: re.sub(r"direction = \[[^\]]*\]", "direction = [0, 0, 0]",
                                                                    t, count=1))),
    "hostile expr": ("toml-edit", ("li2018.toml", lambda t: t + '\n[effects.ls]\nerror = "dx_x"\nexpr = "p1*x + 0*len('
                                   '__import__(\'os\').makedirs(\'{m}\') or \'a\')"\n')),
    "reserved name": ("toml-edit", ("li2018.toml", lambda t: t.replace('name = "li2018"', 'name = "__init__"', 1))),
    "latin-1": ("bytes", LI.replace("li2018", "li2018\xe9", 1).encode("latin-1")),
}
#: Commands that read a machine file, with {f} the machine: argv (all refused for every MACHINE_FILES entry).
COMMANDS_READING_MACHINE = {
    "gsa": ["gsa", "--machine", "{f}", "--axis", "X=0"],
    "lsa": ["lsa", "--machine", "{f}", "--pose", "X=0,Y=0,Z=0,A=0,B=0"],
    "sobol": ["sobol", "--machine", "{f}", "--samples", "64"],
    "dask": ["dask", "--machine", "{f}", "--workers", "1"],
    "simulate": ["simulate", "--machine", "{f}", "--n", "20", "-o", "{out}/s.csv"],
    "fit": ["fit", "{base}/meas.csv", "--machine", "{f}"],
    "diagnose": ["diagnose", "{base}/meas.csv", "--machine", "{f}"],
    "report": ["report", "{base}/meas.csv", "--machine", "{f}", "-o", "{out}/r.html"],
    "plan": ["plan", "--machine", "{f}", "--n", "10", "-o", "{out}/p.csv"],
    "names": ["names", "--machine", "{f}"],
    "table2": ["table2", "--machine", "{f}"],
    "derive": ["derive", "{f}", "--out", "{out}/gen"],
    "model": ["model", "add", "ex_x:x1", "--machine", "{f}", "-o", "{out}/m.toml"],
    "compensate": ["compensate", "{base}/model.json", "--machine", "{f}", "-o", "{out}"],
}


# -- measurement files ------------------------------------------------------------------------------------------------------
def _cell(col, value, row=3):
    def edit(df):
        df[col] = df[col].astype(object)
        df.loc[row, col] = value
        return df
    return edit


def _rename(old, new):
    return lambda df: df.rename(columns={old: new})


def _same_poses(df):
    for c in "XYZAB":
        df[c] = df[c].iloc[0]
    return df.head(40)


def _setups(df):
    import numpy as np
    import pandas as pd
    big = pd.concat([df] * 120).head(24000).reset_index(drop=True)
    big["X"] = big["X"] + np.arange(len(big)) * 1e-3
    big["setup"] = [f"s{i // 6}" for i in range(len(big))]
    return big


MEASUREMENT_FILES = {   # name -> (maker, content, expect)
    "NaN cell": ("csv-edit", ("meas.csv", _cell("dx", "nan")), EITHER),
    "inf cell": ("csv-edit", ("meas.csv", _cell("dx", "inf")), REFUSE),
    "1e300 pose": ("csv-edit", ("meas.csv", _cell("X", 1e300)), REFUSE),
    "1e300 deviation": ("csv-edit", ("meas.csv", _cell("dy", 1e300)), REFUSE),
    "sigma 1e-300": ("csv-edit", ("meas.csv", lambda df: df.assign(sigma=1e-300)), REFUSE),
    "sigma 0": ("csv-edit", ("meas.csv", lambda df: df.assign(sigma=0.0)), REFUSE),
    "text cell": ("csv-edit", ("meas.csv", _cell("Z", "abc")), REFUSE),
    "200k cell": ("csv-edit", ("meas.csv", _cell("Z", "9" * 200000)), REFUSE),
    "DX": ("csv-edit", ("meas.csv", _rename("dx", "DX")), REFUSE),
    "d_x": ("csv-edit", ("meas.csv", _rename("dx", "d_x")), REFUSE),
    "Dz": ("csv-edit", ("meas.csv", _rename("dz", "Dz")), REFUSE),
    "dyy": ("csv-edit", ("meas.csv", _rename("dy", "dyy")), REFUSE),
    "one row": ("csv-edit", ("meas.csv", lambda df: df.head(1).assign(sigma=0.001)), EITHER),
    "identical poses": ("csv-edit", ("meas.csv", _same_poses), EITHER),
    "4000 setups": ("csv-edit", ("meas.csv", _setups), REFUSE),
    "header only": ("csv-edit", ("meas.csv", lambda df: df.head(0)), REFUSE),
    "no readings": ("csv-edit", ("meas.csv", lambda df: df.drop(columns=["dx", "dy", "dz"])), REFUSE),
    "duplicate column": ("text", "X,Y,Z,A,B,dx,dx\n0,0,0,0,0,0,0\n", REFUSE),
    "semicolons": ("text", "X;Y;Z;A;B;dx;dy;dz\n0;0;0;0;0;0;0;0\n", REFUSE),
    "BOM": ("csv-edit", ("meas.csv", lambda df: "\ufeff" + df.to_csv(index=False)), EITHER),
    "binary": ("bytes", bytes(range(256)) * 16, REFUSE),
    "empty": ("text", "", REFUSE),
    "fifo": ("fifo", None, REFUSE),
    "dev zero": ("symlink", "/dev/zero", REFUSE),
    "folder": ("folder", None, REFUSE),
    "parquet bool dx": ("parquet", ("meas.csv", lambda df: df.assign(dx=df["dx"] > 0)), REFUSE),
    "parquet text X": ("parquet", ("meas.csv", lambda df: df.assign(X=df["X"].astype(str))), EITHER),
    "parquet good": ("parquet", ("meas.csv", lambda df: df), OK),
    "radians": ("csv-edit", ("meas.csv", lambda df: df.assign(A=df["A"] / 57.3, B=df["B"] / 57.3)), EITHER),
    "negative L": ("csv-edit", ("meas.csv", lambda df: df.assign(L=-5.0)), REFUSE),
    "time nan": ("csv-edit", ("meas.csv", _cell("t", "nan")), EITHER),
    "bad setup kind": ("csv-edit", ("meas.csv", lambda df: df.assign(setup="a", setup_kind="sideways")), REFUSE),
}
COMMANDS_READING_MEASUREMENTS = {
    "fit": ["fit", "{f}"],
    "diagnose": ["diagnose", "{f}", "--top", "3"],
    "report": ["report", "{f}", "-o", "{out}/r.html", "--no-sensitivity", "--rounds", "1"],
}
#: Files whose valid variants take a whole fit: run only with the first command (they are the same for all).
SLOW_VALID = {"identical poses", "parquet good", "radians", "NaN cell", "time nan", "BOM"}
POSE_FILES = {   # simulate --poses: a file of poses
    "NaN pose": ("csv-edit", ("plan.csv", _cell("X", "nan", 1)), REFUSE),
    "1e300 pose": ("csv-edit", ("plan.csv", _cell("Y", 1e300, 1)), REFUSE),
    "text pose": ("csv-edit", ("plan.csv", _cell("Z", "x", 1)), REFUSE),
    "no X": ("csv-edit", ("plan.csv", lambda df: df.drop(columns=["X"])), REFUSE),
    "x": ("csv-edit", ("plan.csv", _rename("X", "x")), REFUSE),
    "L 1e9": ("csv-edit", ("plan.csv", lambda df: df.assign(L=1e9)), REFUSE),
    "empty": ("text", "", REFUSE), "fifo": ("fifo", None, REFUSE), "dev zero": ("symlink", "/dev/zero", REFUSE),
    "binary": ("bytes", bytes(range(256)) * 16, REFUSE), "good": ("copy", "{base}/plan.csv", OK),
}
ISO_FILES = {   # iso230-2 / iso230-4: hostile variants of an interferometer's and a ballbar's files ({which} the base)
    "NaN du": ("csv-edit", ("{which}.csv", _cell("du", "nan")), REFUSE),
    "1e300 du": ("csv-edit", ("{which}.csv", _cell("du", 1e300)), REFUSE),
    "no du": ("csv-edit", ("{which}.csv", lambda df: df.drop(columns=["du"])), REFUSE),
    "direction zero": ("csv-edit", ("{which}.csv", lambda df: df.assign(ux=0.0, uy=0.0, uz=0.0)), REFUSE),
    "tip readings": ("copy", "{base}/meas.csv", REFUSE),
    "one row": ("csv-edit", ("{which}.csv", lambda df: df.head(1)), REFUSE),
    "text X": ("csv-edit", ("{which}.csv", _cell("X", "x")), REFUSE),
    "empty": ("text", "", REFUSE), "fifo": ("fifo", None, REFUSE), "dev zero": ("symlink", "/dev/zero", REFUSE),
    "binary": ("bytes", bytes(range(256)) * 16, REFUSE),
    "rounded": ("csv-edit", ("{which}.csv", lambda df: df.round(4)), OK),
    "good": ("copy", "{base}/{which}.csv", OK),
}
ISO_COMMANDS = {"iso230-2": ("iso2", ["iso230-2", "{f}"]), "iso230-4": ("iso4", ["iso230-4", "{f}", "--rounds", "1"])}
ISO3_FILES = {   # iso230-3: hostile variants of a simulated spindle test (five sensors, temperatures, spindle_rpm)
    "NaN dz": ("csv-edit", ("iso3.csv", _cell("dz", "nan")), REFUSE),
    "1e300 dx": ("csv-edit", ("iso3.csv", _cell("dx", 1e300)), REFUSE),
    "text dx": ("csv-edit", ("iso3.csv", _cell("dx", "x")), REFUSE),
    "2000 degC": ("csv-edit", ("iso3.csv", _cell("temp_air", 2000.0)), REFUSE),
    "time back": ("csv-edit", ("iso3.csv", _cell("t", 0.0, 5)), REFUSE),
    "um in mm": ("csv-edit", ("iso3.csv", lambda df: df.assign(dz=df["dz"] * 1000)), REFUSE),
    "hours in t": ("csv-edit", ("iso3.csv", lambda df: df.assign(t=df["t"] / 3600)), REFUSE),
    "stuck sensor": ("csv-edit", ("iso3.csv", lambda df: df.assign(dy=0.0)), REFUSE),
    "no time": ("csv-edit", ("iso3.csv", lambda df: df.drop(columns=["t"])), REFUSE),
    "one row": ("csv-edit", ("iso3.csv", lambda df: df.head(1)), REFUSE),
    "empty": ("text", "", REFUSE), "fifo": ("fifo", None, REFUSE), "dev zero": ("symlink", "/dev/zero", REFUSE),
    "binary": ("bytes", bytes(range(256)) * 16, REFUSE),
    "blank temperature": ("csv-edit", ("iso3.csv", _cell("temp_air", "")), OK),
    "good": ("copy", "{base}/iso3.csv", OK),
}
TOOLPATH_CSV = {   # lsa --toolpath X.csv
    "NaN": ("text", "X,Y,Z,A,B\n0,0,0,0,0\nnan,0,0,0,0\n", REFUSE),
    "1e300": ("text", "X,Y,Z,A,B\n0,0,0,0,0\n1e300,0,0,0,0\n", REFUSE),
    "other machine": ("text", "X,Y,Z,A,C\n0,0,0,0,0\n", REFUSE),
    "empty": ("text", "", REFUSE), "header only": ("text", "X,Y,Z,A,B\n", REFUSE),
    "binary": ("bytes", bytes(range(256)) * 16, REFUSE), "fifo": ("fifo", None, REFUSE),
    "normals zero": ("text", "X,Y,Z,A,B,nx,ny,nz\n0,0,0,0,0,0,0,0\n10,0,0,0,0,0,0,0\n", REFUSE),
    "good": ("text", "X,Y,Z,A,B\n0,0,0,0,0\n100,0,0,0,0\n100,100,0,5,5\n", OK),
}
SUMMARY_FILES = {   # report --compensation DIR with a malformed summary.json
    "not json": ("text", "{not json", REFUSE), "a list": ("text", "[1]", REFUSE),
    "deep": ("text", "[" * 100000 + "]" * 100000, REFUSE), "empty": ("text", "", REFUSE),
    "table a list": ("json-edit", ("comp/summary.json", lambda d: dict(d, table=[1])), REFUSE),
    "machine string": ("json-edit", ("comp/summary.json", lambda d: dict(d, machine="li2018")), REFUSE),
    "stats string": ("json-edit", ("comp/summary.json", lambda d: dict(d, predicted_tip_error_mm={
        "before": {"max": "x", "rms": 1, "p95": 1}})), REFUSE),
    "stats NaN": ("text", '{"machine": {"name": "li2018", "sha256": "x"}, "predicted_tip_error_mm": {"before": '
                          '{"max": NaN, "rms": 1, "p95": 1}}}', REFUSE),
    "by length 5": ("json-edit", ("comp/summary.json", lambda d: dict(d, predicted_by_tool_length=5)), REFUSE),
    "warnings dict": ("json-edit", ("comp/summary.json", lambda d: dict(d, warnings={"a": 1})), REFUSE),
    "fifo": ("fifo", None, REFUSE),
}
#: Damage in numbers only the report reads: `simulate --compensation` (the table, checked by its hash) may go on.
SUMMARY_REPORT_ONLY = {"stats string"}


# -- options out of range (no file) ----------------------------------------------------------------------------------------
GSA = ["gsa", "--axis", "X=0", "--axis", "Y=0"]
OPTION_TRIALS = [   # (command argv, expect, names)
    *[(GSA + ["--axis", a], REFUSE, ("--axis",)) for a in ("Y=0:1:inf", "Y=0:1:1e300", "Y=-1000:1000:1e9", "A=5:1:3",
                                                           "Q=0:1:3", "Y=nan:1:3", "Y=0:1:-3", "Y", "Y=0:1:2.5")],
    *[(GSA + [o, v], REFUSE, (o,)) for o, v in (("--l0", "-1"), ("--l0", "1e308"), ("--l0", "nan"), ("--le", "500"),
                                                ("--le", "-3"), ("--le", "inf"), ("--order", "0"), ("--order", "-2"),
                                                ("--order", "1e9"), ("--order", "x"), ("--top", "-3"),
                                                ("--max-poses", "0"), ("--max-poses", "-5"), ("--chunk", "0"),
                                                ("--chunk", "-1"), ("--rot-count", "-1"), ("--errors", "ex_x=nan"),
                                                ("--errors", "ex_x=inf"), ("--errors", "ex_x=1e300"),
                                                ("--errors", "bogus=1"), ("--errors", "ex_x=true"),
                                                ("--convention", "nope"))],
    (GSA + ["--compensate", "--rot-count", "0"], REFUSE, ("--rot-count",)),
    (GSA + ["--top", "0"], EITHER, ("--top",)),
    *[(["lsa", o, v], REFUSE, (o,)) for o, v in (("--positions", "0"), ("--positions", "100000000"),
                                                 ("--positions", "-1"), ("--cone", "3"), ("--step-mm", "0"),
                                                 ("--step-mm", "nan"), ("--step-mm", "-1"), ("--step-deg", "0"),
                                                 ("--segments", "-1"), ("--normal-mode", "2"),
                                                 ("--surface", "sphere:nan,0,0"), ("--surface", "bogus:1"))],
    (["lsa", "--pose", "X=1e300,Y=0,Z=0,A=0,B=0"], REFUSE, ("--pose",)),
    *[(["iso230-2", "{base}/iso2.csv", o, v], REFUSE, (o,)) for o, v in (
        ("--tolerance", "0"), ("--tolerance", "-1"), ("--tolerance", "nan"), ("--u-device", "-1"),
        ("--u-device", "inf"), ("--temperature-deviation", "nan"), ("--expansion-ppm-per-K", "1e300"),
        ("--misalignment", "-1"), ("--drift", "nan"), ("--frame", "sideways"))],
    *[(["iso230-3", "{base}/iso3.csv", "--spacing", "100", o, v], REFUSE, (o,)) for o, v in (
        ("--spindle-off", "nan"), ("--spindle-off", "-5"), ("--spindle-off", "1e9"), ("--spindle-speed", "-1"),
        ("--test", "bogus"))],
    (["iso230-3", "{base}/iso3.csv", "--spacing", "100", "--test", "etve"], REFUSE, ("spindle_rpm", "row")),
    *[(["iso230-3", "{base}/iso3.csv", "--spacing", v], REFUSE, ("--spacing",)) for v in ("nan", "-1", "1e300")],
    (["iso230-3", "{base}/iso3.csv"], REFUSE, ("--spacing",)),
    *[(["simulate", "--iso230-3", "spindle", "-o", "{out}/t.csv", o, v], REFUSE, (o,)) for o, v in (
        ("--hours", "0"), ("--hours", "nan"), ("--hours", "1e9"), ("--interval", "0"), ("--seed", "-1"),
        ("--speed", "inf"), ("--spacing", "0"), ("--run-hours", "-1"))],
    *[(["iso230-4", "{base}/iso4.csv", o, v], REFUSE, (o,)) for o, v in (
        ("--rounds", "-1"), ("--rounds", "x"), ("--feed", "0"), ("--feed", "nan"), ("--feed", "-5"))],
    (["lsa", "--pose", "X=nan,Y=0,Z=0,A=0,B=0"], REFUSE, ("--pose",)),
    (["lsa", "--pose", "X=0,Y=0"], REFUSE, ("--pose",)),
    (["lsa", "--pose", "X=0,Y=0,Z=0,A=0,B=0,nx=0,ny=0,nz=0"], REFUSE, ("--pose", "normal")),
    *[(["sobol", o, v], REFUSE, (o,)) for o, v in (("--samples", "0"), ("--samples", "3"), ("--samples", "-64"),
                                                   ("--samples", "1e12"), ("--bound", "inf"), ("--bound", "0"),
                                                   ("--bound", "-1"), ("--bound", "nan"), ("--seed", "-1"))],
    *[(["simulate", o, v, "-o", "{out}/s.csv"], REFUSE, (o,)) for o, v in (
        ("--n", "0"), ("--n", "-5"), ("--n", "10000000000"), ("--noise", "nan"), ("--noise", "inf"),
        ("--noise", "-1"), ("--duration", "nan"), ("--duration", "inf"), ("--duration", "-1"), ("--seed", "-1"),
        ("--tool-lengths", "100,inf"), ("--tool-lengths", "inf,inf"), ("--tool-lengths", "-5,10"),
        ("--tool-lengths", "1e9,2e9"), ("--effect", "ex_x:x1=nan"), ("--effect", "ex_x:x1=inf"),
        ("--effect", "ex_x:x1=1e300"), ("--effect", "bogus"), ("--error", "ex_x=nan"), ("--error", "ex_x=1e300"),
        ("--error", "bogus=1"), ("--setup-scale", "nan"), ("--setup-scale", "-1"), ("--noise-axis", "nan"),
        ("--max-poses", "0"))],
    (["simulate", "--noise", "0", "--with-sigma", "-o", "{out}/s.csv"], EITHER, ("--noise", "sigma")),
    (["simulate", "--n", "20", "--instrument", "ballbar", "-o", "{out}/s.csv"], EITHER, ("ballbar",)),
    *[(["fit", "{base}/meas.csv", o, v], REFUSE, (o,)) for o, v in (
        ("--fix", "ex_x=nan"), ("--fix", "ex_x=inf"), ("--fix", "bogus=1"), ("--fix", "ex_x"), ("--add", "zz:x1"),
        ("--add", "ex_x:x9"), ("--add", ""), ("--add", "ex_x:q1"), ("--scheduler", "garbage"),
        ("--scheduler", "tcp://"), ("--convention", "nope"))],
    *[(["diagnose", "{base}/meas.csv", o, v], REFUSE, (o,)) for o, v in (
        ("--top", "0"), ("--top", "-1"), ("--fix", "ex_x=nan"), ("--add", "ex_x:x9"), ("--plot", "{base}/meas.csv"))],
    *[(["compensate", "{base}/model.json", "-o", "{out}", o, v], REFUSE, (o,)) for o, v in (
        ("--nodes", "X=1e9"), ("--nodes", "X=1"), ("--nodes", "X=0"), ("--nodes", "Q=3"), ("--nodes", "X=2.5"),
        ("--nodes", "X=nan"), ("--nodes", "X"), ("--tool-lengths", "1e9,2e9"), ("--tool-lengths", "100,inf"),
        ("--tool-lengths", "200,100"), ("--tool-lengths", "100"), ("--tool-lengths", "0:100:5"),
        ("--tool-lengths", "a,b"), ("--damping", "nan"), ("--damping", "-1"),
        ("--damping", "inf"), ("--comp-points", "1"), ("--comp-points", "1000"), ("--poses", "0"),
        ("--poses", "-1"), ("--seed", "-1"), ("--max-nodes", "0"))],
    *[(["verify", "{base}/model.json", "--compensation", "{base}/comp", o, v], REFUSE, (o,)) for o, v in (
        ("--n", "0"), ("--seed", "-1"), ("--noise", "nan"), ("--noise", "0"), ("--compensation", "{out}/none"),
        ("--readings", "{base}/iso2.csv"), ("--readings", "{out}/none.csv"), ("-o", "{out}/v.txt"))],
    (["verify", "{base}/model.json", "--compensation", "{base}/comp", "--readings", "{base}/meas.csv"], EITHER, ()),
    (["compensate", "{base}/model.json", "-o", "{out}", "--nodes", "X=1e9", "--max-nodes", "2000000000000"], REFUSE,
     ("--nodes", "memory")),
    (["compensate", "{base}/model.json", "-o", "{out}", "--damping", "0", "--nodes", "X=2,Y=2,Z=2"], EITHER,
     ("damping",)),
    *[(["plan", "--n", "10", "-o", "{out}/p.csv", o, v], REFUSE, (o,)) for o, v in (
        ("--n", "0"), ("--n", "-1"), ("--n", "100000000"), ("--seed", "-1"), ("--noise", "nan"), ("--noise", "0"),
        ("--feed", "0"), ("--feed", "inf"), ("--dwell", "-1"), ("--dwell", "nan"), ("--effects", "zz:x1"),
        ("--tool-lengths", "nan"), ("--tool-lengths", "-5"), ("--tool-lengths", "1e9"))],
    (["plan", "--n", "10", "-o", "{out}/p.txt"], REFUSE, ("p.txt",)),
    *[(["report", "{base}/meas.csv", "-o", "{out}/r.html", o, v], REFUSE, (o,)) for o, v in (
        ("--rounds", "0"), ("--rounds", "-1"), ("--add", "zz:x1"), ("--compensation", "{base}/meas.csv"),
        ("--compensation", "{out}/none"), ("--pdf", "{out}/r.txt"))],
    (["report", "{base}/meas.csv", "-o", "{out}/r.txt"], REFUSE, ("r.txt",)),
    *[(["dask", o, v], REFUSE, (o,)) for o, v in (("--workers", "0"), ("--workers", "-1"), ("--chunk", "0"),
                                                  ("--scheduler", "garbage"), ("--scheduler", "tcp://"),
                                                  ("--max-poses", "0"), ("--axis", "Y=0:1:inf"))],
    *[(["table2", o, v], REFUSE, (o,)) for o, v in (("--convention", "nope"), ("--machine", "nosuch"))],
    (["table2", "--machine", "{base}/planar.toml", "--reconcile"], REFUSE, ("li2018",)),
    *[(["names", o, v], REFUSE, (o,)) for o, v in (("--convention", "nope"), ("--machine", "nosuch"),
                                                   ("--machine", "x" * 5000))],
    *[(["derive", m, "--out", "{out}/gen"], REFUSE, (m,)) for m in ("nosuch", "{base}/meas.csv", "")],
    (["derive", "{base}/planar.toml", "--out", "{base}/meas.csv"], REFUSE, ("meas.csv",)),
    *[(["model", "add", e, "-o", "{out}/m.toml"], REFUSE, ("effect", e[:10] or "model")) for e in (
        "zz:x1", ":", "", "ex_x:", "ex_x:x1=3", "ex_x:x9", "ex_x:x0", "x" * 500)],
    (["model", "add", "ex_x:x1", "-o", "{base}/meas.csv"], REFUSE, ("meas.csv",)),
    (["model", "add", "ex_x:x1", "--machine", "{base}/li2018.toml", "-o", "{base}/li2018.toml"], REFUSE,
     ("li2018.toml",)),
    (["simulate", "--compensation", "{base}/meas.csv", "-o", "{out}/s.csv"], REFUSE, ("meas.csv",)),
    (["simulate", "--compensation", "{out}", "-o", "{out}/s.csv"], REFUSE, ("summary.json",)),
    (["names", "--json"], OK, ()),
    (["table2", "--json"], OK, ()),
    (GSA + ["--json"], OK, ()),
]

#: Writers: name -> (command argv with {o} the output path, its file name, cases where replacing is by design).
#: Each gets OUTPUT_CASES at {o}: a dangling link, a link to a file, {o} under a file, {o} a folder, {o} existing
#: without --force (plots and generated modules replace their own earlier files by design: EITHER there).
WRITERS = {
    "simulate": (["simulate", "--n", "20", "--no-time", "-o", "{o}"], "s.csv", ()),
    "fit": (["fit", "{base}/meas_nt.csv", "-o", "{o}"], "model.json", ()),
    "plan": (["plan", "--n", "10", "-o", "{o}"], "p.csv", ()),
    "plan --gcode": (["plan", "--n", "10", "-o", "{out}/q.csv", "--gcode", "{o}"], "p.ngc", ()),
    "report": (["report", "{base}/meas.csv", "-o", "{o}", "--no-sensitivity", "--rounds", "1"], "r.html", ()),
    "model": (["model", "add", "ex_x:x1", "-o", "{o}"], "m.toml", ()),
    "gsa --plot": (GSA + ["--plot", "{out}"], "gsa_pie.png", ("exists",)),
    "compensate": (["compensate", "{base}/model.json", "-o", "{out}", "--nodes", "X=2,Y=2,Z=2", "--poses", "200",
                    "--comp-points", "9"], "table.csv", ()),
    "derive": (["derive", "{base}/planar.toml", "--out", "{out}"], "planar.py", ("exists",)),
    "iso230-2 --plot": (["iso230-2", "{base}/iso2.csv", "--plot", "{out}"], "iso230-2_X_laser-X.png", ("exists",)),
    "iso230-3 --plot": (["iso230-3", "{base}/iso3.csv", "--spacing", "100", "--plot", "{out}"],
                        "iso230-3_spindle.png", ("exists",)),
    "simulate --iso230-3": (["simulate", "--iso230-3", "spindle", "-o", "{o}"], "t.csv", ()),
}
OUTPUT_CASES = ("dangling link", "link to a file", "under a file", "a folder", "exists")
#: kill -9 while writing: (id, argv, reader argv, files that must come from one run); killed the moment a file in
#: {out} starts to change; the reader must then refuse or find those files all old or all new.
KILLS = [
    ("compensate --force", ["compensate", "{base}/model.json", "-o", "{out}", "--force", "--nodes", "X=3,Y=2,Z=2",
                            "--poses", "200", "--comp-points", "11"],
     ["simulate", "--n", "10", "--no-time", "--compensation", "{out}", "-o", "{out}/after.csv"],
     ("table.csv", "table.parquet", "summary.json", "linuxcnc/*")),
    ("fit -o --force", ["fit", "{base}/meas_nt.csv", "-o", "{out}/model.json", "--force"],
     ["compensate", "{out}/model.json", "-o", "{out}/c", "--nodes", "X=2,Y=2,Z=2", "--poses", "100"],
     ("model.json",)),
    ("simulate -o --force", ["simulate", "--n", "3000", "-o", "{out}/s.csv", "--force"],
     ["fit", "{out}/s.csv", "--first-order"], ("s.csv",)),
]


# -- round 4 (issue 28; issue 34's leftovers) ---------------------------------------------------------------------
#: A model file named with a payload (compensate writes its path into LinuxCNC's files): a comment of safe
#: characters only (check "inject": HAL lines are commands of ours, the INIs parse strictly, README's `$ ` lines ours).
HOSTILE_MODEL_NAMES = {
    "HAL loadusr": "m\nloadusr -W touch CANARY\n.json",
    "README command": "m\n$ touch CANARY\n.json",
    "INI section": "m\n[EMC]\nDISPLAY = touchy\n.json",
    "CR and substitutions": "m\r\nsetp x 1 $(HOME) [EMC]X `touch CANARY`.json",
}
#: A machine file named with halcompile declarations (check "kins": none outside a // comment of the module).
HOSTILE_MACHINE_NAMES = {
    "halcompile option": 'x""";option userspace yes;option extra_link_args "`touch CANARY`";description """y.toml',
    "halcompile pin": 'x""";include <stdio.h>;pin out float injected;description """y.toml',
    "line feeds": 'x\n""";\npin out float injected;\n"""\ny.toml',
}
#: Links planted in a compensate folder (the previous run's), to a victim file or folder beside it: refused.
PLANTED_LINKS = {"linuxcnc folder": ("linuxcnc", "dir"), "HAL file": ("linuxcnc/volumetric/fiveaxis.hal", "file"),
                 "INI": ("linuxcnc/fiveaxis.ini", "file"), "summary": ("summary.json", "file")}
#: Programs for `plan --check` that never end or block.
PROGRAM_FILES = {"fifo": ("fifo", None, REFUSE), "dev zero": ("symlink", "/dev/zero", REFUSE),
                 "folder": ("folder", None, REFUSE), "huge": ("huge", 300 * 2 ** 20, REFUSE),
                 "good": ("copy", "{base}/plan.ngc", OK)}
#: Effects of model_p.json (a periodic effect dx_x:xp800) edited: refused with the file and the key.
EFFECT_EDITS = {
    "std string": lambda e: e.update(std_mm_rad={k: "abc" for k in e["coefficients_mm_rad"]}),
    "std list": lambda e: e.update(std_mm_rad={k: [1] for k in e["coefficients_mm_rad"]}),
    "period 1e-300": lambda e: e.update(period=1e-300),
    "period 1e300": lambda e: e.update(period=1e300),
    "bad id": lambda e: e.update(id="dx_x:xq800"),
    "id 1e-300": lambda e: e.update(id="dx_x:xp1e-300", period=1e-300),
}
#: (argv, expect, names, check) of round 4: unit slips, one-axis machines, the options issue 34 and 28 name.
ROUND4 = [
    (["compensate", "{base}/stage_um.json", "-o", "{out}"], REFUSE, ("did you write um in a mm column",), "clean"),
    (["fit", "{base}/stage_um.csv", "--machine", "{base}/stage42.toml"], OK, (), "hint"),
    (["diagnose", "{base}/stage_um.csv", "--machine", "{base}/stage42.toml", "--top", "2"], OK, (), "hint"),
    (["iso230-2", "{base}/stage_um.csv", "--machine", "{base}/stage42.toml"], OK, (), "hint"),
    (["compensate", "{base}/stage_mm.json", "-o", "{out}", "--plot"], OK, (), None),
    (["report", "{base}/stage_mm.csv", "--machine", "{base}/nocut.toml", "-o", "{out}/r.html", "--rounds", "1"],
     OK, (), None),
    (["gsa", "--machine", "{base}/nocut.toml"], REFUSE, ("tool.length", "--l0"), None),
    (["iso230-2", "{base}/stage3.csv"], REFUSE, ("--machine",), None),
    (["iso230-2", "{base}/stage3.csv", "--machine", "{base}/stage42.toml"], OK, (), None),
    (["iso230-2", "{base}/iso2.csv", "--tolerance", "1e9"], REFUSE, ("--tolerance",), None),
    (["simulate", "--n", "20", "-o", "{out}/s.csv", "--truth", "{base}/meas.csv/t.json"], REFUSE, ("meas.csv",),
     "clean"),
    (["plan", "--n", "6", "-o", "{out}/p.csv", "--feed", "1e-9"], REFUSE, ("--feed",), "clean"),
    (["compensate", "{base}/model.json", "-o", "{out}", "--damping", "1e300"], REFUSE, ("--damping",), "clean"),
    (["compensate", "{base}/model.json", "-o", "{out}", "--tool-lengths", "100,100.0000000001"], REFUSE,
     ("--tool-lengths",), "clean"),
    (["plan", "--n", "6", "-o", "{out}/p.csv", "--tool-lengths", "100,100.0000000001"], REFUSE, ("--tool-lengths",),
     "clean"),
    (["simulate", "--n", "20", "-o", "{out}/s.csv", "--tool-lengths", "100,100.0000000001"], REFUSE,
     ("--tool-lengths",), "clean"),
    (["gsa", "--le", "500", "--axis", "X=0"], REFUSE, ("--le",), None),
    (["gsa", "--errors", "ex_x", "--axis", "X=0"], REFUSE, ("--errors",), None),
    (["lsa", "--positions", "100000000"], REFUSE, ("--positions",), None),
    (["simulate", "--effect", "L:t1", "--no-time", "-o", "{out}/s.csv"], REFUSE, ("--effect 'L:t1'",), "clean"),
    (["fit", "{base}/meas_nt.csv", "--add", "L:t1"], REFUSE, ("--add 'L:t1'",), None),
    (["simulate", "--n", "20", "--machine", "{base}/li2018.toml", "--effect", "zz", "-o", "{out}/s.csv"], REFUSE,
     ("--effect",), "clean"),
]
#: Measurement files of round 4 (fit, diagnose, report read them): a unit in a reading's name, a spreadsheet's
#: export with ';' and decimal commas.
MEASUREMENT_FILES_4 = {
    "dx mm": ("csv-edit", ("meas.csv", _rename("dx", "dx mm")), REFUSE),
    "du_um": ("csv-edit", ("meas.csv", _rename("dx", "du_um")), REFUSE),
    "dx[um]": ("csv-edit", ("meas.csv", _rename("dx", "dx[um]")), REFUSE),
    "decimal commas": ("csv-edit", ("meas.csv", lambda df: df.to_csv(index=False, sep=";", decimal=",")), REFUSE),
}


def _effects_edit(edit):
    def apply(d):
        edit(d["effects"][0])
        return d
    return apply


# -- the trials ---------------------------------------------------------------------------------------------------------------
def trials() -> list[Trial]:
    out = []
    for machine in ("ac_trunnion", "li2018"):
        for name, (maker, content, expect) in GCODE.items():
            out.append(Trial(f"lsa {machine} gcode: {name}", "lsa",
                             ["lsa", "--machine", machine, "--toolpath", "{f}", "--step-mm", "5", "--step-deg", "5"],
                             expect if machine == "ac_trunnion" or expect != OK else EITHER,
                             ("{f}", "line"), (maker, content), suffix=".ngc"))
    for name, (maker, content, e_comp, e_err) in MODEL_FILES.items():
        out.append(Trial(f"compensate model: {name}", "compensate",
                         ["compensate", "{f}", "-o", "{out}", "--nodes", "X=2,Y=2,Z=2", "--poses", "200",
                          "--comp-points", "9"], e_comp, ("{f}", "machine", "errors"), (maker, content),
                         check="comp", suffix=".json"))
        for cmd, argv in (("gsa", GSA + ["--errors", "{f}", "--json"]),
                          ("lsa", ["lsa", "--errors", "{f}", "--json"])):
            out.append(Trial(f"{cmd} --errors model: {name}", cmd, argv, e_err, ("{f}", "--errors"),
                             (maker, content), suffix=".json"))
    for name, (maker, content) in MACHINE_FILES.items():
        for cmd, argv in COMMANDS_READING_MACHINE.items():
            out.append(Trial(f"{cmd} machine: {name}", cmd, argv, REFUSE, ("{f}", "machine"), (maker, content),
                             suffix=".toml"))
    for name, (maker, content, expect) in MEASUREMENT_FILES.items():
        for i, (cmd, argv) in enumerate(COMMANDS_READING_MEASUREMENTS.items()):
            if name in SLOW_VALID and i > 0:
                continue
            out.append(Trial(f"{cmd} measurements: {name}", cmd, argv, expect, ("{f}", "column", "row"),
                             (maker, content), suffix=".parquet" if maker == "parquet" else ".csv"))
    for name, (maker, content, expect) in POSE_FILES.items():
        out.append(Trial(f"simulate --poses: {name}", "simulate", ["simulate", "--poses", "{f}", "-o", "{out}/s.csv"],
                         expect, ("{f}", "column", "row"), (maker, content), suffix=".csv"))
    for name, (maker, content, expect) in ISO_FILES.items():
        for cmd, (which, argv) in ISO_COMMANDS.items():
            what = (content[0].format(which=which), content[1]) if maker == "csv-edit" else \
                content.replace("{which}", which) if isinstance(content, str) else content
            out.append(Trial(f"{cmd} measurements: {name}", cmd, argv, expect, ("{f}", "column", "row", "du"),
                             (maker, what), suffix=".csv"))
    for name, (maker, content, expect) in ISO3_FILES.items():
        out.append(Trial(f"iso230-3 file: {name}", "iso230-3", ["iso230-3", "{f}", "--spacing", "100"], expect,
                         ("{f}", "column", "row"), (maker, content), suffix=".csv"))
    for name, (maker, content, expect) in TOOLPATH_CSV.items():
        out.append(Trial(f"lsa toolpath csv: {name}", "lsa", ["lsa", "--toolpath", "{f}"], expect,
                         ("{f}", "row", "column"), (maker, content), suffix=".csv"))
    for name, (maker, content, expect) in SUMMARY_FILES.items():
        for cmd, argv in (("report", ["report", "{base}/meas.csv", "--compensation", "{out}/comp", "-o",
                                      "{out}/r.html", "--no-sensitivity", "--rounds", "1"]),
                          ("simulate", ["simulate", "--n", "10", "--compensation", "{out}/comp", "-o",
                                        "{out}/s.csv"])):
            out.append(Trial(f"{cmd} --compensation summary: {name}", cmd, argv,
                             EITHER if cmd == "simulate" and name in SUMMARY_REPORT_ONLY else expect,
                             ("summary.json",), ("summary:" + maker, content)))
    for argv, expect, names in OPTION_TRIALS:
        out.append(Trial(" ".join(argv)[:110], argv[0], argv, expect, names))
    for cmd, (argv, name, by_design) in WRITERS.items():
        for case in OUTPUT_CASES:
            out.append(Trial(f"{cmd} output: {case}", cmd.split()[0], argv, EITHER if case in by_design else REFUSE,
                             ("{o}", name, "--force"), ("output:" + case, name)))
    for name, argv, reader, together in KILLS:
        out.append(Trial(f"kill -9 {name}", argv[0], argv, EITHER, (), kill="write", reader=reader, timeout=400,
                         together=together))
    out += round4()
    seen: dict = {}
    for t in out:                                     # ids are unique: a repeated one gets #2, #3...
        seen[t.id] = seen.get(t.id, 0) + 1
        if seen[t.id] > 1:
            t.id = f"{t.id} #{seen[t.id]}"
    return out


# -- running ---------------------------------------------------------------------------------------------------------------------
@dataclass
class Result:
    trial: Trial
    cls: str
    rc: int | None
    seconds: float
    message: str = ""


@dataclass
class Runner:
    work: Path
    python: str = sys.executable
    pythonpath: str | None = None
    memory: int = MEMORY_LIMIT
    env: dict = field(default_factory=dict)

    def __post_init__(self):
        for d in ("home", "tmp", "cache"):
            (self.work / d).mkdir(parents=True, exist_ok=True)
        self.env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": str(self.work / "home"),
                    "TMPDIR": str(self.work / "tmp"), "FIVEAXIS_CACHE": str(self.work / "cache"), "LC_ALL": "C.UTF-8",
                    "MPLBACKEND": "Agg", "PYTHONDONTWRITEBYTECODE": "1"}
        if self.pythonpath:
            self.env["PYTHONPATH"] = self.pythonpath

    def command(self, argv) -> list:
        return ["prlimit", f"--as={self.memory}", "--core=0", "--", self.python, "-m", "fiveaxis.cli", *argv]

    def run(self, argv, cwd=None, timeout=TIMEOUT):
        try:
            p = subprocess.run(self.command(argv), cwd=cwd or self.work, env=self.env, capture_output=True,
                               text=True, errors="replace", timeout=timeout, stdin=subprocess.DEVNULL,
                               start_new_session=True)
            return p.returncode, p.stdout, p.stderr
        except subprocess.TimeoutExpired as exc:
            return None, exc.stdout or "", exc.stderr or ""


def _subst(argv, values) -> list:
    out = []
    for a in argv:
        for k, v in values.items():
            a = a.replace("{" + k + "}", str(v))
        out.append(a)
    return out


def _prepare(trial: Trial, tdir: Path, base: Path, marker: Path) -> dict:
    """The trial's folder, file and substitutions."""
    out = tdir / "out"
    out.mkdir(parents=True)
    values = {"out": out, "base": base, "m": marker}
    if trial.file is None:
        return values
    maker, content = trial.file
    if maker.startswith("output:"):
        case, name = maker[len("output:"):], content
        o = out / name
        victim = tdir / "victim"
        if case == "dangling link":
            o.symlink_to(victim)
        elif case == "link to a file":
            victim.write_text("the user's file\n")
            o.symlink_to(victim)
        elif case == "under a file":
            (tdir / "FILE").write_text("x")
            o = tdir / "FILE" / name
            if "{o}" not in " ".join(trial.argv):     # the command writes into the folder {out}: put that there
                values["out"] = tdir / "FILE" / "out"
        elif case == "a folder":
            o.mkdir()
            (o / "keep").write_text("x")
        elif case == "exists":
            o.write_text("the user's file\n")
        values["o"] = o
        return values
    if maker.startswith("summary:"):
        shutil.copytree(base / "comp", out / "comp")
        (out / "comp" / "summary.json").unlink()
        path = make_file(tdir, "summary.json", (maker[len("summary:"):], content), base, marker)
        shutil.move(str(path), out / "comp" / "summary.json")
        values["f"] = out / "comp" / "summary.json"
        return values
    if maker == "model-copy":                     # the base model under a hostile name, beside its machine file
        path = out.parent / trial.filename
        data = json.loads(Path(content.format(base=base)).read_text())
        data["machine"]["file"] = os.path.relpath((base / data["machine"]["file"]).resolve(), out.parent)
        path.write_text(json.dumps(data))
        values["f"] = path
        return values
    if maker.startswith("outlink:"):             # a previous run's folder with a link planted in it
        rel = maker[len("outlink:"):]
        shutil.copytree(base / "comp", out, dirs_exist_ok=True)
        victim = tdir / "victim"
        if content == "dir":
            victim.mkdir()
        else:
            victim.write_text("the user's file\n")
        link = out / rel
        if link.is_dir() and not link.is_symlink():
            shutil.rmtree(link)
        elif link.exists() or link.is_symlink():
            link.unlink()
        link.symlink_to(victim)
        return values
    values["f"] = make_file(tdir, trial.filename or "hostile" + trial.suffix, (maker, content), base, marker)
    return values


def _victims_untouched(tdir: Path) -> bool:
    v = tdir / "victim"
    if v.is_dir():
        return not any(v.iterdir())
    return not v.exists() or v.read_text() == "the user's file\n"


def _outputs_finite(out: Path, stdout: str) -> str | None:
    """A reason when an output holds a non-finite number; None when all are finite."""
    texts = [("stdout", stdout)]
    for p in out.rglob("*"):
        if p.is_file() and p.suffix in (".json", ".csv", ".comp", ".ini", ".hal", ".ngc") and p.stat().st_size < 5e7:
            texts.append((p.name, p.read_text(errors="replace")))
    for name, text in texts:
        text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)     # C comments of the kinematics module's source
        lines = [line for line in text.splitlines() if not line.lstrip().startswith(("#", "(", ";", "//"))]
        body = "\n".join(lines)
        if name.endswith(".csv"):
            body = body.replace(",,", ",").replace(",\n", "\n")
        m = NOT_FINITE.search(body)
        if m and not (name.endswith(".csv") and m.group(0).lower() == "nan" and False):
            return f"{name}: {m.group(0)!r}"
    return None


def _implausible_comp(out: Path) -> str | None:
    """A compensation folder with corrections beyond any machine's (the comp files' trims, the table's c_)."""
    for f in (out / "linuxcnc").glob("*.comp") if (out / "linuxcnc").is_dir() else ():
        for line in f.read_text().splitlines():
            parts = line.split()
            if len(parts) == 3:
                try:
                    if max(abs(float(parts[1])), abs(float(parts[2]))) > 50:
                        return f"{f.name}: a trim of {parts[1]}"
                except ValueError:
                    return f"{f.name}: {line[:40]!r}"
    return None


#: The command words of the HAL files compensate writes; the `$ ` lines of the kinematics module's README.
HAL_WORDS = {"loadrt", "addf", "net", "setp"}
README_COMMANDS = ("$ sudo apt-get install linuxcnc-uspace-dev", "$ sudo halcompile --install ",
                   "$ linuxcnc fiveaxis.ini", "$ halcmd show pin ")


def _injected(out: Path) -> str | None:
    """What a payload in a path made of compensate's LinuxCNC files, or None: a HAL line that is not a command of
    ours, an INI a strict parser refuses (a second section), a README command line that is not ours."""
    import configparser
    for f in out.rglob("*.hal"):
        for line in f.read_text(errors="replace").splitlines():
            if line.strip() and not line.lstrip().startswith("#") and line.split()[0] not in HAL_WORDS:
                return f"{f.name}: {line[:60]!r}"
    for f in out.rglob("*.ini"):
        cp = configparser.ConfigParser(strict=True, interpolation=None, comment_prefixes=("#", ";"))
        try:
            cp.read_string(f.read_text(errors="replace"))
        except configparser.Error as exc:
            return f"{f.name}: {str(exc).splitlines()[0][:80]}"
    for f in out.rglob("README.txt"):
        for line in f.read_text(errors="replace").splitlines():
            if line.startswith("$") and not line.startswith(README_COMMANDS):
                return f"{f.name}: {line[:60]!r}"
    return None


def _kins_injected(out: Path) -> str | None:
    """A halcompile declaration from a machine file's name in a generated module (outside its // comments)."""
    for f in out.rglob("*_kins.comp"):
        head = f.read_text(errors="replace").split("\n;;\n", 1)[0]
        for line in head.splitlines():
            if not line.startswith("//") and re.search(r"injected|extra_link_args|CANARY|include|userspace", line):
                return f"{f.name}: {line[:60]!r}"
    return None


def classify(trial: Trial, rc, stdout: str, stderr: str, values: dict, marker: Path, tdir: Path) -> tuple[str, str]:
    if marker.exists() or (marker.parent / "PWNED").exists() or list(marker.parent.glob("ran*")) or \
            list(tdir.rglob("CANARY")):
        return "code-execution", "the marker file appeared"
    if rc is None:
        return "hang", f"no end within {trial.timeout:g} s"
    if "Traceback" in stderr:
        return "traceback", stderr.strip().splitlines()[-1][:200]
    if rc < 0 or rc not in (0, 1, 2):
        return "traceback", f"died with exit code {rc}"
    out = values["out"]
    if not _victims_untouched(tdir):
        return "silent", "a file the user had (or a link's target) was written"
    if rc == 0:
        if trial.expect == REFUSE:
            return "silent", "exit 0 where a refusal was expected"
        bad = _outputs_finite(out, stdout) or (_implausible_comp(out) if trial.check == "comp" else None)
        if bad:
            return "silent", f"non-finite or implausible output: {bad}"
        bad = _injected(out) if trial.check == "inject" else _kins_injected(out) if trial.check == "kins" else None
        if bad:
            return "silent", f"user text in a file a controller or a shell runs: {bad}"
        if trial.check == "hint" and "did you write um in a mm column" not in stderr:
            return "silent", "a unit slip without the hint"
        return "ok", ""
    if trial.check == "clean" and out.is_dir() and any(p.is_file() for p in out.rglob("*")):
        return "silent", f"a refusal left {sorted(p.name for p in out.rglob('*') if p.is_file())[:3]} behind"
    errors = [line for line in stderr.splitlines() if line.startswith("fiveaxis: error: ")]
    last = errors[-1] if errors else (stderr.strip().splitlines() or [""])[-1]
    if trial.expect == OK:
        return "refused-valid", last[:200]
    names = [str(n.format(**{k: str(v) for k, v in values.items()})) if "{" in n else n for n in trial.names]
    named = any(n and (n in last or Path(n).name in last) for n in names)
    if len(errors) != 1 or not (named or EXPECTED.search(last)):
        return "vague", last[:200]
    return "ok", last[:200]


def _kill_when_writing(proc, out: Path, t0: float, deadline: float):
    """SIGKILL proc the moment a file in out changes (written, replaced or removed) after t0."""
    before = {p: p.stat().st_mtime for p in out.rglob("*") if p.is_file()}
    while proc.poll() is None and time.monotonic() < deadline:
        now = {p: p.stat().st_mtime for p in out.rglob("*") if p.is_file() and not p.name.endswith(".tmp")}
        if set(now) != set(before) or any(now[p] != before[p] for p in now):
            break
        time.sleep(0.0005)
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def run_kill(runner: Runner, trial: Trial, tdir: Path, base: Path) -> Result:
    """Prepare the previous outputs (a complete earlier run), kill the command when it starts writing, then run the
    reader: it must refuse, or find one consistent set (all files older or all newer than the kill's start)."""
    out = tdir / "out"
    out.mkdir(parents=True)
    values = {"out": out, "base": base}
    t = time.monotonic()
    rc, _, err = runner.run(_subst(trial.argv, values), timeout=trial.timeout)
    if rc != 0:
        return Result(trial, "traceback" if "Traceback" in err else "ok", rc, time.monotonic() - t,
                      f"first run: {err.strip()[-150:]}")
    time.sleep(1.1)
    t0 = time.time()
    proc = subprocess.Popen(runner.command(_subst(trial.argv, values)), cwd=runner.work, env=runner.env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    _kill_when_writing(proc, out, t0, time.monotonic() + trial.timeout)
    files = sorted({p for pattern in trial.together for p in out.glob(pattern) if p.is_file()})
    newer = sorted(p.name for p in files if p.stat().st_mtime >= t0)
    older = sorted(p.name for p in files if p.stat().st_mtime < t0)
    rc, stdout, err = runner.run(_subst(trial.reader, values), timeout=trial.timeout)
    seconds = time.monotonic() - t
    if "Traceback" in err:
        return Result(trial, "traceback", rc, seconds, err.strip().splitlines()[-1][:200])
    if rc == 0 and newer and older:
        return Result(trial, "silent", rc, seconds, f"a mixed folder was used: new {newer}, old {older}")
    return Result(trial, "ok", rc, seconds, f"killed: new {newer[:4]}, old {older[:4]}; reader exit {rc}")


def run_trial(runner: Runner, trial: Trial, index: int, base: Path) -> Result:
    tdir = runner.work / "trials" / f"{index:04d}"
    if tdir.exists():
        shutil.rmtree(tdir, ignore_errors=True)
    tdir.mkdir(parents=True)
    if trial.kill:
        return run_kill(runner, trial, tdir, base)
    mdir = tdir / "marker"
    mdir.mkdir()
    marker = mdir / "ran"
    t = time.monotonic()
    try:
        values = _prepare(trial, tdir, base, marker)
    except Exception as exc:                          # a trial that cannot be set up is the corpus' bug
        return Result(trial, "traceback", None, 0.0, f"trial setup failed: {exc!r}")
    argv = _subst(trial.argv, values)
    rc, stdout, stderr = runner.run(argv, cwd=tdir, timeout=trial.timeout)
    cls, msg = classify(trial, rc, stdout, stderr, values, marker, tdir)
    return Result(trial, cls, rc, time.monotonic() - t, msg)


#: A fast subset for the test suite (tests/test_adversarial.py): one trial of each class of hostile input that
#: needs no base files (no fit, no compensation), a few seconds each.
#: (The shared base folder's fit and compensate cost 30 s: the um-in-mm ISO 230-3 file, which needs it, is
#: tests/test_iso230_3.py's in-process; the whole corpus is `make fuzz`.)
FAST = ("lsa ac_trunnion gcode: py", "lsa ac_trunnion gcode: ;py,", "lsa ac_trunnion gcode: o<$(shell)>",
        "lsa ac_trunnion gcode: NUL", "lsa ac_trunnion gcode: o<abs path>", "gsa machine: dev zero",
        "names machine: fifo", "table2 machine: deep tables", "gsa --errors model: deep JSON",
        "lsa toolpath csv: NaN", "model output: dangling link", "simulate --n 10000000000 -o {out}/s.csv",
        "compensate model: NaN literal", "sobol --bound inf", "plan --check program: fifo",
        "plan --check program: dev zero", "round 4: lsa --positions 100000000", "round 4: gsa --le 500 --axis X=0")


def round4() -> list[Trial]:
    """The trials of round 4 (issue 28, issue 34): classes kept as tables above."""
    out = []
    small = ["--nodes", "X=2,Y=2,Z=2", "--poses", "200", "--comp-points", "9"]
    for name, filename in HOSTILE_MODEL_NAMES.items():
        out.append(Trial(f"compensate model name: {name}", "compensate", ["compensate", "{f}", "-o", "{out}", *small],
                         OK, (), ("model-copy", "{base}/model.json"), check="inject", filename=filename))
    for name, filename in HOSTILE_MACHINE_NAMES.items():
        out.append(Trial(f"derive machine name: {name}", "derive", ["derive", "{f}", "--out", "{out}/gen"], OK, (),
                         ("copy", "{base}/li2018.toml"), check="kins", filename=filename))
    for name, (rel, kind) in PLANTED_LINKS.items():
        out.append(Trial(f"compensate link in the folder: {name}", "compensate",
                         ["compensate", "{base}/model.json", "-o", "{out}", "--force", *small], REFUSE,
                         ("symbolic link",), (f"outlink:{rel}", kind)))
    for name, (maker, content, expect) in PROGRAM_FILES.items():
        out.append(Trial(f"plan --check program: {name}", "plan", ["plan", "--check", "{f}"], expect, ("{f}",),
                         (maker, content), suffix=".ngc"))
    for name, edit in EFFECT_EDITS.items():
        out.append(Trial(f"compensate model effect: {name}", "compensate", ["compensate", "{f}", "-o", "{out}",
                                                                            *small], REFUSE,
                         ("{f}", "effects[0]"), ("json-edit", ("model_p.json", _effects_edit(edit))), check="clean",
                         suffix=".json"))
    for argv, expect, names, check in ROUND4:
        out.append(Trial("round 4: " + " ".join(argv)[:100], argv[0], argv, expect, names, check=check))
    for name, (maker, content, expect) in MEASUREMENT_FILES_4.items():
        for cmd, argv in COMMANDS_READING_MEASUREMENTS.items():
            out.append(Trial(f"{cmd} measurements: {name}", cmd, argv, expect, ("{f}", "did you mean", "decimal"),
                             (maker, content), suffix=".csv", check="clean"))
    return out


def _uses_base(trial: Trial) -> bool:
    return any("{base}" in a for a in trial.argv + (trial.reader or [])) or (
        trial.file is not None and any(str(x).endswith((".json", ".csv")) or "{base}" in str(x)
                                       for x in (trial.file[1] if isinstance(trial.file[1], tuple) else
                                                 (trial.file[1],)))) or (
        trial.file is not None and trial.file[0].startswith(("summary:", "json-edit", "csv-edit", "parquet",
                                                             "toml-edit", "copy")))


def run_all(runner: Runner, selected: list[Trial], jobs: int = 2, progress=True) -> list[Result]:
    base = runner.work / "base"
    if any(_uses_base(t) for t in selected):
        make_base(base, lambda argv: runner.run(argv))
    else:
        base.mkdir(parents=True, exist_ok=True)
    results = [None] * len(selected)
    with cf.ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(run_trial, runner, t, i, base): i for i, t in enumerate(selected)}
        for n, fut in enumerate(cf.as_completed(futures), 1):
            i = futures[fut]
            results[i] = fut.result()
            if progress:
                r = results[i]
                print(f"[{n}/{len(selected)}] {r.cls:14s} {r.seconds:6.1f}s  {r.trial.id[:70]}"
                      + (f"  -- {r.message[:100]}" if r.cls != "ok" else ""), file=sys.stderr, flush=True)
    return results


def totals(results) -> dict:
    out = {c: 0 for c in CLASSES}
    for r in results:
        out[r.cls] += 1
    return out


def table(results) -> str:
    by_cmd: dict = {}
    for r in results:
        by_cmd.setdefault(r.trial.command, {c: 0 for c in CLASSES})[r.cls] += 1
    head = f"{'command':12s} " + " ".join(f"{c[:9]:>9s}" for c in CLASSES) + "    total"
    lines = [head]
    for cmd, t in sorted(by_cmd.items()):
        lines.append(f"{cmd:12s} " + " ".join(f"{t[c]:9d}" for c in CLASSES) + f" {sum(t.values()):8d}")
    t = totals(results)
    lines.append(f"{'all':12s} " + " ".join(f"{t[c]:9d}" for c in CLASSES) + f" {sum(t.values()):8d}")
    bad = [r for r in results if r.cls != "ok"]
    if bad:
        lines.append("")
        lines += [f"{r.cls:14s} {r.trial.id}: {r.message}" for r in bad]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, default=None, help="work folder (default: a new temporary one)")
    ap.add_argument("--pythonpath", default=None, help="PYTHONPATH of the code under test (default: installed)")
    ap.add_argument("--python", default=sys.executable)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=TIMEOUT, help=f"seconds per trial (default {TIMEOUT:g})")
    ap.add_argument("--only", action="append", default=None, help="only trials whose id contains this (repeatable)")
    ap.add_argument("--again", type=Path, default=None,
                    help="only the trials that were not ok in a results file of --json (ids as they are now)")
    ap.add_argument("--list", action="store_true", help="list the trials and exit")
    ap.add_argument("--json", type=Path, default=None, help="also write the results as JSON")
    args = ap.parse_args(argv)
    selected = [t for t in trials() if args.only is None or any(o in t.id for o in args.only)]
    if args.again is not None:
        bad = {r["id"] for r in json.loads(args.again.read_text()) if r["class"] != "ok"}
        selected = [t for t in selected if t.id in bad]
    if args.list:
        for t in selected:
            print(f"{t.command:11s} {t.expect:7s} {t.id}")
        print(f"{len(selected)} trials", file=sys.stderr)
        return 0
    for t in selected:
        if not t.kill:
            t.timeout = args.timeout
    import tempfile
    work = args.work or Path(tempfile.mkdtemp(prefix="fiveaxis-adversarial-"))
    runner = Runner(work, args.python, args.pythonpath)
    t = time.monotonic()
    results = run_all(runner, selected, args.jobs)
    print(table(results))
    print(f"\n{len(results)} trials in {time.monotonic() - t:.0f} s (work folder {work}); classes: "
          + ", ".join(f"{c} {n}" for c, n in totals(results).items()))
    if args.json:
        args.json.write_text(json.dumps([{"id": r.trial.id, "command": r.trial.command, "class": r.cls, "rc": r.rc,
                                          "seconds": round(r.seconds, 2), "message": r.message} for r in results],
                                        indent=1))
    t = totals(results)
    return 1 if any(t[c] for c in ("code-execution", "traceback", "hang", "silent")) else 0


if __name__ == "__main__":
    sys.exit(main())
