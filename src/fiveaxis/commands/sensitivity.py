"""`fiveaxis gsa`, `fiveaxis lsa` and `fiveaxis sobol`: sensitivity indices and the compensation experiments,
on any machine.

gsa: GSIL over the machine's workspace (its file's [workspace] table, else its strokes), or a named preset
     (`--preset paper`: Sect. 4.2); `--compensate` halves the vital / other / all errors at the diagonal points
     of the workspace (Fig. 16).
lsa: LSIL along a toolpath (`--toolpath` CSV or G-code, `--pose`), or at the cone positions of Tables 3-4
     (`--cone`, li2018); per segment too; `--compensate` the same experiment along the path (Fig. 11).
sobol: Sobol' total indices (SALib) over the same workspace, compared with the GSIL ranking.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from . import options
from ..exceptions import InputError

#: Default most poses of one run (fiveaxis.guards): gsa and sobol evaluate and forget (10^9), lsa keeps 41
#: indices per pose in memory (10^6).
GSA_MAX_POSES = 10 ** 9
LSA_MAX_POSES = 10 ** 6
#: Segments listed in the text output of a toolpath (all are in --json).
SEGMENTS_SHOWN = 20


# -- shared options ----------------------------------------------------------------------------------------------
def _order(text):
    """--order: an integer (Gauss-Legendre) or 'exact'; range checks happen in sensitivity.quadrature."""
    if text is None or text == "exact":
        return text
    try:
        return int(text)
    except ValueError:
        raise InputError(f"--order: expected an integer or 'exact', got {text!r}") from None


def _count(text: str) -> int:
    """--max-poses: a positive whole number, also written as 1e9."""
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v) or v < 1 or v != int(v):
        import argparse
        raise argparse.ArgumentTypeError(f"expected a positive whole number such as 1e9, got {text!r}")
    return int(v)


def _common(p, le_default: str, order_default: str, max_poses: int):
    options.machine(p)
    options.convention(p)
    options.json_output(p, "print {indices, ranking, settings} as JSON")
    p.add_argument("--plot", type=Path, metavar="DIR", help="write PNG plots into DIR (their paths go to stderr)")
    p.add_argument("--l0", type=float, default=None,
                   help="tool length L0, mm (default: the machine file's; li2018: 200, the paper's)")
    p.add_argument("--le", type=float, default=None,
                   help=f"effective cutting length LE, mm, at most L0 (default: {le_default})")
    p.add_argument("--order", default=None, metavar="N|exact",
                   help="integral over [L0-LE, L0]: Gauss-Legendre of order N, or 'exact' (closed form; W_i only) "
                        f"(default: {order_default})")
    p.add_argument("--errors", action="append", default=[], metavar="FILE|NAME=VALUE",
                   help="error values (mm, rad): NAME=VALUE, a file of NAME=VALUE lines, a JSON object, or a fitted "
                        "model (`fiveaxis fit ... -o model.json`); repeatable, applied in order; errors not named keep "
                        "the machine file's values (li2018: all 1e-4, the value behind the paper's rankings)")
    p.add_argument("--top", type=int, default=10, help="rows of the printed ranking (default 10)")
    p.add_argument("--max-poses", type=_count, default=max_poses, metavar="N",
                   help=f"refuse a run of more than N pose evaluations before starting it (default {max_poses:.0e})")


def _model(args):
    from ..model.error_model import load
    return load(args.machine, args.convention)


def _setup(args, L0_default=None, LE_default=None):
    """(model, ErrorValues, L0, LE) of a sensitivity command: L0 and LE (mm) from the options, else the given
    defaults, else the machine file's tool data; both checked before anything runs."""
    from ..model.error_values import read
    from ..sensitivity.indices import quadrature
    if args.top < 1:
        raise InputError(f"--top: expected a positive number of rows, got {args.top}")
    model = _model(args)
    ev = read(model, args.errors)
    L0 = args.l0 if args.l0 is not None else (L0_default if L0_default is not None else model.machine.tool_length)
    LE = args.le if args.le is not None else (LE_default if LE_default is not None else model.machine.cutting_length)
    try:
        quadrature(L0, LE, 1)                # L0 > 0, 0 < LE <= L0, finite
    except InputError as exc:               # lengths the user did not give: the machine file's, named as such
        given = {"L0": args.l0 is not None or L0_default is not None,
                 "LE": args.le is not None or LE_default is not None}
        keys = (exc.key,) if isinstance(exc.key, str) else tuple(exc.key or ())
        if keys and not any(given.get(k, True) for k in keys):
            raise InputError(f"{model.machine.path}: tool.length {model.machine.tool_length:g} mm, "
                             f"tool.cutting_length {model.machine.cutting_length:g} mm: {exc} (the machine file's; "
                             f"give the tool with --l0 and --le, mm)") from None
        raise
    if args.plot is not None and args.plot.exists() and not args.plot.is_dir():
        raise InputError(f"--plot {args.plot}: exists and is not a directory")
    return model, ev, L0, LE


def _error_settings(settings, ev):
    settings["errors"] = ev.label()
    if ev.kept:
        settings["errors_undetermined_kept"] = list(ev.kept)
    if ev.left_out:
        settings["errors_left_out_parameters"] = list(ev.left_out)


def _dump(out):
    try:
        print(json.dumps(out, indent=1, allow_nan=False))
    except ValueError:
        raise InputError("a computed number is not finite (NaN or inf): no JSON written; please report this "
                         "with the command line") from None


def _wrote(paths):
    for p in paths:
        print(f"fiveaxis: wrote {p}", file=sys.stderr)


def _grid(args, model):
    """(grid, description of where it comes from, L0 default, LE default) for gsa, sobol and dask."""
    from ..sensitivity import paper as presets
    from ..sensitivity.grid import describe_source, workspace_grid
    base, L0, LE = None, None, None
    if getattr(args, "preset", None):
        base = presets.workspace_preset(args.preset, model)
        source = f"preset {args.preset} ({presets.WORKSPACE_PRESETS[args.preset]})"
        L0, LE = presets.WORKSPACE_L0, presets.WORKSPACE_LE
    else:
        source = describe_source(model.machine)
    grid = workspace_grid(model.machine, args.axis, base)
    if args.axis:
        source += "; changed by --axis " + " ".join(args.axis)
    return grid, source, L0, LE


def _rows_json(rows):
    return [{"scenario": r.scenario, "value": r.value, "improvement": r.improvement,
             "improvement_pct": r.improvement_pct} for r in rows]


def _vital(result, paper_vital=None):
    """(vital errors, how they were chosen) for a compensation experiment."""
    from ..sensitivity.experiments import VITAL_MAX_RANK, vital_set
    if paper_vital is not None:
        return list(paper_vital), "the paper's vital set"
    v = vital_set(result.names, result.proportions)
    p = dict(zip(result.names, result.proportions))
    order = result.ranking
    drop = (f", {100 * p[order[len(v) - 1]]:.2f}% -> {100 * p[order[len(v)]]:.2f}%"
            if len(v) < len(order) else "")
    return v, (f"this run's {len(v)} largest {'PG_i' if result.kind == 'GSIL' else 'PL_i'}: above the largest "
               f"relative drop between consecutive proportions within the first {VITAL_MAX_RANK} ranks{drop}")


# -- gsa -----------------------------------------------------------------------------------------------------------
def _workspace_options(p):
    p.add_argument("--preset", choices=("paper",), default=None,
                   help="a named workspace instead of the machine's: 'paper' = Sect. 4.2 (li2018 kinematics; X 21, "
                        "Y 9, Z 5, A 13, B 13 points; L0 200 mm, LE 30 mm)")
    p.add_argument("--axis", action="append", default=[], metavar="NAME=LO:HI:COUNT",
                   help="grid of one axis (mm; degrees for rotary axes; within the stroke), or NAME=VALUE to fix it; "
                        "repeatable. Default: the machine file's [workspace] table, else its strokes, 5 points each")


def register_gsa(p):
    _common(p, "the machine file's; li2018: 30, Sect. 4.2", "exact when the kernels have it, else 8", GSA_MAX_POSES)
    _workspace_options(p)
    p.add_argument("--chunk", type=int, default=None, help="poses per chunk (bounded memory; default 2**20)")
    bar = p.add_mutually_exclusive_group()
    bar.add_argument("--progress", action="store_true", default=None,
                     help="always show the progress bar (default: for long runs, also in logs)")
    bar.add_argument("--no-progress", dest="progress", action="store_false", help="never show the progress bar")
    p.add_argument("--compensate", action="store_true",
                   help="also halve the vital / other / all errors and average the tool's position and posture "
                        "error at the diagonal points of the workspace over its rotary axes (Fig. 16); vital: the "
                        "paper's four with --preset paper, else this run's own (see docs/sensitivity.md)")
    p.add_argument("--points", default="quarter", choices=("quarter", "corner"),
                   help="the points: quarter marks of the body diagonals of the linear axes (default) or the "
                        "corners, and the centre")
    p.add_argument("--rot-count", type=int, default=13,
                   help="points per rotary axis for --compensate (default 13; 1: the middle of the range)")
    p.add_argument("--no-reduce", dest="reduce", action="store_false",
                   help="evaluate every grid pose, also along axes that appear in no J (X for li2018); "
                        "by default such an axis is evaluated once and weighted by its count (exact)")
    p.set_defaults(func=run_gsa)


def _compensate_gsa(args, model, errors, grid, L0, res):
    from ..sensitivity import experiments, paper as presets
    from ..guards import check_size
    if args.rot_count < 1:
        raise InputError(f"--rot-count: expected at least 1 point per rotary axis, got {args.rot_count}")
    check_size(experiments.point_count(model, args.rot_count) * 8, "poses", args.max_poses, "--max-poses {n}",
               f"--compensate: points x {args.rot_count} per rotary axis x 4 scenarios x 2 measures")
    paper = args.preset == "paper"
    vital, why = _vital(res, presets.PAPER_VITAL["workspace"] if paper else None)
    box = presets.paper_box(model) if paper else {a.name: (a.lo, a.hi) for a in grid.axes}

    def run(e):
        return experiments.point_errors(model, box, e, args.rot_count, args.points, L0)

    comp = {key: experiments.compensation(errors, vital, lambda e: run(e)[key],
                                          f"the average {key.split('_')[0]} error at the points")
            for key in ("position_mm", "posture_rad")}
    return vital, why, comp, run


def run_gsa(args) -> int:
    from ..report import sensitivity_text as S
    from ..sensitivity import paper as presets
    from ..sensitivity.experiments import scenario_errors
    from ..sensitivity.indices import CHUNK, gsil
    if args.rot_count < 1:                        # checked even without --compensate: no option is taken unread
        raise InputError(f"--rot-count: expected at least 1 point per rotary axis, got {args.rot_count}")
    model = _model(args)
    grid, source, L0d, LEd = _grid(args, model)
    model, ev, L0, LE = _setup(args, L0d, LEd)
    errors = ev.values
    chunk = CHUNK if args.chunk is None else args.chunk
    if chunk < 1:
        raise InputError(f"--chunk: expected a positive number of poses, got {chunk}")
    res = gsil(model, grid, errors, L0, LE, _order(args.order), chunk=chunk, progress=args.progress,
               reduce=args.reduce, max_size=args.max_poses, how="--max-poses {n}")
    res.settings["workspace"] = source
    _error_settings(res.settings, ev)
    out = res.to_json()
    comp = None
    if args.compensate:
        vital, why, comp, run = _compensate_gsa(args, model, errors, grid, L0, res)
        out["compensation"] = {"vital": list(vital), "vital_rule": why, "points": args.points,
                               "rot_count": args.rot_count, "L_mm": L0,
                               "position_mm": _rows_json(comp["position_mm"]),
                               "posture_rad": _rows_json(comp["posture_rad"])}
    paper = args.preset == "paper"
    if args.plot:
        from ..plots import sensitivity as plots
        files = [plots.pie(res.names, res.proportions, args.plot / "gsa_pie.png",
                           f"GSIL proportions PG_i (%), {model.machine.name} ({model.convention} convention)")]
        if args.compensate:
            maps = {"none": run(errors)}
            maps["vital"] = run(scenario_errors(errors, vital, "vital halved"))
            if len(maps["none"]["rotary"]) == 2:
                r0, r1 = maps["none"]["rotary"]
                for key, name, unit in (("position_map", "position", "mm"), ("posture_map", "posture", "rad")):
                    both = np.concatenate([m[key].ravel() for m in maps.values()])
                    levels = np.linspace(both.min(), both.max(), 15)      # one scale for both, as Fig. 17-18
                    for tag, r in maps.items():
                        files.append(plots.ab_contour(
                            r["rotary_deg"][0], r["rotary_deg"][1], r[key], args.plot / f"gsa_{name}_{tag}.png",
                            f"average {name} error at the {args.points} points, "
                            f"{'no compensation' if tag == 'none' else 'vital errors halved'}",
                            f"|{'P' if name == 'position' else 'V'}_err| ({unit})", levels, (r0, r1)))
            fig = "Fig. 16a: " if paper else ""
            files.append(plots.bars(comp["position_mm"], args.plot / "gsa_compensation_position.png",
                                    f"{fig}average position error |P_err| at the points, {model.machine.name}",
                                    "position error |P_err| (mm)"))
            files.append(plots.bars(comp["posture_rad"], args.plot / "gsa_compensation_posture.png",
                                    f"{'Fig. 16b: ' if paper else ''}average posture error |V_err| at the points, "
                                    f"{model.machine.name}", "posture error |V_err| (rad)"))
        _wrote(files)
    if args.json:
        _dump(out)
        return 0
    lines = (S.ranking(out, _iso(model), args.top, "GSIL proportions PG_i (Eq. 14, 16), largest first")
             + S.settings(out["settings"]) + S.error_notes(out["settings"]))
    if comp:
        c = out["compensation"]
        fig = "Fig. 16a: " if paper else ""
        where = f"the {c['points']} points of Fig. 15" if paper else \
            f"the {c['points']} points of the workspace's body diagonals and its centre"
        lines += S.compensation(c["position_mm"], f"{fig}average position error at {where} (L = {c['L_mm']:g} mm), "
                                f"vital = {', '.join(c['vital'])} ({c['vital_rule']})", "mm",
                                presets.PAPER_COMPENSATION["workspace_position"] if paper else None)
        lines += S.compensation(c["posture_rad"], f"{'Fig. 16b: ' if paper else ''}average posture error", "rad",
                                presets.PAPER_COMPENSATION["workspace_posture"] if paper else None)
    print("\n".join(lines))
    return 0


# -- lsa -----------------------------------------------------------------------------------------------------------
def register_lsa(p):
    _common(p, "the machine file's; the cone: 34.6, Sect. 4.1", "16", LSA_MAX_POSES)
    where = p.add_mutually_exclusive_group()
    where.add_argument("--toolpath", type=Path, metavar="FILE",
                       help="a CSV of tool poses (the machine's axes, mm and degrees; optional nx,ny,nz surface "
                            "normals in the workpiece frame and a segment column) or a G-code program (LinuxCNC "
                            "dialect, read by rs274; G1 moves and G2/G3 arcs sampled along the path)")
    where.add_argument("--pose", action="append", default=None, metavar="X=..,Y=..,...",
                       help="an explicit pose (mm, degrees; optional nx=,ny=,nz=); repeatable")
    where.add_argument("--cone", type=int, default=None, choices=(1, 2),
                       help="li2018 preset: the machining position of the paper's 1/4 cone (Tables 3-4); the "
                            "default on li2018 when no path is given")
    p.add_argument("--positions", type=int, default=5, help="tool positions on the cone (default 5, Tables 3-4)")
    p.add_argument("--surface", default=None, metavar="KIND:NUMBERS",
                   help="normals of a G-code path: sphere:CX,CY,CZ | plane:NX,NY,NZ | cylinder:PX,PY,PZ,UX,UY,UZ | "
                        "cone:AX,AY,AZ,UX,UY,UZ,HALF_DEG (workpiece frame, mm, degrees)")
    p.add_argument("--step-mm", type=float, default=1.0, help="G-code sampling step along the linear axes (mm)")
    p.add_argument("--step-deg", type=float, default=1.0, help="G-code sampling step along the rotary axes (deg)")
    p.add_argument("--segments", type=int, default=SEGMENTS_SHOWN,
                   help=f"segments listed in the text output (default {SEGMENTS_SHOWN}; all are in --json)")
    p.add_argument("--normal-mode", type=int, default=None, choices=(0, 1),
                   help="how the surface normal N enters LSIL: 0 = W_i alone, 1 = int |P_err,i . N| / |P_err| dL "
                        "(see docs/sensitivity.md). Default: 0 for the cone (the paper's reading) and for paths "
                        "without normals, 1 for paths with normals")
    p.add_argument("--compensate", action="store_true",
                   help="also halve the vital / other / all errors and average the machining error along the path "
                        "(Fig. 11; the cone: its side surface)")
    p.set_defaults(func=run_lsa)


def _path(args, model, L0):
    """The toolpath of an lsa run from --toolpath or --pose (fiveaxis.sensitivity.toolpath)."""
    from ..linuxcnc import rs274 as gcode
    from ..sensitivity import surfaces, toolpath
    from ..guards import check_size
    how = "--max-poses {n}"
    if args.pose is not None:
        check_size(len(args.pose), "poses", args.max_poses, how)
        tp = toolpath.from_specs(args.pose, model.machine)
    elif args.toolpath.suffix.lower() == ".csv":
        tp = toolpath.read_csv(args.toolpath, model.machine, max_rows=args.max_poses)
    else:
        program = gcode.interpret(args.toolpath)      # read through fiveaxis.inputs: a regular file, bounded
        tp = toolpath.from_program(program, model.machine, args.step_mm, args.step_deg, args.max_poses, how)
    if args.surface:
        if tp.has_normals:
            raise InputError(f"--surface: the toolpath already has normals ({tp.normals_source}); give one or the "
                             f"other")
        tp = toolpath.with_surface(tp, surfaces.parse(args.surface), model, L0)
    return tp


def run_lsa(args) -> int:
    from ..report import sensitivity_text as S
    from ..sensitivity import paper as presets
    from ..sensitivity.indices import DEFAULT_ORDER, lsil
    from ..guards import check_size
    for option, value in (("--step-mm", args.step_mm), ("--step-deg", args.step_deg)):
        if not (value > 0 and math.isfinite(value)):   # checked even without a G-code path: none taken unread
            raise InputError(f"{option}: expected a positive, finite sampling step, got {value}")
    if args.positions < 1:
        raise InputError(f"--positions: expected at least 1, got {args.positions}")
    model = _model(args)
    cone = args.cone
    path_given = args.toolpath is not None or args.pose is not None
    if not path_given and cone is None:
        if tuple(model.variables) != ("X", "Y", "Z", "A", "B"):
            raise InputError(f"lsa on {model.machine.name}: give a path with --toolpath FILE or --pose "
                             f"{'=..,'.join(model.variables)}=.. (the cone of Sect. 4.1 is a preset of li2018)")
        cone = 1
    if args.surface and args.toolpath is None:
        raise InputError("--surface gives the normals of a --toolpath; --pose takes nx=,ny=,nz= instead")
    model, ev, L0, LE = _setup(args, *((presets.CONE_L0, presets.CONE_LE) if cone else (None, None)))
    errors = ev.values
    order = 2 * DEFAULT_ORDER if args.order is None else _order(args.order)
    if args.segments < 0:
        raise InputError(f"--segments: expected a number of segments >= 0, got {args.segments}")
    tp = None
    if cone:
        if args.positions < 1:
            raise InputError(f"--positions: expected at least 1, got {args.positions}")
        check_size(args.positions, "cone positions", args.max_poses, "--max-poses {n}",
                   detail=f"--positions {args.positions}")
        poses = presets.cone_poses(model, cone, args.positions)
        mode = 0 if args.normal_mode is None else args.normal_mode
    else:
        tp = _path(args, model, L0)
        poses = tp.poses
        mode = (1 if tp.has_normals else 0) if args.normal_mode is None else args.normal_mode
        if mode == 1 and not tp.has_normals:
            raise InputError("normal mode 1 needs surface normals: give nx,ny,nz columns, --surface, or "
                             "--normal-mode 0")
    res = lsil(model, poses, errors, L0, LE, order, mode=mode)
    _error_settings(res.settings, ev)
    if cone:
        res.settings.update(cone=cone, positions=[[round(float(x), 3) for x in row[:3]] +
                                                  [round(math.degrees(float(x)), 3) for x in row[3:]]
                                                  for row in poses.array],
                            positions_columns="X Y Z (mm) A B (deg); Z is -(ram extension of Tables 3-4)")
        res.settings["normals"] = "the cone's outward normals" + ("" if mode else " (normal mode 0: not used)")
    else:
        res.settings["path"] = tp.source
        res.settings["normals"] = (tp.normals_source + ("" if mode else " (normal mode 0: not used)")
                                   if tp.has_normals else "none: LSIL without the surface normal N (W_i alone)")
    out = res.to_json()
    segs = None
    if tp is not None:
        from ..sensitivity.toolpath import segment_indices
        segs = segment_indices(res, tp)
        out["segments"] = [{"label": s["label"], "first_pose": s["first_pose"], "last_pose": s["last_pose"],
                            "indices": None if s["proportions"] is None else
                            {n: float(v) for n, v in zip(res.names, s["proportions"])},
                            "ranking": None if s["proportions"] is None else
                            _ranking(res.names, s["proportions"])[:5]} for s in segs]
    comp = vital = None
    if args.compensate:
        from ..sensitivity import experiments
        if cone:
            vital, why = _vital(res, presets.PAPER_VITAL[f"cone{cone}"])

            def metric(e):
                return presets.cone_machining_error(model, cone, e, L0, LE)["mean_mm"]
            measure = "|N . P_err| over the cone's side surface (mm)"
        else:
            vital, why = _vital(res)
            nrm = poses.normals if tp.has_normals else None       # the cut surface moves along N only

            def metric(e):
                return experiments.path_machining_error(model, poses.array, e, L0, LE, nrm)["mean_mm"]
            measure = ("|N . P_err| along the path (mm)" if nrm is not None else
                       "|P_err| along the path (mm; no surface normal)")
        comp = experiments.compensation(errors, vital, metric, "the machining error")
        out["compensation"] = {"vital": list(vital), "vital_rule": why, "measure": measure,
                               "machining_error_mm": _rows_json(comp)}
    if args.plot:
        files = _lsa_plots(args, model, res, cone, tp, comp, errors, L0, LE, mode, vital)
        _wrote(files)
    if args.json:
        _dump(out)
        return 0
    what = f"at cone position {cone}" if cone else ("at the given poses" if args.pose else "along the path")
    st = out["settings"]
    lines = (S.ranking(out, _iso(model), args.top, f"LSIL proportions PL_i {what} (normal mode {mode}), largest "
                                                   f"first") + S.settings(st)
             + ([f"path: {st['path']}"] if "path" in st else []) + [f"normals: {st['normals']}"]
             + S.error_notes(st))
    if "segments" in out:
        lines += S.segments(out["segments"], args.segments)
    if comp:
        c = out["compensation"]
        title = (f"Fig. 11: average machining error of the side surface, vital = " if cone else
                 f"machining error {c['measure']}, vital = ")
        lines += S.compensation(c["machining_error_mm"], title + f"{', '.join(c['vital'])} ({c['vital_rule']})", "mm",
                                presets.PAPER_COMPENSATION[f"cone{cone}"] if cone else None)
    print("\n".join(lines))
    return 0


def _iso(model) -> dict:
    """{error: ISO 230 name or None} for the rankings."""
    from ..model import iso_names as iso
    return {n: e.iso for n, e in iso.names(model).items()}


def _ranking(names, proportions):
    from ..sensitivity.indices import ranking
    return ranking(list(names), proportions)


def _lsa_plots(args, model, res, cone, tp, comp, errors, L0, LE, mode, vital):
    from ..sensitivity import paper as presets
    from ..sensitivity.experiments import scenario_errors
    from ..plots import sensitivity as plots
    d = args.plot
    if cone:
        files = [plots.pie(res.names, res.proportions, d / f"lsa_cone{cone}_pie.png",
                           f"LSIL proportions PL_i (%), cone position {cone}, normal mode {mode}")]
        if comp:
            maps = {sc: presets.cone_machining_error(model, cone, scenario_errors(errors, vital, sc), L0, LE)
                    for sc in ("none", "vital halved")}
            vmax = float(max(m["map"].max() for m in maps.values()))
            for tag, sc in (("none", "none"), ("vital", "vital halved")):
                files.append(plots.cone_map(maps[sc], d / f"lsa_cone{cone}_map_{tag}.png",
                                            f"machining error |N . P_err|, cone position {cone}, "
                                            f"{'no compensation' if sc == 'none' else 'vital errors halved'}", vmax))
            files.append(plots.bars(comp, d / f"lsa_cone{cone}_compensation.png",
                                    f"Fig. 11: machining error of the cone's side surface, position {cone}",
                                    "machining error |N . P_err| (mm)"))
        return files
    files = [plots.pie(res.names, res.proportions, d / "lsa_path_pie.png",
                       f"LSIL proportions PL_i (%) along the path, {model.machine.name}, normal mode {mode}"),
             plots.path_shares(res.names, res.per_pose, tp.segment, d / "lsa_path_shares.png",
                               f"share of the largest PL_i along the path, {model.machine.name}")]
    if comp:
        normal = tp.has_normals
        files.append(plots.bars(comp, d / "lsa_path_compensation.png",
                                f"machining error along the path, {model.machine.name}: mean of "
                                f"{'|N . P_err|' if normal else '|P_err| (no surface normal)'} over the poses and "
                                f"L in [L0-LE, L0]",
                                f"machining error {'|N . P_err|' if normal else '|P_err|'} (mm)"))
    return files


# -- sobol ---------------------------------------------------------------------------------------------------------
def register_sobol(p):
    _common(p, "the machine file's; li2018: 30, Sect. 4.2", "exact when the kernels have it, else 8", GSA_MAX_POSES)
    _workspace_options(p)
    p.add_argument("--samples", type=int, default=512, help="SALib base sample, a power of 2 (default 512)")
    p.add_argument("--bound", type=float, default=1e-4, help="errors uniform in [-bound, bound] (mm, rad)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run_sobol)


def run_sobol(args) -> int:
    from ..report import sensitivity_text as S
    from ..guards import check_size
    from ..sensitivity.indices import gsil, ranking
    from ..sensitivity.sobol import MAX_POSES, compare, sobol_total
    model = _model(args)
    grid, source, L0d, LEd = _grid(args, model)
    model, ev, L0, LE = _setup(args, L0d, LEd)
    if args.seed < 0:
        raise InputError(f"--seed: expected a whole number >= 0, got {args.seed}")
    if not (math.isfinite(args.bound) and args.bound > 0):
        raise InputError(f"--bound: expected a positive finite error magnitude (mm, rad), got {args.bound}")
    if args.samples >= 2:
        evaluations = args.samples * (len(model.errors) + 2)
        check_size(evaluations * min(grid.size, MAX_POSES) * 2, "poses", args.max_poses,
                   "--max-poses {n}", f"{evaluations} Saltelli samples x {min(grid.size, MAX_POSES)} poses x 2 "
                   f"tool lengths")
    s = sobol_total(model, grid, L0, LE, args.bound, args.samples, args.seed)
    g = gsil(model, grid, ev.values, L0, LE, _order(args.order), progress=False, max_size=args.max_poses,
             how="--max-poses {n}")
    cmp = compare(model.errors, g.values, s["ST"])
    s["settings"]["workspace"] = source
    out = {"indices": {n: float(v) for n, v in zip(s["names"], s["ST"])},
           "ranking": ranking(s["names"], s["ST"]), "settings": s["settings"], "comparison": cmp,
           "ST_conf": {n: float(v) for n, v in zip(s["names"], s["ST_conf"])}}
    if args.plot:
        from ..plots import sensitivity as plots
        _wrote([plots.pie(s["names"], np.clip(s["ST"], 0, None), args.plot / "sobol_total_pie.png",
                          f"Sobol' total indices S_T (normalised, %), {model.machine.name}")])
    if args.json:
        _dump(out)
        return 0
    print("\n".join(S.sobol(out, g.to_json(), args.top)))
    return 0
