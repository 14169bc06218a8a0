"""Benchmark: `diagnose` on 1,500 poses with the whole vocabulary (756 candidates), against two baselines
measured in the same run and extrapolated to all candidates:
  - refit per candidate, first order: a least-squares solve of [design, candidate] for each candidate;
  - refit per candidate, as a user would with `--add`: `fit` (first order + exact refinement) per candidate.
diagnose instead scores every candidate against the fitted design's column space at once (one SVD, Q^T G, G^T r).
All on one BLAS thread, as diagnose runs (several BLAS threads slow badly on busy cores).
Target: diagnose under 5 s on 2 cores. Run: .venv/bin/python bench/bench_diagnose.py
"""
from __future__ import annotations

import os
import time

import numpy as np

import fiveaxis
from fiveaxis import diagnose as D
from fiveaxis import fit as F
from fiveaxis.simulate import simulate


def _best(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main(n: int = 1500, subset_first: int = 60, subset_exact: int = 6) -> dict:
    model = fiveaxis.load("li2018")
    meas = simulate(model, ["ex_x:x1=2e-5"], n=n, noise=1e-3, seed=1).meas
    D.diagnose(model, meas)                                   # warm up numba and imports
    t_diag, dg = _best(lambda: D.diagnose(model, meas))
    M = dg.n_candidates
    res = F.fit(model, meas)
    prob = res.problem
    vocab = [e for e in fiveaxis.effects.vocabulary(model.machine, model.errors, True)]
    G = D.candidate_matrix(prob, vocab)
    Aw = prob.A * prob.w[:, None]
    dw = prob.d * prob.w

    def first_order():
        rss = []
        for j in range(subset_first):
            X = np.hstack([Aw, G[:, [j]]])
            coef, *_ = np.linalg.lstsq(X, dw, rcond=None)
            rss.append(float(np.sum((dw - X @ coef) ** 2)))
        return rss

    with F.one_blas_thread():                                 # same BLAS setting as diagnose
        t_first, _ = _best(first_order, repeat=1)
    t_first_all = t_first / subset_first * M

    def exact():
        return [F.fit(model, meas, [vocab[j]]).rms_mm for j in range(subset_exact)]

    t_exact, _ = _best(exact, repeat=1)
    t_exact_all = t_exact / subset_exact * M
    out = {"poses": n, "candidates": M, "cores": os.cpu_count(), "diagnose_s": t_diag,
           "refit_first_order_s": t_first_all, "refit_exact_s": t_exact_all,
           "speedup_vs_first_order_refit": t_first_all / t_diag, "speedup_vs_exact_refit": t_exact_all / t_diag}
    print(f"diagnose, {n} poses, {M} candidates: {t_diag:.2f} s (best of 3, warm; target < 5 s on 2 cores; "
          f"{out['cores']} cores here)")
    print(f"  baseline refit per candidate, first order: {t_first_all:.1f} s "
          f"({subset_first} candidates timed, extrapolated) -> diagnose is {out['speedup_vs_first_order_refit']:.0f}x "
          f"faster")
    print(f"  baseline refit per candidate, fit --add (exact): {t_exact_all:.1f} s "
          f"({subset_exact} candidates timed, extrapolated) -> diagnose is {out['speedup_vs_exact_refit']:.0f}x faster")
    print(f"  (diagnose also runs {D.K_FOLDS}-fold nested cross-validation and the alias search in that time)")
    return out


if __name__ == "__main__":
    main()
