"""A top grasp's regrasp posture (Figure 14's recovery loop back to Fine Reach): the coarse
reach's goal, the hovering hand turned about the vertical by a wrist roll, so that the grasp
controller starts from other contacts. The arm's IK (:meth:`CollisionChecker.solve_ik
<controllers.planning.cspace.CollisionChecker.solve_ik>`) solves it backed off along the
approach axis, the other way round (the palm turned half a turn about it) where the roll alone
has no solution, and then at the goal itself."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.planning.cspace import CollisionChecker
from controllers.preshape.palm_candidates import turn_about_vertical
from controllers.reach.coarse import ApproachGoal
from hand_sim.world import World


@dataclass(frozen=True, eq=False)
class WristTurn:
    """A turned regrasp posture: ``found`` with the arm joints to move to (``arm_q``: at the
    goal where the IK reaches it, else backed off from it), and how the hand was turned, for
    the log."""

    found: bool
    how: str
    arm_q: NDArray[np.float64] | None = None


def turned_wrist(
    world: World,
    planning: mujoco.MjModel,
    goal: ApproachGoal,
    roll: float,
    backoff: float,
) -> WristTurn:
    """The arm posture that puts the palm at the coarse reach's ``goal`` with the wrist rolled
    by ``roll`` (rad) about the vertical, first ``backoff`` (m) back along the approach axis,
    collision-free in the ``planning`` model, from the arm's present targets; not found when
    neither the roll nor the roll half a turn about the approach axis has an IK solution."""
    checker = CollisionChecker(world, model=planning)
    arm_now = world.arm_targets()
    p, R = goal.palm_position, goal.palm_rotation
    seed = arm_now.copy()
    goal_p, goal_R = p, turn_about_vertical(roll) @ R
    seed[-1] += roll
    how = f"wrist turned {np.degrees(roll):+.0f} deg"
    ik = checker.solve_ik(goal_p - backoff * goal_R[:, 2], goal_R, seed)
    if not ik.found:  # the other way round
        goal_R = goal_R @ np.diag([-1.0, -1.0, 1.0])
        seed[-1] += np.pi if seed[-1] < 0 else -np.pi
        ik = checker.solve_ik(goal_p - backoff * goal_R[:, 2], goal_R, seed)
    if not ik.found:
        return WristTurn(False, how)
    back = checker.solve_ik(goal_p, goal_R, ik.q)
    return WristTurn(True, how, back.q if back.found else ik.q)
