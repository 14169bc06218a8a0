"""What the data must offer before a diagnosis starts (issue 19, point 10), checked at the input.

The diagnosis cross-validates over folds of poses (the readings of one pose held out together, see
fiveaxis.diagnosis.diagnose.folds_of_readings): with fewer distinct poses than folds, a fold trains on no reading
at all (`math domain error` on a 1-row file or on identical poses). `check(meas)` refuses such data in one line
before the estimator runs.
"""
from __future__ import annotations

import numpy as np

from ..exceptions import InputError
from ..measurement.observations import pose_groups

#: One distinct pose per cross-validation fold at least (fiveaxis.diagnosis.diagnose.K_FOLDS).
MIN_DISTINCT_POSES = 5
#: Rows looked at first: distinct poses are usually found among them without grouping the whole file.
QUICK_ROWS = 1000


def distinct_poses(meas, enough: int = MIN_DISTINCT_POSES) -> int:
    """How many distinct poses (variables, tool length, time, directions) meas has, counted exactly up to enough
    (more may be reported as enough when the first rows already hold that many pose variables)."""
    head = np.unique(meas.poses[:QUICK_ROWS], axis=0) if len(meas.poses) else meas.poses
    if len(head) >= enough:
        return len(head)
    groups = pose_groups(meas)
    return int(groups.max()) + 1 if len(groups) else 0


def check(meas) -> None:
    """InputError unless meas has at least MIN_DISTINCT_POSES distinct poses."""
    n = distinct_poses(meas)
    if n < MIN_DISTINCT_POSES:
        raise InputError(f"{meas.path}: {n} distinct pose(s): a diagnosis cross-validates over "
                         f"{MIN_DISTINCT_POSES} folds of poses, so it needs at least {MIN_DISTINCT_POSES} distinct "
                         f"poses (rows at the same pose, tool length, time and directions count once)")
