"""Posture Control (section 5.2; Grupen & Souccar, ref. [16]): the arm and hand reconfigure to
maximise the hand's manipulability holding the fingertips (after Fine Reach), or to bring the
virtual contacts within the fingers' reach (from Wrench Closure) by the palm-pose search."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace

import numpy as np

from controllers.grasp.synthesis3d import GraspSynthesis3D
from controllers.grasp.task_height import HEIGHT_GAP
from controllers.hand.finger_assignment import ranked_assignments
from controllers.hand.grip import PRE_CONTACT
from controllers.hand.reachability import ASSIGNMENTS_TRIED, grip_targets
from controllers.planning.belief import PERCEIVED_GEOM
from controllers.planning.cspace import CollisionChecker
from controllers.posture.solver import apply_posture, solve_posture
from controllers.preshape.moves import approach, approach_touches, reposition
from controllers.preshape.palm_candidates import (
    PalmPose,
    PoseSetting,
    lateral_poses,
    roll_seeds,
    top_poses,
)
from controllers.preshape.palm_search import PalmPoseResult, SeedStart, search_poses, search_seeds
from fsm.context import Episode
from fsm.episode_queries import (
    block_site,
    is_lateral,
    plan_approach,
    reach_query,
    sampled_preshape,
    side_arcs,
)
from fsm.recovery import regrasp_or_fail
from fsm.states import MAX_FINE_REACH_LOOPS, MAX_POSTURE_RETRIES, State, Step


def posture_control(ep: Episode) -> Step:
    """Posture Control (Grupen & Souccar, ref. [16]): the arm and hand reconfigure to maximise
    the hand's manipulability, holding the fingertips (after Fine Reach) or bringing the current
    virtual contacts within the fingers' reach (from Wrench Closure), never touching anything
    but the block's surface with the pads (collision avoidance in the perceived world)."""
    world = ep.world
    if ep.posture_mode == "hold" and sampled_preshape(ep):
        # a sampled lateral pre-shape's palm pose was chosen for its contacts, at the edge of
        # the fingers' workspace: raising the manipulability with the tips held moves the palm
        # off it and the contacts out of reach
        return Step(State.WRENCH_CLOSURE, "palm held where the sampled pre-shape put it")
    if ep.posture_mode == "hold":
        sol = solve_posture(
            world,
            model=ep.planning,
            avoid_collisions=True,
            touchable=PERCEIVED_GEOM,
            pads_press=False,
        )
        before = world.fingertip_positions()
        if sol.reachable:
            apply_posture(world, sol)
        drift = float(np.linalg.norm(world.fingertip_positions() - before, axis=1).max())
        gain = sol.log_manipulability_end - sol.log_manipulability_start
        if drift > ep.config.posture_drift and ep.record.fine_reach_loops < MAX_FINE_REACH_LOOPS:
            ep.record.fine_reach_loops += 1
            return Step(State.FINE_REACH, f"fingertips drifted {drift * 1000:.1f} mm")
        return Step(
            State.WRENCH_CLOSURE,
            f"manipulability log M +{gain:.2f}, tips held within {drift * 1000:.1f} mm",
        )
    # contacts mode: make the virtual contacts reachable, trying the wrist roll in steps
    if ep.record.posture_retries > MAX_POSTURE_RETRIES:
        return regrasp_or_fail(ep)
    found = reachable_posture(ep)
    raised = ""
    if not found.found:
        higher = search_other_heights(ep)
        if higher is not None:
            found, up = higher
            raised = f", at the task's next-best common height ({up * 1000:+.0f} mm)"
    if not found.found:
        if ep.record.posture_retries >= MAX_POSTURE_RETRIES:
            return regrasp_or_fail(ep)
        return Step(State.WRENCH_CLOSURE, "no arm posture reaches the contacts yet")
    ep.contacts = found.contacts
    touched = ""
    plan = found.approach
    if plan is None and is_lateral(ep):
        plan = plan_approach(ep, found.qpos, found.contacts)
    if plan is not None:
        approach(block_site(ep), plan)
    else:
        pre, pre_pads = grip_targets(found.contacts.points, found.contacts.normals, -PRE_CONTACT)
        hand_pre = solve_posture(
            world,
            pre,
            optimize=False,
            joints="hand",
            model=ep.planning,
            pad_centres=pre_pads,
            qpos=found.qpos,
        ).hand_q
        # a straight approach that meets a neighbour would push it: take an approach that clears
        # the perceived world instead (the fingers wider open), or give this posture up
        # (docs/findings.md, "An approach that clears the neighbours")
        touches = approach_touches(block_site(ep), found.arm_q, hand_pre)
        if not touches:
            reposition(block_site(ep), found.arm_q, hand_pre)
        else:
            touched = f"; its straight approach met {', '.join(touches)}"
            clear = plan_approach(ep, found.qpos, found.contacts)
            if clear is None:
                ep.record.posture_retries += 1
                return Step(
                    State.WRENCH_CLOSURE,
                    f"no arm posture reaches the contacts yet (search from {found.label}"
                    f"{touched}, and no approach clears it)",
                )
            approach(block_site(ep), clear)
            touched += ": approached with the fingers opened clear of it"
    return Step(
        State.WRENCH_CLOSURE,
        f"arm reconfigured (search from {found.label}) so that the contacts are within reach"
        + raised
        + touched,
    )


def search_other_heights(ep: Episode) -> tuple[PalmPoseResult, float] | None:
    """When no arm posture reaches a finished top 3-D grasp's contacts at the task's common
    height: the palm-pose search at each next-best common height in turn
    (:meth:`~controllers.grasp.synthesis3d.GraspSynthesis3D.height_options`,
    ``config.height_tries`` in all, :data:`~controllers.grasp.task_height.HEIGHT_GAP` apart),
    once per synthesis. The first posture found, with how far (m) its height is above the
    task's; the controller keeps that height. None (the task's height kept) when none is found
    or the grasp is planar, lateral or still moving."""
    syn = ep.synthesis
    if (
        is_lateral(ep)
        or not isinstance(syn, GraspSynthesis3D)
        or not syn.done
        or ep.heights_searched is syn
    ):
        return None
    ep.heights_searched = syn
    options = syn.height_options(ep.config.height_tries, HEIGHT_GAP)
    for option in options[1:]:
        syn.set_heights(option)
        found = reachable_posture(ep)
        if found.found:
            return found, float(np.mean(option - options[0]))
    syn.set_heights(options[0])
    return None


def reachable_posture(ep: Episode) -> PalmPoseResult:
    """An arm and hand configuration from which the current contacts are reachable, with the
    contacts given to the fingers, the search's label and the approach plan (None when the
    arm's own IK found the posture). A top grasp first follows the arm's IK from wrist-roll
    seeds (:func:`controllers.preshape.palm_search.search_seeds`), then, when that finds nothing,
    searches :func:`controllers.preshape.palm_candidates.top_poses` (the hand IK starting from
    the hand's posture at each pose: a top grasp's contacts do not slide, and the sampled finger
    starts are for sliding contacts); a lateral grasp searches
    :func:`controllers.preshape.palm_candidates.lateral_poses`. Its effect on the bench:
    docs/findings.md, "The palm-pose search above the block"."""
    params = ep.config.palm_pose
    rotation = ep.coarse.goal.palm_rotation
    where = PoseSetting(ep.world, ep.planning, ep.target, rotation)
    if is_lateral(ep):
        if ep.preshape_rolls is not None:  # the hand turned as its pre-shape took it
            params = replace(params, lateral_rolls=ep.preshape_rolls)
        poses = lateral_poses(where, params, side_arcs(ep), hand=ep.preshape_hand_q)
        return _posture_among(ep, poses)
    query = reach_query(ep)
    theta = ep.synthesis.theta

    def starts() -> Iterator[SeedStart]:
        # the contacts the nearest assignment gives the fingers at each seed
        for label, seed in roll_seeds(ep.world, params):
            contacts = ranked_assignments(
                ep.world,
                ep.prism,
                ep.target,
                theta,
                model=ep.planning,
                qpos=seed,
                heights=query.heights,
                count=1,
            )[0]
            yield SeedStart(label, seed, contacts)

    found = search_seeds(
        query,
        theta,
        starts(),
        checker=CollisionChecker(ep.world, model=ep.planning),
        axis=rotation[:, 2],
        max_tilt=params.max_palm_tilt(ep.coarse.approach),
        touchable=PERCEIVED_GEOM,
        confirm_tries=ASSIGNMENTS_TRIED,
        check_spacing=False,
    )
    if found.found:
        return found
    # the arm's differential IK from the roll seeds found nothing: search palm poses above the
    # block
    key = (ep.world.data.qpos.tobytes(), rotation.tobytes(), id(ep.target), id(ep.planning))
    if ep.top_poses is None or ep.top_poses[0] != key:
        ep.top_poses = (key, top_poses(where, params))
    return _posture_among(ep, ep.top_poses[1])


def _posture_among(ep: Episode, poses: list[PalmPose]) -> PalmPoseResult:
    """A palm pose of ``poses`` from which the hand reaches the current contacts and that it
    approaches without collision (:func:`controllers.preshape.palm_search.search_poses`)."""
    theta = ep.synthesis.theta
    return search_poses(
        reach_query(ep),
        poses,
        lambda pose: theta,
        lambda qpos, contacts: plan_approach(ep, qpos, contacts),
        tries=ep.config.palm_pose.pose_tries,
        reachable_only=True,
    )
