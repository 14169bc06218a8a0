"""Measurement plans (issue 12): how good `fiveaxis plan` is, measured, not timed.

1. D-criterion: a plan of N poses against random plans of N, 2N and 3N poses (median of 20 each, drawn uniformly
   within the instrument's constraints from the same population), and against the upper bound of any N-pose plan
   from the same candidates: log det(N M(w*)) of the approximate D-optimal design w* (multiplicative algorithm;
   Kiefer-Wolfowitz: max_c d_c(w*) = r at the optimum, printed; `plan.bound`), and widened by r log(max d / r) over
   fresh candidates (Atwood 1969) to bound any N poses within the constraints. For R-test the bound leaves the
   setups out, so it bounds D_s from above too.
2. Detection: a hidden effect named in --effects; per size N, the share of simulations at the planned poses (5
   noise seeds) and of random plans of N poses (10 plans) in which `diagnose` finds it (missing effect; the effect
   or an exact alias of it on top); "poses needed" is the smallest N from which the share stays >= 0.8.

Run: .venv/bin/python bench/bench_plan.py [--quick | --tiny]   (--tiny: the smoke test's one case of each part,
one size, one noise seed, 2 random plans; its numbers mean nothing)
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

import fiveaxis
from fiveaxis.planning import criterion, exchange, pool
from fiveaxis.planning import plan as P
from fiveaxis.diagnosis.diagnose import diagnose
from fiveaxis.measurement.simulate import simulate

CASES_D = [("ac_trunnion", "rtest", 20), ("ac_trunnion", "rtest", 40), ("li2018", "tip", 20), ("li2018", "tip", 40)]
CASES_DETECT = [("li2018", "tip", "ex_x:x2=5e-6"), ("ac_trunnion", "rtest", "ex_A:A2=2e-5")]
SIZES = [8, 12, 16, 20, 24, 32, 40, 48, 64, 80]
RANDOM = 20
NOISE_SEEDS = 5
RANDOM_DETECT = 10
SHARE = 0.8


def part_d(cases, random: int = RANDOM, fresh_units: int = 20000) -> list:
    print("== D-criterion: plan of N poses vs random plans (median of %d) and the bound of any N-pose plan" % random)
    print(f"{'machine':12s} {'instrument':10s} {'N':>4s} {'r':>3s} {'plan':>8s} {'bound':>8s} {'bound*':>8s} "
          f"{'rand N':>8s} "
          f"{'rand 2N':>8s} {'rand 3N':>8s}  plan>=rand 3N  worth (random poses)  time")
    rows = []
    for machine, instrument, n in cases:
        model = fiveaxis.load(machine)
        t = time.perf_counter()
        res = P.make(model, instrument, n, seed=0, random_plans=1, pool_units=max(30 * n, 1000))
        secs = time.perf_counter() - t
        dsg = res.design
        rng = np.random.default_rng(7)
        med = {}
        for mult in (1, 2, 3):
            med[mult] = float(np.median([dsg.criterion(exchange.random_units(dsg, mult * n, rng))[0]
                                         for _ in range(random)]))
        logdet_w, dmax, M = exchange.bound(dsg.X[:, :, dsg.cols("base")])
        b = logdet_w + res.r * math.log(n)
        # The bound holds for any plan within the constraints if no fresh candidate has d above r (equivalence
        # theorem): a second, larger pool from another seed, its rows in the same reference coordinates.
        fresh_pool = pool.pool(model, instrument, fresh_units, fresh_units, np.random.default_rng(99))
        fresh = criterion.design(model, fresh_pool, [], model.machine.fixed)
        A = criterion.design_block(fresh.problem).A[:, criterion.theta_columns(fresh.problem)]
        Xf = (A * fresh.problem.w[:, None] / dsg.ref.scale) @ dsg.ref.basis
        Xf = Xf[np.argsort(fresh.pool.unit[fresh.problem.obs.row], kind="stable")].reshape(fresh.C, fresh.k, -1)
        Xf = Xf.reshape(-1, res.r)
        d_fresh = np.sum((Xf @ np.linalg.inv(M)) * Xf, axis=1).reshape(fresh.C, fresh.k).sum(axis=1).max()
        # Atwood (1969): log det M* <= log det M(w) + r log(max_x d(x, w) / r) over the whole design space; the max
        # over the pool and the fresh candidates stands in for the max over every pose within the constraints.
        b_all = b + res.r * math.log(max(dmax, d_fresh) / res.r)
        # Equivalent random size from D_random(m) ~ a + r log m through the medians at N and 3N.
        slope = (med[3] - med[1]) / math.log(3)
        worth = n * math.exp((res.D - med[1]) / slope) if slope > 0 else float("nan")
        print(f"{machine:12s} {instrument:10s} {n:4d} {res.r:3d} {res.D:8.2f} {b:8.2f} {b_all:8.2f} {med[1]:8.2f} "
              f"{med[2]:8.2f} "
              f"{med[3]:8.2f}  {'yes' if res.D >= med[3] else 'NO':13s}  {worth:6.1f} ({worth / n:.2f} N)"
              f"        {secs:.1f} s   (bound check: max d = {dmax:.4f} on the pool, {d_fresh:.4f} on "
              f"{2 * fresh_units} fresh candidates; r = {res.r})")
        rows.append({"machine": machine, "instrument": instrument, "n": n, "D": res.D, "bound": b,
                     "bound_any": b_all, "random_median": med})
    print("   bound: log det(N M(w*)) over the same candidates: no N-pose plan from them exceeds it; bound*: the same\n"
          f"   widened by r log(max d / r) over {2 * fresh_units} fresh candidates (Atwood 1969): any N poses within\n"
          "   the constraints.\n"
          "   Where bound* < rand 3N, no plan of N poses reaches the median random plan of 3N on this criterion.")
    return rows


def found(model, plan, spec, seed) -> bool:
    sim = simulate(model, [spec], plan=plan, seed=seed, duration=None, noise=1e-3)
    dg = diagnose(model, sim.meas)
    eff = spec.split("=")[0]
    top = dg.candidates[0]
    return bool(dg.missing_effect and (top["id"] == eff or eff in top["aliases"]))


def needed(shares):
    """Smallest N from which the share stays >= SHARE, or None."""
    ok = None
    for n, s in shares:
        if s >= SHARE:
            ok = n if ok is None else ok
        else:
            ok = None
    return ok


def part_detect(cases, sizes, noise_seeds: int = NOISE_SEEDS, random_detect: int = RANDOM_DETECT) -> dict:
    print(f"\n== Detection of a named effect: share of simulations in which diagnose finds it (plan: {noise_seeds} "
          f"noise seeds; random: {random_detect} plans), noise 1 um")
    out = {}
    for machine, instrument, spec in cases:
        model = fiveaxis.load(machine)
        eff = spec.split("=")[0]
        plan_share, rand_share = [], []
        print(f"{machine} {instrument} hidden {spec}, plan --effects {eff}")
        print(f"   {'N':>4s} {'plan':>6s} {'random':>7s}  predicted std (u = 1): plan / random")
        for n in sizes:
            try:
                res = P.make(model, instrument, n, effects=[eff], seed=0, random_plans=1)
            except P.TooFewPoses:
                continue
            p = np.mean([found(model, res.plan, spec, 100 + s) for s in range(noise_seeds)])
            rr = np.random.default_rng(1000 + n)
            rand = pool.subplan(res.design.pool, exchange.random_units(res.design, len(res.units), rr))
            r = np.mean([found(model, rand, spec, 200 + s) for s in range(random_detect)])
            plan_share.append((n, p))
            rand_share.append((n, r))
            std = res.effect_std.get(eff, {})
            fmt = (lambda x: "-" if x is None else f"{x:.3g}")
            print(f"   {n:4d} {p:6.2f} {r:7.2f}  {fmt(std.get('plan'))} / {fmt(std.get('random'))} "
                  f"{std.get('unit', '')}", flush=True)
        print(f"   poses needed (share >= {SHARE} from there on): plan {needed(plan_share)}, random "
              f"{needed(rand_share) or f'more than {sizes[-1]}'}")
        out[(machine, instrument, spec)] = {"plan": plan_share, "random": rand_share}
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="every other case and size")
    ap.add_argument("--tiny", action="store_true", help="one case of each part, one size (the smoke test)")
    a = ap.parse_args(argv)
    if a.tiny:
        return {"d": part_d(CASES_D[:1], random=2, fresh_units=500),
                "detect": part_detect(CASES_DETECT[:1], [12], noise_seeds=1, random_detect=1)}
    return {"d": part_d(CASES_D[::2] if a.quick else CASES_D),
            "detect": part_detect(CASES_DETECT, SIZES[::2] if a.quick else SIZES)}


if __name__ == "__main__":
    main()
