"""The common height of a 3-D grasp, set by the task wrenches (section 3.5, Eq. 13 in 3-D).

The null-grasp controllers (:mod:`controllers.grasp.trials3d`) leave one direction of a grasp
free: raising or lowering every contact together changes neither eps_FC nor, once the contacts'
unit normal forces balance, eps_MC (their moments about any point are then the same). The task
decides it: a grasp must resist its task wrenches (the paper's t: gravity, a push), and a push
through the centre of mass tips the block about contacts above or below it. :func:`task_shift`
moves every contact by the same shift, within the band of heights the hand reaches, to the shift
whose worst S_G over the tasks (:func:`controllers.grasp.prism3d.worst_task_score`) is least.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.errors import GraspError
from controllers.grasp.prism3d import worst_task_score
from controllers.grasp.score3d import GraspScore3D

#: Shifts tried across the band (evenly spaced, both ends included).
SHIFTS = 9


@dataclass(frozen=True)
class TaskShift:
    """The shift chosen (same unit as the heights) and the worst task's name and score there."""

    shift: float
    stage: str
    score: GraspScore3D


def task_shift(
    points: ArrayLike,
    normals: ArrayLike,
    z_low: float,
    z_high: float,
    load: float,
    yaw: float = 0.0,
    shifts: int = SHIFTS,
) -> TaskShift:
    """The common height shift of contacts ``points`` (n, 3) with outward ``normals`` (n, 3),
    keeping every height in [z_low, z_high], that minimizes the worst-task S_G (ties: the
    smaller shift in magnitude). ``load`` and ``yaw`` as in
    :func:`~controllers.grasp.prism3d.physical_tasks`. When the contacts span more than the
    band, no shift is tried but 0."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise GraspError(f"points must be a finite (n, 3) array, got shape {p.shape}")
    if not (np.isfinite(z_low) and np.isfinite(z_high) and z_low <= z_high):
        raise GraspError(f"the band [{z_low}, {z_high}] is not an interval")
    if shifts < 1:
        raise GraspError(f"shifts must be >= 1, got {shifts}")
    lo, hi = z_low - p[:, 2].min(), z_high - p[:, 2].max()
    candidates: NDArray[np.float64] = (
        np.linspace(lo, hi, shifts) if lo <= hi and shifts > 1 else np.zeros(1)
    )
    best: TaskShift | None = None
    for d in sorted(candidates, key=abs):
        q = p.copy()
        q[:, 2] += d
        stage, score = worst_task_score(q, normals, load, yaw)
        if best is None or score.s_g < best.score.s_g - 1e-9:
            best = TaskShift(float(d), stage, score)
    assert best is not None
    return best
