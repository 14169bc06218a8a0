"""The set selection (`decision.select`, which keeps each member set's gains and value once made) against a plain
NumPy reference: the RSS it reports is that of a least-squares fit on the model and the set, and no move of the
rule (add one, remove one, swap one for one or two for one) lowers the set's extended BIC computed from lstsq."""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

from fiveaxis.diagnosis import candidates as cd
from fiveaxis.diagnosis import decision as dc


@dataclass(frozen=True)
class _Col:
    id: str
    names: tuple = ("c",)


def _rss(rw, Q, X):
    A = np.hstack([Q, X]) if X.shape[1] else Q
    r = rw - A @ np.linalg.lstsq(A, rw, rcond=None)[0]
    return float(r @ r)


def test_select_matches_a_least_squares_reference():
    rng = np.random.default_rng(7)
    N, M = 240, 14
    Q, _ = np.linalg.qr(rng.normal(size=(N, 5)))
    X = rng.normal(size=(N, M))
    y = 0.8 * X[:, 3] - 0.6 * X[:, 9] + 0.3 * X[:, 11] + rng.normal(size=N)
    rw = y - Q @ (Q.T @ y)
    lay = dc.layout(0, [(_Col(f"c{j}"), "polynomial", None) for j in range(M)])
    ks = lay.main()
    pens = {k: cd.ebic_penalty(N, M) for k in ks}
    used, rss = dc.select(X, Q, rw, lay, ks, pens, N, True)
    assert {3, 9} <= set(used)
    assert abs(rss - _rss(rw, Q, X[:, used])) <= 1e-9 * rss
    rss0 = float(rw @ rw)

    def value(S):
        return -(rss0 - _rss(rw, Q, X[:, sorted(S)])) + sum(pens[k] for k in S)
    best = value(used)
    others = [k for k in ks if k not in used]
    moves = [set(used) | {k} for k in others] if len(used) < dc.FORWARD_MAX else []
    moves += [set(used) - {j} for j in used] if len(used) > 1 else []
    moves += [(set(used) - set(out)) | {k} for n in (1, 2) for out in combinations(used, n) for k in others]
    assert all(value(S) >= best - 1e-6 for S in moves)
