"""tip: the tool tip's 3-D deviation (optionally the tool axis too) at any pose within the strokes, workpiece frame.

Standard plan: random poses within the strokes. Candidates of a plan: any pose within the strokes. Program: straight
moves between the poses (in tcp mode through a hub where a straight world move would leave the strokes, else up to
the travel height and down again: nothing is mounted).
"""
from __future__ import annotations

import numpy as np

from . import paths
from .base import Common, NoPath, Plan, approach_directions, candidate_plan, linear_rotary, quantized, sample_poses


def lengths(model, n, rng, tool_lengths):
    """Tool lengths (n,) mm and whether the plan states them: the machine's L0, or uniform in (min, max)."""
    if tool_lengths is None:
        return np.full(n, model.machine.tool_length), False
    lo, hi = tool_lengths
    return (rng.uniform(lo, hi, n) if hi > lo else np.full(n, float(lo))), True


class Tip(Common):
    name = "tip"
    about = "any pose within the strokes; the tool tip's 3-D deviation (and the tool axis), workpiece frame"
    plan_options = ("with_axis", "tool_lengths", "directions")
    mounts = "tool"
    rule_text = "straight moves between the poses, or through the travel height where they would leave the strokes"

    def standard_plan(self, model, n, rng, with_axis: bool = False, tool_lengths=None,
                      directions: bool = False) -> Plan:
        """Random poses within the strokes, 3-D tool-tip deviations (and the tool axis with with_axis); directions:
        the approach direction of every linear axis (dir_ columns) when the poses are visited in order."""
        poses = model.machine.random_poses(n, rng)
        L, has_L = lengths(model, n, rng, tool_lengths)
        dirs = {}
        if directions:
            lin, _ = linear_rotary(model)
            D = approach_directions(poses[:, [model.variables.index(v) for v in lin]])
            dirs = {v: D[:, j] for j, v in enumerate(lin)}
        return Plan(self.name, poses, L, has_L, "tip+axis" if with_axis else "tip", dirs=dirs)

    def candidates(self, model, count, rng, extreme, L, fixtures):
        poses = sample_poses(model, count, rng, extreme, fixtures["strokes"])
        return candidate_plan(self.name, quantized(model, poses, L, fixtures), np.full(count, L), "tip"), \
            np.arange(count)

    def program(self, w, plan, notes, feed, dwell):
        for L, s, idx, q in paths.setups(w, plan, notes, self.mounts):
            for k, j in enumerate(idx):
                try:
                    if not k:
                        raise NoPath("the first pose of a setup")
                    paths.transit(w, q[k], feed)
                except NoPath:                    # nothing is mounted: through the travel height
                    paths.approach(w, q[k])
                paths.reading(w, j, dwell)
