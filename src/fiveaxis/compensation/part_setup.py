"""The part's set-up: what probing a part on the machine takes out of the error a part sees.

Before machining, the operator probes the part: that sets a work offset (a translation t, 3 values) and the part's
alignment about the table's axis (a rotation theta about the axis a of the rotary table the part sits on; on a
machine without one, about the vertical, the tool axis at the zero pose). Whatever of the machine's tool-tip error
over the workspace is such a translation plus rotation is therefore invisible on the part. `SetupRemoval` takes it
out: over the workspace poses, with p the nominal tool tip in the workpiece frame, the least-squares fit of
e(q) ~ t + theta a x p(q) is removed (an orthogonal projection of the stacked errors, the same for every stage and
for every first-order change of the machine's parameters).

Units: mm and rad; the errors (n, 3) in the workpiece frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def setup_axis(machine) -> tuple[str, np.ndarray]:
    """(name, unit vector in the workpiece frame) of the axis the part is aligned about: the rotary axis of the
    workpiece chain nearest the workpiece (the table the part sits on), else the tool axis at the zero pose."""
    rotary = [a for a in machine.workpiece_chain if a.type == "rotary"]
    if rotary:
        a = rotary[-1]
        d = np.asarray(a.direction, float)
        return a.name, d / np.linalg.norm(d)
    d = np.asarray(machine.tool_direction, float)
    return "the tool axis at the zero pose", d / np.linalg.norm(d)


@dataclass
class SetupRemoval:
    """The projection that removes the part's set-up from tool-tip errors at given poses (see the module
    docstring): Q (3n, 4) orthonormal columns spanning the translations and the rotation about the axis."""
    axis_name: str
    axis: np.ndarray           # (3,) unit vector, workpiece frame
    Q: np.ndarray              # (3n, 4)

    @classmethod
    def at(cls, machine, tip) -> "SetupRemoval":
        """The set-up removal over the nominal tool tips tip (n, 3; mm, workpiece frame)."""
        name, a = setup_axis(machine)
        tip = np.asarray(tip, float)
        A = np.zeros((len(tip), 3, 4))
        A[:, :, :3] = np.eye(3)
        A[:, :, 3] = np.cross(a, tip)
        Q, _ = np.linalg.qr(A.reshape(-1, 4))
        return cls(name, a, Q)

    def remove(self, e: np.ndarray) -> np.ndarray:
        """Errors e (n, 3), or stacked columns (3n, k), with the part's set-up taken out (same shape)."""
        e = np.asarray(e, float)
        flat = e.reshape(len(self.Q), -1)
        return (flat - self.Q @ (self.Q.T @ flat)).reshape(e.shape)

    def describe(self) -> dict:
        return {"removed": "a work offset (3 translations) and the alignment about the table's axis (1 rotation), "
                           "fitted to the tool-tip error over the workspace poses by least squares: what probing "
                           "the part sets anyway",
                "axis": self.axis_name, "axis_direction": [float(x) for x in self.axis]}
