"""The regrasp (Figure 14's recovery loop back to Fine Reach): after Posture Control's retries
the contacts stay out of reach, in Fine Reach a fingertip is held off its surface point, or in
Grasp Object a finger misses the block as the hand closes; shared by those three states."""

from __future__ import annotations

import numpy as np

from controllers.planning.cspace import CollisionChecker
from controllers.preshape.moves import reposition
from controllers.preshape.palm_candidates import turn_about_vertical
from fsm.context import Episode
from fsm.handlers.common import block_site, slides
from fsm.handlers.lateral_preshape import lateral_preshape
from fsm.handlers.look_again import look_again
from fsm.handlers.other_approach import other_approach_left, take_other_approach
from fsm.states import Failure, State, Step, TaskFailedError


def regrasp_or_fail(
    ep: Episode,
    reason: str | None = None,
    failure: Failure = Failure.CONTACT_UNREACHABLE,
    *,
    look: bool = False,
) -> Step:
    """After MAX_POSTURE_RETRIES the contacts stay out of reach (or, from Fine Reach, a
    fingertip was held off its surface point; from Grasp Object, a finger missed the block as
    the hand closed): start again from Fine Reach with the hand turned (top grasp: the wrist
    rolled by the next of ``config.regrasp_rolls``) or moved (lateral: the pre-shape at the next
    palm pose beside the block, :func:`fsm.handlers.lateral_preshape.lateral_preshape`), so the
    grasp controller starts from other contacts; after ``config.max_regrasps``, or with no other
    palm pose or wrist turn to regrasp from, fail with ``failure`` (the reason the regrasp was
    asked for) and the reason, except that under ``--approach auto`` a top grasp unreachable
    at its end gives way to the lateral approach (:mod:`fsm.handlers.other_approach`).
    With ``look`` (Grasp Object's: the fingers have been on the block and may have pushed it) a
    lateral regrasp first looks at the block again and goes by Coarse Reach
    (:func:`fsm.handlers.look_again.look_again`)."""
    record = ep.record
    config = ep.config
    if reason is None:
        reason = ep.reach.reason if ep.reach is not None else "unreachable"
    if record.regrasps >= config.max_regrasps:
        return _other_approach_or_fail(
            ep,
            failure,
            f"after {config.max_regrasps} regrasps and {record.posture_retries} posture "
            f"retries: {reason}",
        )
    if slides(ep) and look:
        return look_again(ep, reason, failure)
    if slides(ep):
        # lateral: the pre-shape at the next palm pose beside the block
        record.regrasps += 1
        done = lateral_preshape(ep, skip=record.regrasps)
        if done is None:
            raise TaskFailedError(failure, f"{reason}; no other palm pose to regrasp from")
        record.posture_retries = 0
        ep.synthesis = ep.contacts = ep.reach = None
        return Step(State.FINE_REACH, f"regrasp ({reason}): {done}")
    world = ep.world
    backoff = config.motion.backoff
    checker = CollisionChecker(world, model=ep.planning)
    arm_now = world.arm_targets()
    # back to the coarse reach's goal (the hand hovering in its pre-shape), turned or moved
    p, R = ep.coarse.goal.palm_position, ep.coarse.goal.palm_rotation
    seed = arm_now.copy()
    roll = config.regrasp_rolls[record.regrasps]
    goal_p, goal_R = p, turn_about_vertical(roll) @ R
    seed[-1] += roll
    how = f"wrist turned {np.degrees(roll):+.0f} deg"
    ik = checker.solve_ik(goal_p - backoff * goal_R[:, 2], goal_R, seed)
    record.regrasps += 1
    if not ik.found:  # the other way round
        goal_R = goal_R @ np.diag([-1.0, -1.0, 1.0])
        seed[-1] += np.pi if seed[-1] < 0 else -np.pi
        ik = checker.solve_ik(goal_p - backoff * goal_R[:, 2], goal_R, seed)
    if not ik.found:
        return _other_approach_or_fail(ep, failure, f"{reason}; cannot regrasp ({how})")
    back = checker.solve_ik(goal_p, goal_R, ik.q)
    reposition(block_site(ep), back.q if back.found else ik.q, np.asarray(ep.coarse.hand_q))
    record.posture_retries = 0
    ep.synthesis = ep.contacts = ep.reach = None
    return Step(State.FINE_REACH, f"regrasp ({reason}) with the {how}")


def _other_approach_or_fail(ep: Episode, failure: Failure, detail: str) -> Step:
    """Under ``--approach auto``, a top grasp unreachable after its regrasps gives way to the
    lateral approach (:mod:`fsm.handlers.other_approach`); otherwise the episode fails with
    ``failure`` and ``detail``."""
    other = other_approach_left(ep, failure)
    if other is None:
        raise TaskFailedError(failure, detail)
    return take_other_approach(ep, other, failure, detail)
