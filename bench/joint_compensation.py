"""Issue 29's joint-fit criterion through the real compensation: laser runs of X, Y, Z and an R-test on a machine
with errors on every axis, fitted alone and jointly (default priors), each fit compensated by `compensate`'s table;
the true machine's tool-tip error over random poses before and after the table, the part's set-up taken out, from the
independent chain (model/htm.py: readings simulated through it, the truth evaluated with it), as a share of before,
beside the prediction's k = 2 range (the fit's posterior) of the same figure.

    .venv/bin/python bench/joint_compensation.py [--seeds 1,2,3] [--rtest-poses 600] [--poses 2000] [--json]

The criterion: joint <= 20 % of before, where the laser alone and the R-test alone do not get there. Units: um in
the table, mm in the JSON.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from fiveaxis.compensation import pipeline as CP
from fiveaxis.compensation.part_setup import SetupRemoval
from fiveaxis.compensation.table import compensated_commands
from fiveaxis.estimation import fit as F
from fiveaxis.estimation.fitted_model import from_fit
from fiveaxis.measurement.files import join
from fiveaxis.measurement.simulate import simulate
from fiveaxis.model import htm
from fiveaxis.model.error_model import load

#: The positioning effects of each linear axis (linear and bowed), the model the fits use.
EFFECTS = ("dx_x:x1", "dy_y:y1", "dz_z:z1", "dx_x:x2", "dy_y:y2", "dz_z:z2")
LOCATION_MM = ("dYOA", "dZOA", "dXOC", "dYOC")
LOCATION_RAD = ("SBOA", "SCOA", "SAOC", "SBOC", "Sxy", "Sxz", "Syz")


def true_machine(model, seed):
    """Errors on every axis: the rotary axes' locations and the linear axes' squareness 10-30 um / urad, each linear
    axis's positioning 20-40 um over its stroke (EFFECTS: the value at the stroke's end), the rest 0.9 um, 6 urad."""
    rng = np.random.default_rng(200 + seed)
    errors = {n: float(rng.normal() * (6e-6 if model.machine.is_angular(n) else 0.9e-3)) for n in model.errors}
    for n in LOCATION_MM:
        errors[n] = float(rng.choice([-1, 1]) * rng.uniform(0.010, 0.030))
    for n in LOCATION_RAD:
        errors[n] = float(rng.choice([-1, 1]) * rng.uniform(10e-6, 30e-6))
    effects = {e: float(rng.choice([-1, 1]) * rng.uniform(0.02, 0.04)) for e in EFFECTS}
    return errors, effects


def error_values(model, q, errors, effects):
    """(n, n_errors) the true error values at poses q (mm, rad): the constants plus c u^deg per effect, u the axis
    position scaled to its model stroke (-1 to 1), in the model's order."""
    E = np.tile([errors[n] for n in model.errors], (len(q), 1))
    for ident, c in effects.items():
        param, spec = ident.split(":")
        var = next(v for v in model.variables if v.lower() == spec[0])
        lo, hi = model.machine.axis(var).model_stroke
        u = (q[:, list(model.variables).index(var)] - 0.5 * (lo + hi)) / (0.5 * (hi - lo))
        E[:, list(model.errors).index(param)] += c * u ** int(spec[1:])
    return E


def one(model, seed, rtest_poses, poses, nodes, fits=("laser", "rtest", "joint"), comp_points=None):
    machine = model.machine
    errors, effects = true_machine(model, seed)
    order = [list(model.errors).index(n) for n in machine.error_names]
    chain = (lambda at, E, L: htm.tool_errors(machine, at, L, E[:, order]))
    spec = [f"{k}={v!r}" for k, v in effects.items()]
    laser = simulate(model, spec, instrument="interferometer", seed=seed, errors=errors, noise=1e-3, chain=chain)
    rtest = simulate(model, spec, instrument="rtest", n=rtest_poses, seed=seed + 1, errors=errors, noise=1e-3,
                     chain=chain)
    laser.meas.path, rtest.meas.path = "laser.csv", "rtest.csv"
    q = machine.random_poses(poses, np.random.default_rng(12))
    L = machine.tool_length
    P0 = htm.tool(machine, q, L)[0]
    setup = SetupRemoval.at(machine, P0)

    def true_tip(positions):
        return htm.tool(machine, positions, L, error_values(model, positions, errors, effects)[:, order])[0] - P0
    before = _rms(setup.remove(true_tip(q)))
    out = {"seed": seed, "before_mm": before, "fits": {}}
    sets = {"laser": lambda: laser.meas, "rtest": lambda: rtest.meas,
            "joint": lambda: join([laser.meas, rtest.meas], machine)}
    for label in fits:
        meas = sets[label]()
        fm = from_fit(F.fit(model, meas, list(EFFECTS)))
        comp = CP.compensate(fm, model, {v: nodes for v in machine.variables if v not in machine.rotary},
                             comp_points=comp_points, poses=poses)
        after = _rms(setup.remove(true_tip(compensated_commands(comp.table, q))))
        band = comp.account["uncertainty"]["tip_error_mm"]["after_table"]["setup_removed"]
        lo, hi = band["range_k2"]
        out["fits"][label] = {"after_mm": after, "share": after / before, "range_k2_mm": [lo, hi],
                              "predicted_mm": band["predicted_rms"], "inside": bool(lo <= after <= hi)}
    return out


def _rms(e) -> float:
    return float(np.sqrt(np.mean(np.sum(np.asarray(e) ** 2, axis=1))))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="1,2,3")
    p.add_argument("--rtest-poses", type=int, default=600)
    p.add_argument("--poses", type=int, default=2000, help="random poses of the truth and of the account")
    p.add_argument("--nodes", type=int, default=5, help="table nodes per linear axis")
    p.add_argument("--comp-points", type=int, default=None, help="points per LinuxCNC comp file (default 33)")
    p.add_argument("--fits", default="laser,rtest,joint", help="which fits (laser, rtest, joint)")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    model = load("ac_trunnion")
    fits = tuple(f.strip() for f in args.fits.split(","))
    rows = [one(model, int(s), args.rtest_poses, args.poses, args.nodes, fits, args.comp_points)
            for s in args.seeds.split(",")]
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        print("seed  before (um)  after the table and the part's set-up, % of before [true um; predicted k = 2 um]")
        for r in rows:
            cells = [f"{k} {100 * f['share']:.1f} % [{1e3 * f['after_mm']:.2f}; {1e3 * f['range_k2_mm'][0]:.2f}-"
                     f"{1e3 * f['range_k2_mm'][1]:.2f}{'' if f['inside'] else ' OUTSIDE'}]"
                     for k, f in r["fits"].items()]
            print(f"{r['seed']:4d}  {1e3 * r['before_mm']:10.2f}  " + "; ".join(cells))
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
