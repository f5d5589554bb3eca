"""What several state handlers share: the episode's view of the controllers' explicit inputs
(the motion primitives' :class:`~controllers.motion.BlockSite`, the palm-pose search's
:class:`~controllers.palm_pose.ReachQuery`), whether this cycle's grasp is lateral, and the
lateral pre-shape (Coarse Reach, and a lateral regrasp)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np
from numpy.typing import NDArray

from controllers.arm_path import execute_path
from controllers.cspace import CollisionChecker
from controllers.delivery import RISE_STEP, SET_DOWN_CLEARANCE, rise_until_clear
from controllers.finger_assignment import FingerContacts
from controllers.finger_geometry import fingertips_at
from controllers.finger_samples import PAD_NORMAL_LOCAL, FingerSamples
from controllers.grasp.score import SUCCESS_THRESHOLD, grasp_score
from controllers.grasp.session import keep_contacts
from controllers.grasp.session3d import GraspSynthesis3D
from controllers.hand_reach import CONTACT_SEPARATION, SQUEEZE_REACH
from controllers.lateral_grasp import (
    CandidateCache,
    SampledGrasp,
    sampled_lateral_grasp,
    three_contact_lateral_grasp,
)
from controllers.lateral_squeeze import lateral_squeeze
from controllers.motion import ApproachPlan, BlockSite, approach, approach_plan
from controllers.palm_candidates import (
    LATERAL_ROLL_STEP,
    PalmPose,
    PoseSetting,
    face_arcs,
    lateral_arcs,
    lateral_poses,
    robot_base_xy,
    side_contacts,
)
from controllers.palm_pose import PalmPoseResult, ReachQuery, search_poses
from fsm.context import Episode
from fsm.handlers.set_down_pitch import grasp_sets_down, set_down_gate
from hand_sim import robot
from hand_sim.geometry import place_polygon


def slides(ep: Episode) -> bool:
    """Whether the contacts may slide up and down their faces: in a lateral grasp the finger row
    is horizontal and the thumb below it, so the hand's shape, not a depth below the top, sets
    each finger's height on the block (a top grasp keeps its fingers at the depth they
    reached)."""
    return ep.coarse is not None and ep.coarse.approach == "lateral"


def top_to_clear(ep: Episode) -> float | None:
    """The block's top (world z) a lateral hand's fingertips rise above before it backs off
    from a block left standing (:func:`controllers.transport.retreat`), None for a top grasp
    or with ``lateral_retreat_rise`` off."""
    return ep.target.top_z if slides(ep) and ep.config.lateral_retreat_rise else None


def rise_clear(ep: Episode, clear: CollisionChecker) -> float | None:
    """Raise the palm straight up until the arm is clear of everything by ``clear``
    (:func:`controllers.delivery.rise_until_clear`, each step kept
    :data:`~controllers.delivery.SET_DOWN_CLEARANCE` from everything with the hand as it is)
    and move it there; how far (m), or None when it cannot rise clear (the arm stays)."""
    tight = CollisionChecker(ep.world, clearance=SET_DOWN_CLEARANCE, model=clear.model)
    start = ep.world.arm_qpos()
    risen = rise_until_clear(clear, tight, start)
    if risen is None:
        return None
    execute_path(ep.world, np.vstack([start[None], risen]))
    return len(risen) * RISE_STEP


@dataclass
class PoseGrasps:
    """One pre-shape search's palm poses beside the block, each with its sampled grasp (None
    where the samples make none), by the wrist rolls searched and whether the grasps are of
    three contacts; and the fingers' candidate contacts at each pose, which both share."""

    grasps: dict[tuple[tuple[float, ...], bool], list[tuple[PalmPose, SampledGrasp | None]]] = (
        field(default_factory=dict)
    )
    candidates: CandidateCache = field(default_factory=dict)


def finger_samples(ep: Episode) -> FingerSamples:
    """Sampled finger postures, IK starts for a palm-pose search (drawn once an episode)."""
    if ep.finger_samples is None:
        ep.finger_samples = FingerSamples.draw(pad_normal_local=PAD_NORMAL_LOCAL)
    return ep.finger_samples


def squeeze_reach(ep: Episode) -> float:
    """How far past its contact each fingertip must reach in this cycle's grasp."""
    return ep.config.lateral_squeeze_reach if slides(ep) else SQUEEZE_REACH


def sampled_preshape(ep: Episode) -> bool:
    """Whether this cycle's lateral pre-shape took sampled contacts (``ep.preshape_hand_q`` is
    the posture that took them): each stays on its own face at its height, the reach tests start
    from that posture and the arm holds the pre-shape's palm pose."""
    return slides(ep) and ep.preshape_hand_q is not None


def idle_finger(ep: Episode) -> int | None:
    """The finger that takes no contact in this cycle's grasp (a three-contact lateral
    pre-shape's, :func:`controllers.lateral_grasp.three_contact_lateral_grasp`), or None."""
    return ep.preshape_contacts.idle if sampled_preshape(ep) else None


def block_centre(ep: Episode) -> NDArray[np.float64]:
    """The perceived block's centre of mass (world, m): its footprint's centroid, half its
    height below its top."""
    return np.array([*ep.target.position_xy, ep.target.top_z - 0.5 * ep.model.height])


def grasp_reserve(ep: Episode, grasp: SampledGrasp) -> float:
    """A sampled lateral grasp's friction reserve (N) by the 3-D model, squeezed as Grasp
    Object would squeeze it (:func:`controllers.lateral_squeeze.lateral_squeeze`); -inf where no
    forces hold the weight."""
    polygon = ep.target.polygon
    normals_xy = place_polygon(polygon.locate(grasp.theta).normal, (0.0, 0.0), ep.target.yaw)
    normals = np.column_stack([normals_xy, np.zeros(len(grasp.theta))])
    planar = planar_normal_forces(ep, grasp.theta)
    squeeze = lateral_squeeze(grasp.points, normals, planar, ep.expected_load, block_centre(ep))
    return -np.inf if squeeze.reserve is None else squeeze.reserve


def planar_normal_forces(ep: Episode, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """The normal forces (n,) of the S_G linear programme (Eq. 13) for contacts ``theta`` on the
    perceived polygon, in its unit-moment frame: the squeeze's shares (a lateral squeeze's
    prior)."""
    frames = ep.target.polygon.unit_moment().locate(theta)
    return grasp_score(frames.point, frames.normal).normal_forces


def block_site(ep: Episode) -> BlockSite:
    """The motion primitives' inputs for this cycle's block: the approach axis is the coarse
    reach's (straight down for a top grasp, along the arm's radius for a lateral one)."""
    return BlockSite(
        ep.world,
        ep.planning,
        ep.target,
        ep.world.block_body_id(ep.target_name),
        ep.coarse.goal.palm_rotation[:, 2],
        lateral=slides(ep),
        params=ep.config.motion,
    )


def reach_query(ep: Episode) -> ReachQuery:
    """The reach test's inputs for this cycle's block. In a lateral grasp the contacts slide on
    their faces and the hand IK starts from the episode's sampled finger postures (drawn when
    first needed: the reach test searches them for sliding contacts only), unless the pre-shape's
    contacts were sampled: those are taken at their heights; a top 3-D grasp's contacts are
    taken at their own heights."""
    lateral = slides(ep)
    sampled = sampled_preshape(ep)
    # a lateral hand's fingers slide to the heights they can take (a lateral 3-D grasp then
    # takes those heights), but keep the heights of sampled pre-shape contacts (each finger on
    # its own face, where its sampled posture took it); a top 3-D grasp's fingers go to its
    # contacts' heights
    if sampled:
        contacts = ep.preshape_contacts
        heights = contacts.points[contacts.pressing, 2].copy()
    else:
        heights = None if lateral else contact_heights(ep)
    return ReachQuery(
        ep.world,
        ep.planning,
        ep.prism,
        ep.target,
        slide=lateral and not sampled,
        samples=finger_samples(ep) if lateral else None,
        squeeze=squeeze_reach(ep),
        heights=heights,
        idle=idle_finger(ep),
    )


def reach_start(ep: Episode) -> NDArray[np.float64] | None:
    """Where a reach test of this cycle starts its hand IK: the world's configuration with the
    hand in the posture that took the sampled pre-shape's contacts (a lateral hand at the edge of
    its workspace: from the hand's present posture the IK stalls millimetres short), or None
    (the world's configuration)."""
    if not sampled_preshape(ep):
        return None
    qpos = ep.world.data.qpos.copy()
    qpos[robot.hand_qpos_addresses(ep.world.model)] = ep.preshape_hand_q
    return qpos


def contact_heights(ep: Episode) -> NDArray[np.float64] | None:
    """World z of the 3-D grasp's contacts (None for a planar grasp: the fingers' heights)."""
    syn = ep.synthesis
    if not isinstance(syn, GraspSynthesis3D):
        return None
    return ep.prism.centre_z + syn.heights


def plan_approach(
    ep: Episode, qpos: NDArray[np.float64], contacts: FingerContacts
) -> ApproachPlan | None:
    """:func:`controllers.motion.approach_plan` for this cycle's block and grasp."""
    return approach_plan(block_site(ep), qpos, contacts, squeeze_reach(ep))


def contact_points(ep: Episode, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """World points (n, 3) of contacts ``theta`` on the perceived polygon, at a 3-D grasp's
    contact heights, else at the top's height less 3 cm (for drawing)."""
    frames = ep.target.polygon.locate(theta)
    xy = place_polygon(frames.point, ep.target.position_xy, ep.target.yaw)
    z = contact_heights(ep)
    return np.column_stack([xy, np.full(len(xy), ep.target.top_z - 0.03) if z is None else z])


def side_arcs(ep: Episode) -> NDArray[np.float64]:
    """The stretches of the perceived block's outline this cycle's lateral hand can take
    (:func:`controllers.palm_candidates.lateral_arcs`; row 0 left of the approach axis, row 1
    right)."""
    return lateral_arcs(ep.target, robot_base_xy(ep.world), ep.config.palm_pose)


def arcs_of(arcs: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each contact's arc (n, 2): the one of ``arcs`` (:func:`side_arcs`) it lies on or is
    nearest to (by contact coordinate)."""
    two_pi = 2.0 * np.pi

    def distance(t: float, arc: NDArray[np.float64]) -> float:
        span = float(np.mod(arc[1] - arc[0], two_pi))
        rel = float(np.mod(t - arc[0], two_pi))
        return 0.0 if rel <= span else min(rel - span, two_pi - rel)

    return np.array([min(arcs, key=lambda arc: distance(float(t), arc)) for t in theta])


def contact_arcs(ep: Episode, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each lateral contact's arc (n, 2): the pre-shape contact's own face when they were sampled
    (:func:`controllers.palm_candidates.face_arcs`), else its side's (:func:`arcs_of` of
    :func:`side_arcs`)."""
    if sampled_preshape(ep):
        inset = ep.config.palm_pose.side_inset
        contacts = ep.preshape_contacts
        return face_arcs(ep.target.polygon, contacts.theta[contacts.pressing], inset)
    return arcs_of(side_arcs(ep), theta)


def lateral_preshape(ep: Episode, skip: int = 0) -> str | None:
    """The lateral pre-shape: the palm pose beside the block from which the hand best reaches
    its contacts (:func:`controllers.palm_pose.search_poses`), the hand then shaped outside them
    and the palm moved there along its approach axis (``skip``: the next pose). The contacts
    come from ``config.lateral_contacts``: "sampled-first" (default), the lowest-S_G contacts
    the hand's sampled finger postures take at a pose
    (:func:`controllers.lateral_grasp.sampled_lateral_grasp`, over
    :func:`controllers.palm_candidates.lateral_poses`' wider set), each kept on its own face
    afterwards (:func:`contact_arcs`), and where no pose has such a grasp the pinch pre-shape's
    (the surface points nearest its fingertips, kept a pad spacing apart on the side arcs);
    "sampled", the pinch's first and the sampled ones where no pose reaches those; "pinch", the
    pinch's only. The sampled grasps come in bands of S_G (:func:`_gated_preshapes`): the
    paper's 0.4 first, then up to the gate counted from the thumb's opposition
    (``config.lateral_gate_rule`` "opposition"). By the rule "paper", when none is reached and
    ``config.lateral_gate`` is above 0.4 (a study's), the sampled grasps up to that gate; then
    the pinch's pose of least reach load, taken all the same. The contacts, when the hand
    reaches them there, are kept (``ep.preshape_contacts``) for Fine Reach and the grasp
    controller. Returns what was done, for the log, or None when no pose is approached without
    collision."""
    ep.preshape_contacts = None
    ep.preshape_hand_q = None
    ep.preshape_rolls = None
    memo = PoseGrasps()  # each palm pose's sampled grasp, searched once a call
    if ep.config.lateral_contacts == "sampled-first":
        done = _gated_preshapes(ep, skip, memo)
        if done is not None:
            return done
    if ep.retry_floor is not None:
        return None  # only sampled grasps are rated by their reserve
    pinch = _pinch_search(ep, skip)
    reached = pinch.found and pinch.reach is not None and pinch.reach.reachable
    if not reached and ep.config.lateral_contacts == "sampled":
        done, _ = _sampled_preshape(ep, skip, (-np.inf, SUCCESS_THRESHOLD), memo)
        if done is not None:
            return done
    paper_rule = ep.config.lateral_gate_rule == "paper"
    if not reached and paper_rule and ep.config.lateral_gate > SUCCESS_THRESHOLD:
        # a study's wider gate (TaskConfig.lateral_gate): a grasp above Eq. 13's 0.4, only here
        done, _ = _sampled_preshape(ep, skip, (-np.inf, ep.config.lateral_gate), memo)
        if done is not None:
            return done
    if not pinch.found:
        return None
    approach(block_site(ep), pinch.approach)
    if reached:
        ep.preshape_contacts = pinch.contacts
    return f"pinch pre-shape, {pinch.label} (reach load {pinch.load:.2f})"


def _gated_preshapes(ep: Episode, skip: int, memo: PoseGrasps) -> str | None:
    """:func:`lateral_preshape`'s sampled pre-shapes, in order: four contacts within the
    paper's 0.4 (Eq. 13), three within it (``config.lateral_three_contacts``), then, by
    ``config.lateral_gate_rule`` "opposition", four and three above 0.4 up to the gate counted
    from the thumb's opposition (:meth:`fsm.config.TaskConfig.lateral_gate_for`). A regrasp
    (``skip``) passes over the poses the earlier bands took; each pose's grasp is searched once
    per ``memo``."""
    config = ep.config
    bands = [(False, (-np.inf, SUCCESS_THRESHOLD))]
    if config.lateral_three_contacts:
        bands.append((True, (-np.inf, SUCCESS_THRESHOLD)))
    if config.lateral_gate_rule == "opposition":
        bands.append((False, (SUCCESS_THRESHOLD, config.lateral_gate_for(4))))
        if config.lateral_three_contacts:
            bands.append((True, (SUCCESS_THRESHOLD, config.lateral_gate_for(3))))
    for three, band in bands:
        done, skipped = _sampled_preshape(ep, skip, band, memo, three)
        if done is not None:
            return done
        skip -= skipped
    return None


def _sampled_preshape(
    ep: Episode,
    skip: int,
    band: tuple[float, float],
    memo: PoseGrasps,
    three: bool = False,
) -> tuple[str | None, int]:
    """:func:`lateral_preshape` from sampled contacts of S_G above ``band[0]`` and at most
    ``band[1]`` (Eq. 13), with how many acceptable poses ``skip`` passed over; None when no
    pose has such a sampled grasp that the hand reaches and approaches without collision
    (after ``skip`` of them). The palm poses at the default wrist rolls are searched first;
    only where none is taken, again with the poses at ``lateral_more_rolls`` after them (the
    hand upside down or its finger row vertical), whose rolls Posture Control then keeps
    (``ep.preshape_rolls``). ``three``: grasps of three contacts, the thumb's and two fingers'
    (:func:`controllers.lateral_grasp.three_contact_lateral_grasp`)."""
    params = ep.config.palm_pose
    grasps: dict[int, SampledGrasp] = {}
    rolls_of: dict[int, tuple[float, ...]] = {}
    poses = _sampled_poses(ep, params.lateral_rolls, band, grasps, memo, three=three)
    found = _search_sampled(ep, poses, grasps, skip) if poses else None
    if (found is None or not found.found) and params.lateral_more_rolls:
        for roll in params.lateral_more_rolls:
            turned = (roll, roll + LATERAL_ROLL_STEP, roll - LATERAL_ROLL_STEP)
            # searched after every pose at the default rolls (a group of their own)
            for pose in _sampled_poses(ep, (roll,), band, grasps, memo, 1.0, three):
                rolls_of[id(pose)] = turned
                poses.append(pose)
        found = _search_sampled(ep, poses, grasps, skip) if poses else None
    if found is None or not found.found:
        return None, 0 if found is None else found.skipped
    approach(block_site(ep), found.approach)
    ep.preshape_contacts = found.contacts
    ep.preshape_hand_q = found.hand_q
    ep.preshape_rolls = rolls_of.get(id(poses[found.start]))
    return f"sampled pre-shape, {found.label} (reach load {found.load:.2f})", skip


def _sampled_poses(
    ep: Episode,
    rolls: tuple[float, ...],
    band: tuple[float, float],
    grasps: dict[int, SampledGrasp],
    memo: PoseGrasps,
    group_offset: float = 0.0,
    three: bool = False,
) -> list[PalmPose]:
    """The palm poses beside the block at wrist ``rolls`` whose sampled grasp
    (:func:`controllers.lateral_grasp.sampled_lateral_grasp`) scores above ``band[0]`` and at
    most ``band[1]``, the hand in the grasp's posture; each pose's grasp goes into ``grasps``
    (by the pose's id). ``three``: the three-contact grasps instead. The grasps at each pose
    are searched once per ``memo``."""
    if (rolls, three) not in memo.grasps:
        memo.grasps[rolls, three] = _pose_grasps(ep, rolls, three, memo.candidates)
    hand_adr = robot.hand_qpos_addresses(ep.world.model)
    # only a start that is already a grasp (Eq. 13), in this band
    kept = [
        (pose, grasp)
        for pose, grasp in memo.grasps[rolls, three]
        if grasp is not None and band[0] < grasp.s_g <= band[1]
    ]
    by_reserve = ep.config.lateral_reserve_order
    first = ep.config.lateral_reserve_first and not by_reserve
    reserves: dict[int, float] = {}  # each grasp's friction reserve, solved once
    if by_reserve or first or ep.retry_floor is not None:
        reserves = {id(grasp): grasp_reserve(ep, grasp) for _, grasp in kept}
    if ep.retry_floor is not None:
        kept = [(p, g) for p, g in kept if reserves[id(g)] > ep.retry_floor]
    if by_reserve:
        # the most friction to spare first, each pose a group of its own (search_poses takes
        # the groups in order)
        kept.sort(key=lambda pg: -reserves[id(pg[1])])
    poses: list[PalmPose] = []
    for rank, (pose, grasp) in enumerate(kept):
        qpos = pose.qpos.copy()
        qpos[hand_adr] = grasp.hand_q
        label = f"{pose.label}, {grasp.contacts_label()} S_G {grasp.s_g:.3f}"
        group = pose.group
        if by_reserve:
            label += f", reserve {reserves[id(grasp)]:.2f} N"
            group = rank / (len(kept) + 1)
        shaped = PalmPose(qpos, group + group_offset, label)
        grasps[id(shaped)] = grasp
        poses.append(shaped)
    if first:
        # the grasps the 3-D model says hold the weight first, each part in its order
        poses.sort(key=lambda p: reserves[id(grasps[id(p)])] < 0.0)
    return poses


def _pose_grasps(
    ep: Episode, rolls: tuple[float, ...], three: bool, cache: CandidateCache
) -> list[tuple[PalmPose, SampledGrasp | None]]:
    """Each palm pose beside the block at wrist ``rolls`` with its sampled grasp
    (:func:`controllers.lateral_grasp.sampled_lateral_grasp`, or
    :func:`~controllers.lateral_grasp.three_contact_lateral_grasp` when ``three``), None where
    the hand's samples make none; the fingers' candidates at each pose shared through ``cache``."""
    params = replace(ep.config.palm_pose, lateral_rolls=rolls)
    query = reach_query(ep)
    where = PoseSetting(ep.world, ep.planning, ep.target, ep.coarse.goal.palm_rotation)
    pose_xy = (np.asarray(ep.target.position_xy, dtype=float), float(ep.target.yaw))
    search = three_contact_lateral_grasp if three else sampled_lateral_grasp
    return [
        (
            pose,
            search(
                ep.planning,
                pose.qpos,
                query.samples,
                query.prism,
                ep.target.polygon,
                pose_xy,
                query.squeeze,
                cache=cache,
            ),
        )
        for pose in lateral_poses(where, params, side_arcs(ep), sampled=True)
    ]


def _search_sampled(
    ep: Episode, poses: list[PalmPose], grasps: dict[int, SampledGrasp], skip: int
) -> PalmPoseResult:
    """The first of ``poses`` (after ``skip``) from which the hand reaches its sampled grasp's
    contacts at their heights, that is approached without collision
    (:func:`controllers.palm_pose.search_poses`) and whose grasp can set the block down at the
    place point (:func:`fsm.handlers.set_down_pitch.set_down_gate`, until
    ``config.lateral_grasp_set_down_checks`` poses were passed over for it)."""
    approach_of = partial(plan_approach, ep)
    checks = ep.config.lateral_grasp_set_down_checks
    if checks and ep.place is not None:
        sets_down = partial(grasp_sets_down, ep, check_lift=False)
        approach_of = set_down_gate(approach_of, sets_down, checks)
    return search_poses(
        reach_query(ep),
        poses,
        lambda pose: grasps[id(pose)].theta,
        approach_of,
        tries=1,
        reachable_only=True,
        skip=skip,
        heights_of=lambda pose: grasps[id(pose)].points[:, 2],
        idle_of=lambda pose: grasps[id(pose)].idle,
    )


def _pinch_search(ep: Episode, skip: int) -> PalmPoseResult:
    """The pinch pre-shape's palm-pose search of :func:`lateral_preshape` (not carried out)."""
    base = robot_base_xy(ep.world)
    params = ep.config.palm_pose
    arcs = side_arcs(ep)

    def pinch_contacts(pose: PalmPose) -> NDArray[np.float64]:
        tips = fingertips_at(ep.planning, pose.qpos)
        theta = side_contacts(ep.target, base, tips, params.side_inset, arcs)
        # pads apart, each contact kept on its side's arc
        return keep_contacts(
            ep.target.polygon,
            theta,
            CONTACT_SEPARATION,
            robot.PAD_RADIUS,
            arcs_of(arcs, theta),
        )

    where = PoseSetting(ep.world, ep.planning, ep.target, ep.coarse.goal.palm_rotation)
    poses = lateral_poses(where, params, arcs)
    return search_poses(
        reach_query(ep),
        poses,
        pinch_contacts,
        lambda qpos, contacts: plan_approach(ep, qpos, contacts),
        tries=params.pose_tries,
        reachable_only=False,
        skip=skip,
    )
