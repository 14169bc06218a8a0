"""`fiveaxis report`: the calibration report of a measurement file as one self-contained HTML page (and PDF); with
a campaign (`--campaign FILE.toml`, `--set KEY=VALUE`) a calibration certificate, also as a DCC (XML)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from . import options
from ..exceptions import InputError
from .iso230 import uncertainty_inputs, uncertainty_options
from .iso230_3 import spindle, thermal_options


def register_report(p):
    p.add_argument("file", type=Path, nargs="+",
                   help="measurements: CSV or Parquet, one row per pose (as for `fiveaxis fit`); several files: one "
                        "joint fit, each file with its own instrument, setups and noise")
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
    p.add_argument("--campaign", type=Path, default=None, metavar="FILE.toml",
                   help="the calibration campaign (customer, machine and serial, place, dates, environment, "
                        "instruments with their certificates, procedure, operator, approval; docs/report.md): the "
                        "report becomes a calibration certificate")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="sets",
                   help="a campaign key, e.g. customer.name=ACME or dates.begin=2025-03-10 (repeatable; over the "
                        "campaign file's)")
    uncertainty_options(p)
    p.add_argument("-o", "--output", type=Path, required=True, help="the HTML file to write")
    p.add_argument("--pdf", nargs="?", const=True, default=None, metavar="PDF",
                   help="also print a PDF with headless Chromium (default name: the HTML file's, .pdf)")
    p.add_argument("--dcc", nargs="?", const=True, default=None, metavar="XML",
                   help="also write the certificate as a PTB Digital Calibration Certificate (DCC 3.3.0 XML; needs "
                        "a campaign; default name: the HTML file's, .xml)")
    options.reference_temperature(p)
    options.json_output(p, "also print the report's record (without figures) as JSON")
    options.force(p)
    p.set_defaults(func=run_report)


def _beside(output: Path, given, suffix: str, option: str) -> Path | None:
    """The path of an extra output: given (True: the HTML file's name with suffix), None when not asked for."""
    if given is None:
        return None
    path = output.with_suffix(suffix) if given is True else Path(given)
    if path.suffix.lower() != suffix:
        raise InputError(f"{option} {path}: expected a {suffix} file")
    return path


def _step(text: str) -> None:
    """One line on stderr per step of the report (its rounds, figures, sensitivity: seconds each)."""
    print(f"fiveaxis: report: {text}", file=sys.stderr, flush=True)


def run_report(args) -> int:
    from ..iso230 import uncertainty as U
    from ..outputs import target, write_text
    from ..report import campaign as CP
    from ..report import html, record
    if args.output.suffix.lower() not in (".html", ".htm"):
        raise InputError(f"-o {args.output}: expected an .html file")
    pdf = _beside(args.output, args.pdf, ".pdf", "--pdf")
    xml = _beside(args.output, args.dcc, ".xml", "--dcc")
    camp = CP.load(args.campaign, args.sets)
    if xml is not None and camp is None:
        raise InputError("--dcc: a Digital Calibration Certificate needs the campaign (--campaign FILE.toml or "
                         "--set KEY=VALUE: customer, machine serial, dates, instruments, operator)")
    inputs = dict(CP.iso230_9(camp), **uncertainty_inputs(args))
    statement = U.check(U.Statement(**inputs))
    for path in (p for p in (pdf, xml) if p is not None):
        target(path, args.force)
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
                       sensitivity=sensitivity, title=args.title, frame=args.frame, campaign=camp,
                       uncertainty=statement, references=options.references_of(args.reference_temperature),
                       progress=_step)
    if thermal is not None:
        rep.record["iso230_3"], figs = thermal
        rep.figures.update(figs)
    _step("the page")
    page = html.render(rep)
    if xml is not None:
        from ..report import dcc
        certificate = dcc.write(rep.record)          # made before any file is written: all or nothing
    write_text(args.output, page, force=args.force)
    path = args.output
    print(f"fiveaxis: wrote {path} ({path.stat().st_size / 1e6:.2f} MB): {rep.record['verdict']['headline']}",
          file=sys.stderr)
    if xml is not None:
        write_text(xml, certificate, force=args.force)
        print(f"fiveaxis: wrote {xml} (Digital Calibration Certificate, DCC {dcc.SCHEMA_VERSION})", file=sys.stderr)
    if pdf is not None:
        from ..report.pdf import print_pdf
        out = print_pdf(path, pdf, force=args.force)
        print(f"fiveaxis: wrote {out} (PDF printed by headless Chromium)", file=sys.stderr)
    if args.json:
        print(json.dumps(rep.record, indent=1))
    return 0
