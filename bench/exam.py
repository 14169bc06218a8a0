"""The proof at scale (issue 29): a Monte-Carlo exam of the fit and the diagnosis over random true machines.

Each trial draws a true machine (random base errors as `simulate` draws them: 3 um, 20 urad) on one of the three
shipped machines, measures it with one instrument's standard plan (every instrument in turn), the readings computed
by an independent plain NumPy chain (`fiveaxis.model.htm`), 1 um noise, written as a controller writes them (0.001
mm, 0.0001 deg, readings to 0.01 um) or with 7 significant digits, and read back. Two sets in five are null (no
effect beyond the geometric errors), the others hide one polynomial effect (an error motion changing linearly or
quadratically along an axis the plan moves) whose part the model's errors cannot absorb is k = 2..10 times the
noise (RMS over the readings). Then, as a user would: `diagnose`; the top candidate added when the verdict is a
missing effect; the fit. Measured:
- false alarms: null sets whose verdict is not "no missing effect";
- misses: sets with an effect of k >= 3 whose verdict is not "missing effect";
- right physics: of the effects found, the hidden one named (the top candidate or one of its aliases);
- the residual after adding / the noise;
- coverage of the k = 2 intervals of what the data determine (parameters and combinations, against the truth);
- coverage of the workspace band: the k = 2 range of the workspace RMS after compensation and the part's set-up,
  predicted from the posterior (draws of the parameters), against the truth's (the independent chain);
- the workspace error after / before (compensation with the fitted model, the part's set-up taken out).
Not a timed test: `python bench/exam.py --trials 210` prints the table (docs/measurements.md); tests/test_bench.py
runs it on three trials.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fiveaxis.compensation.part_setup import SetupRemoval
from fiveaxis.diagnosis import diagnose as D
from fiveaxis.effects import families as fx
from fiveaxis.estimation import fit as F
from fiveaxis.estimation.design import InMemory
from fiveaxis.estimation.fitted_model import errors_at, from_fit
from fiveaxis.estimation.problem import build, truth_theta
from fiveaxis.measurement.files import read
from fiveaxis.measurement.simulate import simulate, to_frame
from fiveaxis.model import htm
from fiveaxis.model.error_model import load

MACHINES = ("li2018", "ac_trunnion", "tilting_head")
INSTRUMENTS = ("tip", "rtest", "probe-sphere", "ballbar", "interferometer", "tracker", "test-part")
RESOLUTIONS = ("controller", "seven digits")
NOISE = 1e-3
#: Share of null sets.
NULL_SHARE = 0.4
#: A hidden effect's part the model cannot absorb must be at least this share of its signal (else another draw).
VISIBLE = 0.3
#: A hidden effect is at most this size over the plan's range (mm, rad: what an error motion of a machine tool can
#: be); a draw whose k x noise needs more is drawn again.
MAX_SIZE = {"mm": 0.030, "rad": 100e-6}
#: Workspace poses and draws of the posterior for the band.
WORKSPACE_POSES = 400
BAND_DRAWS = 400


def chain_of(model):
    """The independent chain as `simulate` takes it: (poses, E in the model's order, L) -> (P_err, V_err)."""
    machine = model.machine
    order = [list(model.errors).index(n) for n in machine.error_names]

    def chain(poses, E, L):
        return htm.tool_errors(machine, poses, L, np.asarray(E)[:, order])
    return chain


def written(model, sim, path: Path, resolution: str) -> Path:
    """The set as a controller writes it (fixed decimals) or with 7 significant digits."""
    df = to_frame(sim, model)
    rotary = {v for v in model.variables if model.machine.axis(v).type == "rotary"}
    if resolution == "controller":
        fmt = {c: ("%.4f" if c in rotary else "%.3f" if c in ("X", "Y", "Z", "L") else "%.5f"
                   if c in ("dx", "dy", "dz", "du") else "%.8f" if c in ("di", "dj", "dk") else "%.10g")
               for c in df.columns}
    else:
        fmt = {c: "%.7g" for c in df.columns}
    with open(path, "w") as fh:
        fh.write(",".join(df.columns) + "\n")
        for row in df.itertuples(index=False):
            fh.write(",".join("" if isinstance(v, float) and v != v else v if isinstance(v, str) else fmt[c] % v
                              for c, v in zip(df.columns, row)) + "\n")
    return path


def hidden_effect(model, sim0, rng, k: float):
    """An effect the plan sees (its part the model's errors cannot absorb at least VISIBLE of its signal), scaled
    so that part is k times the noise (RMS over the mm readings), of a size a machine can have (MAX_SIZE over the
    plan's range): (effect, values) or None."""
    machine = model.machine
    prob = build(model, sim0.meas, [])
    block = InMemory(prob).block
    A = block.A
    mm = prob.obs.group == 0
    moving = [v for i, v in enumerate(machine.variables) if np.ptp(sim0.meas.poses[:, i]) > 0]
    params = [n for a in machine.axes for n in a.pdge]
    for _ in range(30):
        var = moving[rng.integers(len(moving))]
        param = params[rng.integers(len(params))]
        ident = f"{param}:{fx.var_token(machine, var)}{int(rng.integers(1, 3))}"
        eff = fx.parse(ident, machine, model.errors)
        col = block.effect_columns([eff])[:, 0]
        raw = float(np.sqrt(np.mean(col[mm] ** 2))) if mm.any() else 0.0
        if raw == 0.0:
            continue
        orth = col - A @ np.linalg.lstsq(A, col, rcond=None)[0]
        part = float(np.sqrt(np.mean(orth[mm] ** 2)))
        value = k * NOISE / part if part > 0 else np.inf
        size = abs(value) * float(np.max(np.abs(eff.basis(prob.ctx))))
        if part >= VISIBLE * raw and size <= MAX_SIZE["rad" if machine.is_angular(param) else "mm"]:
            return eff, np.array([rng.choice([-1.0, 1.0]) * value] + [0.0] * (len(eff.names) - 1))
    return None


def coverage(res, sim) -> tuple[int, int]:
    """(within k = 2, count) over what the data determine: parameters alone and combinations, against the truth."""
    truth = truth_theta(res.problem, sim)
    idx = {n: i for i, n in enumerate(res.names)}
    std = res.std()
    inside = total = 0
    for name, det, norm in zip(res.free_names, res.idf.determined, res.idf.norms):
        i = idx[name]
        if det and norm > 0 and std[i] > 0:
            total += 1
            inside += abs(res.theta[i] - truth[i]) <= 2 * std[i]
    for c in res.combinations:
        if c.std > 0:
            total += 1
            inside += abs(c.value - sum(v * truth[idx[n]] for n, v in c.terms.items())) <= 2 * c.std
    return int(inside), int(total)


class Workspace:
    """Random poses of the workspace at the machine's tool: tool-tip errors from the independent chain, the part's
    set-up taken out."""

    def __init__(self, model, seed: int):
        self.model, machine = model, model.machine
        self.poses = machine.random_poses(WORKSPACE_POSES, np.random.default_rng(seed))
        self.L = machine.tool_length
        self.order = [list(model.errors).index(n) for n in machine.error_names]
        self.setup = SetupRemoval.at(machine, htm.tool(machine, self.poses, self.L, None)[0])

    def tip(self, E) -> np.ndarray:
        return htm.tool_errors(self.model.machine, self.poses, self.L, np.asarray(E)[:, self.order])[0]

    def rms(self, e) -> float:
        r = self.setup.remove(e)
        return float(np.sqrt(np.mean(np.sum(r ** 2, axis=1))))

    def band(self, res, rng) -> tuple[float, float]:
        """The k = 2 range (2.5 % and 97.5 % of draws) of the RMS left after compensating with the fit, from its
        posterior covariance of the machine's parameters (first order)."""
        prob = res.problem
        model = prob.model
        ne = prob.n_errors
        nm = ne + prob.n_effect_coefs
        J, _ = model.jk(self.poses, np.full(len(self.poses), self.L))
        cols = [J[:, i, :] for i in range(ne)]
        ctx = fx.context(model.machine, self.poses, None, {}, sc=prob.scales)
        for eff in prob.effects:
            basis = eff.basis(ctx)
            jp = J[:, list(model.errors).index(eff.param), :] if eff.param != fx.TOOL else \
                model.ideal_tool(self.poses, np.full(len(self.poses), self.L))[1]
            cols += [jp * basis[:, [j]] for j in range(basis.shape[1])]
        G = self.setup.remove(np.stack(cols, axis=-1).reshape(-1, nm)).reshape(len(self.poses), 3, nm)
        C = res.cov[:nm, :nm]
        w, V = np.linalg.eigh((C + C.T) / 2)
        draws = (V * np.sqrt(np.clip(w, 0, None))) @ rng.normal(size=(nm, BAND_DRAWS))
        e = np.einsum("pkn,nd->dpk", G, draws)
        rms = np.sqrt(np.mean(np.sum(e ** 2, axis=2), axis=1))
        return float(np.quantile(rms, 0.025)), float(np.quantile(rms, 0.975))


def trial(t: int, seed: int, n: int, folder: Path, models: dict) -> dict:
    rng = np.random.default_rng([seed, t])
    machine = MACHINES[t % len(MACHINES)]
    instrument = INSTRUMENTS[(t // len(MACHINES)) % len(INSTRUMENTS)]
    resolution = RESOLUTIONS[(t // (len(MACHINES) * len(INSTRUMENTS))) % len(RESOLUTIONS)]
    model = models[machine]
    chain = chain_of(model)
    sim_seed = int(rng.integers(1 << 30))
    null = bool(rng.random() < NULL_SHARE)
    k = float(rng.uniform(2.0, 10.0))
    rec = {"trial": t, "machine": machine, "instrument": instrument, "resolution": resolution, "null": null}
    effects = []
    if not null:
        sim0 = simulate(model, [], n=n, instrument=instrument, seed=sim_seed, noise=NOISE, chain=chain)
        drawn = hidden_effect(model, sim0, rng, k)
        if drawn is None:
            null = rec["null"] = True
        else:
            effects = [drawn]
            rec.update(effect=drawn[0].id, k=k)
    sim = simulate(model, effects, n=n, instrument=instrument, seed=sim_seed, noise=NOISE, chain=chain)
    meas = read(written(model, sim, folder / f"t{t}.csv", resolution), model.machine)
    dg = D.diagnose(model, meas)
    rec["verdict"] = dg.verdict
    top = dg.candidates[0] if dg.candidates else None
    added = [top["id"]] if dg.verdict == "missing effect" and top else []
    if top is not None:
        rec["top"], rec["aliases"] = top["id"], list(top["aliases"])
    if not null and added:
        rec["right"] = rec["effect"] in [top["id"]] + list(top["aliases"])
    res = F.fit(model, meas, added)
    rec["rms_over_noise"] = res.rms_mm / NOISE
    rec["covered"], rec["quantities"] = coverage(res, sim)
    ws = Workspace(model, seed + t)
    ctx = fx.context(model.machine, ws.poses, None, {}, sc=fx.scales(model.machine, sim.meas.t))
    E_true = np.tile([sim.base_errors[e] for e in model.errors], (len(ws.poses), 1))
    for eff, vals in effects:
        dE, _ = fx.per_pose([eff], [vals], ctx, model.errors)
        E_true = E_true + dE
    E_fit, _ = errors_at(from_fit(res), model, ws.poses)
    e_true = ws.tip(E_true)
    before, after = ws.rms(e_true), ws.rms(e_true - ws.tip(E_fit))
    lo, hi = ws.band(res, rng)
    rec.update(workspace_before_um=before * 1e3, workspace_after_um=after * 1e3, band_um=[lo * 1e3, hi * 1e3],
               band_covers=bool(lo <= after <= hi))
    return rec


def summary(trials: list) -> dict:
    nulls = [r for r in trials if r["null"]]
    hidden = [r for r in trials if not r["null"]]
    strong = [r for r in hidden if r["k"] >= 3]
    found = [r for r in hidden if "right" in r]
    ratio = np.array([r["rms_over_noise"] for r in trials])
    after = np.array([r["workspace_after_um"] / r["workspace_before_um"] for r in trials
                      if r["workspace_before_um"] > 0])

    def rate(a, b):
        return None if not b else a / b
    return {"trials": len(trials), "null_sets": len(nulls), "hidden_effects": len(hidden),
            "false_alarm_rate": rate(sum(r["verdict"] != "no missing effect" for r in nulls), len(nulls)),
            "miss_rate_k3": rate(sum(r["verdict"] != "missing effect" for r in strong), len(strong)),
            "miss_rate_all": rate(sum(r["verdict"] != "missing effect" for r in hidden), len(hidden)),
            "right_physics": rate(sum(r["right"] for r in found), len(found)),
            "rms_over_noise_median": float(np.median(ratio)) if len(ratio) else None,
            "rms_over_noise_p95": float(np.quantile(ratio, 0.95)) if len(ratio) else None,
            "coverage_k2": rate(sum(r["covered"] for r in trials), sum(r["quantities"] for r in trials)),
            "coverage_k2_null_sets": rate(sum(r["covered"] for r in nulls), sum(r["quantities"] for r in nulls)),
            "coverage_k2_named_right": rate(sum(r["covered"] for r in found if r["right"] and r["top"] == r["effect"]),
                                            sum(r["quantities"] for r in found if r["right"] and
                                                r["top"] == r["effect"])),
            "band_coverage": rate(sum(r["band_covers"] for r in trials), len(trials)),
            "workspace_after_over_before_median": float(np.median(after)) if len(after) else None}


def table(s: dict) -> str:
    """The summary as a Markdown table (docs/measurements.md)."""
    def pct(x):
        return "-" if x is None else f"{100 * x:.1f} %"
    rows = [("trials (null sets / hidden effects)", f"{s['trials']} ({s['null_sets']} / {s['hidden_effects']})"),
            ("false alarms (null sets)", pct(s["false_alarm_rate"])),
            ("misses, effects >= 3x the noise (all)", f"{pct(s['miss_rate_k3'])} ({pct(s['miss_rate_all'])})"),
            ("right physics named (top or alias)", pct(s["right_physics"])),
            ("residual after adding / noise: median, p95",
             f"{s['rms_over_noise_median']:.3f}, {s['rms_over_noise_p95']:.3f}"),
            ("coverage of the k = 2 intervals: all (null sets; hidden effect named itself)",
             f"{pct(s['coverage_k2'])} ({pct(s['coverage_k2_null_sets'])}; {pct(s['coverage_k2_named_right'])})"),
            ("coverage of the workspace band (k = 2)", pct(s["band_coverage"])),
            ("workspace error after / before (median)", pct(s["workspace_after_over_before_median"]))]
    return "\n".join(["| measured | value |", "|---|---|"] + [f"| {a} | {b} |" for a, b in rows])


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=210, help="random true machines (default 210)")
    ap.add_argument("--poses", type=int, default=400, help="poses of each plan (default 400)")
    ap.add_argument("--seed", type=int, default=29)
    ap.add_argument("--json", type=Path, default=None, help="write the trials and the summary here")
    args = ap.parse_args(argv)
    models = {m: load(m) for m in MACHINES}
    t0 = time.perf_counter()
    trials = []
    with tempfile.TemporaryDirectory() as tmp:
        for t in range(args.trials):
            trials.append(trial(t, args.seed, args.poses, Path(tmp), models))
            r = trials[-1]
            what = "null" if r["null"] else f"{r['effect']} k={r['k']:.1f}"
            print(f"{t:4d} {r['machine']:12s} {r['instrument']:14s} {r['resolution']:12s} "
                  f"{what:24s} {r['verdict']:22s} "
                  f"{r.get('top', '-'):16s} rms/noise {r['rms_over_noise']:.3f} cov {r['covered']}/{r['quantities']} "
                  f"ws {r['workspace_after_um']:.2f}/{r['workspace_before_um']:.2f} um "
                  f"band [{r['band_um'][0]:.2f}, {r['band_um'][1]:.2f}]", file=sys.stderr)
    s = summary(trials)
    s["seconds"] = time.perf_counter() - t0
    print(table(s))
    out = {"summary": s, "trials": trials, "table": table(s)}
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=1) + "\n")
    return out


if __name__ == "__main__":
    main()
