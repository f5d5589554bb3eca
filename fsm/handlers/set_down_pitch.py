"""A lateral approach pitched for its set-down (section 5.2: "the path computed determines" the
grasp; here the delivery's path too): before Coarse Reach commits to a lateral goal, it asks
whether a hand holding the block as that goal would can set it down at the place point
(:func:`controllers.delivery.plan_delivery` from the grasp's palm pose, without the transit).
A level hand sets its block down with its wrist and forearm low along the radial line, where a
neighbour standing up to 25 cm inward of the place point is in their way; pitched down
(:data:`controllers.reach.LATERAL_TILTS`) the forearm passes above it. Where the goal's hand has
no set-down, the pitched goals are tried in order and the first whose hand has one is taken."""

from __future__ import annotations

import math
from dataclasses import replace

from controllers.delivery import plan_delivery
from controllers.palm_candidates import PoseSetting, lateral_poses
from controllers.reach import (
    LATERAL_TILTS,
    PITCH_TOLERANCE,
    ApproachGoal,
    CoarseReachPlan,
    pitched_lateral_goal,
    plan_coarse_reach,
)
from fsm.context import Episode


def goal_sets_down(ep: Episode, goal: ApproachGoal) -> bool:
    """Whether a hand that grasps the block from the lateral ``goal``'s pitch can set it down at
    the cycle's place point: the palm as the sampled pre-shape search's nearest pose puts it
    (:func:`controllers.palm_candidates.lateral_poses` from the goal's posture: the smallest
    sampled gap, not rolled, not shifted), the hand in the pinch pre-shape, the block held
    where it stands."""
    params = ep.config.palm_pose
    nearest = replace(
        params,
        lateral_sampled_gaps=params.lateral_sampled_gaps[:1],
        lateral_rolls=(0.0,),
        lateral_sampled_shifts=(0.0,),
    )
    where = PoseSetting(ep.world, ep.planning, ep.target, goal.palm_rotation, goal.q)
    poses = lateral_poses(where, nearest, sampled=True)
    if not poses:
        return False
    plan = plan_delivery(
        ep.world,
        ep.target_name,
        ep.place,
        block_height=ep.model.height,
        nearer=ep.cycle == 0,
        qpos=poses[0].qpos,
        with_transit=False,
    )
    return plan.found


def pitch_for_set_down(ep: Episode, plan: CoarseReachPlan) -> tuple[CoarseReachPlan, str]:
    """``plan`` (a lateral coarse reach) when its goal's hand can set the block down
    (:func:`goal_sets_down`), else the first plan to a goal pitched further down
    (:data:`controllers.reach.LATERAL_TILTS`) whose hand can, with why, for the log; ``plan``
    itself when none can (Deliver then says so)."""
    if plan.goal is None or goal_sets_down(ep, plan.goal):
        return plan, ""
    pitch = max(0.0, math.degrees(plan.goal.pitch))  # a level goal's may be -1e-9
    for tilt in LATERAL_TILTS:
        if tilt <= plan.goal.pitch + PITCH_TOLERANCE:
            continue
        # the goal's hand checked first: a path is planned only to a goal that can set down
        goal = pitched_lateral_goal(ep.world, ep.target, tilt, model=ep.planning)
        if goal is None or not goal_sets_down(ep, goal):
            continue
        pitched = plan_coarse_reach(
            ep.world, ep.target, approaches=("lateral",), model=ep.planning, lateral_tilt=tilt
        )
        if pitched.found:
            why = (
                f"; pitched {math.degrees(tilt):.0f} deg down: a hand pitched {pitch:.0f} deg "
                "could not set the block down at the place point"
            )
            return replace(pitched, choice=plan.choice), why
    return plan, f"; no pitch of the hand sets the block down at the place point ({pitch:.0f} deg)"
