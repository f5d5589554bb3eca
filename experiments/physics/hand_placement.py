"""Put the hand on synthesized contacts without the task cycle: a top grasp whose arm posture is
found by the task cycle's Posture Control, started from palm-down postures held over the block.

The physical grasp study (:mod:`experiments.physics.study`) tests many grasps of one block; it
needs each grasp placed quickly and the same way every time, not the task cycle's reach, so:
- **seeds**: the palm held :data:`PALM_GAPS` above the block's top, palm down (a top grasp),
  turned about the vertical to one of :data:`YAWS` equally spaced yaws; the arm's IK
  (:meth:`controllers.planning.cspace.CollisionChecker.solve_ik`) gives each posture once per block,
  the fingers pre-shaped with their tips on the block's faces at the task cycle's grasp depth
  (:func:`controllers.reach.fine.project_to_surface`, what Fine Reach does);
- **which seed, which finger on which contact**: every seed with every one of the 24 ways to
  give the four contacts to the four fingers, ranked first by whether each pad, at the seed's
  pre-shape, faces its contact's face within the reach test's :data:`MAX_PAD_ANGLE`, then by
  the task cycle's reach cost (total squared fingertip-to-contact distance, each contact at its
  fingertip's height). The task cycle's rule (the nearest assignment only, ranked by distance)
  gives a finger a face its pad turns away from on most evenly spread grasps (a square with one
  contact per face: docs/findings.md, "Finger assignment by pad facing"). The ranked pairs are
  then taken in turn from each kind of seed (palm gap and pre-shape depth,
  :func:`interleaved_starts`): the ranking alone puts one kind in every early place;
- **Posture Control** (the task cycle's IK seeding for a top grasp, one implementation:
  :func:`controllers.preshape.palm_search.search_seeds`): from each of the first :data:`SEEDS_TRIED`
  (seed, assignment) pairs so taken, arm and hand IK
  (:func:`controllers.posture.solver.solve_posture`, ``joints="arm+hand"``, collision avoidance with
  the fingers allowed to touch the block, fingertips :data:`SQUEEZE_REACH` inside each contact and
  pads facing it,
  :func:`controllers.hand.reachability.grip_targets`); a posture that tilts the palm more than
  :data:`MAX_PALM_TILT` from vertical is refused (the task cycle's limit for a top grasp); the
  contacts are then confirmed from that posture with the task cycle's reachability test
  (:func:`controllers.hand.reachability.reachable_contacts`: pad spacing, hand IK, pad angle, link
  penetration). The first confirmed posture places the hand; when none is, the grasp is
  unreachable with the last reason.
Nothing here moves the simulation; the study sets the arm and hand where this says.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.hand.finger_assignment import FingerContacts, contacts_at_tips, given_contacts
from controllers.hand.finger_geometry import PerceivedPrism, fingertips_at, pad_normals
from controllers.hand.reachability import MAX_PAD_ANGLE, HandReach, grip_targets
from controllers.planning.cspace import CollisionChecker
from controllers.posture.solver import solve_posture
from controllers.preshape.palm_candidates import DEFAULT_PALM_POSE, robot_base_xy
from controllers.preshape.palm_search import ReachQuery, SeedStart, search_seeds
from controllers.reach.coarse import PRESHAPE, ReachTarget
from controllers.reach.fine import GRASP_DEPTH, project_to_surface
from hand_sim import robot
from hand_sim.blocks import GEOM_SUFFIX
from hand_sim.world import World

#: Heights (m) of the palm face (the ``palm_center`` site) above the block's top in the seed
#: postures: contacts are taken 4 cm below the top (the task cycle's grasp depth).
PALM_GAPS = (0.005, 0.02)
#: Wrist yaws (equally spaced over a turn) the seed postures take over the block.
YAWS = 12
#: (seed posture, finger assignment) pairs Posture Control starts from per grasp, best first.
#: Chosen by its effect on placement: docs/findings.md, "Posture Control starts per grasp".
SEEDS_TRIED = 6
#: Largest tilt (rad) of the palm's approach axis from vertical (the task cycle's limit for a
#: top grasp, :attr:`controllers.preshape.palm_candidates.PalmPoseParams.max_palm_tilt_top`).
MAX_PALM_TILT = DEFAULT_PALM_POSE.max_palm_tilt_top
#: The palm's approach axis when it points straight down.
DOWN = np.array([0.0, 0.0, -1.0])
#: Arm IK seed (shoulder, elbow, wrist pitch, wrist roll) of a palm-down posture over the table;
#: the waist is turned towards the block.
ARM_SEED = (0.3, 1.5, 1.3, 0.0)
#: The 24 ways to give four contacts to four fingers: row k gives finger f contact ORDERS[k, f].
ORDERS = np.array(list(itertools.permutations(range(4))))


@dataclass(frozen=True, eq=False)
class HandPosture:
    """The arm holding the palm over the block at ``yaw``, the hand pre-shaped on its faces."""

    yaw: float  #: rad, palm yaw about the vertical
    qpos: NDArray[np.float64]  #: full world qpos (arm, hand; the rest as the world has it)
    tips: NDArray[np.float64]  #: (4, 3) fingertip positions there
    pads: NDArray[np.float64]  #: (4, 3) pad normals (out of the pad) there
    gap: float  #: m, the palm face's height above the block's top
    depth: float  #: m below the top, where the pre-shape put the fingertips


@dataclass(frozen=True, eq=False)
class Placement:
    """Where the hand takes a grasp: ``reachable`` with the configuration found (``qpos``: arm
    from Posture Control, hand from the reach test), the palm's yaw and tilt there, the seed it
    started from and the fingers' contacts; or not, with the reason."""

    reachable: bool
    reason: str
    qpos: NDArray[np.float64] | None = None
    yaw: float | None = None  #: rad, of the palm's x axis about the vertical
    tilt: float | None = None  #: rad, of the palm's approach axis from vertical
    seed: HandPosture | None = None
    contacts: FingerContacts | None = None
    reach: HandReach | None = None


def _palm_down(yaw: float) -> NDArray[np.float64]:
    """Palm rotation: z down, x turned by ``yaw`` about the vertical."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.diag([1.0, -1.0, -1.0])


def top_postures(
    world: World,
    target: ReachTarget,
    *,
    palm_gaps: tuple[float, ...] = PALM_GAPS,
    yaws: int = YAWS,
    depths: tuple[float, ...] = (GRASP_DEPTH,),
) -> list[HandPosture]:
    """The palm-down seed postures over ``target`` (those the arm's IK reaches), from the world's
    current state; each hand pre-shaped with its fingertips on the block's faces at each of
    ``depths`` (m below the top; default the task cycle's grasp depth)."""
    if yaws < 1:
        raise ValueError(f"yaws must be >= 1, got {yaws}")
    model = world.model
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    arm_adr, hand_adr = robot.arm_qpos_addresses(model), robot.hand_qpos_addresses(model)
    base = robot_base_xy(world)
    waist = float(np.arctan2(target.position_xy[1] - base[1], target.position_xy[0] - base[0]))
    data = mujoco.MjData(model)
    out = []
    for gap, k, depth in itertools.product(palm_gaps, range(yaws), depths):
        pos = np.array([*target.position_xy, target.top_z + gap])
        yaw = target.yaw + 2.0 * np.pi * k / yaws
        ik = checker.solve_ik(pos, _palm_down(yaw), [waist, *ARM_SEED])
        if not ik.found:
            continue
        qpos = world.data.qpos.copy()
        qpos[arm_adr] = ik.q
        qpos[hand_adr] = PRESHAPE
        # the preshape's tips, raised (or lowered) to the depth below the top
        at_depth = fingertips_at(model, qpos)
        at_depth[:, 2] = target.top_z - depth
        surface = project_to_surface(target, at_depth, table_z=world.scene.table.height)
        tips, centres = grip_targets(surface.points, surface.normals, 0.0)
        hand = solve_posture(
            world, tips, optimize=False, joints="hand", qpos=qpos, pad_centres=centres
        )
        qpos[hand_adr] = hand.hand_q
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        out.append(
            HandPosture(
                float(yaw), qpos, fingertips_at(model, qpos), pad_normals(model, data), gap, depth
            )
        )
    return out


def ranked_starts(
    target: ReachTarget,
    theta: ArrayLike,
    postures: list[HandPosture],
    table_z: float,
    heights: ArrayLike | None = None,
) -> list[tuple[HandPosture, FingerContacts]]:
    """Every (seed posture, contacts given to its fingers) pair, best first: the pairs whose
    every pad faces its contact's face within :data:`MAX_PAD_ANGLE` at the seed's pre-shape
    before the others, then by total squared fingertip-to-contact distance. Each contact is at
    the height of the fingertip it is given to (a planar grasp) or, with ``heights`` (n,),
    world z per contact, at its own height (a 3-D grasp)."""
    th = np.asarray(theta, dtype=float)
    keys, pairs = [], []
    for i, p in enumerate(postures):
        xy, nxy, z = contacts_at_tips(target, th, p.tips, table_z)
        # finger f's height in assignment k: its tip's, or the height of the contact it takes
        zk = (
            np.broadcast_to(z[None, :], (len(ORDERS), 4))
            if heights is None
            else np.asarray(heights, dtype=float)[ORDERS]
        )
        points = np.concatenate([xy[ORDERS], zk[:, :, None]], axis=2)
        distance = ((points - p.tips[None]) ** 2).sum(axis=(1, 2))
        # cosine between each pad normal and its contact's inward (horizontal) face normal
        cosine = -np.einsum("kfd,fd->kf", nxy[ORDERS], p.pads[:, :2])
        turned_away = (cosine < np.cos(MAX_PAD_ANGLE)).any(axis=1)
        for k in range(len(ORDERS)):
            keys.append((bool(turned_away[k]), float(distance[k])))
            pairs.append((i, k, xy, nxy, zk[k]))
    out = []
    for j in sorted(range(len(keys)), key=keys.__getitem__):
        i, k, xy, nxy, z = pairs[j]
        out.append((postures[i], given_contacts(th, xy, nxy, z, ORDERS[k])))
    return out


def interleaved_starts(
    pairs: list[tuple[HandPosture, FingerContacts]], count: int
) -> list[tuple[HandPosture, FingerContacts]]:
    """The first ``count`` of ``pairs`` (ranked, :func:`ranked_starts`) taken in turn from each
    kind of seed posture (palm gap and pre-shape depth), each kind's best first, the kinds in
    the order of their best start: every kind of start is tried before any is tried twice. The
    ranking alone gives one kind every early place (its fingertips sit nearest the contacts),
    and the others, the starts that differ, are never tried."""
    kinds: dict[tuple[float, float], list[tuple[HandPosture, FingerContacts]]] = {}
    for pair in pairs:
        kinds.setdefault((pair[0].gap, pair[0].depth), []).append(pair)
    queues = list(kinds.values())
    out: list[tuple[HandPosture, FingerContacts]] = []
    for turn in itertools.count():
        if len(out) == count or not any(turn < len(q) for q in queues):
            break
        out.extend(q[turn] for q in queues if turn < len(q))
    return out[:count]


def place_hand(
    world: World,
    prism: PerceivedPrism,
    target: ReachTarget,
    theta: ArrayLike,
    postures: list[HandPosture],
    *,
    seeds: int = SEEDS_TRIED,
    checker: CollisionChecker | None = None,
    heights: ArrayLike | None = None,
) -> Placement:
    """Posture Control from the first ``seeds`` of :func:`ranked_starts` for contacts ``theta``
    (contact coordinates on ``target``'s polygon), taken in turn from each kind of seed
    (:func:`interleaved_starts`), with :func:`place_from`; see the module docstring.
    ``checker``: the world's collision checker, for the palm's pose (default: built here).
    ``heights``: world z of each contact (a 3-D grasp; default: each at the height of its
    finger's tip, a planar grasp)."""
    if not postures:
        return Placement(False, "the arm reaches no palm-down posture over the block")
    th = np.asarray(theta, dtype=float)
    pairs = interleaved_starts(ranked_starts(target, th, postures, prism.bottom, heights), seeds)
    return place_from(world, prism, target, th, pairs, checker=checker)


def place_from(
    world: World,
    prism: PerceivedPrism,
    target: ReachTarget,
    theta: ArrayLike,
    pairs: list[tuple[HandPosture, FingerContacts]],
    *,
    checker: CollisionChecker | None = None,
) -> Placement:
    """Posture Control for contacts ``theta`` from each of ``pairs`` (seed posture, contacts
    given to its fingers) in order: the task cycle's IK seeding
    (:func:`controllers.preshape.palm_search.search_seeds`), the palm's tilt measured from vertical;
    the
    first confirmed posture places the hand."""
    th = np.asarray(theta, dtype=float)
    checker = CollisionChecker(world) if checker is None else checker
    found = search_seeds(
        ReachQuery(world, None, prism, target),
        th,
        (SeedStart(f"yaw {np.degrees(p.yaw):.0f} deg", p.qpos, given) for p, given in pairs),
        checker=checker,
        axis=DOWN,
        max_tilt=MAX_PALM_TILT,
        touchable=world.scene.target + GEOM_SUFFIX,
        confirm_tries=1,
        check_spacing=True,
        axis_name="vertical",
    )
    if not found.found:
        return Placement(False, found.reason)
    R = found.palm_rotation
    yaw = float(np.arctan2(R[1, 0], R[0, 0]))
    seed = pairs[found.start][0]
    return Placement(True, "", found.qpos, yaw, found.tilt, seed, found.contacts, found.reach)
