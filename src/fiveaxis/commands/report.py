"""`fiveaxis report`: the calibration report of a measurement file as one self-contained HTML page (and PDF)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from . import options
from ..exceptions import InputError
from .iso230_3 import spindle, thermal_options


def register_report(p):
    p.add_argument("file", type=Path, help="measurements: CSV or Parquet, one row per pose (as for `fiveaxis fit`)")
    options.machine(p)
    options.convention(p)
    p.add_argument("--frame", default=None, choices=("workpiece", "machine"),
                   help="frame of the deviations (default: the file's frame column, else workpiece)")
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="add an effect to the model before the first round, e.g. ex_x:x1 or E_AX:x1 (repeatable)")
    p.add_argument("--rounds", type=int, default=4,
                   help="diagnosis rounds at most: diagnose, add the top candidate, repeat (default 4)")
    p.add_argument("--compensation", type=Path, default=None, metavar="DIR",
                   help="folder of a compensation run: summary.json (predicted error before/after, mm) and maps")
    p.add_argument("--iso230-3", type=Path, default=None, metavar="FILE",
                   help="an ISO 230-3 thermal test file (docs/iso230-3.md): its section, with the options below")
    thermal_options(p)
    p.add_argument("--no-sensitivity", action="store_true", help="leave out the machine's GSIL section")
    p.add_argument("--title", default=None, help="title of the report (default: from the machine file)")
    p.add_argument("-o", "--output", type=Path, required=True, help="the HTML file to write")
    p.add_argument("--pdf", nargs="?", const=True, default=None, metavar="PDF",
                   help="also print a PDF with headless Chromium (default name: the HTML file's, .pdf)")
    options.json_output(p, "also print the report's record (without figures) as JSON")
    options.force(p)
    p.set_defaults(func=run_report)


def run_report(args) -> int:
    from ..outputs import target, write_text
    from ..report import html, record
    if args.output.suffix.lower() not in (".html", ".htm"):
        raise InputError(f"-o {args.output}: expected an .html file")
    pdf = None
    if args.pdf is not None:
        pdf = args.output.with_suffix(".pdf") if args.pdf is True else Path(args.pdf)
        if pdf.suffix.lower() != ".pdf":
            raise InputError(f"--pdf {pdf}: expected a .pdf file")
        target(pdf, args.force)
    target(args.output, args.force)
    if args.rounds < 1:
        raise InputError(f"--rounds: expected a positive number, got {args.rounds}")
    thermal = None
    if args.iso230_3 is not None:                 # checked before the fit: a bad file ends the run at once
        from ..report.iso230_3 import section
        thermal = section(args.iso230_3, args.test, spindle(args), args.spacing)
    sensitivity = not args.no_sensitivity
    if sensitivity:                               # GSIL integrates over a cutting length: a machine without a tool
        from ..model.machine import load_machine
        m = load_machine(args.machine)
        if not 0 < m.cutting_length <= m.tool_length:
            print(f"fiveaxis: warning: {m.path}: tool.length {m.tool_length:g} mm, tool.cutting_length "
                  f"{m.cutting_length:g} mm: no cutting tool to rank the errors for, so the report leaves out the "
                  f"sensitivity (GSIL)", file=sys.stderr)
            sensitivity = False
    rep = record.build(args.file, args.machine, args.convention, args.add, args.compensation, args.rounds,
                       sensitivity=sensitivity, title=args.title, frame=args.frame)
    if thermal is not None:
        rep.record["iso230_3"], figs = thermal
        rep.figures.update(figs)
    write_text(args.output, html.render(rep), force=args.force)
    path = args.output
    print(f"fiveaxis: wrote {path} ({path.stat().st_size / 1e6:.2f} MB): {rep.record['verdict']['headline']}",
          file=sys.stderr)
    if pdf is not None:
        from ..report.pdf import print_pdf
        out = print_pdf(path, pdf, force=args.force)
        print(f"fiveaxis: wrote {out} (PDF printed by headless Chromium)", file=sys.stderr)
    if args.json:
        print(json.dumps(rep.record, indent=1))
    return 0
