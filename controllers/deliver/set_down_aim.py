"""Aiming a set-down off the place point, within the judge's tolerance, to keep the descent's
clearance (section 5.2, "Deliver").

A carried block is lowered with every link of the hand :data:`SET_DOWN_CLEARANCE` from the
blocks around it (:func:`controllers.deliver.plan.plan_delivery`). Where the only set-downs the
hand can hold pass a neighbour by a little less than that, the place point is not a wall: the
task asks for the block within 2 cm of it (:data:`fsm.judge.PLACE_TOLERANCE`). The set-down is
then aimed off the point, away from that neighbour along the horizontal part of the pair's
contact normal, by the shortfall and :data:`AIM_MARGIN`, at most :data:`MAX_AIM_OFFSET` in all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.planning.cspace import CollisionChecker, Nearest
from controllers.reach.arm_path import VERIFY_STEP, interpolate_path

#: Largest distance (m) a set-down is aimed off the place point: a quarter of the judge's 2 cm
#: tolerance, leaving the rest to how far the block moves as it is lowered and released.
#: Chosen by where released blocks land: docs/findings.md, "A set-down aimed off the place point".
MAX_AIM_OFFSET = 0.005
#: Distance (m) kept beyond the clearance when aiming off (the arm's links other than the hand
#: do not move rigidly with the place point).
AIM_MARGIN = 0.001
#: Horizontal share of a pair's normal below which a horizontal move does not part it (a
#: finger above a neighbour).
MIN_HORIZONTAL = 0.3


@dataclass(frozen=True, eq=False)
class DescentMiss:
    """The pair that comes closest on a set-down's way down, nearer than the clearance."""

    nearest: Nearest
    clearance: float  #: m, the clearance the descent had to keep

    def offset(self) -> NDArray[np.float64] | None:
        """The horizontal move (2,) of the set-down that parts the pair by the clearance and
        :data:`AIM_MARGIN` (to first order: the hand moves rigidly with it); None when the
        pair's normal is nearly vertical or the move is longer than :data:`MAX_AIM_OFFSET`."""
        horizontal = self.nearest.away[:2]
        share = float(np.linalg.norm(horizontal))
        if share < MIN_HORIZONTAL:
            return None
        length = (self.clearance - self.nearest.distance) / share + AIM_MARGIN
        if length > MAX_AIM_OFFSET:
            return None
        return horizontal / share * length

    def describe(self) -> str:
        """The pair and its distance, for the log."""
        n = self.nearest
        return f"{n.robot_geom} {n.distance * 1000:.1f} mm from {n.env_geom}"


def descent_miss(checker: CollisionChecker, path: NDArray[np.float64]) -> DescentMiss | None:
    """The robot-environment pair that comes closest along ``path`` (k, 5; checked every
    :data:`~controllers.reach.arm_path.VERIFY_STEP` rad) within ``checker``'s clearance; None when
    nothing comes within it, or when at some posture the robot's own links do (no horizontal
    move parts those)."""
    closest: Nearest | None = None
    for q in interpolate_path(np.asarray(path, dtype=float), VERIFY_STEP):
        near = checker.nearest_obstacle(q)
        if near is None:
            if checker.collides(q):
                return None
            continue
        if closest is None or near.distance < closest.distance:
            closest = near
    return None if closest is None else DescentMiss(closest, checker.clearance)
