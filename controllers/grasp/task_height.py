"""The common height of a 3-D grasp, set by the task wrenches (section 3.5, Eq. 13 in 3-D).

The null-grasp controllers (:mod:`controllers.grasp.trials3d`) leave one direction of a grasp
free: raising or lowering every contact together changes neither eps_FC nor, once the contacts'
unit normal forces balance, eps_MC (their moments about any point are then the same). The task
decides it: a grasp must resist its task wrenches (the paper's t: gravity, a push), and a push
through the centre of mass tips the block about contacts above or below it. :func:`ranked_shifts`
ranks the shifts that move every contact by the same amount, within the band of heights the hand
reaches, by their worst S_G over the tasks (:func:`controllers.grasp.prism3d.worst_task_score`);
the task's shift is the first (the least). When the hand cannot take the contacts there,
:func:`spread_shifts` gives the next-best shifts, a few millimetres apart, for the hand to try
in turn.
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
#: Common heights a hand tries in turn, best first by the worst-task S_G (1: only the task's
#: best). A top grasp's 2 cm band holds five heights 5 mm apart, and the task ranks the lowest
#: first, so four reach into the upper band (the contacts' own spread, about 5 mm, leaves room
#: for three on most grasps). Set in advance: docs/findings.md, "Next-best common heights".
HEIGHT_TRIES = 4
#: The least difference (m) between two common heights tried (closer ones are nearly the same
#: reach problem for the hand).
HEIGHT_GAP = 0.005


@dataclass(frozen=True)
class TaskShift:
    """The shift chosen (same unit as the heights) and the worst task's name and score there."""

    shift: float
    stage: str
    score: GraspScore3D


def ranked_shifts(
    points: ArrayLike,
    normals: ArrayLike,
    z_low: float,
    z_high: float,
    load: float,
    yaw: float = 0.0,
    shifts: int = SHIFTS,
) -> list[TaskShift]:
    """Every common height shift tried for contacts ``points`` (n, 3) with outward ``normals``
    (n, 3), keeping every height in [z_low, z_high], best first: the least worst-task S_G
    first (ties within 1e-9: the smaller shift in magnitude), then the others by their worst-task
    S_G. ``load`` and ``yaw`` as in :func:`~controllers.grasp.prism3d.physical_tasks`. When
    the contacts span the band or more, only the shift 0 is tried."""
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise GraspError(f"points must be a finite (n, 3) array, got shape {p.shape}")
    if not (np.isfinite(z_low) and np.isfinite(z_high) and z_low <= z_high):
        raise GraspError(f"the band [{z_low}, {z_high}] is not an interval")
    if shifts < 1:
        raise GraspError(f"shifts must be >= 1, got {shifts}")
    lo, hi = z_low - p[:, 2].min(), z_high - p[:, 2].max()
    candidates: NDArray[np.float64] = (
        np.unique(np.linspace(lo, hi, shifts)) if lo <= hi and shifts > 1 else np.zeros(1)
    )
    tried: list[TaskShift] = []
    best = 0
    for d in sorted(candidates, key=abs):
        q = p.copy()
        q[:, 2] += d
        stage, score = worst_task_score(q, normals, load, yaw)
        tried.append(TaskShift(float(d), stage, score))
        if score.s_g < tried[best].score.s_g - 1e-9:
            best = len(tried) - 1
    rest = [t for i, t in enumerate(tried) if i != best]
    return [tried[best], *sorted(rest, key=lambda t: (t.score.s_g, abs(t.shift)))]


def spread_shifts(ranked: list[TaskShift], tries: int, min_gap: float) -> list[TaskShift]:
    """The first ``tries`` shifts of ``ranked`` (best first) that lie at least ``min_gap`` from
    every shift kept before them: alternatives for the hand that differ enough to be worth a
    reach test each."""
    if tries < 1 or not (np.isfinite(min_gap) and min_gap >= 0.0):
        raise GraspError(f"need tries >= 1 and a gap >= 0, got {tries}, {min_gap}")
    kept: list[TaskShift] = []
    for t in ranked:
        if all(abs(t.shift - k.shift) >= min_gap - 1e-12 for k in kept):
            kept.append(t)
            if len(kept) == tries:
                break
    return kept
