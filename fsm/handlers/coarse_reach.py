"""Coarse Reach (section 5.2): the arm moves on a harmonic path in its c-space to above (top)
or beside (lateral) the perceived block."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from controllers.planning.cspace import CollisionChecker
from controllers.preshape.palm_candidates import from_base_side, robot_base_xy
from controllers.preshape.set_down_check import SetDownGate, next_tilt
from controllers.reach.arm_path import START_IN_COLLISION, ArmPath, execute_path
from controllers.reach.coarse import APPROACHES, PITCH_TOLERANCE, PRESHAPE, plan_coarse_reach
from fsm.context import Episode
from fsm.episode_queries import rise_clear
from fsm.lateral_preshape import lateral_preshape, pitch_for_set_down, pitched_at_least
from fsm.states import Failure, State, Step, TaskFailedError


def coarse_reach(ep: Episode) -> Step:
    """Coarse Reach: a harmonic path in the arm's c-space to above (top) or beside (lateral)
    the perceived block; the path determines the approach unless one is forced. A lateral
    approach then takes its pre-shape at a palm pose beside the block
    (:func:`fsm.lateral_preshape.lateral_preshape`). Where that search passes over
    ``config.lateral_grasp_set_down_checks`` grasps that cannot set the block down at the place
    point and a lateral axis pitched further down is left
    (:data:`controllers.reach.coarse.LATERAL_TILTS`), Coarse Reach is entered again for that
    pitch (``ep.set_down_floor``). Under ``auto``, an approach given up because its grasp was
    unreachable at its end (:func:`fsm.recovery.other_approach_left`) is not planned again, and
    the log says so."""
    approaches = APPROACHES if ep.options.approach == "auto" else (ep.options.approach,)
    # under auto, an approach whose grasp proved unreachable at its end is not planned again
    approaches = tuple(a for a in approaches if a not in ep.closed_approaches)
    plan = plan_coarse_reach(ep.world, ep.target, approaches=approaches, model=ep.planning)
    risen = ""
    if not plan.found and _start_in_collision(plan.candidates.values()):
        # the reach's checker: the planning model, the hand pre-shaped
        height = rise_clear(ep, CollisionChecker(ep.world, hand_q=PRESHAPE, model=ep.planning))
        if height is not None:
            risen = f"; the palm first risen {height * 100:.0f} cm, clear of what it stood beside"
            plan = plan_coarse_reach(ep.world, ep.target, approaches=approaches, model=ep.planning)
    if not plan.found:
        raise TaskFailedError(Failure.NO_COARSE_PATH, plan.reason)
    if ep.closed_approaches:
        closed = " and ".join(ep.closed_approaches)
        why = f"the only approach left: the {closed} approach's grasp was unreachable at its end"
        plan = replace(plan, choice=why)
    for_set_down = ""
    floor = ep.set_down_floor
    if plan.approach == "lateral" and floor is not None and math.isfinite(floor):
        pitched = pitched_at_least(ep, plan, floor)
        if pitched is None:  # no further pitch has a path: the gate takes poses unasked
            ep.set_down_floor = math.inf
        else:
            plan, for_set_down = pitched, "; pitched on: no grasp at a lesser pitch sets it down"
    if plan.approach == "lateral" and ep.config.lateral_set_down_pitch and ep.place is not None:
        plan, why = pitch_for_set_down(ep, plan)
        for_set_down += why
    ep.coarse = plan
    ep.record.approach = plan.approach
    pitch = math.degrees(plan.goal.pitch)
    ep.record.approach_pitch_deg = round(pitch, 1)
    pitched = (
        f" (axis pitched {pitch:.0f} deg down)"
        if plan.approach == "lateral" and plan.goal.pitch > PITCH_TOLERANCE
        else ""
    )
    far = plan.approach == "lateral" and _far_side(ep, plan.goal.palm_rotation)
    if far:
        ep.record.approach_far_side = True
        pitched += " from the block's far side (no goal on the arm base's side)"
    run = execute_path(ep.world, plan.path.path, hand_q=plan.hand_q)
    touched = ", ".join(f"{a}-{b}" for a, b in run.contacts) or "nothing"
    preshape = ""
    if plan.approach == "lateral":
        # after the camera looked again (fsm.recovery.look_again), the next palm pose
        done = None
        gate = _set_down_gate(ep, None if far else plan.goal.pitch)
        if ep.retry_floor is not None:  # a grasp that holds more than the one that slipped
            reserve = ep.retry_floor
            done = lateral_preshape(ep, skip=0, gate=gate)
            if done is None:
                ep.retry_floor = None
            else:
                done += f"; its grasp's reserve above the {reserve:.2f} N of the one that slipped"
        if done is None:
            done = lateral_preshape(ep, skip=ep.record.regrasps, gate=gate)
        if done is None and gate is not None and gate.strict and gate.spent:
            ep.set_down_floor = next_tilt(plan.goal.pitch)
            return Step(
                State.COARSE_REACH,
                f"{plan.approach} approach{pitched}: {plan.choice}{for_set_down}{risen}; "
                f"{gate.refused} grasps passed over: none could set the block down at the "
                f"place point; the axis pitched {math.degrees(ep.set_down_floor):.0f} deg "
                "down next",
            )
        if done is None and ep.regrasp_failure is not None:
            failure, reason = ep.regrasp_failure
            raise TaskFailedError(failure, f"{reason}; no other palm pose to regrasp from")
        preshape = "; " + (done or "no pre-shape (none is approached without collision)")
    return Step(
        State.FINE_REACH,
        f"{plan.approach} approach{pitched}: {plan.choice}{for_set_down}{risen}; touched "
        f"{touched} on the way{preshape}",
    )


def _set_down_gate(ep: Episode, pitch: float | None) -> SetDownGate | None:
    """The lateral pre-shape's set-down gate at a goal pitched ``pitch`` (rad; None: a far-side
    goal's, no pitch left to take) strict while a further pitch is left to take
    (:func:`controllers.preshape.set_down_check.next_tilt`); None where no grasp is asked for a
    set-down (no place point, or no checks configured)."""
    checks = ep.config.lateral_grasp_set_down_checks
    if not checks or ep.place is None:
        return None
    left = pitch is not None and ep.set_down_floor != math.inf and next_tilt(pitch) is not None
    return SetDownGate(checks, strict=left and ep.config.lateral_set_down_pitch)


def _far_side(ep: Episode, rotation: NDArray[np.float64]) -> bool:
    """Whether a lateral palm of ``rotation`` faces the block from its far side."""
    return not from_base_side(robot_base_xy(ep.world), ep.target, rotation)


def _start_in_collision(paths: Iterable[ArmPath]) -> bool:
    """Whether a coarse path failed because the arm starts within the planning clearance of
    something (a regrasp's retreat may leave a lateral hand beside a neighbour)."""
    return any(not p.found and p.reason == START_IN_COLLISION for p in paths)
