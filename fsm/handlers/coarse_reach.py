"""Coarse Reach (section 5.2): the arm moves on a harmonic path in its c-space to above (top)
or beside (lateral) the perceived block."""

from __future__ import annotations

import math

from controllers.arm_path import execute_path
from controllers.reach import APPROACHES, PITCH_TOLERANCE, plan_coarse_reach
from fsm.context import Episode
from fsm.handlers.common import lateral_preshape
from fsm.states import Failure, State, Step, TaskFailedError


def coarse_reach(ep: Episode) -> Step:
    """Coarse Reach: a harmonic path in the arm's c-space to above (top) or beside (lateral)
    the perceived block; the path determines the approach unless one is forced. A lateral
    approach then takes its pre-shape at a palm pose beside the block
    (:func:`fsm.handlers.common.lateral_preshape`)."""
    approaches = APPROACHES if ep.options.approach == "auto" else (ep.options.approach,)
    plan = plan_coarse_reach(ep.world, ep.target, approaches=approaches, model=ep.planning)
    if not plan.found:
        raise TaskFailedError(Failure.NO_COARSE_PATH, plan.reason)
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
        done = lateral_preshape(ep, skip=ep.record.regrasps)
        if done is None and ep.regrasp_failure is not None:
            failure, reason = ep.regrasp_failure
            raise TaskFailedError(failure, f"{reason}; no other palm pose to regrasp from")
        preshape = "; " + (done or "no pre-shape (none is approached without collision)")
    return Step(
        State.FINE_REACH,
        f"{plan.approach} approach{pitched}: {plan.choice}; touched {touched} on the way{preshape}",
    )
