"""A lateral grasp checked for its set-down before it is taken (section 5.2: "the path computed
determines" the grasp; here the delivery's path too): whether a hand holding the block as a
lateral goal or a palm pose would can set it down at the place point
(:func:`controllers.deliver.plan.plan_delivery` from the grasp's palm pose, without the
transit). A level hand sets its block down with its wrist and forearm low along the radial line,
where a neighbour standing up to 25 cm inward of the place point is in their way; pitched down
(:data:`controllers.reach.coarse.LATERAL_TILTS`) the forearm passes above it. Where a goal's hand
has no set-down, the pitched goals are tried in order and the first whose hand has one is taken
(:func:`pitch_for_set_down`). The palm-pose search asks the same of each grasp it would take
(:class:`SetDownGate`); where it passes over its checks' worth of grasps for want of one, Coarse
Reach takes the next pitch (:func:`next_tilt`, :func:`pitched_at_least`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.deliver.plan import plan_delivery
from controllers.hand.finger_assignment import FingerContacts
from controllers.preshape.moves import ApproachPlan
from controllers.preshape.palm_candidates import PalmPoseParams, PoseSetting, lateral_poses
from controllers.reach.coarse import (
    LATERAL_TILTS,
    PITCH_TOLERANCE,
    ApproachGoal,
    CoarseReachPlan,
    ReachTarget,
    pitched_lateral_goal,
    plan_coarse_reach,
)
from hand_sim.world import World


@dataclass(frozen=True, eq=False)
class SetDownQuery:
    """What a set-down check needs: the world, the planning model (the perceived block in place
    of the real one), the perceived block and the real block's scene name, the place point
    (world xy), the perceived block's height (m), whether the hand may set it down nearer its
    neighbours (a place point the user or the scene asked for:
    :func:`controllers.deliver.plan.plan_delivery` ``nearer``), and the palm-pose parameters."""

    world: World
    planning: mujoco.MjModel
    target: ReachTarget
    block: str
    place: NDArray[np.float64]
    block_height: float
    nearer: bool
    palm_pose: PalmPoseParams


def goal_sets_down(query: SetDownQuery, goal: ApproachGoal) -> bool:
    """Whether a hand that grasps the block from the lateral ``goal``'s pitch can set it down at
    the place point: the palm as the sampled pre-shape search's nearest pose puts it
    (:func:`controllers.preshape.palm_candidates.lateral_poses` from the goal's posture: the
    smallest sampled gap, not rolled, not shifted), the hand in the pinch pre-shape, the block
    held where it stands."""
    params = query.palm_pose
    nearest = replace(
        params,
        lateral_sampled_gaps=params.lateral_sampled_gaps[:1],
        lateral_rolls=(0.0,),
        lateral_sampled_shifts=(0.0,),
    )
    where = PoseSetting(query.world, query.planning, query.target, goal.palm_rotation, goal.q)
    poses = lateral_poses(where, nearest, sampled=True)
    return bool(poses) and grasp_sets_down(query, poses[0].qpos)


def grasp_sets_down(
    query: SetDownQuery, qpos: NDArray[np.float64], check_lift: bool = True
) -> bool:
    """Whether the hand in configuration ``qpos`` (arm and fingers), holding the block where it
    stands, can lift it and set it down at the place point
    (:func:`controllers.deliver.plan.plan_delivery` without the transit; without ``check_lift``,
    from the lifted block, the lift itself unchecked as Deliver's is)."""
    plan = plan_delivery(
        query.world,
        query.block,
        query.place,
        block_height=query.block_height,
        nearer=query.nearer,
        qpos=qpos,
        with_transit=False,
        check_lift=check_lift,
    )
    return plan.found


@dataclass
class SetDownGate:
    """One pre-shape search's set-down gate: a palm pose whose grasp cannot set the block down
    at the place point is passed over, the way an approach that collides is, until ``checks``
    poses were passed over for it (``refused``; the gate is then ``spent``). After that the
    approached poses are taken unasked (Deliver then names a missing set-down), or, when
    ``strict``, passed over unasked too (Coarse Reach then pitches the lateral axis further
    down, :func:`next_tilt`)."""

    checks: int
    strict: bool = False
    refused: int = 0

    @property
    def spent(self) -> bool:
        """Whether ``checks`` poses were passed over for want of a set-down."""
        return self.refused >= self.checks

    def wrap(
        self,
        plan_approach: Callable[[NDArray[np.float64], FingerContacts], ApproachPlan | None],
        sets_down: Callable[[NDArray[np.float64]], bool],
    ) -> Callable[[NDArray[np.float64], FingerContacts], ApproachPlan | None]:
        """``plan_approach`` (a palm pose's approach: a plan, or None to pass the pose over)
        gated by ``sets_down(qpos)`` (e.g. :func:`grasp_sets_down`, the hand at its contacts)."""

        def gated(qpos: NDArray[np.float64], contacts: FingerContacts) -> ApproachPlan | None:
            if self.strict and self.spent:
                return None
            plan = plan_approach(qpos, contacts)
            if plan is None or self.spent or sets_down(qpos):
                return plan
            self.refused += 1
            return None

        return gated


def set_down_gate(
    plan_approach: Callable[[NDArray[np.float64], FingerContacts], ApproachPlan | None],
    sets_down: Callable[[NDArray[np.float64]], bool],
    checks: int,
) -> Callable[[NDArray[np.float64], FingerContacts], ApproachPlan | None]:
    """``plan_approach`` gated by a fresh, not strict :class:`SetDownGate` of ``checks``."""
    return SetDownGate(checks).wrap(plan_approach, sets_down)


def next_tilt(pitch: float) -> float | None:
    """The first of :data:`controllers.reach.coarse.LATERAL_TILTS` pitched further down than
    ``pitch`` (rad), or None."""
    return next((t for t in LATERAL_TILTS if t > pitch + PITCH_TOLERANCE), None)


def pitched_at_least(
    world: World,
    target: ReachTarget,
    planning: mujoco.MjModel,
    plan: CoarseReachPlan,
    floor: float,
) -> CoarseReachPlan | None:
    """The first lateral coarse reach to ``target`` (in the ``planning`` model) to a goal pitched
    ``floor`` (rad) or further down (:data:`controllers.reach.coarse.LATERAL_TILTS`, in order)
    that has a path, chosen as ``plan`` was; None when none has."""
    for tilt in LATERAL_TILTS:
        if tilt < floor - PITCH_TOLERANCE:
            continue
        pitched = plan_coarse_reach(
            world, target, approaches=("lateral",), model=planning, lateral_tilt=tilt
        )
        if pitched.found:
            return replace(pitched, choice=plan.choice)
    return None


def pitch_for_set_down(query: SetDownQuery, plan: CoarseReachPlan) -> tuple[CoarseReachPlan, str]:
    """``plan`` (a lateral coarse reach) when its goal's hand can set the block down
    (:func:`goal_sets_down`), else the first plan to a goal pitched further down
    (:data:`controllers.reach.coarse.LATERAL_TILTS`) whose hand can, with why, for the log;
    ``plan`` itself when none can (Deliver then says so)."""
    if plan.goal is None or goal_sets_down(query, plan.goal):
        return plan, ""
    world, target, planning = query.world, query.target, query.planning
    pitch = max(0.0, math.degrees(plan.goal.pitch))  # a level goal's may be -1e-9
    for tilt in LATERAL_TILTS:
        if tilt <= plan.goal.pitch + PITCH_TOLERANCE:
            continue
        # the goal's hand checked first: a path is planned only to a goal that can set down
        goal = pitched_lateral_goal(world, target, tilt, model=planning)
        if goal is None or not goal_sets_down(query, goal):
            continue
        pitched = plan_coarse_reach(
            world, target, approaches=("lateral",), model=planning, lateral_tilt=tilt
        )
        if pitched.found:
            why = (
                f"; pitched {math.degrees(tilt):.0f} deg down: a hand pitched {pitch:.0f} deg "
                "could not set the block down at the place point"
            )
            return replace(pitched, choice=plan.choice), why
    return plan, f"; no pitch of the hand sets the block down at the place point ({pitch:.0f} deg)"
