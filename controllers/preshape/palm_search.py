"""Posture Control's palm-pose search (section 5.2, Posture Control; Grupen & Souccar, ref. [16]):
find an arm and hand configuration from which the hand reaches a set of virtual contacts on the
perceived block. Used by the task cycle (:mod:`fsm.handlers.posture_control`, and its lateral
pre-shape) and by the physical grasp study's placement (:mod:`experiments.physics.hand_placement`).

Two searches, over candidates generated elsewhere (:mod:`controllers.preshape.palm_candidates`, or
the study's ranked palm-down seeds):
- :func:`search_seeds` (IK seeding): from each start configuration, with the contacts given to
  its fingers, the arm-and-hand IK (:func:`controllers.posture.solver.solve_posture`) takes the
  fingertips onto the contacts; a posture that tilts the palm more than a limit from the
  reference approach axis is refused; the contacts are then confirmed from that posture by the
  reach test (:func:`controllers.hand.reachability.reachable_contacts`). The first confirmed one
  wins.
- :func:`search_poses`: at fixed palm poses, the hand IK alone (starting from sampled finger
  postures), ranked by the reach test's load, each accepted only when the hand approaches it
  without collision (a callback plans the approach).

Both return a :class:`PalmPoseResult`.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.hand.finger_assignment import FingerContacts
from controllers.hand.finger_geometry import PerceivedPrism
from controllers.hand.finger_samples import FingerSamples
from controllers.hand.reachability import (
    SQUEEZE_REACH,
    HandReach,
    grip_targets,
    reachable_contacts,
)
from controllers.planning.cspace import CollisionChecker
from controllers.posture.solver import solve_posture
from controllers.preshape.moves import ApproachPlan
from controllers.preshape.palm_candidates import PalmPose
from controllers.reach.coarse import ReachTarget
from hand_sim import robot
from hand_sim.world import World


@dataclass(frozen=True, eq=False)
class ReachQuery:
    """What the reach test of a configuration needs: the world, the model it plans in (None:
    the world's own; the task cycle's planning model has the perceived block in place of the
    real one), the perceived block, and how the contacts are reached (``slide``: they may move
    up or down their faces; ``samples``: sampled finger postures the hand IK starts from;
    ``squeeze``: how far past its contact each fingertip must reach)."""

    world: World
    planning: mujoco.MjModel | None
    prism: PerceivedPrism
    target: ReachTarget
    slide: bool = False
    samples: FingerSamples | None = None
    squeeze: float = SQUEEZE_REACH
    heights: NDArray[np.float64] | None = None  #: world z of each contact (3-D grasp), or None
    #: a three-contact grasp's finger that takes no contact (three contacts), or None
    idle: int | None = None


@dataclass(frozen=True, eq=False)
class SeedStart:
    """A start of :func:`search_seeds`: a configuration (full qpos) with the contacts given to
    its fingers, and a label for the log."""

    label: str
    qpos: NDArray[np.float64]
    contacts: FingerContacts


@dataclass(frozen=True, eq=False)
class PalmPoseResult:
    """The outcome of a palm-pose search: ``found`` with the configuration (``qpos``, full; its
    ``arm_q`` and ``hand_q``), the contacts given to the fingers and their reach test, the
    candidate used (``label``; ``start``, its index in the order tried), and what the search
    knows of it (``load``: the reach test's load; ``tilt``, rad, and ``palm_rotation``: the
    palm's; ``approach``: the approach plan the callback gave); or not, with the ``reason``."""

    found: bool
    reason: str = ""
    qpos: NDArray[np.float64] | None = None
    arm_q: NDArray[np.float64] | None = None
    hand_q: NDArray[np.float64] | None = None
    contacts: FingerContacts | None = None
    reach: HandReach | None = None
    label: str = ""
    start: int = -1
    load: float | None = None
    tilt: float | None = None
    palm_rotation: NDArray[np.float64] | None = None
    approach: ApproachPlan | None = None
    #: not found: how many acceptable poses ``skip`` passed over (fewer than it asked)
    skipped: int = 0


def _configuration(model: mujoco.MjModel, qpos: NDArray[np.float64]) -> dict[str, Any]:
    """The result fields of configuration ``qpos``."""
    return {
        "qpos": qpos,
        "arm_q": qpos[robot.arm_qpos_addresses(model)],
        "hand_q": qpos[robot.hand_qpos_addresses(model)],
    }


def search_seeds(
    query: ReachQuery,
    theta: ArrayLike,
    starts: Iterable[SeedStart],
    *,
    checker: CollisionChecker,
    axis: ArrayLike,
    max_tilt: float,
    touchable: str,
    confirm_tries: int,
    check_spacing: bool,
    axis_name: str = "the approach axis",
) -> PalmPoseResult:
    """Arm-and-hand IK from each of ``starts`` in turn (see the module docstring) for contacts
    ``theta`` (contact coordinates on the perceived polygon): the fingertips taken to the
    contacts the start gives them (fingers allowed to touch the block named ``touchable``,
    collision avoidance otherwise); refused when the palm's approach axis (from ``checker``'s
    palm pose) tilts more than ``max_tilt`` (rad) from ``axis`` (named ``axis_name`` in the
    reason); confirmed by :func:`controllers.hand.reachability.reachable_contacts` with
    ``confirm_tries`` assignments and ``check_spacing``. The contacts are at fixed heights (a
    top grasp)."""
    world = query.world
    th = np.asarray(theta, dtype=float)
    ref = np.asarray(axis, dtype=float)
    arm_adr = robot.arm_qpos_addresses(world.model)
    hand_adr = robot.hand_qpos_addresses(world.model)
    reason = "no start tried"
    for index, start in enumerate(starts):
        tips, centres = grip_targets(start.contacts.points, start.contacts.normals)
        sol = solve_posture(
            world,
            tips,
            joints="arm+hand",
            model=query.planning,
            avoid_collisions=True,
            touchable=touchable,
            fingers_may_touch=True,
            pad_centres=centres,
            qpos=start.qpos,
            give_up=True,  # an unreachable posture is passed over
        )
        if not sol.reachable:
            reason = f"Posture Control: {', '.join(sol.unreachable)} cannot reach"
            continue
        _, R = checker.palm_pose(sol.arm_q)
        tilt = float(np.arccos(np.clip(R[:, 2] @ ref, -1.0, 1.0)))
        if tilt > max_tilt:
            reason = f"Posture Control tilts the palm {np.degrees(tilt):.0f} deg from {axis_name}"
            continue
        qpos = start.qpos.copy()
        qpos[arm_adr] = sol.arm_q
        qpos[hand_adr] = sol.hand_q
        contacts, reach = reachable_contacts(
            world,
            query.prism,
            query.target,
            th,
            model=query.planning,
            qpos=qpos,
            tries=confirm_tries,
            check_spacing=check_spacing,
            heights=query.heights,
            give_up=True,
            idle=query.idle,
        )
        if not reach.reachable:
            reason = reach.reason
            continue
        return PalmPoseResult(
            True,
            **_configuration(world.model, qpos),
            contacts=contacts,
            reach=reach,
            label=start.label,
            start=index,
            tilt=tilt,
            palm_rotation=R,
        )
    return PalmPoseResult(False, reason)


def search_poses(
    query: ReachQuery,
    poses: Sequence[PalmPose],
    contacts_of: Callable[[PalmPose], NDArray[np.float64]],
    plan_approach: Callable[[NDArray[np.float64], FingerContacts], ApproachPlan | None],
    *,
    tries: int,
    reachable_only: bool,
    skip: int = 0,
    heights_of: Callable[[PalmPose], NDArray[np.float64]] | None = None,
    idle_of: Callable[[PalmPose], int | None] | None = None,
) -> PalmPoseResult:
    """Search the palm ``poses`` (:func:`controllers.preshape.palm_candidates.lateral_poses`,
    :func:`~controllers.preshape.palm_candidates.top_poses`) group by group (a lateral grasp's palm
    nearest the block first: the fingers on the far contacts keep room to squeeze; at the limit
    of their reach they push the block along instead) for one from which the hand reaches the
    contacts ``contacts_of(pose)`` (the hand IK starting from ``query.samples``, ``tries``
    assignments of contacts to fingers) and that ``plan_approach(qpos, contacts)`` approaches
    (a plan, or None when the approach collides); of several in one group, the one with the
    lowest ``HandReach.load``. Without ``reachable_only``, when none reaches, the lowest load
    that approaches. ``skip`` passes over that many acceptable poses first (a regrasp tries the
    next). ``heights_of(pose)``: the contacts' world heights at that pose (contacts taken
    where given, not slid; the hand IK from the pose's own hand posture). ``idle_of(pose)``: the
    finger that takes no contact at that pose (a three-contact grasp; default ``query.idle``)."""
    world = query.world
    hand_adr = robot.hand_qpos_addresses(world.model)
    tried = []
    passed = skip
    for _, group in itertools.groupby(enumerate(poses), key=lambda item: item[1].group):
        found = []
        for index, pose in group:
            fixed = heights_of is not None
            contacts, reach = reachable_contacts(
                world,
                query.prism,
                query.target,
                contacts_of(pose),
                model=query.planning,
                qpos=pose.qpos,
                tries=tries,
                check_spacing=False,
                slide=query.slide and not fixed,
                samples=None if fixed else query.samples,
                squeeze=query.squeeze,
                heights=heights_of(pose) if fixed else query.heights,
                give_up=reachable_only,  # else the loads of unreachable poses rank them
                span_test=reachable_only,  # unreachable verdicts' reasons are not reported
                idle=query.idle if idle_of is None else idle_of(pose),
            )
            qpos = pose.qpos.copy()
            qpos[hand_adr] = reach.hand_q
            found.append((reach.load, qpos, contacts, pose.label, reach, index))
        found.sort(key=lambda c: c[0])
        for candidate in found:
            if candidate[0] >= 1.0:
                break
            result = _accepted(world, candidate, plan_approach)
            if result is not None:
                if skip == 0:
                    return result
                skip -= 1
        tried += [c for c in found if c[0] >= 1.0]
    if reachable_only:
        return PalmPoseResult(False, "no palm pose reaches the contacts", skipped=passed - skip)
    for candidate in sorted(tried, key=lambda c: c[0]):
        result = _accepted(world, candidate, plan_approach)
        if result is not None:
            if skip == 0:
                return result
            skip -= 1
    return PalmPoseResult(
        False, "no palm pose is approached without collision", skipped=passed - skip
    )


def _accepted(
    world: World,
    candidate: tuple[float, NDArray[np.float64], FingerContacts, str, HandReach, int],
    plan_approach: Callable[[NDArray[np.float64], FingerContacts], ApproachPlan | None],
) -> PalmPoseResult | None:
    """The result of ``candidate`` (load, qpos, contacts, label, reach, index) when
    ``plan_approach`` approaches it, else None."""
    load, qpos, contacts, label, reach, index = candidate
    plan = plan_approach(qpos, contacts)
    if plan is None:
        return None
    return PalmPoseResult(
        True,
        **_configuration(world.model, qpos),
        contacts=contacts,
        reach=reach,
        label=label,
        start=index,
        load=float(load),
        approach=plan,
    )
