"""rtest: an R-test (ISO 10791-6-like): a sphere on a holder in the spindle, a nest of three displacement sensors on
the table around it; the 3-D deviation of the tool tip relative to the table, workpiece frame; each placement of the
nest a setup.

Standard plan: each rotary axis swept over its stroke (the others at 0, then at a quarter of their stroke) with the
linear axes keeping the tool tip on the sphere, at 3 placements. Candidates of a plan: rotary positions (uniform or
at the ends of the strokes) at one of 3 placements, the linear axes following. Program: per placement the tool
comes down its axis to the sphere centre (nothing mounted), M0 to mount the nest, then from pose to pose the tool
tip stays at the sphere centre while the rotary axes turn, M0 to remove the nest, out along the tool axis.
Limit: the tip within limit_mm of where the nest was mounted around it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...exceptions import InputError
from . import paths
from .base import Limit, Plan, linear_rotary, nearest_path
from .spheres import OnSphere, on_spheres, rotary_grid_sweeps, sphere_positions


@dataclass(frozen=True)
class RTestGeometry:
    """R-test: a sphere on a holder in the spindle (tool length = gauge line to the sphere centre), a nest of three
    displacement sensors on the table around it. The sensors read +-travel_mm; a program keeps the sphere centre
    within limit_mm of where the nest was mounted around it, and leaves the nest along the tool axis (retract_mm)."""
    travel_mm: float = 2.0
    limit_mm: float = 0.5
    retract_mm: float = 50.0


def centre_distance(model, q, tip, axis, ref) -> np.ndarray:
    """Distance (mm) of the tool tip from the sphere centre the nest was mounted around."""
    return np.linalg.norm(tip - ref["centre"], axis=1)


class RTest(OnSphere):
    name = "rtest"
    about = ("a sphere in the spindle, a nest of three sensors on the table around it at a few placements; the "
             "tip's 3-D deviation while the rotary axes turn, workpiece frame")
    geometry = RTestGeometry()
    spheres = 3
    typical_poses = 30
    mounts = "R-test sphere"
    rule_text = ("the tool tip stays at the sphere centre while the rotary axes move; the nest is mounted and "
                 "removed at M0 stops")
    limits = (Limit("tip distance from the sphere centre", "max", RTestGeometry.limit_mm, "mm", "mounted",
                    centre_distance),)

    def standard_plan(self, model, n, rng, spheres: int = 3, L: float | None = None) -> Plan:
        """R-test sweeps of every rotary axis around `spheres` sphere placements (setups), workpiece frame."""
        _, rot = linear_rotary(model)
        if not rot:
            raise InputError(f"instrument rtest: machine {model.machine.name} has no rotary axis to sweep")
        L = model.machine.tool_length if L is None else L
        per = max(4, int(round(n / (spheres * 2 * len(rot)))))
        grid = rotary_grid_sweeps(model, per)
        poses, setup = on_spheres(model, grid, L, sphere_positions(model, L, spheres), "sphere")
        if len(poses) < 0.5 * len(grid) * spheres:
            raise InputError(f"instrument rtest: machine {model.machine.name}: the sweeps leave the strokes for most "
                             f"sphere placements ({len(poses)} of {len(grid) * spheres} poses fit)")
        return self.sphere_plan(poses, setup, L)

    def order(self, model, q, L, strokes) -> list:
        """Nearest-neighbour order from a pose the approach fits at to one the exit retract (retract_mm along the
        tool axis) fits at, where there are such: the nest is removed at the last and the tool leaves along its
        axis (the last: the one nearest the others' centre; the first: the farthest from it)."""
        d = self.geometry.retract_mm + 0.05           # room for the rounding of the program's words
        fits = [k for k in range(len(q)) if paths.retract_length(model, strokes, q[k], L, d, "joint") >= d]
        if not fits or len(q) < 2:
            return super().order(model, q, L, strokes)
        span = np.ptp(q, axis=0)
        x = q / np.where(span > 0, span, 1.0)
        last = fits[int(np.argmin(np.sum((x[fits] - x.mean(axis=0)) ** 2, axis=1)))]
        others = [k for k in fits if k != last]           # the first: where the approach fits too, far from the last
        first = others[int(np.argmax(np.sum((x[others] - x[last]) ** 2, axis=1)))] if others else None
        rest = ([first] if first is not None else []) + [k for k in range(len(q)) if k not in (first, last)]
        return [rest[j] for j in nearest_path(q[rest])] + [last]

    def program(self, w, plan, notes, feed, dwell):
        model = w.model
        g = self.geometry
        for L, s, idx, q in paths.setups(w, plan, notes, self.mounts):
            centre, _ = paths.tips(model, q[0], L)
            paths.approach(w, paths.retract(model, w.strokes, q[0], L, g.retract_mm, w.mode))
            paths.follow(w, paths.straight(model, w.q, q[0], L), feed)
            w.event("mount", centre=centre[0])
            w.stop(f"mount the R-test nest around the sphere {s} [centre {paths.vec(centre[0])} mm, workpiece "
                   f"frame], zero the sensors, then resume")
            paths.reading(w, idx[0], dwell)
            for k in range(1, len(idx)):
                paths.rotate_holding_tip(w, q[k], feed, f"R-test pose {idx[k] + 1}")
                if w.words(w.q) != w.words(q[k]):
                    w.move(q[k], feed)             # the planned pose exactly (a move of the rounding, joint mode)
                paths.reading(w, idx[k], dwell)
            w.event("unmount")
            w.stop("remove the R-test nest, then resume")
            paths.exit_retract(w, g.retract_mm, feed)
