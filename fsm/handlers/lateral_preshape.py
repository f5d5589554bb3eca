"""The lateral pre-shape (Coarse Reach, and a lateral regrasp): the palm pose beside the block
from which the hand reaches a sampled grasp's contacts (or the pinch pre-shape's), approached
without collision and, as a set-down gate asks, able to set the block down at the place point."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import partial
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.score import SUCCESS_THRESHOLD
from controllers.grasp.synthesis import keep_contacts
from controllers.hand.finger_geometry import fingertips_at
from controllers.hand.reachability import CONTACT_SEPARATION
from controllers.preshape.lateral_grasp import (
    CandidateCache,
    SampledGrasp,
    sampled_lateral_grasp,
    three_contact_lateral_grasp,
)
from controllers.preshape.moves import approach
from controllers.preshape.palm_candidates import (
    LATERAL_ROLL_STEP,
    PalmPose,
    PoseSetting,
    lateral_poses,
    side_contacts,
)
from controllers.preshape.palm_search import PalmPoseResult, search_poses
from fsm.config import TaskConfig
from fsm.context import Episode
from fsm.handlers.common import (
    approach_from,
    arcs_of,
    block_site,
    grasp_reserve,
    plan_approach,
    reach_query,
    side_arcs,
)
from fsm.handlers.set_down_pitch import SetDownGate, grasp_sets_down
from hand_sim import robot


@dataclass
class PoseGrasps:
    """One pre-shape search's palm poses beside the block, each with its sampled grasp (None
    where the samples make none), by the wrist rolls searched and whether the grasps are of
    three contacts; the fingers' candidate contacts at each pose, which both share; and the
    search's set-down gate, None without one."""

    grasps: dict[tuple[tuple[float, ...], bool], list[tuple[PalmPose, SampledGrasp | None]]] = (
        field(default_factory=dict)
    )
    candidates: CandidateCache = field(default_factory=dict)
    gate: SetDownGate | None = None
    #: each grasp's friction reserve by the 3-D model (N, by the grasp's id), solved once
    reserves: dict[int, float] = field(default_factory=dict)
    #: the grasps a search pass takes: those whose reserve (N) lies in [low, high), or all
    #: (None)
    reserve_range: tuple[float, float] | None = None


def lateral_preshape(ep: Episode, skip: int = 0, gate: SetDownGate | None = None) -> str | None:
    """The lateral pre-shape: the palm pose beside the block from which the hand best reaches
    its contacts (:func:`controllers.preshape.palm_search.search_poses`), the hand then shaped
    outside them and the palm moved there along its approach axis (``skip``: the next pose). The
    contacts come from ``config.lateral_contacts``: "sampled-first" (default), the lowest-S_G
    contacts the hand's sampled finger postures take at a pose
    (:func:`controllers.preshape.lateral_grasp.sampled_lateral_grasp`, over
    :func:`controllers.preshape.palm_candidates.lateral_poses`' wider set), each kept on its own
    face afterwards (:func:`contact_arcs`), and where no pose has such a grasp the pinch pre-shape's
    (the surface points nearest its fingertips, kept a pad spacing apart on the side arcs);
    "sampled", the pinch's first and the sampled ones where no pose reaches those; "pinch", the
    pinch's only. The sampled grasps come in bands of S_G (:func:`_gated_preshapes`): the
    paper's 0.4 first, then up to the gate counted from the thumb's opposition
    (``config.lateral_gate_rule`` "opposition"). By the rule "paper", when none is reached and
    ``config.lateral_gate`` is above 0.4 (a study's), the sampled grasps up to that gate; then
    the pinch's pose of least reach load, taken all the same. The contacts, when the hand
    reaches them there, are kept (``ep.preshape_contacts``) for Fine Reach and the grasp
    controller. Returns what was done, for the log, or None when no pose is approached without
    collision, or when a strict set-down ``gate`` (default: one of
    ``config.lateral_grasp_set_down_checks``, not strict) was spent."""
    ep.preshape_contacts = None
    ep.preshape_hand_q = None
    ep.preshape_rolls = None
    checks = ep.config.lateral_grasp_set_down_checks
    if gate is None and checks and ep.place is not None:
        gate = SetDownGate(checks)
    memo = PoseGrasps(gate=gate)  # each palm pose's sampled grasp, searched once a call
    if ep.config.lateral_contacts == "sampled-first":
        done = _gated_preshapes(ep, skip, memo)
        if done is not None or (gate is not None and gate.strict and gate.spent):
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
    for tier in _reserve_tiers(config):
        memo.reserve_range = tier
        for three, band in bands:
            done, skipped = _sampled_preshape(ep, skip, band, memo, three)
            if done is not None:
                return done
            skip -= skipped
    return None


def _reserve_tiers(config: TaskConfig) -> list[tuple[float, float] | None]:
    """The search passes of :func:`_gated_preshapes` by the grasps' friction reserve by the 3-D
    model (N, [low, high)): with ``config.lateral_reserve_before_bands``, first the grasps that
    keep ``config.lateral_reserve_margin`` or more, then those that keep less but some, then
    the rest, each pass through every band; without it one pass takes them all."""
    if not config.lateral_reserve_before_bands:
        return [None]
    margin = config.lateral_reserve_margin
    edges = [np.inf, margin, 0.0, -np.inf] if margin > 0.0 else [np.inf, 0.0, -np.inf]
    return [(low, high) for high, low in pairwise(edges)]


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
    (:func:`controllers.preshape.lateral_grasp.three_contact_lateral_grasp`)."""
    params = ep.config.palm_pose
    grasps: dict[int, SampledGrasp] = {}
    rolls_of: dict[int, tuple[float, ...]] = {}
    poses = _sampled_poses(ep, params.lateral_rolls, band, grasps, memo, three=three)
    found = _search_sampled(ep, poses, grasps, skip, memo.gate) if poses else None
    if (found is None or not found.found) and params.lateral_more_rolls:
        for roll in params.lateral_more_rolls:
            turned = (roll, roll + LATERAL_ROLL_STEP, roll - LATERAL_ROLL_STEP)
            # searched after every pose at the default rolls (a group of their own)
            for pose in _sampled_poses(ep, (roll,), band, grasps, memo, 1.0, three):
                rolls_of[id(pose)] = turned
                poses.append(pose)
        found = _search_sampled(ep, poses, grasps, skip, memo.gate) if poses else None
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
    (:func:`controllers.preshape.lateral_grasp.sampled_lateral_grasp`) scores above ``band[0]`` and
    at most ``band[1]``, the hand in the grasp's posture; each pose's grasp goes into ``grasps``
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
    reserves = memo.reserves
    if by_reserve or first or ep.retry_floor is not None or memo.reserve_range is not None:
        for _, grasp in kept:
            if id(grasp) not in reserves:
                reserves[id(grasp)] = grasp_reserve(ep, grasp)
    if memo.reserve_range is not None:
        low, high = memo.reserve_range
        kept = [(p, g) for p, g in kept if low <= reserves[id(g)] < high]
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
    (:func:`controllers.preshape.lateral_grasp.sampled_lateral_grasp`, or
    :func:`~controllers.preshape.lateral_grasp.three_contact_lateral_grasp` when ``three``), None
    where the hand's samples make none; the fingers' candidates at each pose shared through
    ``cache``."""
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
    ep: Episode,
    poses: list[PalmPose],
    grasps: dict[int, SampledGrasp],
    skip: int,
    gate: SetDownGate | None,
) -> PalmPoseResult:
    """The first of ``poses`` (after ``skip``) from which the hand reaches its sampled grasp's
    contacts at their heights, that is approached without collision
    (:func:`controllers.preshape.palm_search.search_poses`) and whose grasp can set the block down at the
    place point, as the set-down ``gate`` asks (None: not asked)."""
    approach_of = partial(plan_approach, ep)
    if gate is not None:
        approach_of = gate.wrap(approach_of, partial(grasp_sets_down, ep, check_lift=False))
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
    base = approach_from(ep)
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
