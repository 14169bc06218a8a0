"""What the instruments that hold the tool tip on a sphere on the table share (rtest, probe-sphere): the sphere's
placements (each a setup), the rotary positions the tip is held there at, the poses that do it, the candidates of a
plan. Units: mm, rad."""
from __future__ import annotations

import numpy as np

from ...exceptions import InputError
from ...model.inverse import linear_for_tip, within_strokes
from .base import Common, NoCandidates, Plan, axes, candidate_plan, centre_pose, linear_rotary, quantized, sample_poses


def sphere_positions(model, L, count: int) -> list[np.ndarray]:
    """Sphere placements on the table (workpiece frame, mm) that the tool tip can reach at every rotary position
    of the sweeps: candidates around the nominal tip at the centre pose, shrunk until they fit."""
    centre = centre_pose(model)
    base, _ = model.ideal_tool(centre[None, :], L)
    lin, _ = linear_rotary(model)
    spans = [np.diff(model.machine.axis(v).model_stroke)[0] for v in lin]
    r = 0.15 * min(spans)
    dirs = [np.array([1.0, 0.0, 0.3]), np.array([-0.6, 0.8, 0.0]), np.array([0.0, -1.0, 0.5]),
            np.array([0.7, 0.7, -0.2])]
    return [base[0] + r * d / np.linalg.norm(d) for d in dirs[:count]]


def rotary_grid_sweeps(model, per_sweep: int) -> np.ndarray:
    """Rotary positions (k, nrot) rad: each rotary axis swept over its stroke with the others at 0 (or mid),
    then again with the others at a second value (a quarter of their stroke): ISO 10791-6 K-tests."""
    _, rot = linear_rotary(model)
    mach = model.machine
    strokes = [mach.axis(v).model_stroke for v in rot]
    centre = [0.0 if lo <= 0 <= hi else 0.5 * (lo + hi) for lo, hi in strokes]
    second = [lo + 0.25 * (hi - lo) if abs(lo + 0.25 * (hi - lo) - c) > 1e-9 else lo + 0.75 * (hi - lo)
              for (lo, hi), c in zip(strokes, centre)]
    out = []
    for j, (lo, hi) in enumerate(strokes):
        sweep = np.linspace(lo, hi, per_sweep)
        for others in (centre, second):
            block = np.tile(np.array(others, float), (per_sweep, 1))
            block[:, j] = sweep
            out.append(block)
    return np.vstack(out) if out else np.zeros((1, 0))


def on_spheres(model, rot_positions, L, spheres, setup_prefix):
    """Poses holding the tool tip on each sphere at each rotary position; keeps poses within the strokes."""
    lin, rot = linear_rotary(model)
    idx_rot = [model.variables.index(v) for v in rot]
    poses_all, setups = [], []
    centre = centre_pose(model)
    for s, p in enumerate(spheres):
        q = np.tile(centre, (len(rot_positions), 1))
        q[:, idx_rot] = rot_positions
        q = linear_for_tip(model, q, p, L)
        ok = within_strokes(model.machine, q)
        q = q[ok]
        poses_all.append(q)
        setups += [f"{setup_prefix}{s + 1}"] * len(q)
    poses = np.vstack(poses_all)
    return poses, np.array(setups, dtype=object)


class OnSphere(Common):
    """The tool tip held on a sphere at `spheres` placements on the table (setups), the rotary axes turning."""
    spheres = 1                 # placements of a plan's candidates
    plan_options = ("spheres", "L")
    mount_keys = {"centre": 3}

    def check_host(self, machine) -> None:
        lin = [v for v in machine.variables if machine.axis(v).type == "linear"]
        if not machine.rotary:
            raise InputError(f"instrument {self.name}: machine {machine.name} has no rotary axis (the sphere is "
                             f"measured while rotary axes turn; use tip, ballbar, interferometer or tracker)")
        if len(lin) < 3:
            raise InputError(f"instrument {self.name}: machine {machine.name} has {len(lin)} linear axes; holding "
                             f"the tool tip on a sphere needs three")

    def fixtures(self, model, rng, mode: str, strokes) -> dict:
        """The sphere placements (at the words' resolution) with their notes."""
        out = super().fixtures(model, rng, mode, strokes)
        spheres = [np.round(p, 4) for p in sphere_positions(model, model.machine.tool_length, self.spheres)]
        out["spheres"] = spheres
        for i, p in enumerate(spheres):
            out["notes"][f"sphere{i + 1}"] = (f"sphere at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) mm on the table "
                                              f"(workpiece frame)")
        return out

    def reachable(self, model, q, L, strokes) -> np.ndarray:
        """(n,) bool: candidate poses q (the tip at a sphere centre, within the strokes) the instrument can use."""
        return np.ones(len(q), bool)

    def candidates(self, model, count, rng, extreme, L, fixtures):
        _, rot = axes(model)
        spheres, strokes = fixtures["spheres"], fixtures["strokes"]
        poses, setup = [], []
        for _ in range(50):
            q = sample_poses(model, 2 * count, rng, extreme, strokes, rot)
            s = rng.integers(0, len(spheres), len(q))
            target = np.array(spheres)[s]
            q = quantized(model, linear_for_tip(model, q, target, L), L, fixtures)
            ok = strokes.inside(q)
            ok[ok] = self.reachable(model, q[ok], L, strokes)
            poses.append(q[ok])
            setup += [f"sphere{i + 1}" for i in s[ok]]
            if len(setup) >= count:
                break
        poses = np.vstack(poses)[:count]
        setup = np.array(setup[:count], dtype=object)
        if len(poses) < count:
            raise NoCandidates(f"instrument {self.name}: machine {model.machine.name}: too few rotary positions keep "
                               f"the tool tip on the sphere within the strokes less the margins ({len(poses)} of "
                               f"{count} candidates found)")
        ids = dict.fromkeys(f"sphere{i + 1}" for i in range(len(spheres)))
        return candidate_plan(self.name, poses, np.full(len(poses), L), "tip", setup=setup,
                              setup_kind={s: "point" for s in ids}, setup_frame={s: "workpiece" for s in ids},
                              frame=self.frame), np.arange(len(poses))

    def sphere_plan(self, poses, setup, L) -> Plan:
        """The standard plan of poses on the spheres (one setup per placement)."""
        return Plan(self.name, poses, np.full(len(poses), L), False, "tip", setup=setup, frame=self.frame,
                    setup_kind={s: "point" for s in dict.fromkeys(setup)},
                    setup_frame={s: "workpiece" for s in dict.fromkeys(setup)})
