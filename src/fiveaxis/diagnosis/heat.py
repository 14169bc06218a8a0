"""Heat in a diagnosis: every temperature channel searched against every error and the tool length, and what the
decision's answer means for the sensors.

The search (`search`, for `fiveaxis.diagnosis.candidates.build_pool`): for each channel temp_<name> of the data and
each parameter p (every error and L), the column a_p (T_lag - T_ref) of the temperature family
(`fiveaxis.effects.temperature`) for the lag tau = 0 (none) and every tau of the time-constant grid of the thermal
search (`fiveaxis.diagnosis.searches.tau_grid`), scored exactly (projected off the fitted design, from the per-pose
sums of `searches.RowSums`); the best tau per (p, channel) refined on the log scale (9 points over +-1 grid step,
then +-1/4) for the REFINE best pairs of each channel, rounded to 3 significant figures. The scale expansion of each
linear axis (its positioning error times its position: `dx_x:x.temp_<name>`) is searched the same way. Each found
candidate is one column (a single of the pool); the family's trials are every (parameter, channel, tau) tried.

What the answer means (`assess`, after the decision):
- confounded: an accepted temperature effect whose column is nearly that of a time effect of the same parameter
  (or an accepted time effect nearly that of a temperature one): |cos| of their columns projected off the fitted
  design above CONFOUNDED; the test cannot tell time from temperature (temperatures rising with time); a cool-down
  phase, a spindle stop or a second day would separate them;
- missing sensor: the accepted set explains a drift by time (or the residual after it still drifts with time)
  while no measured channel does: the temperature that drives it is not measured (or only through a proxy); a
  model in time does not hold tomorrow: a sensor is asked for;
- sensors: the channels the accepted effects use, and for each whether the others keep the error at the noise
  without it (the model refitted without that channel's effects, the channel's best candidate searched again among
  the remaining channels): the smallest set, the redundant channels (another channel takes its place) and those
  that explain nothing here.
Units: weighted readings in the search; mm (RMS) in the assessment; tau in s; temperatures in degC.
"""
from __future__ import annotations

import math

import numpy as np

from ..effects import families as fx
from ..effects.base import axis_of_token
from ..estimation import fit as F
from . import searches as es

#: Pairs (parameter, channel) per channel whose lag is refined between grid points.
REFINE = 8
#: |cos| between projected columns above which a temperature and a time effect are confounded in a test.
CONFOUNDED = 0.95
#: A channel is not needed when the model without its effects leaves at most this times the noise.
KEEPS_NOISE = 1.1


def channels(ctx) -> list[str]:
    """The temperature channels of a context that vary and are read in every row (or interpolated in time)."""
    return [c for c, T in ctx.temps.items() if np.isfinite(T).all() and np.ptp(T) > 0]


def search(sums: es.RowSums, ctx, machine, grid, rss: float, N: int, present=(), only=None) -> tuple[list, int]:
    """(found candidates `searches.Found`, trials) of the temperature family on a screen: sums over its poses (the
    parameters' columns with the residual, live poses), ctx the screen's effect context, grid the thermal search's
    `TauGrid` (None: no lags, only tau = 0), rss the weighted residual's sum of squares over N readings (a lag is
    kept only where it lowers the BIC against none: N ln((rss - g_0) / (rss - g_tau)) > ln N); present: ids of
    the model's effects: a (parameter, channel, axis) the model has already is not offered again with another lag
    (a second time constant of one sensor on one error would model the sensor's noise, not the machine); only: the
    channels to search (None: every varying one)."""
    live = sums.live
    cols = np.flatnonzero(sums.W2.sum(axis=0) > 0)
    chans = [c for c in channels(ctx) if only is None or c in only]
    if not len(cols) or not chans:
        return [], 0
    sub = es.RowSums(sums.params, sums.W1[live][:, cols], sums.W2[live][:, cols], sums.W3[live][:, :, cols], live)
    taus = np.concatenate([[0.0], grid.taus if grid is not None else []])
    scale = [(j, tok) for j, p in enumerate(cols) for tok in fx.tokens(machine, False)
             if sums.params[p] != fx.TOOL and machine.axis(axis_of_token(machine, tok)).type == "linear"
             and fx.is_positioning(machine, sums.params[p], tok)]
    out = []
    for ch in chans:
        ref = ctx.scales[ch].centre
        X = np.column_stack([ctx.lagged(ch, tau) - ref for tau in taus])[live]       # (n_live, k)
        g = es.column_gains(sub, X)                                                  # (np, k)
        out += _best(sub, g, taus, lambda tau, _j: ctx.lagged(ch, tau, keep=False)[live] - ref,
                     [(j, sums.params[p], ch, None) for j, p in enumerate(cols)], cols, rss, N)
        for j, tok in scale:
            u = ctx.u(tok)[live]
            gj = es.column_gains(_one(sub, j), X * u[:, None])
            out += _best(_one(sub, j), gj, taus,
                         lambda tau, _j, u=u: (ctx.lagged(ch, tau, keep=False)[live] - ref) * u,
                         [(0, sums.params[cols[j]], ch, tok)], cols[[j]], rss, N)
    trials = (len(cols) + len(scale)) * len(chans) * len(taus)
    have = set()
    for ident in present:
        got = fx.split(ident, fx.tokens(machine))
        if got is not None and got[0] is fx.Temperature:
            param, channel, _, axis = got[1]
            have.add((param, channel, axis))
    return [f for f in out if f.gain > 0 and (f.effect.param, f.effect.var, f.effect.axis) not in have], trials


def fold_search(sums: es.RowSums, ctx, machine, grid, rss: float, N: int, keys) -> list:
    """The lags of a cross-validation fold's own search (its training rows' sums, rss and N): for each (parameter
    index into sums.params, parameter, channel, axis) of keys, the best lag of that candidate searched again as
    `search` does on the whole data, so that a lag chosen on all the readings never enters a fold."""
    out = []
    for j, param, channel, axis in keys:
        one = es.RowSums([sums.params[j]], sums.W1[:, [j]], sums.W2[:, [j]], sums.W3[:, :, [j]], sums.live)
        found, _ = search(one, ctx, machine, grid, rss, N, only={channel})
        out += [es.Found(f.effect, f.gain, j) for f in found
                if (f.effect.param, f.effect.var, f.effect.axis) == (param, channel, axis)]
    return out


def _one(sub: es.RowSums, j: int) -> es.RowSums:
    return es.RowSums([sub.params[j]] if len(sub.params) > j else sub.params, sub.W1[:, [j]], sub.W2[:, [j]],
                      sub.W3[:, :, [j]], sub.live)


def _best(sub, g, taus, basis, rows, cols, rss, N) -> list:
    """The best tau per row of gains g (np, k; column 0: no lag), a lag only where it lowers the BIC against none;
    the REFINE best with a lag refined on a log scale."""
    k = np.argmax(g, axis=1)
    gain = g[np.arange(len(k)), k]
    g0 = g[:, 0]
    worth = N * np.log(np.maximum(rss - g0, 1e-300) / np.maximum(rss - gain, 1e-300)) > math.log(max(N, 2))
    k = np.where(worth, k, 0)
    gain = np.where(worth, gain, g0)
    best = taus[k]
    step = math.log(taus[2] / taus[1]) if len(taus) > 2 else 0.0
    for i in np.argsort(-gain)[:REFINE]:
        if best[i] <= 0 or not step:
            continue
        j = rows[i][0]
        x = math.log(best[i])
        for width in (step, step / 4):
            cand = x + np.linspace(-width, width, 9)
            gains = [_gain(sub, j, basis(math.exp(c), j)) for c in cand]
            x = cand[int(np.argmax(gains))]
        tau = es.rounded(math.exp(x), 3)
        gt = _gain(sub, j, basis(tau, j))
        if gt >= gain[i]:
            best[i], gain[i] = tau, gt
    return [es.Found(fx.Temperature.make(param, ch, float(best[i]), axis), float(gain[i]), int(cols[i]))
            for i, (j, param, ch, axis) in enumerate(rows)]


def _gain(sub, j, b) -> float:
    return float(es.column_gains(_one(sub, j), b[:, None])[0, 0])


# -- what the answer means for the sensors -----------------------------------------------------------------------
def assess(res, scores, pool, accepted: list, noise: float, verdict: str, strongest) -> dict | None:
    """The heat section of a diagnosis (see the module docstring), or None when the data have no temperature and no
    effect of time is accepted. res: the fit; scores: `candidates.project` of the pool's singles on the screen;
    accepted: the effects the decision accepts; noise (mm); verdict; strongest: the strongest structure test left
    (its JSON record, `residual_tests`), or None."""
    prob = res.problem
    data = list(prob.meas.temps)
    timed = [e for e in accepted if getattr(e, "var", None) == fx.TIME]
    heated = [e for e in accepted if isinstance(e, fx.Temperature)]
    if not data and not timed:
        return None
    out = {"channels": data, "varying": channels(prob.ctx), "accepted": [e.id for e in heated]}
    index = {e.id: j for j, e in enumerate(pool.singles)}
    conf = []
    for e in heated + timed:
        j = index.get(e.id)
        if j is None:
            continue
        cos = scores.cos_with(j)
        rivals = [i for i, f in enumerate(pool.singles) if f.param == e.param and f is not e
                  and (getattr(f, "var", None) == fx.TIME if isinstance(e, fx.Temperature)
                       else isinstance(f, fx.Temperature))]
        if rivals:
            i = max(rivals, key=lambda i: cos[i])
            if cos[i] > CONFOUNDED:
                conf.append({"effect": e.id, "with": pool.singles[i].id, "cos": float(cos[i])})
    if conf:
        out["confounded"] = conf
        out["confounded_note"] = ("time and temperature are confounded in this test: the temperatures rise (or fall) "
                                  "with time, so a time effect explains the same readings; a cool-down phase, a spindle "
                                  "stop or a second day with another temperature history would separate them")
    drift = bool(strongest) and strongest.get("var") == fx.TIME and verdict == "unexplained structure"
    if timed or drift:
        out["missing_sensor"] = {
            "explained_by_time": [e.id for e in timed],
            "note": ("a thermal drift the measured temperatures do not explain: "
                     + (f"the best candidate is in time ({', '.join(e.id for e in timed)})" if timed else
                        "the residual still drifts with time")
                     + (f" (measured channels: {', '.join(data)}: a proxy at best)" if data else "")
                     + "; a model in time does not hold on another day: measure the temperature that drives it (a "
                     "sensor on the " + ("spindle housing" if any(e.param == fx.TOOL for e in timed) else
                                         "structure whose error drifts") + ") and diagnose again")}
    if heated:
        out["sensors"] = sensors(res, accepted, heated, noise, scores, pool)
    return out


def sensors(res, accepted, heated, noise: float, scores, pool) -> dict:
    """The smallest set of channels that keeps the error at the noise (backward: a channel whose effects the model
    can do without, within KEEPS_NOISE x the noise, is dropped), and why each other channel is not needed."""
    prob = res.problem
    used = list(dict.fromkeys(e.var for e in heated))
    keep = list(used)
    rms = {}
    for ch in used:
        trial = [e for e in accepted if not isinstance(e, fx.Temperature) or e.var in set(keep) - {ch}]
        fitted = F.fit(prob.model, prob.meas, list(prob.effects) + trial, robust=False)
        rms[ch] = float(fitted.rms_mm)
        if noise and rms[ch] <= KEEPS_NOISE * noise:
            keep.remove(ch)
    index = {e.id: j for j, e in enumerate(pool.singles)}
    others = []
    for ch in [c for c in prob.meas.temps if c not in keep]:
        own = [j for j, e in enumerate(pool.singles) if isinstance(e, fx.Temperature) and e.var == ch]
        best_cos, with_ = 0.0, None
        for e in heated:
            if e.var == ch or e.id not in index or not own:
                continue
            cos = scores.cos_with(index[e.id])[own]
            if cos.max() > best_cos:
                best_cos, with_ = float(cos.max()), e.var
        if ch in used:
            why = f"the others keep the error at the noise without it (RMS {rms[ch] * 1000:.3g} um without)"
        elif with_ is not None and best_cos > CONFOUNDED:
            why = f"redundant: it reads what {with_} reads here (|cos| {best_cos:.3f} of their columns)"
        else:
            why = "explains nothing the accepted effects do not"
        others.append({"channel": ch, "why": why})
    return {"smallest_set": keep, "rms_without_mm": rms, "not_needed": others,
            "rule": f"a channel is dropped when the model without its effects leaves at most {KEEPS_NOISE:g} x the "
                    f"noise ({noise * 1000:.3g} um)"}
