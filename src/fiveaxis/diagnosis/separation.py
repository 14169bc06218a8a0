"""Which extra measurement would separate what the data cannot: the one place for that advice.

Three questions, one method: repeat the measured readings at modified poses (`options`: another tool length; the
whole stroke of an axis the data covers less than FULL_STROKE of), build the design of the data plus the variant,
and see what parts.
- `effects`: candidate effects the diagnosis cannot tell apart (aliases): which option makes their projected
  columns part (|cos| no longer above ALIAS_COS);
- `parameters`: groups of parameters a fit does not determine alone: which option determines which member;
- `hidden_by_placement`: candidate effects only a setup's placement unknowns absorb (a machine error that looks
  like the artefact lying differently), and whether readings of known orientation would separate them.
Units: mm and rad, as the measurements.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.sparse.csgraph import connected_components

from ..estimation import design as dsg
from ..estimation import solver as sv
from ..estimation.problem import build
from ..exceptions import InputError
from ..measurement.files import concat
from ..measurement.setups import is_setup_param
from ..model import iso_names as iso
from . import candidates as cd
from .decision import ALIAS_COS, orthonormal

#: An axis covered over less than this fraction of its stroke is offered the whole stroke.
FULL_STROKE = 0.9
#: Another tool length: this much longer than the measured one (mm).
EXTRA_TOOL_MM = 100.0


def options(model, meas, seed: int = 1) -> list[tuple[str, object]]:
    """Extra measurements to try, as (text, the measured readings at the modified poses): another tool length;
    the whole stroke of each axis the data covers less than FULL_STROKE of (poses drawn uniformly over it)."""
    rng = np.random.default_rng(seed)
    L0 = float(np.median(meas.L))
    out = [(f"another tool length (L = {L0 + EXTRA_TOOL_MM:g} mm besides {L0:g} mm)",
            meas.with_poses(meas.poses, np.full(meas.n, L0 + EXTRA_TOOL_MM)))]
    for i, v in enumerate(meas.variables):
        ax = model.machine.axis(v)
        lo, hi = ax.model_stroke
        vals = meas.poses[:, i]
        if vals.max() - vals.min() < FULL_STROKE * (hi - lo):
            to = 180.0 / math.pi if ax.type == "rotary" else 1.0
            unit = "deg" if ax.type == "rotary" else "mm"
            poses = meas.poses.copy()
            poses[:, i] = rng.uniform(lo, hi, meas.n)
            out.append((f"a wider range of {v} (this data covers {vals.min() * to:.4g} to {vals.max() * to:.4g} "
                        f"{unit}; the stroke is {lo * to:.4g} to {hi * to:.4g} {unit})", meas.with_poses(poses)))
    return out


def _variant(model, meas, extra, effects, fixed=None):
    """The problem and its in-memory design for the data plus a variant's readings (None: not a valid set)."""
    try:
        prob = build(model, concat(meas, extra), effects, fixed)
    except (InputError, ValueError, TypeError, IndexError):   # a variant the data's setups cannot host: no advice
        return None
    return prob, dsg.InMemory(prob)


def effects(prob, group) -> list[dict]:
    """Extra measurements that would tell the effects of an alias set apart: [{"measure", "separates": [[ids],
    ...]}] for each option whose columns part the set."""
    tips = []
    for text, extra in options(prob.model, prob.meas):
        made = _variant(prob.model, prob.meas, extra, prob.effects, prob.fixed)
        if made is None:
            continue
        p2, d2 = made
        A = d2.block.A[:, p2.free] * p2.w[:, None]
        Q = orthonormal(sv.identify(sv.tsqr(None, A)).basis(A))
        G = cd.candidate_matrix(d2.block, p2.w, group)
        c = cd.project(Q, G, np.zeros(len(p2.d)), group)
        cos = np.array([c.cos_with(i) for i in range(len(group))])
        k, label = connected_components(cos > ALIAS_COS, directed=False)
        if k > 1:
            tips.append({"measure": text, "separates": [[group[i].id for i in range(len(group)) if label[i] == g]
                                                        for g in range(k)]})
    return tips


def parameters(model, meas, added, groups: list[list[str]], names: list[str]) -> list[dict]:
    """For each group of parameters the data does not separate: why, and which extra measurement would.

    Errors with the same J_i and K_i at every pose (a row of Table 2) are never separated by the tool tip; an
    error whose J_i is zero at every pose has no effect at all; otherwise the design is rebuilt with the data plus
    the extra poses of each option and the members that become determined are listed."""
    table2 = [set(g) for g in model.groups]
    probe = model.machine.random_poses(64, 7)
    J, _ = model.jk(probe, np.linspace(0.5, 1.5, 64) * (model.machine.tool_length or 100.0))
    silent = {n for k, n in enumerate(model.errors) if not np.any(np.abs(J[:, k]) > 1e-12)}
    out = [{"members": list(g), "iso": [iso.name(model, n) for n in g], "why": "", "separate_by": []} for g in groups]
    pending = []
    for row, g in zip(out, groups):
        members = set(g)
        same = next((k for k, t in enumerate(table2, 1) if members <= t), None)
        if members <= silent:
            row["why"] = "no effect on the tool tip at any pose (e.g. a rotation about the tool axis): no " \
                         "measurement of the tool tip determines it"
        elif same is not None and len(members) > 1:
            row["why"] = (f"the same effect on the tool tip and tool axis at every pose and tool length (group "
                          f"{same} of Table 2): no measurement separates them; only the combination matters, for "
                          f"compensation too")
        else:
            pending.append(row)
    if pending:
        index = {n: i for i, n in enumerate(names)}
        if dsg.use_blocks(meas.n):          # what separates the errors is a property of the poses: a sample shows it
            meas = meas.subset(sample_poses(meas.n))
        for text, extra in options(model, meas):
            made = _variant(model, meas, extra, added)
            if made is None:
                continue
            prob, design = made
            idf, _ = sv.factor(design, prob.w, np.ones(len(prob.names), bool), np.zeros(0))
            for row in pending:
                now = [n for n in row["members"] if n in index and idf.determined[index[n]] and idf.norms[index[n]] > 0]
                if now:
                    row["separate_by"].append({"measure": text, "determines": now})
        for row in pending:
            if not row["separate_by"]:
                row["why"] = "neither another tool length nor a wider range of an axis separates them on these poses"
            else:
                row["why"] = "the measured poses do not separate them; an extra measurement would (below)"
    return out


#: Poses of the sample a large set's advice and screen are made on.
SAMPLE_POSES = 8192


def sample_poses(n: int, k: int | None = None, seed: int = 0) -> np.ndarray:
    """Sorted indices of k (default SAMPLE_POSES) of n poses drawn at random (all of them if n <= k)."""
    k = SAMPLE_POSES if k is None else k
    if n <= k:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, k, replace=False))


def hidden_by_placement(block, w, effects, G: np.ndarray, absorbed: list[int]) -> list[dict]:
    """Candidate effects (columns G, weighted, on the block's readings) that the fit cannot see only because a
    setup's placement unknowns absorb them: absorbed by the full design, not by the machine's own columns. For
    each, which setups hide it and whether readings of known orientation would separate it. Returns [{"id",
    "setups", "separate_by"}]."""
    prob = block.prob
    sb = prob.setups
    if not sb.q or not absorbed:
        return []
    machine_cols = [i for i, n in enumerate(prob.names) if not is_setup_param(n) and prob.free[i]]
    Am = block.A[:, machine_cols] * w[:, None]
    Qm = orthonormal(sv.identify(sv.tsqr(None, Am)).basis(Am))
    out = []
    for j in absorbed:
        g = G[:, j]
        r = g - Qm @ (Qm.T @ g)
        if np.linalg.norm(r) <= 1e-6 * np.linalg.norm(g):
            continue                                 # the machine's own columns already hold it
        hiding = [s.id for s in sb.setups if _correlates(r, sb.columns[:, [sb.names.index(n) for n in s.names]]
                                                         * w[:, None])]
        out.append({"id": effects[j].id, "setups": hiding})
    if out:
        tip = _known_orientation_separates(prob, [effects[j] for j in absorbed if effects[j].id in
                                                  {o["id"] for o in out}])
        for o in out:
            o["separate_by"] = tip.get(o["id"], "")
    return out


def _correlates(r, X) -> bool:
    return bool(np.linalg.norm(X.T @ r) > 1e-6 * np.linalg.norm(r) * max(np.linalg.norm(X), 1e-300))


def _known_orientation_separates(prob, effs) -> dict:
    """Whether readings of the same features in a setup of KNOWN orientation (offset only: a straightedge or laser
    straightness kit aligned to the machine, or the part aligned on the machine and its rotation held) would
    separate each effect from the placement: the effects whose columns the extended design no longer absorbs.
    (Measuring the same part again in another placement on the CMM cannot: the part carries the machine's errors
    in its own frame, whatever its placement.)"""
    meas, model = prob.meas, prob.model
    rotating = {s.id for s in prob.setups.setups if s.kind != "point"}
    if meas.setup is None or not rotating:
        return {}
    extra = meas.with_poses(meas.poses.copy(), meas.L.copy())
    extra.setup = np.array([None if s is None else f"{s}~aligned" for s in meas.setup], dtype=object)
    extra.setup_kind = {f"{k}~aligned": "point" for k in meas.setup_kind}
    extra.setup_frame = {f"{k}~aligned": v for k, v in meas.setup_frame.items()}
    made = _variant(model, meas, extra, prob.effects, prob.fixed)
    if made is None:
        return {}
    p2, d2 = made
    A = d2.block.A[:, p2.free] * p2.w[:, None]
    Q = orthonormal(sv.identify(sv.tsqr(None, A)).basis(A))
    G2 = cd.candidate_matrix(d2.block, p2.w, effs)
    out = {}
    rot_names = [n for s in prob.setups.setups if s.id in rotating for n in s.names if n.startswith("w_")]
    for k, eff in enumerate(effs):
        g = G2[:, k]
        if np.linalg.norm(g - Q @ (Q.T @ g)) > 1e-6 * np.linalg.norm(g):
            out[eff.id] = (f"readings whose orientation is known would separate it from the placement of "
                           f"{', '.join(sorted(rotating))}: a straightness measurement against a reference aligned "
                           f"to the machine (laser or straightedge), or the part aligned on the machine and its "
                           f"rotation held fixed ({', '.join(f'{n} = 0' for n in rot_names)})")
    return out
