#!/usr/bin/env python3
"""Every text a person reads from the README's examples, written to a folder, to compare two versions byte by byte.

    scripts/text-snapshot.py OUT [--bin .venv/bin] [--only NAME,...] [--src DIR]   then: diff -r BEFORE AFTER

Each case runs one `fiveaxis` command (as the README and `make run` show it) in a scratch folder of data made by
`fiveaxis simulate` with fixed seeds, and writes its stdout and stderr to OUT/NAME.txt; what changes from run to
run by design (the report's generation time, seconds measured, the scratch folder's path) is masked. Exit status
0; a case that fails keeps its stderr in its file, so a change of that shows as well.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "li2018_measurements.csv"

#: Data made once per snapshot, in order: (file name, simulate arguments).
DATA = (
    ("m.csv", "simulate --effect ex_x:x1=2e-5 --effect L:t1=0.008 --n 1500 --noise 0.001 --seed 1 -o m.csv"),
    ("r.csv", "simulate --machine ac_trunnion --instrument rtest --n 600 --effect dx_C:C1=0.01 --seed 2 "
              "--with-sigma -o r.csv"),
    ("ball.csv", "simulate --machine li2018 --instrument ballbar --n 600 --effect dx_x:xr=0.003 --seed 3 "
                 "-o ball.csv"),
    ("laser.csv", "simulate --machine ac_trunnion --instrument interferometer --axes X --targets 9 "
                  "--effect dx_x:xk100=0,0.012,-0.008,0.015,-0.004,0.003,-0.015,0.009,-0.005 "
                  "--effect dx_x:xr=0.0125 --seed 3 -o laser.csv"),
    ("c.csv", "simulate --machine ac_trunnion --effect dx_x:x2 --effect ex_x:x1 --seed 4 --n 1000 -o c.csv"),
)

#: (name, command line after `fiveaxis`); {EXAMPLE} is the bundled example.
CASES = (
    ("gsa_paper", "gsa --convention printed --preset paper --compensate"),
    ("gsa_trunnion", "gsa --machine ac_trunnion --compensate"),
    ("lsa_toolpath", "lsa --machine ac_trunnion --toolpath " + str(ROOT / "examples" / "ac_trunnion_sphere.ngc")
     + " --surface sphere:50,30,20 --compensate --top 6 --segments 6"),
    ("lsa_pose", "lsa --machine tilting_head --pose X=100,Y=0,Z=300,B=30,C=45 --compensate"),
    ("lsa_cone", "lsa --convention printed --cone 2 --compensate"),
    ("sobol", "sobol --machine tilting_head --samples 64"),
    ("fit", "fit m.csv"),
    ("diagnose", "diagnose m.csv"),
    ("diagnose_add", "diagnose m.csv --add ex_x:x1"),
    ("fit_rtest", "fit r.csv --machine ac_trunnion"),
    ("diagnose_rtest", "diagnose r.csv --machine ac_trunnion"),
    ("iso230_2", "iso230-2 laser.csv --machine ac_trunnion --u-device 0.4 --temperature-deviation 0.5 "
                 "--expansion-ppm-per-K 2 --misalignment 0.5 --drift 0.2"),
    ("iso230_2_plain", "iso230-2 laser.csv --machine ac_trunnion"),
    ("iso230_2_json", "iso230-2 laser.csv --machine ac_trunnion --u-device 0.4 --json"),
    ("iso230_4", "iso230-4 ball.csv --feed 1000"),
    ("iso230_4_json", "iso230-4 ball.csv --feed 1000 --json"),
    ("fit_model", "fit c.csv --machine ac_trunnion --add dx_x:x2 --add ex_x:x1 -o model.json --force"),
    ("compensate", "compensate model.json -o comp --force"),
    ("report_example", "report {EXAMPLE} -o ex.html --json --force"),
    ("report_rtest", "report r.csv --machine ac_trunnion -o rt.html --json --force --no-sensitivity"),
    ("report_laser", "report laser.csv --machine ac_trunnion -o laser.html --json --force --no-sensitivity"),
    ("report_comp", "report c.csv --machine ac_trunnion --compensation comp -o comp.html --json --force "
                    "--no-sensitivity"),
    ("names", "names --machine ac_trunnion"),
)

ENV = dict(os.environ)
MASKS = ((re.compile(r'"generated": "[^"]*"'), '"generated": "(masked)"'),
         (re.compile(r"\d+(\.\d+)? s\b"), "(seconds)"),
         (re.compile(r"\(\d+\.\d\d MB\)"), "(size MB)"))


def run(bin_dir: Path, line: str, cwd: Path) -> str:
    args = [str(bin_dir / "fiveaxis")] + line.replace("{EXAMPLE}", str(EXAMPLE)).split()
    p = subprocess.run(args, cwd=cwd, capture_output=True, text=True, env=ENV)
    text = p.stdout + ("\n--- stderr\n" + p.stderr if p.stderr else "") + f"\n--- exit {p.returncode}\n"
    text = text.replace(str(cwd), "SCRATCH")
    for rx, repl in MASKS:
        text = rx.sub(repl, text)
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--bin", type=Path, default=ROOT / ".venv" / "bin")
    ap.add_argument("--only", default=None, help="comma-separated case names")
    ap.add_argument("--src", type=Path, default=None,
                    help="run the package of this src folder (e.g. `git archive BASE src` unpacked) instead")
    a = ap.parse_args(argv)
    if a.src is not None:
        ENV["PYTHONPATH"] = str(a.src.resolve())
    only = set(a.only.split(",")) if a.only else None
    a.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        cwd = Path(tmp)
        for name, line in DATA:
            run(a.bin, line, cwd)
        for name, line in CASES:
            if only and name not in only:
                continue
            (a.out / f"{name}.txt").write_text(run(a.bin, line, cwd))
            print(f"{name}: {line}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
