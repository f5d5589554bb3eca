"""Figure 14's recovery loop, as the states ask for it (section 5.2):

- the regrasp (:func:`regrasp_or_fail`): after Posture Control's retries the contacts stay out
  of reach, in Fine Reach a fingertip is held off its surface point, or in Grasp Object a finger
  misses the block as the hand closes; the task cycle starts again from Fine Reach with the hand
  turned (a top grasp: :func:`controllers.preshape.wrist_turn.turned_wrist`) or moved (a lateral
  grasp: the pre-shape at the next palm pose beside the block);
- looking again before a lateral regrasp (:func:`look_again`): a grasp that failed with the
  fingers on the block (a finger that missed it as the hand closed, a squeeze that did not
  settle, a block that slipped at the lift) may have pushed the block from where Select/Model
  saw it, and a regrasp planned on the old model then misses it again. The hand lets go, the
  arm parks, the overhead camera models the block again (Select/Model's perception) and the
  task cycle goes back to Coarse Reach for the next palm pose beside the block;
- the other approach under ``--approach auto`` (:func:`other_approach_left`; section 5.2: "The
  path computed determines whether a top or lateral grasp will be executed"): Coarse Reach
  takes the shorter of the two paths, and the paper's choice also weighs whether a grasp is
  reachable at the end of it. Where the top approach's grasp proves unreachable there (Posture
  Control's retries and every regrasp spent, or a fingertip held off its contact after them),
  the hand lets go, the arm parks, the camera models the block again and Coarse Reach plans the
  lateral approach, which had a path too, instead of the episode failing.

:func:`park_arm` also parks the arm between cycles."""

from __future__ import annotations

import numpy as np

from controllers.deliver.carry import retreat
from controllers.hand.grip import release
from controllers.planning.cspace import CollisionChecker
from controllers.preshape.moves import reposition
from controllers.preshape.wrist_turn import turned_wrist
from controllers.reach.arm_path import execute_path, plan_arm_path
from fsm.context import Episode
from fsm.episode_queries import block_site, is_lateral, rise_clear, top_to_clear
from fsm.lateral_preshape import lateral_preshape
from fsm.perception import adopt_model, log_view, perceive
from fsm.states import Failure, State, Step, TaskFailedError
from vision import ObjectModel, VisionError

#: The block seen again counts as the one grasped, still standing as modelled, when its top
#: face's centre is within this distance (m) of the model's, it has as many edges and its area
#: differs by at most AREA_TOLERANCE (a block tipped onto a side shows another face).
SAME_BLOCK_RADIUS = 0.05
AREA_TOLERANCE = 0.25


def park_arm(ep: Episode) -> str:
    """Take the arm back to where it stood when the first Select/Model looked, so that the next
    look sees the table as the first did (Select/Model's guard: the arm is parked clear of the
    table; a hand left above the table hides blocks from the overhead camera, and its faces merge
    with theirs). The path is planned among the blocks where they stand now; where the retreat
    left the hand within the planning clearance of something (a lateral hand backing out beside
    a neighbour), the palm first rises straight up until it is clear
    (:func:`controllers.deliver.plan.rise_until_clear`, as a set-down's transit starts), and stays
    risen when no path parks it (Coarse Reach then plans from a posture that is clear). Returns
    what was done, for the transition log."""
    if ep.parked_arm is None:
        return "the arm stays where it retreated to"
    checker = CollisionChecker(ep.world)
    first = ""
    if checker.collides(ep.world.arm_qpos()):
        height = rise_clear(ep, checker)  # parked or not, Coarse Reach starts from there
        first = "" if height is None else f"the palm risen {height * 100:.0f} cm clear, "
    path = plan_arm_path(checker, ep.world.arm_qpos(), ep.parked_arm)
    if not path.found:
        return (
            f"{first}the arm stays where it retreated to (no path to its parked posture: "
            f"{path.reason})"
        )
    execute_path(ep.world, path.path)
    return f"{first}the arm is parked clear of the view"


def _seen_again(ep: Episode) -> tuple[ObjectModel, float] | str:
    """The picked block's model from a new overhead image and how far (m) its top face's centre
    is from the old model's, or why it is not the block grasped, standing as modelled (matched
    by where its top face is, not by name)."""
    old = ep.model
    try:
        check = ep.config.closed_loop.camera_check
        selection = ep.selection = perceive(ep.world, check_camera=check)
        model = selection.model(selection.index_near(old.centroid))
    except VisionError as e:
        return f"the overhead camera does not model it again ({e})"
    moved = float(np.linalg.norm(model.centroid[:2] - old.centroid[:2]))
    area = abs(model.polygon.area - old.polygon.area) / old.polygon.area
    if moved > SAME_BLOCK_RADIUS or model.n_edges != old.n_edges or area > AREA_TOLERANCE:
        return (
            f"the overhead camera sees {model.n_edges} edges {moved * 1000:.0f} mm from where it "
            f"stood, area {area * 100:.0f} % off (it no longer stands as modelled)"
        )
    return model, moved


def release_and_look(ep: Episode, reason: str, failure: Failure) -> tuple[str, float]:
    """Let go of the block (if held), retreat, park the arm (:func:`park_arm`) and model the
    picked block again from a new overhead image (adopted as Select/Model adopts one). Returns
    what the park did, for the log, and how far (m) the block is from where it was modelled;
    fails with ``failure`` and ``reason`` when the block is not seen standing as modelled."""
    world = ep.world
    if ep.grip is not None:
        release(world, ep.grip)
    world.let_go()
    retreat(world, CollisionChecker(world), clear_top=top_to_clear(ep))
    parked = park_arm(ep)
    seen = _seen_again(ep)
    if isinstance(seen, str):
        raise TaskFailedError(failure, f"{reason}; {seen}")
    model, moved = seen
    adopt_model(ep, ep.target_name, model)
    log_view(ep, model)
    return parked, moved


def look_again(ep: Episode, reason: str, failure: Failure, label: str = "regrasp") -> Step:
    """Release, retreat, park, look again and go back to Coarse Reach, whose lateral pre-shape
    is then taken at the next palm pose (``skip`` = the regrasps so far, this one counted).
    ``reason`` (why the grasp failed) and ``failure`` are what the episode fails with when the
    block is not seen standing as modelled, or (in Coarse Reach) no palm pose is left;
    ``label`` names the retry in the transition log."""
    parked, moved = release_and_look(ep, reason, failure)
    ep.record.regrasps += 1
    ep.record.posture_retries = 0
    ep.regrasp_failure = (failure, reason)
    ep.synthesis = ep.contacts = ep.reach = ep.grip = None
    return Step(
        State.COARSE_REACH,
        f"{label} ({reason}): released, {parked}; seen again {moved * 1000:.0f} mm from where "
        "it was modelled: grasp again from the next palm pose",
    )


def lift_retry_left(ep: Episode) -> bool:
    """Whether a lateral grasp that failed its lift may be taken again: fewer than
    ``config.lift_retries`` such retries and ``config.max_regrasps`` regrasps so far."""
    record, config = ep.record, ep.config
    return (
        is_lateral(ep)
        and record.lift_retries < config.lift_retries
        and record.regrasps < config.max_regrasps
    )


def grasp_again_or_fail(ep: Episode, detail: str) -> Step:
    """After a lateral grasp's block slipped at the lift (``detail``: what the hand sensed),
    :func:`look_again`; fails with Failure.SLIPPED_DURING_LIFT for a top grasp, after
    ``config.lift_retries`` such retries or ``config.max_regrasps`` regrasps."""
    record = ep.record
    if not lift_retry_left(ep):
        raise TaskFailedError(Failure.SLIPPED_DURING_LIFT, detail)
    record.lift_retries += 1
    if ep.config.lateral_retry_by_reserve:
        reserve = record.squeeze_reserve
        ep.retry_floor = -np.inf if reserve is None else reserve
    return look_again(ep, detail, Failure.SLIPPED_DURING_LIFT, label="slipped at the lift")


#: The failures that say a grasp is not reachable at the approach's end (the grasp's contacts
#: out of the hand's reach, or its fingertips held off them), after which ``auto`` may take
#: the other approach.
UNREACHABLE = (Failure.CONTACT_UNREACHABLE, Failure.FINGERS_CANNOT_REACH)


def other_approach_left(ep: Episode, failure: Failure) -> str | None:
    """The approach ``auto`` takes next when the grasp at the end of the one taken is
    unreachable (``failure`` one of :data:`UNREACHABLE`): the lateral one after a top grasp,
    when Coarse Reach found a path for it too; None otherwise (an approach forced on the
    command line, a lateral grasp, the approach taken after a switch, another failure)."""
    coarse = ep.coarse
    if ep.options.approach != "auto" or coarse is None or failure not in UNREACHABLE:
        return None
    if coarse.approach != "top":  # after the switch Coarse Reach's plan is the lateral one
        return None
    lateral = coarse.candidates.get("lateral")
    return "lateral" if lateral is not None and lateral.found else None


def take_other_approach(ep: Episode, approach: str, failure: Failure, detail: str) -> Step:
    """Give up the approach taken (its grasp unreachable at its end: ``failure``, ``detail``),
    let go, park, look again (:func:`release_and_look`) and go back to Coarse Reach for
    ``approach``, its regrasp and posture-retry counts starting afresh. The summary's
    ``approach_given_up`` says which approach was given up and why."""
    given_up = ep.coarse.approach
    parked, moved = release_and_look(ep, detail, failure)
    ep.closed_approaches += (given_up,)
    record = ep.record
    record.approach_given_up = f"{given_up}: {failure.value}: {detail}"
    record.regrasps = record.posture_retries = 0
    ep.synthesis = ep.contacts = ep.reach = ep.grip = None
    ep.regrasp_failure = None
    return Step(
        State.COARSE_REACH,
        f"{given_up} grasp unreachable at its end ({failure.value}: {detail}): released, "
        f"{parked}; seen again {moved * 1000:.0f} mm from where it was modelled: the "
        f"{approach} approach next (auto)",
    )


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
    palm pose beside the block, :func:`fsm.lateral_preshape.lateral_preshape`), so the grasp
    controller starts from other contacts; after ``config.max_regrasps``, or with no other
    palm pose or wrist turn to regrasp from, fail with ``failure`` (the reason the regrasp was
    asked for) and the reason, except that under ``--approach auto`` a top grasp unreachable
    at its end gives way to the lateral approach (:func:`other_approach_left`). With ``look``
    (Grasp Object's: the fingers have been on the block and may have pushed it) a lateral
    regrasp first looks at the block again and goes by Coarse Reach (:func:`look_again`)."""
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
    if is_lateral(ep) and look:
        return look_again(ep, reason, failure)
    if is_lateral(ep):
        # lateral: the pre-shape at the next palm pose beside the block
        record.regrasps += 1
        done = lateral_preshape(ep, skip=record.regrasps)
        if done is None:
            raise TaskFailedError(failure, f"{reason}; no other palm pose to regrasp from")
        record.posture_retries = 0
        ep.synthesis = ep.contacts = ep.reach = None
        return Step(State.FINE_REACH, f"regrasp ({reason}): {done}")
    # back to the coarse reach's goal (the hand hovering in its pre-shape), turned
    roll = config.regrasp_rolls[record.regrasps]
    turn = turned_wrist(ep.world, ep.planning, ep.coarse.goal, roll, config.motion.backoff)
    record.regrasps += 1
    if not turn.found:
        return _other_approach_or_fail(ep, failure, f"{reason}; cannot regrasp ({turn.how})")
    reposition(block_site(ep), turn.arm_q, np.asarray(ep.coarse.hand_q))
    record.posture_retries = 0
    ep.synthesis = ep.contacts = ep.reach = None
    return Step(State.FINE_REACH, f"regrasp ({reason}) with the {turn.how}")


def _other_approach_or_fail(ep: Episode, failure: Failure, detail: str) -> Step:
    """Under ``--approach auto``, a top grasp unreachable after its regrasps gives way to the
    lateral approach (:func:`take_other_approach`); otherwise the episode fails with
    ``failure`` and ``detail``."""
    other = other_approach_left(ep, failure)
    if other is None:
        raise TaskFailedError(failure, detail)
    return take_other_approach(ep, other, failure, detail)
