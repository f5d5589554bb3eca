"""Coarse Reach (section 5.2): the arm moves on a harmonic path in its c-space to above (top)
or beside (lateral) the perceived block."""

from __future__ import annotations

import math
from collections.abc import Iterable

from controllers.arm_path import START_IN_COLLISION, ArmPath, execute_path
from controllers.cspace import CollisionChecker
from controllers.reach import APPROACHES, PITCH_TOLERANCE, PRESHAPE, plan_coarse_reach
from fsm.context import Episode
from fsm.handlers.common import lateral_preshape, rise_clear
from fsm.handlers.set_down_pitch import pitch_for_set_down
from fsm.states import Failure, State, Step, TaskFailedError


def coarse_reach(ep: Episode) -> Step:
    """Coarse Reach: a harmonic path in the arm's c-space to above (top) or beside (lateral)
    the perceived block; the path determines the approach unless one is forced. A lateral
    approach then takes its pre-shape at a palm pose beside the block
    (:func:`fsm.handlers.common.lateral_preshape`)."""
    approaches = APPROACHES if ep.options.approach == "auto" else (ep.options.approach,)
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
    for_set_down = ""
    if plan.approach == "lateral" and ep.config.lateral_set_down_pitch and ep.place is not None:
        plan, for_set_down = pitch_for_set_down(ep, plan)
    ep.coarse = plan
    ep.record.approach = plan.approach
    pitch = math.degrees(plan.goal.pitch)
    ep.record.approach_pitch_deg = round(pitch, 1)
    pitched = (
        f" (axis pitched {pitch:.0f} deg down)"
        if plan.approach == "lateral" and plan.goal.pitch > PITCH_TOLERANCE
        else ""
    )
    run = execute_path(ep.world, plan.path.path, hand_q=plan.hand_q)
    touched = ", ".join(f"{a}-{b}" for a, b in run.contacts) or "nothing"
    preshape = ""
    if plan.approach == "lateral":
        # after the camera looked again (fsm.handlers.look_again), the next palm pose
        done = None
        if ep.retry_floor is not None:  # a grasp that holds more than the one that slipped
            floor = ep.retry_floor
            done = lateral_preshape(ep, skip=0)
            if done is None:
                ep.retry_floor = None
            else:
                done += f"; its grasp's reserve above the {floor:.2f} N of the one that slipped"
        if done is None:
            done = lateral_preshape(ep, skip=ep.record.regrasps)
        if done is None and ep.regrasp_failure is not None:
            failure, reason = ep.regrasp_failure
            raise TaskFailedError(failure, f"{reason}; no other palm pose to regrasp from")
        preshape = "; " + (done or "no pre-shape (none is approached without collision)")
    return Step(
        State.FINE_REACH,
        f"{plan.approach} approach{pitched}: {plan.choice}{for_set_down}{risen}; touched "
        f"{touched} on the way{preshape}",
    )


def _start_in_collision(paths: Iterable[ArmPath]) -> bool:
    """Whether a coarse path failed because the arm starts within the planning clearance of
    something (a regrasp's retreat may leave a lateral hand beside a neighbour)."""
    return any(not p.found and p.reason == START_IN_COLLISION for p in paths)
