"""`fiveaxis gsa`, `fiveaxis lsa` and `fiveaxis sobol`: sensitivity indices and the paper's experiments.

gsa: GSIL over a workspace grid (default: Sect. 4.2 of the paper); `--compensate` adds Fig. 16 (nine points).
lsa: LSIL at the cone positions of Tables 3-4 (Sect. 4.1); `--compensate` adds Fig. 11 (cone side surface).
sobol: Sobol' total indices (SALib) over the same workspace, compared with the GSIL ranking.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import InputError


# -- shared options ----------------------------------------------------------------------------------------------
def _order(text):
    """--order: an integer (Gauss-Legendre) or 'exact'; range checks happen in sensitivity.quadrature."""
    if text is None or text == "exact":
        return text
    try:
        return int(text)
    except ValueError:
        raise InputError(f"--order: expected an integer or 'exact', got {text!r}") from None


def _common(p, le_default: str, order_default: str):
    p.add_argument("--machine", default="li2018", help="machine name or file (default: li2018)")
    p.add_argument("--convention", default="equations",
                   help="'equations' (errors where Eq. 1-6 place them) or a convention of the machine file "
                        "(li2018: 'printed', the placement behind the printed Table 2 and the paper's results)")
    p.add_argument("--json", action="store_true", help="print {indices, ranking, settings} as JSON")
    p.add_argument("--plot", type=Path, metavar="DIR", help="write PNG plots into DIR")
    p.add_argument("--l0", type=float, default=None,
                   help="tool length L0, mm (default: the machine file's; li2018: 200, the paper's)")
    p.add_argument("--le", type=float, default=None, help=f"effective cutting length LE, mm (default: {le_default})")
    p.add_argument("--order", default=None, metavar="N|exact",
                   help="integral over [L0-LE, L0]: Gauss-Legendre of order N, or 'exact' (closed form; W_i only) "
                        f"(default: {order_default})")
    p.add_argument("--errors", action="append", default=[], metavar="FILE|NAME=VALUE",
                   help="error values (mm, rad): NAME=VALUE, or a file of NAME=VALUE lines or a JSON object; "
                        "repeatable; errors not named keep the machine file's values (li2018: all 1e-4, the "
                        "value behind the paper's rankings)")
    p.add_argument("--top", type=int, default=10, help="rows of the printed ranking (default 10)")


def _model(args):
    from ..kernels import load
    return load(args.machine, args.convention)


def _setup(args, L0_default=None, LE_default=None):
    """(model, error values, L0, LE) of a sensitivity command: L0 and LE (mm) from the options, else the given
    defaults, else the machine file's tool data."""
    model = _model(args)
    errors = parse_errors(model, args.errors)
    L0 = args.l0 if args.l0 is not None else (L0_default if L0_default is not None else model.machine.tool_length)
    LE = args.le if args.le is not None else (LE_default if LE_default is not None else model.machine.cutting_length)
    return model, errors, L0, LE


def parse_errors(model, specs) -> dict[str, float]:
    """The machine file's error values, overridden by --errors NAME=VALUE or files of such lines / JSON."""
    defaults = model.machine.default_errors()
    from .. import iso
    values = {n: float(defaults[n]) for n in model.errors}

    def put(name, raw, where):
        name = iso.canonical(model, name, where=where)     # a project name or its ISO 230 name (E_AX)
        try:
            v = float(raw)
        except (TypeError, ValueError):
            raise InputError(f"{where}: value of {name} must be a number, got {raw!r}") from None
        if not math.isfinite(v):
            raise InputError(f"{where}: value of {name} must be finite, got {raw!r}")
        values[name] = v

    for spec in specs:
        if "=" in spec and not Path(spec).exists():
            name, _, raw = spec.partition("=")
            put(name, raw, f"--errors {spec}")
            continue
        path = Path(spec)
        if not path.is_file():
            raise InputError(f"--errors {spec}: not NAME=VALUE and no such file")
        text = path.read_text()
        if text.lstrip().startswith("{"):
            try:
                data = json.loads(text)
            except json.JSONDecodeError as exc:
                raise InputError(f"{path}: line {exc.lineno} column {exc.colno}: invalid JSON ({exc.msg})") from None
            for name, raw in data.items():
                put(name, raw, f"{path}: key {name}")
            continue
        for i, line in enumerate(text.splitlines(), 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            name, sep, raw = line.partition("=")
            if not sep:
                parts = line.split()
                if len(parts) != 2:
                    raise InputError(f"{path}: line {i}: expected NAME=VALUE, got {line!r}")
                name, raw = parts
            put(name, raw, f"{path}: line {i}")
    return values


def workspace_grid(model, specs):
    """The GSA grid of `gsa` and `dask`: the paper's workspace for X Y Z A B machines, else 5 points per
    stroke, changed by the --axis specs (mm; degrees for rotary axes)."""
    from .. import presets
    from ..grid import Grid, grid_from_specs
    if tuple(model.variables) == ("X", "Y", "Z", "A", "B"):
        base = presets.workspace_grid(model)
    else:
        base = Grid.from_strokes(model.machine, {n: 5 for n in model.variables})
    return grid_from_specs(base, specs, model.machine.rotary)


def _print_ranking(model, result, top: int, title: str):
    """The largest proportions with each error's ISO 230 name."""
    from .. import iso
    p = result.proportions
    idx = {n: i for i, n in enumerate(result.names)}
    names = iso.names(model)
    print(title)
    print(f"{'rank':>4}  {'error':<6} {'ISO 230':<9} {'proportion':>10}")
    prev = None
    for r, name in enumerate(result.ranking[:top], 1):
        v = p[idx[name]]
        tie = "  (tied: same J)" if prev is not None and abs(v - prev) <= 1e-12 * max(abs(v), 1e-300) else ""
        print(f"{r:>4}  {name:<6} {names[name].iso or '-':<9} {100 * v:>9.2f}%{tie}")
        prev = v


def _print_settings(s):
    q = s["quadrature"]
    rule = "exact integral over L" if q["order"] == "exact" else f"Gauss-Legendre order {q['order']}"
    line = (f"settings: {s['machine']} ({s['convention']} convention), L0 {s['L0_mm']:g} mm, LE {s['LE_mm']:.4g} mm, "
            f"{rule}")
    if "max_abs_change_of_proportion" in q:
        line += (f" (vs Gauss-Legendre order {q['check_order']}: largest change of a proportion "
                 f"{q['max_abs_change_of_proportion']:.1e})")
    left = (f"{s['skipped_poses']} poses" if "skipped_poses" in s else f"{s['skipped_nodes']} nodes")
    line += f", {s['poses']} poses, {left} left out (|P_err| ~ 0)"
    print(line)


def _print_compensation(rows, title, unit, paper: dict | None = None):
    print(title)
    print(f"  {'':2}{'scenario':<15} {unit:>12} {'improvement':>12} {'%':>6}")
    for i, r in enumerate(rows, 1):
        print(f"  {i:<2}{r.scenario:<15} {r.value:>12.5g} {r.improvement:>12.5g} {r.improvement_pct:>6.1f}")
    if paper:
        print("  paper: " + ", ".join(f"{k} {v}" for k, v in paper.items()))


def _rows_json(rows):
    return [{"scenario": r.scenario, "value": r.value, "improvement": r.improvement,
             "improvement_pct": r.improvement_pct} for r in rows]


# -- gsa -----------------------------------------------------------------------------------------------------------
def register_gsa(p):
    _common(p, "the machine file's; li2018: 30, Sect. 4.2", "exact when the kernels have it, else 8")
    p.add_argument("--axis", action="append", default=[], metavar="NAME=LO:HI:COUNT",
                   help="grid of one axis (mm; degrees for rotary axes), or NAME=VALUE to fix it; repeatable. "
                        "Default: Sect. 4.2's workspace, X 21, Y 9, Z 5, A 13, B 13 points")
    p.add_argument("--chunk", type=int, default=None, help="poses per chunk (bounded memory; default 2**20)")
    bar = p.add_mutually_exclusive_group()
    bar.add_argument("--progress", action="store_true", default=None, help="always show the progress bar")
    bar.add_argument("--no-progress", dest="progress", action="store_false", help="never show the progress bar")
    p.add_argument("--compensate", action="store_true",
                   help="also run Fig. 16: halve the vital / other / all errors and average the tool's position "
                        "and posture error at the nine points of Fig. 15 over A, B in [-30, 30] deg")
    p.add_argument("--points", default="quarter", choices=("quarter", "corner"),
                   help="the nine points: quarter marks of the body diagonals (default) or the corners")
    p.add_argument("--rot-count", type=int, default=13, help="points per rotary axis for --compensate (default 13)")
    p.add_argument("--no-reduce", dest="reduce", action="store_false",
                   help="evaluate every grid pose, also along axes that appear in no J (X for li2018); "
                        "by default such an axis is evaluated once and weighted by its count (exact)")
    p.set_defaults(func=run_gsa)


def run_gsa(args) -> int:
    from .. import presets
    from ..sensitivity import CHUNK, gsil
    model, errors, L0, LE = _setup(args)
    grid = workspace_grid(model, args.axis)
    chunk = CHUNK if args.chunk is None else args.chunk
    if chunk < 1:
        raise InputError(f"--chunk: expected a positive number of poses, got {chunk}")
    res = gsil(model, grid, errors, L0, LE, _order(args.order), chunk=chunk, progress=args.progress,
               reduce=args.reduce)
    out = res.to_json()
    comp = None
    if args.compensate:
        vital = presets.PAPER_VITAL["workspace"]
        comp = {}
        for key in ("position_mm", "posture_rad"):
            comp[key] = presets.compensation(
                errors, vital, lambda e: presets.nine_point_errors(model, e, args.rot_count, args.points, L0)[key])
        out["compensation"] = {"vital": list(vital), "points": args.points, "rot_count": args.rot_count,
                               "position_mm": _rows_json(comp["position_mm"]),
                               "posture_rad": _rows_json(comp["posture_rad"])}
    if args.plot:
        from ..plots import sensitivity as plots
        plots.pie(res.names, res.proportions, args.plot / "gsa_pie.png",
                  f"PG_i, {model.machine.name} ({model.convention})")
        if args.compensate:
            maps = {tag: presets.nine_point_errors(model, presets.scenario_errors(
                        errors, presets.PAPER_VITAL["workspace"], sc), args.rot_count, args.points, L0)
                    for tag, sc in (("none", "none"), ("vital", "vital halved"))}
            for key, name, unit in (("position_map", "position", "mm"), ("posture_map", "posture", "rad")):
                both = np.concatenate([m[key].ravel() for m in maps.values()])
                levels = np.linspace(both.min(), both.max(), 15)      # one scale for a and b, as Fig. 17-18
                for tag, r in maps.items():
                    plots.ab_contour(r["A_deg"], r["B_deg"], r[key], args.plot / f"gsa_{name}_{tag}.png",
                                     f"average {name} error, {'none' if tag == 'none' else 'vital halved'}", unit,
                                     levels)
            plots.bars(comp["position_mm"], args.plot / "gsa_compensation_position.png", "Fig. 16a", "mm")
            plots.bars(comp["posture_rad"], args.plot / "gsa_compensation_posture.png", "Fig. 16b", "rad")
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    _print_ranking(model, res, args.top, "GSIL proportions PG_i (Eq. 14, 16), largest first")
    _print_settings(res.settings)
    if comp:
        _print_compensation(comp["position_mm"], f"Fig. 16a: average position error at the nine points "
                            f"({args.points}), vital = {', '.join(presets.PAPER_VITAL['workspace'])}", "mm",
                            presets.PAPER_COMPENSATION["workspace_position"])
        _print_compensation(comp["posture_rad"], "Fig. 16b: average posture error", "rad",
                            presets.PAPER_COMPENSATION["workspace_posture"])
    return 0


# -- lsa -----------------------------------------------------------------------------------------------------------
def register_lsa(p):
    _common(p, "34.6, Sect. 4.1", "16")
    p.add_argument("--cone", type=int, default=1, choices=(1, 2), help="machining position of the 1/4 cone")
    p.add_argument("--positions", type=int, default=5, help="tool positions on the cone (default 5, Tables 3-4)")
    p.add_argument("--normal-mode", type=int, default=0, choices=(0, 1),
                   help="how the surface normal N enters LSIL: 0 = W_i alone (default), "
                        "1 = int |P_err,i . N| / |P_err| dL (see docs/sensitivity.md)")
    p.add_argument("--compensate", action="store_true",
                   help="also run Fig. 11: halve the vital / other / all errors and average the machining error "
                        "of the cone's side surface")
    p.set_defaults(func=run_lsa)


def run_lsa(args) -> int:
    from .. import presets
    from ..sensitivity import DEFAULT_ORDER, lsil
    model, errors, L0, LE = _setup(args, presets.CONE_L0, presets.CONE_LE)
    order = 2 * DEFAULT_ORDER if args.order is None else _order(args.order)
    if args.positions < 1:
        raise InputError(f"--positions: expected at least 1, got {args.positions}")
    poses = presets.cone_poses(model, args.cone, args.positions)
    res = lsil(model, poses, errors, L0, LE, order, mode=args.normal_mode)
    res.settings.update(cone=args.cone, positions=[[round(float(x), 3) for x in row[:3]] +
                                                   [round(math.degrees(float(x)), 3) for x in row[3:]]
                                                   for row in poses.array],
                        positions_columns="X Y Z (mm) A B (deg); Z is -(ram extension of Tables 3-4)")
    out = res.to_json()
    comp = None
    vital = presets.PAPER_VITAL[f"cone{args.cone}"]
    if args.compensate:
        comp = presets.compensation(errors, vital,
                                    lambda e: presets.cone_machining_error(model, args.cone, e, L0, LE)["mean_mm"])
        out["compensation"] = {"vital": list(vital), "machining_error_mm": _rows_json(comp)}
    if args.plot:
        from ..plots import sensitivity as plots
        plots.pie(res.names, res.proportions, args.plot / f"lsa_cone{args.cone}_pie.png",
                  f"PL_i, cone position {args.cone}, normal mode {args.normal_mode}")
        if args.compensate:
            maps = {sc: presets.cone_machining_error(model, args.cone, presets.scenario_errors(errors, vital, sc), L0, LE)
                    for sc in ("none", "vital halved")}
            vmax = float(max(m["map"].max() for m in maps.values()))
            for tag, sc in (("none", "none"), ("vital", "vital halved")):
                plots.cone_map(maps[sc], args.plot / f"lsa_cone{args.cone}_map_{tag}.png",
                               f"machining error, cone position {args.cone}, {sc}", vmax)
            plots.bars(comp, args.plot / f"lsa_cone{args.cone}_compensation.png", f"Fig. 11, position {args.cone}",
                       "mm")
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    _print_ranking(model, res, args.top, f"LSIL proportions PL_i at cone position {args.cone} (normal mode "
                                         f"{args.normal_mode}), largest first")
    _print_settings(res.settings)
    if comp:
        _print_compensation(comp, f"Fig. 11: average machining error of the side surface, vital = "
                            f"{', '.join(vital)}", "mm", presets.PAPER_COMPENSATION[f"cone{args.cone}"])
    return 0


# -- sobol ---------------------------------------------------------------------------------------------------------
def register_sobol(p):
    _common(p, "the machine file's; li2018: 30, Sect. 4.2", "exact when the kernels have it, else 8")
    p.add_argument("--samples", type=int, default=512, help="SALib base sample, a power of 2 (default 512)")
    p.add_argument("--bound", type=float, default=1e-4, help="errors uniform in [-bound, bound] (mm, rad)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run_sobol)


def run_sobol(args) -> int:
    from .. import presets
    from ..sensitivity import gsil
    from ..sobol import compare, sobol_total
    model, errors, L0, LE = _setup(args)
    grid = presets.workspace_grid(model)
    s = sobol_total(model, grid, L0, LE, args.bound, args.samples, args.seed)
    g = gsil(model, grid, errors, L0, LE, _order(args.order), progress=False)
    cmp = compare(model.errors, g.values, s["ST"])
    out = {"indices": {n: float(v) for n, v in zip(s["names"], s["ST"])},
           "ranking": __import__("fiveaxis.sensitivity", fromlist=["ranking"]).ranking(s["names"], s["ST"]),
           "settings": s["settings"], "comparison": cmp,
           "ST_conf": {n: float(v) for n, v in zip(s["names"], s["ST_conf"])}}
    if args.plot:
        from ..plots import sensitivity as plots
        plots.pie(s["names"], np.clip(s["ST"], 0, None), args.plot / "sobol_total_pie.png",
                  "Sobol' total indices (normalised)")
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    pg = dict(zip(model.errors, g.proportions))
    rank_g = {n: i + 1 for i, n in enumerate(g.ranking)}
    print(f"Sobol' total indices of mean |P_err| over the workspace ({s['evaluations']} evaluations), "
          f"with the GSIL rank")
    print(f"{'rank':>4}  {'error':<6} {'S_T':>7} {'+-95%':>7}   {'PG_i':>7} {'GSIL rank':>9}")
    idx = {n: i for i, n in enumerate(s["names"])}
    for r, n in enumerate(out["ranking"][:args.top], 1):
        print(f"{r:>4}  {n:<6} {s['ST'][idx[n]]:>7.3f} {s['ST_conf'][idx[n]]:>7.3f}   {100 * pg[n]:>6.2f}% "
              f"{rank_g[n]:>9}")
    print(f"Spearman rank correlation of S_T and GSIL: {cmp['spearman']:.3f}; top 4 in common: "
          f"{', '.join(cmp['top4_common'])}")
    return 0
