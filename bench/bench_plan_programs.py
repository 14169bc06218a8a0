"""The worst deviations of measurement programs (docs/plan.md, "Before and after"): every program DIR/M-I.ngc (machine
M, instrument I) measured with the checker (fiveaxis.planning.safety) and with the independent reference of
tests/test_plan_programs.py (rs274's output parsed and sampled there, a plain NumPy chain).

    .venv/bin/python bench/bench_plan_programs.py DIR new            # programs `fiveaxis plan` writes now
    .venv/bin/python bench/bench_plan_programs.py DIR first-pose     # programs of commit 9c35ea1 (see below)
    .venv/bin/python bench/bench_plan_programs.py DIR as-written

Programs of 9c35ea1 say nothing machine-readable about their instrument; they are annotated (DIR/M-I.annotated.ngc)
from their setup comments: the instrument mounted at the first pose of each setup (first-pose: only the moves
between measuring poses count), or at the M0 at which the comments tell the operator to set up (as-written).
Making them without touching the repository:
    mkdir /tmp/old && git archive 9c35ea1 src | tar -x -C /tmp/old
    cd DIR && PYTHONPATH=/tmp/old/src /path/to/.venv/bin/python -m fiveaxis.cli plan --machine M --instrument I \
        --n N --seed 0 -o M-I.csv          (rtest 30, probe-sphere 12, ballbar 96, interferometer 30 with --effects
                                            dx_x:x1, tracker 40)
Output, one line per program: machine | instrument | mode | the first limit's worst (checker) | the same from the
reference | strokes (checker) | the largest stroke excess (reference) | the other limits | rule problems.
--write MACHINE-INSTRUMENT:N (repeatable) first writes DIR/MACHINE-INSTRUMENT.ngc with `fiveaxis plan` (N poses, seed
0); the smoke test: DIR new --write ac_trunnion-rtest:12."""
import argparse
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import test_plan_programs as T   # noqa: E402
import fiveaxis                 # noqa: E402
from fiveaxis.cli import main as cli  # noqa: E402
from fiveaxis.planning import safety  # noqa: E402


def annotate(text, machine, instrument, how):
    lines = text.splitlines()
    out = [lines.pop(0), f"(fiveaxis: program instrument={instrument} machine={machine} kinematics=joint)"]
    mounted = False
    pending = None          # the mount comment waiting for the first pose's move
    for ln in lines:
        m = re.match(r"\(tool length L = ([\d.]+) mm", ln)
        if m:
            if mounted:
                out += ["(fiveaxis: unmount)", "(MSG, remove)", "M0"]
                mounted = False
            out += [f"(fiveaxis: tool length={float(m.group(1)):.4f})", "(MSG, tool)", "M0"]
        m = re.match(r"\(setup (\S+): (.*)\)$", ln)
        if m:
            note = m.group(2)
            if instrument in ("rtest", "probe-sphere"):
                c = re.search(r"sphere at \[([^\]]+)\]", note).group(1)
                tag = f"(fiveaxis: mount centre={c.replace(' ', '')})"
            elif instrument == "ballbar":
                c = re.search(r"pivot at \[([^\]]+)\]", note).group(1)
                r = re.search(r"radius ([\d.]+) mm", note).group(1)
                tag = f"(fiveaxis: mount pivot={c.replace(' ', '')} length={r})"
            elif instrument == "interferometer":
                axis = re.search(r"beam along (\w)", note).group(1)
                tag = f"(fiveaxis: mount axis={axis})"
            elif instrument == "tracker":
                c = re.search(r"station at \[([^\]]+)\]", note).group(1)
                tag = f"(fiveaxis: mount station={c.replace(' ', '')})"
            else:
                tag = None
            if mounted:
                out += ["(fiveaxis: unmount)", "(MSG, remove)", "M0"]
                mounted = False
            pending = tag
        if ln.startswith("M0") and pending and how == "as-written":
            out += [pending, "(MSG, mount)"]
            mounted, pending = True, None
        out.append(ln)
        if pending and how == "first-pose" and re.match(r"G[01] ", ln):
            out += [pending, "(MSG, mount)", "M0"]
            mounted, pending = True, None
    if mounted:
        i = max(k for k, x in enumerate(out) if x.startswith("M2"))
        out[i:i] = ["(fiveaxis: unmount)", "(MSG, remove)", "M0"]
    return "\n".join(out) + "\n"


def main(argv=None) -> list:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("how", choices=("new", "first-pose", "as-written"))
    ap.add_argument("--write", action="append", default=[], metavar="MACHINE-INSTRUMENT:N",
                    help="write this program with `fiveaxis plan` first")
    a = ap.parse_args(argv)
    folder, how = a.folder, a.how
    for spec in a.write:
        name, _, n = spec.rpartition(":")
        machine, instrument = name.split("-", 1)
        rc = cli(["plan", "--machine", machine, "--instrument", instrument, "--n", n, "--seed", "0", "-o",
                  str(folder / f"{name}.csv"), "--force"])
        if rc:
            sys.exit(f"fiveaxis plan {spec} failed ({rc})")
    rows = []
    for prog in sorted(Path(folder).glob("*.ngc")):
        if prog.name.endswith(".annotated.ngc"):
            continue
        machine, instrument = prog.stem.split("-", 1)
        model = fiveaxis.load(machine)
        path = prog
        if how != "new":
            path = prog.with_suffix(".annotated.ngc")
            path.write_text(annotate(prog.read_text(), machine, instrument, how))
        chk = safety.check(path, model, instrument)
        mode = chk.kinematics
        steps = T.reference(machine, model, path, mode, model.machine.tool_length)
        try:
            ind = T.independent_worst(machine, model, steps, instrument)
        except AssertionError as exc:
            ind = {"stroke": float("nan"), "note": str(exc)}
        main_ = chk.worst[0] if chk.worst else None
        rows.append((machine, instrument, mode,
                     f"{main_.limit.name}: {main_.value:.4g} {main_.limit.unit} (line {main_.line}, limit "
                     f"{main_.limit.limit:g})" if main_ and main_.value is not None else "-",
                     f"{ind['value'][0]:.4g}" if "value" in ind else "-",
                     f"{chk.stroke_violations} moves outside, worst {max(chk.stroke_excess, 0):.4g} "
                     f"{chk.stroke_unit}",
                     f"{max(ind['stroke'], 0):.4g}",
                     "; ".join(f"{w.limit.name} {w.value:.4g} {w.limit.unit}" for w in chk.worst[1:]
                               if w.value is not None),
                     len([p for p in chk.problems if "without an operator message" in p[1]])))
    for r in rows:
        print(" | ".join(str(x) for x in r))
    return rows


if __name__ == "__main__":
    main()
