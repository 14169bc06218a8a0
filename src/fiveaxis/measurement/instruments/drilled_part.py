"""test-part: a plate of holes drilled at a grid of X, Y positions (Z and the rotary axes fixed), measured on a CMM in
the plate's plane only (dx, dy; dz blank): one setup of kind `planar` (the plate's unknown position and rotation on
the CMM), workpiece frame. It has a standard plan only: its poses are where the holes are drilled, not chosen by a
plan, and the machine cuts them with a part program of the user's, not a measuring program of ours.
"""
from __future__ import annotations

import math

import numpy as np

from ...exceptions import InputError
from ...model.inverse import within_strokes
from .base import Common, Plan, centre_pose, linear_rotary


class DrilledPart(Common):
    name = "test-part"
    about = "a plate of holes drilled on a grid, measured on a CMM in its plane (dx, dy), workpiece frame"
    reads = "tip-plane"
    plan_options = ("size", "kind")
    plannable = False
    typical_poses = 0
    mounts = "drill"
    rule_text = "no measuring program: the holes are drilled by a part program and measured on a CMM"

    def check_host(self, machine) -> None:
        if sum(machine.axis(v).type == "linear" for v in machine.variables) < 2:
            raise InputError(f"instrument test-part: machine {machine.name} needs two linear axes")

    def candidates(self, model, count, rng, extreme, L, fixtures):
        raise InputError(f"instrument {self.name}: its poses are not planned (the plate's holes are drilled on a "
                         f"grid; simulate its standard plan)")

    def program(self, w, plan, notes, feed, dwell):
        raise InputError(f"instrument {self.name}: no measuring program (the holes are drilled by a part program and "
                         f"measured on a CMM)")

    def standard_plan(self, model, n, rng, size: float | None = None, kind: str = "planar") -> Plan:
        """A plate of about n holes on a square grid (side `size` mm, default 300 mm or 60% of the smaller of the X
        and Y strokes) drilled with the rotary axes at their centre pose; dx, dy measured; one setup `part` of the
        given kind."""
        self.check_host(model.machine)
        lin, _ = linear_rotary(model)
        centre = centre_pose(model)
        ix, iy = model.variables.index(lin[0]), model.variables.index(lin[1])
        spans = [np.diff(model.machine.axis(v).model_stroke)[0] for v in lin[:2]]
        side = min(300.0, 0.6 * min(spans)) if size is None else float(size)
        k = max(3, int(round(math.sqrt(n))))
        g = np.linspace(-side / 2, side / 2, k)
        gx, gy = np.meshgrid(g, g, indexing="ij")
        poses = np.tile(centre, (k * k, 1))
        poses[:, ix] += gx.ravel()
        poses[:, iy] += gy.ravel()
        if not within_strokes(model.machine, poses).all():
            raise InputError(f"instrument test-part: a plate of {side:g} mm leaves the strokes of "
                             f"{model.machine.name}")
        setup = np.array(["part"] * len(poses), dtype=object)
        return Plan(self.name, poses, np.full(len(poses), model.machine.tool_length), False, "tip-plane",
                    setup=setup, setup_kind={"part": kind}, setup_frame={"part": "workpiece"},
                    notes=[f"{k} x {k} holes over {side:g} mm x {side:g} mm, measured in the XY plane"])
