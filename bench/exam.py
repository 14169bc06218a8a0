"""The proof at scale (issue 29): a Monte-Carlo exam of the fit, the diagnosis and the compensation's prediction
over random true machines.

Each trial draws a true machine (random base errors as `simulate` draws them: sd 3 um, 20 urad) on one of the three
shipped machines, measures it with one instrument's standard plan of about --poses poses (every machine, instrument
and way of writing in turn), the readings computed by an independent plain NumPy chain (`fiveaxis.model.htm`, not
the generated kernels; the instrument's reading of the tool's error and the setups' placements are fiveaxis's),
1 um noise, written as a controller writes them (0.001 mm, 0.0001 deg, readings to 0.01 um) or with 7 significant
digits, and read back from the file. Two sets in five are null (no effect beyond the geometric errors); the others
hide one effect of a random family diagnose can name (`_draw_id`: polynomial, reversal where the plan measures both
directions, periodic, thermal in time, profile at the spacing diagnose offers), coefficients in a random direction,
scaled so that its part the model's errors cannot absorb is k = 2..10 times the noise (RMS over the mm readings).
Then, as a user would: `diagnose`; the top candidate added when the verdict is "missing effect"; the fit; the
compensation of the workspace with the fitted model. Measured:
- false alarms: null sets whose verdict is not "no missing effect";
- misses: sets with an effect of k >= 3 whose verdict is not "missing effect";
- right physics: of the effects found, the hidden one named (same family, error and variable; `same_physics`) by
  the top candidate, one of its aliases or the set the decision accepts; the exact id apart;
- the residual after the fit / the noise;
- coverage of the k = 2 intervals of what the fit says the data determine (parameters and combinations) against
  the truth of those quantities: over every set, and over the sets whose model is right (null, or the hidden effect
  itself added: a wrongly named effect's coefficient has no truth);
- coverage of the workspace band: the k = 2 range `compensate` predicts for the RMS tool-tip error left over 400
  random poses after compensation with the fitted model and the part's set-up taken out
  (compensation.prediction.band: its upper end from the fit's posterior, its lower end from the posterior with the
  size priors taken as nearly exact zeros), against the truth's (the independent chain); which end a miss lies
  beyond;
- the workspace error after / before.
Rates come with their counts and Clopper-Pearson 95 % intervals, overall and per machine, instrument, resolution
and family. Not a timed test: `python bench/exam.py --trials 420 --jobs 2 --json out.json --records sets.jsonl`
prints the tables (docs/exam.md) and appends each set's record to sets.jsonl as it finishes (a partial run's
tables: `python bench/exam.py --tables sets.jsonl`); tests/test_bench.py runs it on three trials,
tests/test_exam.py a handful of sets.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from scipy.stats import beta

from fiveaxis.compensation import prediction
from fiveaxis.compensation.part_setup import SetupRemoval
from fiveaxis.diagnosis import diagnose as D
from fiveaxis.diagnosis import profiles
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
#: A hidden effect is at most this size over the plan's readings (peak to peak, mm, rad: what an error motion of a
#: machine tool can be); a draw whose k x noise needs more is drawn again (at most DRAWS times; then the set is
#: null and says so: `drawn_null`). 30 um / 100 urad left most draws at k > 6 without an effect (a linear error
#: motion at 10x the noise of tip readings spans about 60 um).
MAX_SIZE = {"mm": 0.100, "rad": 300e-6}
DRAWS = 100
#: Workspace poses.
WORKSPACE_POSES = 400


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


#: The families a hidden effect is drawn from (what `diagnose` can name), each as likely; reversal only where the
#: plan measures both approach directions of the axis.
FAMILIES = ("polynomial", "reversal", "periodic", "thermal", "profile")
#: A periodic effect's period: this share of the plan's span of its variable (several periods to one).
PERIOD_SHARE = (0.15, 0.8)
#: A thermal drift's time constant (s) over the default hour of a simulated set.
TAU_S = (200.0, 1500.0)
#: A periodic period and a thermal time constant count as the hidden one within these ratios (the searches round
#: them to 3 significant figures and refine on a grid).
PERIOD_RATIO = 1.1
TAU_RATIO = 2.0


def _draw_id(machine, meas, rng) -> str | None:
    """A random effect id of a random family: an error motion of an axis along its own variable (polynomial of
    degree 1-2, reversal, periodic, profile at the spacing a diagnosis offers on these positions), or any error
    motion or the tool length drifting in time (thermal); None if the family cannot be drawn on this plan."""
    family = FAMILIES[rng.integers(len(FAMILIES))]
    if family == "thermal":
        params = [n for a in machine.axes for n in a.pdge] + [fx.TOOL]
        tau = float(np.exp(rng.uniform(*np.log(TAU_S))))
        return f"{params[rng.integers(len(params))]}:te{tau:.3g}"
    moving = [(i, v) for i, v in enumerate(machine.variables) if np.ptp(meas.poses[:, i]) > 0]
    if family == "reversal":
        moving = [(i, v) for i, v in moving if v in meas.dirs and len(np.unique(meas.dirs[v])) > 1]
    if not moving:
        return None
    i, var = moving[rng.integers(len(moving))]
    axis = machine.axis(var)
    param = axis.pdge[rng.integers(len(axis.pdge))]
    tok = fx.var_token(machine, var)
    if family == "polynomial":
        return f"{param}:{tok}{int(rng.integers(1, 3))}"
    if family == "reversal":
        return f"{param}:{tok}r"
    to_unit = 180.0 / np.pi if axis.type == "rotary" else 1.0
    if family == "periodic":
        span = float(np.ptp(meas.poses[:, i])) * to_unit
        return f"{param}:{tok}p{rng.uniform(*PERIOD_SHARE) * span:.3g}"
    spacing = profiles.spacing_for(machine, tok, meas.poses[:, i] * to_unit)
    return None if spacing is None else fx.family("profile").format(param, tok, spacing)


def hidden_effect(model, sim0, rng, k: float):
    """An effect of a random family the plan sees (its part the model's errors cannot absorb at least VISIBLE of
    its signal), its coefficients in a random direction, scaled so that part is k times the noise (RMS over the mm
    readings), of a size a machine can have (MAX_SIZE over the plan's readings): (effect, values) or None."""
    machine = model.machine
    prob = build(model, sim0.meas, [])
    block = InMemory(prob).block
    A = block.A
    mm = prob.obs.group == 0
    for _ in range(DRAWS):
        ident = _draw_id(machine, sim0.meas, rng)
        if ident is None:
            continue
        eff = fx.parse(ident, machine, model.errors, poses=sim0.meas.poses)   # kT<n>: knots at the targets
        direction = rng.normal(size=len(eff.names))
        col = block.effect_columns([eff]) @ direction
        raw = float(np.sqrt(np.mean(col[mm] ** 2))) if mm.any() else 0.0
        if raw == 0.0:
            continue
        orth = col - A @ np.linalg.lstsq(A, col, rcond=None)[0]
        part = float(np.sqrt(np.mean(orth[mm] ** 2)))
        if part < VISIBLE * raw:
            continue
        values = direction * (k * NOISE / part)
        change = np.asarray(eff.basis(prob.ctx), float) @ values
        size = float(np.ptp(change))
        if size <= MAX_SIZE["rad" if eff.param != fx.TOOL and machine.is_angular(eff.param) else "mm"]:
            return eff, values
    return None


def same_physics(hidden, ident: str, model) -> bool:
    """Whether an effect id names the hidden effect's physics: the same error (ids as parsed: ISO names resolved),
    variable and family; any degree of a polynomial and any spacing of a profile; a period within PERIOD_RATIO and
    a time constant within TAU_RATIO of the hidden one's."""
    try:
        eff = fx.parse(ident, model.machine, model.errors)
    except Exception:                       # a custom effect or another grammar: not the hidden one
        got = fx.split(ident, fx.tokens(model.machine))     # a profile at the measured targets (knots from data)
        return got is not None and (got[0].NAME, *got[1][:2]) == ("profile", hidden.param, hidden.var) == (
            hidden.NAME, hidden.param, hidden.var)
    if (eff.NAME, eff.param, eff.var) != (hidden.NAME, hidden.param, hidden.var):
        return False
    if eff.NAME == "periodic":
        return max(eff.arg / hidden.arg, hidden.arg / eff.arg) <= PERIOD_RATIO
    if eff.NAME == "thermal":
        return max(eff.arg / hidden.arg, hidden.arg / eff.arg) <= TAU_RATIO
    return True


def named(dg) -> list[str]:
    """What a diagnosis names: the top candidate and its aliases, the effects its rule accepts (forward selection)."""
    top = dg.candidates[0] if dg.candidates else None
    out = [top["id"], *top["aliases"]] if top else []
    return out + [f["id"] for f in (dg.forward if dg.decision.get("passes") else [])]


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

    def band(self, res) -> tuple[float, float, float | None]:
        """The k = 2 range (mm) of the RMS left over these poses after compensating with the fit, the part's set-up
        taken out, as `compensate` predicts it (compensation.prediction.band), for a compensation that removes the
        fitted model's error exactly; and the share of its upper end's mean square the size priors decide (None
        for a fit without priors)."""
        fm = from_fit(res)
        zero = np.zeros((len(self.poses), 3))
        got = prediction.band(fm, self.model, self.poses, None, self.L, {"after": zero}, {}, fm.fit.get("noise_mm"))
        sr = got["tip_error_mm"]["after"]["setup_removed"]
        lo, hi = sr["range_k2"]
        return float(lo), float(hi), sr.get("prior_share")


def trial(t: int, seed: int, n: int, folder: Path, models: dict) -> dict:
    """Trial t of the exam seeded `seed`: its machine, instrument and resolution by t (every combination in turn),
    null or hidden effect and k drawn."""
    rng = np.random.default_rng([seed, t])
    machine = MACHINES[t % len(MACHINES)]
    instrument = INSTRUMENTS[(t // len(MACHINES)) % len(INSTRUMENTS)]
    resolution = RESOLUTIONS[(t // (len(MACHINES) * len(INSTRUMENTS))) % len(RESOLUTIONS)]
    sim_seed = int(rng.integers(1 << 30))
    null = bool(rng.random() < NULL_SHARE)
    k = float(rng.uniform(2.0, 10.0))
    rec = run_set(models[machine], instrument, resolution, n, sim_seed, None if null else k, rng,
                  folder / f"t{t}.csv", seed + t)
    return {"trial": t, **rec}


def run_set(model, instrument: str, resolution: str, n: int, sim_seed: int, k: float | None, rng, path: Path,
            workspace_seed: int) -> dict:
    """One set: a true machine measured by the instrument's plan of about n poses (a null set for k None, else one
    hidden effect at k times the noise), written at the resolution to path and read back; diagnose, the top
    candidate added on a verdict 'missing effect', the fit; the record of what was measured (see the module)."""
    chain = chain_of(model)
    null = k is None
    rec = {"machine": model.machine.name, "instrument": instrument, "resolution": resolution, "null": null}
    effects = []
    if not null:
        sim0 = simulate(model, [], n=n, instrument=instrument, seed=sim_seed, noise=NOISE, chain=chain)
        drawn = hidden_effect(model, sim0, rng, k)
        if drawn is None:
            null = rec["null"] = rec["drawn_null"] = True
        else:
            effects = [drawn]
            rec.update(effect=drawn[0].id, family=drawn[0].NAME, k=k)
    sim = simulate(model, effects, n=n, instrument=instrument, seed=sim_seed, noise=NOISE, chain=chain)
    meas = read(written(model, sim, path, resolution), model.machine)
    dg = D.diagnose(model, meas)
    rec["verdict"] = dg.verdict
    top = dg.candidates[0] if dg.candidates else None
    added = [top["id"]] if dg.verdict == "missing effect" and top else []
    if top is not None:
        rec["top"], rec["aliases"] = top["id"], list(top["aliases"])
    rec["accepted"] = [f["id"] for f in dg.forward] if dg.decision.get("passes") else []
    if not null and dg.verdict == "missing effect":
        rec["right"] = any(same_physics(effects[0][0], i, model) for i in named(dg))
        rec["right_id"] = rec["effect"] in named(dg)
    res = F.fit(model, meas, added)
    rec["added"] = added
    rec["model_right"] = added == [e.id for e, _ in effects]
    rec["rms_over_noise"] = res.rms_mm / NOISE
    rec["covered"], rec["quantities"] = coverage(res, sim)
    ws = Workspace(model, workspace_seed)
    ctx = fx.context(model.machine, ws.poses, None, {}, sc=fx.scales(model.machine, sim.meas.t))
    E_true = np.tile([sim.base_errors[e] for e in model.errors], (len(ws.poses), 1))
    for eff, vals in effects:
        here = fx.family(eff.NAME).evaluated_in(eff.record(tuple(vals), (None,) * len(vals)), ctx)
        if here is not None:     # as compensation evaluates it: time effects at t = 0, reversals without directions
            dE, _ = fx.per_pose([eff], [vals], here, model.errors)
            E_true = E_true + dE
    E_fit, _ = errors_at(from_fit(res), model, ws.poses)
    e_true = ws.tip(E_true)
    before, after = ws.rms(e_true), ws.rms(e_true - ws.tip(E_fit))
    lo, hi, share = ws.band(res)
    rec.update(workspace_before_um=before * 1e3, workspace_after_um=after * 1e3, band_um=[lo * 1e3, hi * 1e3],
               band_covers=bool(lo <= after <= hi), band_side="below" if after < lo else "above" if after > hi else "",
               band_prior_share=share)
    return rec


def interval(a: int, b: int) -> tuple[float, float] | None:
    """Clopper-Pearson 95 % interval of a binomial rate a / b."""
    if not b:
        return None
    lo = 0.0 if a == 0 else float(beta.ppf(0.025, a, b - a + 1))
    hi = 1.0 if a == b else float(beta.ppf(0.975, a + 1, b - a))
    return lo, hi


def rates(trials: list) -> dict:
    """Counts (a, b) of every rate over these trials."""
    nulls = [r for r in trials if r["null"]]
    hidden = [r for r in trials if not r["null"]]
    strong = [r for r in hidden if r["k"] >= 3]
    found = [r for r in hidden if "right" in r]
    right_model = [r for r in trials if r["model_right"]]
    return {"false_alarms": (sum(r["verdict"] != "no missing effect" for r in nulls), len(nulls)),
            "misses_k3": (sum(r["verdict"] != "missing effect" for r in strong), len(strong)),
            "unnoticed_k3": (sum(r["verdict"] == "no missing effect" for r in strong), len(strong)),
            "misses_all": (sum(r["verdict"] != "missing effect" for r in hidden), len(hidden)),
            "right_physics": (sum(r["right"] for r in found), len(found)),
            "right_id": (sum(r["right_id"] for r in found), len(found)),
            "coverage_k2": (sum(r["covered"] for r in trials), sum(r["quantities"] for r in trials)),
            "coverage_k2_model_right": (sum(r["covered"] for r in right_model),
                                        sum(r["quantities"] for r in right_model)),
            "band_coverage": (sum(r["band_covers"] for r in trials), len(trials)),
            "band_coverage_model_right": (sum(r["band_covers"] for r in right_model), len(right_model)),
            "band_below": (sum(r.get("band_side") == "below" for r in trials), len(trials)),
            "band_above": (sum(r.get("band_side") == "above" for r in trials), len(trials))}


def summary(trials: list) -> dict:
    ratio = np.array([r["rms_over_noise"] for r in trials])
    found = [r for r in trials if r.get("right")]
    ratio_found = np.array([r["rms_over_noise"] for r in found])
    after = np.array([r["workspace_after_um"] / r["workspace_before_um"] for r in trials
                      if r["workspace_before_um"] > 0])
    counts = rates(trials)
    out = {"trials": len(trials), "null_sets": sum(r["null"] for r in trials),
           "hidden_effects": sum(not r["null"] for r in trials), "counts": counts,
           "drawn_null": sum(bool(r.get("drawn_null")) for r in trials)}
    for key, (a, b) in counts.items():
        out[key] = None if not b else a / b
        out[key + "_ci95"] = interval(a, b)
    out.update(rms_over_noise_median=float(np.median(ratio)) if len(ratio) else None,
               rms_over_noise_p95=float(np.quantile(ratio, 0.95)) if len(ratio) else None,
               rms_over_noise_found_median=float(np.median(ratio_found)) if len(ratio_found) else None,
               workspace_after_over_before_median=float(np.median(after)) if len(after) else None)
    # the names the first version of this summary had
    out["false_alarm_rate"], out["miss_rate_k3"] = out["false_alarms"], out["misses_k3"]
    return out


#: The rows of the tables: (label, key of rates) and what the issue's done criteria ask.
ROWS = (("false alarms (null sets)", "false_alarms", "<= 5 %"),
        ("misses, effects >= 3x noise (no verdict 'missing effect')", "misses_k3", "<= 10 %"),
        ("unnoticed, effects >= 3x noise (verdict 'no missing effect')", "unnoticed_k3", ""),
        ("misses, all effects (2-10x noise)", "misses_all", ""),
        ("right physics named (found effects: top, alias or accepted)", "right_physics", ">= 90 %"),
        ("right id named (the exact id)", "right_id", ""),
        ("k = 2 coverage, model right (null or hidden effect added)", "coverage_k2_model_right", "93-97 %"),
        ("k = 2 coverage, every set", "coverage_k2", ""),
        ("workspace band coverage, every set", "band_coverage", ">= 95 %"),
        ("workspace band coverage, model right", "band_coverage_model_right", ""),
        ("workspace band: the truth below its lower end", "band_below", ""),
        ("workspace band: the truth above its upper end", "band_above", ""))


def _cell(a: int, b: int) -> str:
    if not b:
        return "-"
    lo, hi = interval(a, b)
    return f"{100 * a / b:.1f} % ({a}/{b}; {100 * lo:.1f}-{100 * hi:.1f})"


def table(s: dict) -> str:
    """The overall summary as a Markdown table: each rate with its count and Clopper-Pearson 95 % interval."""
    c = s["counts"]
    rows = [("trials (null sets / hidden effects)", f"{s['trials']} ({s['null_sets']} / {s['hidden_effects']}; "
             f"{s.get('drawn_null', 0)} null for want of an effect of that k within the size limit)", "")]
    rows += [(label, _cell(*c[key]), goal) for label, key, goal in ROWS]

    def num(x, f="{:.3f}"):
        return "-" if x is None else f.format(x)
    rows += [("residual after the fit / noise: median, p95 (found right: median)",
              f"{num(s['rms_over_noise_median'])}, {num(s['rms_over_noise_p95'])} "
              f"({num(s['rms_over_noise_found_median'])})", ""),
             ("workspace error after / before (median, part's set-up out)",
              num(s["workspace_after_over_before_median"] and 100 * s["workspace_after_over_before_median"],
                  "{:.1f} %"), "")]
    return "\n".join(["| measured | value (count; 95 % interval) | done when |", "|---|---|---|"]
                     + [f"| {a} | {b} | {g} |" for a, b, g in rows])


def breakdown(trials: list, by: str) -> str:
    """Rates per value of `by` (machine, instrument, resolution, family): one row each, columns the main rates."""
    keys = ("false_alarms", "misses_k3", "right_physics", "coverage_k2_model_right", "band_coverage")
    head = f"| {by} | sets | " + " | ".join(k.replace("_", " ") for k in keys) + " |"
    lines = [head, "|" + "---|" * (len(keys) + 2)]
    values = sorted({r.get(by) or "null" for r in trials}, key=str)
    for v in values:
        sub = [r for r in trials if (r.get(by) or "null") == v]
        c = rates(sub)
        lines.append(f"| {v} | {len(sub)} | " + " | ".join(_cell(*c[k]) for k in keys) + " |")
    return "\n".join(lines)


def _run(args):
    t, seed, n, folder = args
    return trial(t, seed, n, Path(folder), _models())


_MODELS = {}


def _models() -> dict:
    if not _MODELS:
        _MODELS.update({m: load(m) for m in MACHINES})
    return _MODELS


def _line(r) -> str:
    what = "null" if r["null"] else f"{r['effect']} k={r['k']:.1f}"
    return (f"{r['trial']:4d} {r['machine']:12s} {r['instrument']:14s} {r['resolution']:12s} {what:26s} "
            f"{r['verdict']:22s} {r.get('top', '-'):18s} {'right' if r.get('right') else '':5s} "
            f"rms/noise {r['rms_over_noise']:.3f} cov {r['covered']}/{r['quantities']} "
            f"ws {r['workspace_after_um']:.2f}/{r['workspace_before_um']:.2f} um "
            f"band [{r['band_um'][0]:.2f}, {r['band_um'][1]:.2f}]")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=210, help="random true machines (default 210)")
    ap.add_argument("--first", type=int, default=0, help="first trial's number (default 0: trials are seeded by it)")
    ap.add_argument("--poses", type=int, default=400, help="poses of each plan (default 400)")
    ap.add_argument("--seed", type=int, default=29)
    ap.add_argument("--jobs", type=int, default=1, choices=(1, 2), help="processes (default 1)")
    ap.add_argument("--json", type=Path, default=None, help="write the trials and the summary here")
    ap.add_argument("--records", type=Path, default=None,
                    help="append each set's record here as it finishes (JSON lines: a partial run is usable)")
    ap.add_argument("--tables", type=Path, default=None,
                    help="print the tables of the records in this JSON-lines file (a partial run) and stop")
    args = ap.parse_args(argv)
    if args.tables is not None:
        trials = [json.loads(line) for line in args.tables.read_text().splitlines() if line.strip()]
        return report(trials, argv, None, None)
    t0 = time.perf_counter()
    trials = []
    with tempfile.TemporaryDirectory() as tmp:
        work = [(t, args.seed, args.poses, tmp) for t in range(args.first, args.first + args.trials)]
        if args.jobs == 1:
            runs = map(_run, work)
            pool = None
        else:
            pool = ProcessPoolExecutor(args.jobs)
            runs = pool.map(_run, work)
        for r in runs:
            trials.append(r)
            print(_line(r), file=sys.stderr, flush=True)
            if args.records is not None:
                with open(args.records, "a") as fh:
                    fh.write(json.dumps(r) + "\n")
        if pool is not None:
            pool.shutdown()
    return report(trials, argv, args.json, time.perf_counter() - t0)


def report(trials: list, argv, path: Path | None, seconds: float | None) -> dict:
    """Print the tables of these sets' records; write them with the summary to path (JSON) if given."""
    s = summary(trials)
    s["seconds"] = seconds
    tables = {by: breakdown(trials, by) for by in ("machine", "instrument", "resolution", "family")}
    print(table(s))
    for by, text in tables.items():
        print("\n" + text)
    out = {"summary": s, "trials": trials, "table": table(s), "tables": tables,
           "command": "python bench/exam.py " + " ".join(argv if argv is not None else sys.argv[1:])}
    if path is not None:
        path.write_text(json.dumps(out, indent=1) + "\n")
    return out


if __name__ == "__main__":
    main()
