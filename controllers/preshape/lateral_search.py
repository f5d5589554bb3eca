"""The lateral pre-shape search (section 5.2, Coarse Reach and a lateral regrasp): the palm pose
beside the block from which the hand reaches a sampled grasp's contacts (or the pinch
pre-shape's), approached without collision and, as a set-down gate asks, able to set the block
down at the place point; the hand is then shaped outside the contacts and the palm moved there
along its approach axis. Its inputs are explicit (:class:`LateralSearchInputs`,
:class:`LateralSearchSettings`); its result is a :class:`LateralPreshape`."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import partial
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.score import SUCCESS_THRESHOLD
from controllers.grasp.synthesis import keep_contacts
from controllers.hand.finger_assignment import FingerContacts
from controllers.hand.finger_geometry import fingertips_at
from controllers.hand.friction_reserve import friction_reserve
from controllers.hand.reachability import CONTACT_SEPARATION
from controllers.preshape.lateral_grasp import (
    CandidateCache,
    SampledGrasp,
    sampled_lateral_grasp,
    three_contact_lateral_grasp,
)
from controllers.preshape.moves import ApproachPlan, BlockSite, approach, approach_plan
from controllers.preshape.palm_candidates import (
    LATERAL_ROLL_STEP,
    PalmPose,
    PalmPoseParams,
    PoseSetting,
    approach_origin,
    lateral_arcs,
    lateral_poses,
    robot_base_xy,
    side_contacts,
)
from controllers.preshape.palm_search import PalmPoseResult, ReachQuery, search_poses
from controllers.preshape.set_down_check import SetDownGate, SetDownQuery, grasp_sets_down
from hand_sim import robot


@dataclass(frozen=True)
class LateralSearchSettings:
    """How the search takes its contacts (the task cycle's ``TaskConfig.lateral_*`` fields).
    ``contacts``: "sampled-first", the lowest-S_G contacts the hand's sampled finger postures
    take at a pose, the pinch pre-shape's only where no pose has such a grasp; "sampled", the
    pinch's first and the sampled ones where no pose reaches the pinch's; "pinch", the pinch's
    only. ``gate``, ``gate_rule`` and the gates of a grasp of four and of three
    contacts (``gate_four``, ``gate_three``): the S_G (Eq. 13) a lateral grasp must reach.
    ``three_contacts``: grasps of the thumb against two fingers where four cannot pass.
    ``reserve_*``: how the grasps' friction reserve by the 3-D model orders the search.
    ``set_down_checks``: the grasps a set-down gate passes over (0: no gate)."""

    contacts: str
    gate: float
    gate_rule: str
    gate_four: float
    gate_three: float
    three_contacts: bool
    reserve_before_bands: bool
    reserve_margin: float
    reserve_first: bool
    set_down_checks: int
    palm_pose: PalmPoseParams


@dataclass(frozen=True, eq=False)
class LateralSearchInputs:
    """What the search works on: the block's site (world, planning model, perceived block, the
    approach axis), the coarse reach's palm rotation, the reach test's inputs (sliding contacts
    from sampled finger postures), the perceived block's weight (N) and centre of mass (world)
    for the grasps' friction reserve, the reserve a grasp must keep above (after a grasp that
    slipped at the lift; None: any), and the set-down check's inputs (None without a place
    point)."""

    site: BlockSite
    palm_rotation: NDArray[np.float64]
    query: ReachQuery
    load: float
    centre: NDArray[np.float64]
    retry_floor: float | None = None
    set_down: SetDownQuery | None = None

    def plan_approach(
        self, qpos: NDArray[np.float64], contacts: FingerContacts
    ) -> ApproachPlan | None:
        """:func:`controllers.preshape.moves.approach_plan` for this block and grasp."""
        return approach_plan(self.site, qpos, contacts, self.query.squeeze)

    def approach_from(self) -> NDArray[np.float64]:
        """Where the lateral approach axis comes from in the table plane
        (:func:`controllers.preshape.palm_candidates.approach_origin`)."""
        site = self.site
        return approach_origin(robot_base_xy(site.world), site.target, self.palm_rotation)

    def side_arcs(self, params: PalmPoseParams) -> NDArray[np.float64]:
        """The stretches of the perceived block's outline the lateral hand can take
        (:func:`controllers.preshape.palm_candidates.lateral_arcs`; row 0 left of the approach
        axis, row 1 right)."""
        return lateral_arcs(self.site.target, self.approach_from(), params)

    def pose_setting(self) -> PoseSetting:
        """The palm poses' setting: the world, the planning model, the block, the palm
        rotation."""
        site = self.site
        return PoseSetting(site.world, site.planning, site.target, self.palm_rotation)


@dataclass(frozen=True, eq=False)
class LateralPreshape:
    """The search's outcome: what was done, for the log (None when no pose is approached
    without collision, or a strict set-down gate was spent); the contacts the hand reached at
    the palm pose taken (Fine Reach's targets and the grasp controller's start; None without
    one); the hand posture that took sampled contacts (None: the pinch's); the wrist rolls
    Posture Control keeps after a pose at ``PalmPoseParams.lateral_more_rolls`` (None: its
    own)."""

    label: str | None = None
    contacts: FingerContacts | None = None
    hand_q: NDArray[np.float64] | None = None
    rolls: tuple[float, ...] | None = None


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


def arcs_of(arcs: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each contact's arc (n, 2): the one of ``arcs`` (the side arcs) it lies on or is nearest
    to (by contact coordinate)."""
    two_pi = 2.0 * np.pi

    def distance(t: float, arc: NDArray[np.float64]) -> float:
        span = float(np.mod(arc[1] - arc[0], two_pi))
        rel = float(np.mod(t - arc[0], two_pi))
        return 0.0 if rel <= span else min(rel - span, two_pi - rel)

    return np.array([min(arcs, key=lambda arc: distance(float(t), arc)) for t in theta])


def lateral_preshape(
    inputs: LateralSearchInputs,
    settings: LateralSearchSettings,
    skip: int = 0,
    gate: SetDownGate | None = None,
) -> LateralPreshape:
    """The lateral pre-shape: the palm pose beside the block from which the hand best reaches
    its contacts (:func:`controllers.preshape.palm_search.search_poses`), the hand then shaped
    outside them and the palm moved there along its approach axis (``skip``: the next pose). The
    contacts come from ``settings.contacts``: "sampled-first", the lowest-S_G contacts the
    hand's sampled finger postures take at a pose
    (:func:`controllers.preshape.lateral_grasp.sampled_lateral_grasp`, over
    :func:`controllers.preshape.palm_candidates.lateral_poses`' wider set), each kept on its own
    face afterwards, and where no pose has such a grasp the pinch pre-shape's (the surface
    points nearest its fingertips, kept a pad spacing apart on the side arcs); "sampled", the
    pinch's first and the sampled ones where no pose reaches those; "pinch", the pinch's only.
    The sampled grasps come in bands of S_G (:func:`_gated_preshapes`): the paper's 0.4 first,
    then up to the gate counted from the thumb's opposition (gate rule "opposition"). By the
    rule "paper", when none is reached and the gate is above 0.4 (a study's), the sampled
    grasps up to that gate; then the pinch's pose of least reach load, taken all the same. The
    contacts, when the hand reaches them there, are kept for Fine Reach and the grasp
    controller. The label is None when no pose is approached without collision, or when a
    strict set-down ``gate`` (default: one of ``settings.set_down_checks``, not strict) was
    spent."""
    checks = settings.set_down_checks
    if gate is None and checks and inputs.set_down is not None:
        gate = SetDownGate(checks)
    memo = PoseGrasps(gate=gate)  # each palm pose's sampled grasp, searched once a call
    if settings.contacts == "sampled-first":
        done = _gated_preshapes(inputs, settings, skip, memo)
        if done.label is not None or (gate is not None and gate.strict and gate.spent):
            return done
    if inputs.retry_floor is not None:
        return LateralPreshape()  # only sampled grasps are rated by their reserve
    pinch = _pinch_search(inputs, settings.palm_pose, skip)
    reached = pinch.found and pinch.reach is not None and pinch.reach.reachable
    if not reached and settings.contacts == "sampled":
        done, _ = _sampled_preshape(inputs, settings, skip, (-np.inf, SUCCESS_THRESHOLD), memo)
        if done.label is not None:
            return done
    paper_rule = settings.gate_rule == "paper"
    if not reached and paper_rule and settings.gate > SUCCESS_THRESHOLD:
        # a study's wider gate: a grasp above Eq. 13's 0.4, only here
        done, _ = _sampled_preshape(inputs, settings, skip, (-np.inf, settings.gate), memo)
        if done.label is not None:
            return done
    if not pinch.found:
        return LateralPreshape()
    approach(inputs.site, pinch.approach)
    return LateralPreshape(
        f"pinch pre-shape, {pinch.label} (reach load {pinch.load:.2f})",
        pinch.contacts if reached else None,
    )


def _gated_preshapes(
    inputs: LateralSearchInputs, settings: LateralSearchSettings, skip: int, memo: PoseGrasps
) -> LateralPreshape:
    """:func:`lateral_preshape`'s sampled pre-shapes, in order: four contacts within the
    paper's 0.4 (Eq. 13), three within it (``settings.three_contacts``), then, by the gate rule
    "opposition", four and three above 0.4 up to the gate counted from the thumb's opposition
    (``settings.gate_four``, ``settings.gate_three``). A regrasp (``skip``) passes over the
    poses the earlier bands took; each pose's grasp is searched once per ``memo``."""
    bands = [(False, (-np.inf, SUCCESS_THRESHOLD))]
    if settings.three_contacts:
        bands.append((True, (-np.inf, SUCCESS_THRESHOLD)))
    if settings.gate_rule == "opposition":
        bands.append((False, (SUCCESS_THRESHOLD, settings.gate_four)))
        if settings.three_contacts:
            bands.append((True, (SUCCESS_THRESHOLD, settings.gate_three)))
    for tier in _reserve_tiers(settings):
        memo.reserve_range = tier
        for three, band in bands:
            done, skipped = _sampled_preshape(inputs, settings, skip, band, memo, three)
            if done.label is not None:
                return done
            skip -= skipped
    return LateralPreshape()


def _reserve_tiers(settings: LateralSearchSettings) -> list[tuple[float, float] | None]:
    """The search passes of :func:`_gated_preshapes` by the grasps' friction reserve by the 3-D
    model (N, [low, high)): with ``settings.reserve_before_bands``, first the grasps that
    keep ``settings.reserve_margin`` or more, then those that keep less but some, then the
    rest, each pass through every band; without it one pass takes them all."""
    if not settings.reserve_before_bands:
        return [None]
    margin = settings.reserve_margin
    edges = [np.inf, margin, 0.0, -np.inf] if margin > 0.0 else [np.inf, 0.0, -np.inf]
    return [(low, high) for high, low in pairwise(edges)]


def _sampled_preshape(
    inputs: LateralSearchInputs,
    settings: LateralSearchSettings,
    skip: int,
    band: tuple[float, float],
    memo: PoseGrasps,
    three: bool = False,
) -> tuple[LateralPreshape, int]:
    """:func:`lateral_preshape` from sampled contacts of S_G above ``band[0]`` and at most
    ``band[1]`` (Eq. 13), with how many acceptable poses ``skip`` passed over; no label when no
    pose has such a sampled grasp that the hand reaches and approaches without collision
    (after ``skip`` of them). The palm poses at the default wrist rolls are searched first;
    only where none is taken, again with the poses at ``lateral_more_rolls`` after them (the
    hand upside down or its finger row vertical), whose rolls Posture Control then keeps.
    ``three``: grasps of three contacts, the thumb's and two fingers'
    (:func:`controllers.preshape.lateral_grasp.three_contact_lateral_grasp`)."""
    params = settings.palm_pose
    grasps: dict[int, SampledGrasp] = {}
    rolls_of: dict[int, tuple[float, ...]] = {}
    poses = _sampled_poses(inputs, settings, params.lateral_rolls, band, grasps, memo, three=three)
    found = _search_sampled(inputs, poses, grasps, skip, memo.gate) if poses else None
    if (found is None or not found.found) and params.lateral_more_rolls:
        for roll in params.lateral_more_rolls:
            turned = (roll, roll + LATERAL_ROLL_STEP, roll - LATERAL_ROLL_STEP)
            # searched after every pose at the default rolls (a group of their own)
            for pose in _sampled_poses(inputs, settings, (roll,), band, grasps, memo, 1.0, three):
                rolls_of[id(pose)] = turned
                poses.append(pose)
        found = _search_sampled(inputs, poses, grasps, skip, memo.gate) if poses else None
    if found is None or not found.found:
        return LateralPreshape(), 0 if found is None else found.skipped
    approach(inputs.site, found.approach)
    label = f"sampled pre-shape, {found.label} (reach load {found.load:.2f})"
    return LateralPreshape(
        label, found.contacts, found.hand_q, rolls_of.get(id(poses[found.start]))
    ), skip


def _sampled_poses(
    inputs: LateralSearchInputs,
    settings: LateralSearchSettings,
    rolls: tuple[float, ...],
    band: tuple[float, float],
    grasps: dict[int, SampledGrasp],
    memo: PoseGrasps,
    group_offset: float = 0.0,
    three: bool = False,
) -> list[PalmPose]:
    """The palm poses beside the block at wrist ``rolls`` whose sampled grasp
    (:func:`controllers.preshape.lateral_grasp.sampled_lateral_grasp`) scores above ``band[0]``
    and at most ``band[1]``, the hand in the grasp's posture; each pose's grasp goes into
    ``grasps`` (by the pose's id). ``three``: the three-contact grasps instead. The grasps at
    each pose are searched once per ``memo``."""
    if (rolls, three) not in memo.grasps:
        memo.grasps[rolls, three] = _pose_grasps(inputs, settings, rolls, three, memo.candidates)
    hand_adr = robot.hand_qpos_addresses(inputs.site.world.model)
    # only a start that is already a grasp (Eq. 13), in this band
    kept = [
        (pose, grasp)
        for pose, grasp in memo.grasps[rolls, three]
        if grasp is not None and band[0] < grasp.s_g <= band[1]
    ]
    first = settings.reserve_first
    reserves = memo.reserves
    retry_floor = inputs.retry_floor
    if first or retry_floor is not None or memo.reserve_range is not None:
        for _, grasp in kept:
            if id(grasp) not in reserves:
                reserves[id(grasp)] = _grasp_reserve(inputs, grasp)
    if memo.reserve_range is not None:
        low, high = memo.reserve_range
        kept = [(p, g) for p, g in kept if low <= reserves[id(g)] < high]
    if retry_floor is not None:
        kept = [(p, g) for p, g in kept if reserves[id(g)] > retry_floor]
    poses: list[PalmPose] = []
    for pose, grasp in kept:
        qpos = pose.qpos.copy()
        qpos[hand_adr] = grasp.hand_q
        label = f"{pose.label}, {grasp.contacts_label()} S_G {grasp.s_g:.3f}"
        shaped = PalmPose(qpos, pose.group + group_offset, label)
        grasps[id(shaped)] = grasp
        poses.append(shaped)
    if first:
        # the grasps the 3-D model says hold the weight first, each part in its order
        poses.sort(key=lambda p: reserves[id(grasps[id(p)])] < 0.0)
    return poses


def _grasp_reserve(inputs: LateralSearchInputs, grasp: SampledGrasp) -> float:
    """A sampled grasp's friction reserve (N) by the 3-D model, squeezed as Grasp Object would
    squeeze it (:func:`controllers.hand.friction_reserve.friction_reserve`); -inf where no
    forces hold the weight."""
    target = inputs.site.target
    return friction_reserve(target, grasp.theta, grasp.points, inputs.load, inputs.centre)


def _pose_grasps(
    inputs: LateralSearchInputs,
    settings: LateralSearchSettings,
    rolls: tuple[float, ...],
    three: bool,
    cache: CandidateCache,
) -> list[tuple[PalmPose, SampledGrasp | None]]:
    """Each palm pose beside the block at wrist ``rolls`` with its sampled grasp
    (:func:`controllers.preshape.lateral_grasp.sampled_lateral_grasp`, or
    :func:`~controllers.preshape.lateral_grasp.three_contact_lateral_grasp` when ``three``),
    None where the hand's samples make none; the fingers' candidates at each pose shared
    through ``cache``."""
    params = replace(settings.palm_pose, lateral_rolls=rolls)
    query = inputs.query
    site = inputs.site
    target = site.target
    pose_xy = (np.asarray(target.position_xy, dtype=float), float(target.yaw))
    search = three_contact_lateral_grasp if three else sampled_lateral_grasp
    return [
        (
            pose,
            search(
                site.planning,
                pose.qpos,
                query.samples,
                query.prism,
                target.polygon,
                pose_xy,
                query.squeeze,
                cache=cache,
            ),
        )
        for pose in lateral_poses(
            inputs.pose_setting(), params, inputs.side_arcs(settings.palm_pose), sampled=True
        )
    ]


def _search_sampled(
    inputs: LateralSearchInputs,
    poses: list[PalmPose],
    grasps: dict[int, SampledGrasp],
    skip: int,
    gate: SetDownGate | None,
) -> PalmPoseResult:
    """The first of ``poses`` (after ``skip``) from which the hand reaches its sampled grasp's
    contacts at their heights, that is approached without collision
    (:func:`controllers.preshape.palm_search.search_poses`) and whose grasp can set the block
    down at the place point, as the set-down ``gate`` asks (None: not asked)."""
    approach_of = inputs.plan_approach
    if gate is not None:
        sets_down = partial(grasp_sets_down, inputs.set_down, check_lift=False)
        approach_of = gate.wrap(approach_of, sets_down)
    return search_poses(
        inputs.query,
        poses,
        lambda pose: grasps[id(pose)].theta,
        approach_of,
        tries=1,
        reachable_only=True,
        skip=skip,
        heights_of=lambda pose: grasps[id(pose)].points[:, 2],
        idle_of=lambda pose: grasps[id(pose)].idle,
    )


def _pinch_search(inputs: LateralSearchInputs, params: PalmPoseParams, skip: int) -> PalmPoseResult:
    """The pinch pre-shape's palm-pose search of :func:`lateral_preshape` (not carried out)."""
    base = inputs.approach_from()
    arcs = inputs.side_arcs(params)
    site = inputs.site

    def pinch_contacts(pose: PalmPose) -> NDArray[np.float64]:
        tips = fingertips_at(site.planning, pose.qpos)
        theta = side_contacts(site.target, base, tips, params.side_inset, arcs)
        # pads apart, each contact kept on its side's arc
        return keep_contacts(
            site.target.polygon,
            theta,
            CONTACT_SEPARATION,
            robot.PAD_RADIUS,
            arcs_of(arcs, theta),
        )

    poses = lateral_poses(inputs.pose_setting(), params, arcs)
    return search_poses(
        inputs.query,
        poses,
        pinch_contacts,
        inputs.plan_approach,
        tries=params.pose_tries,
        reachable_only=False,
        skip=skip,
    )
