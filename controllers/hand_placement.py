"""Put the hand on synthesized contacts without the task cycle: the arm held over the block, palm
down, at one of a few wrist yaws, and the fingers on the contacts by the hand's IK.

The physical grasp study (:mod:`controllers.physics_study`) tests many grasps of one block; it
needs each grasp placed quickly and the same way every time, not the task cycle's reach, so:
- the palm is held :data:`PALM_GAPS` above the block's top, palm down (a top grasp), turned about
  the vertical to one of :data:`YAWS` equally spaced yaws; the arm's IK
  (:meth:`controllers.cspace.CollisionChecker.solve_ik`) gives each posture once per block;
- at each, the fingers are pre-shaped with their tips on the block's faces at the task cycle's
  grasp depth (:func:`controllers.fine_reach.project_to_surface`, what Fine Reach does), so the
  contacts are taken at that height;
- for a grasp, the postures are ranked by how far the fingertips are from the contacts under the
  task cycle's finger-to-contact rule (:func:`controllers.hand_reach.finger_contacts`), and the
  first :data:`POSTURES_TRIED` are checked with the task cycle's reachability test
  (:func:`controllers.hand_reach.reachable_contacts`: pad spacing, hand IK, pad angle, link
  penetration), each finger's IK starting from the sampled finger posture that takes its
  contact best (:class:`controllers.finger_samples.FingerSamples`, as the task cycle's palm-pose
  search does: the local IK from the pre-shape alone turns most pads onto their sides). The
  first reachable one places the hand; when none is, the grasp is unreachable with the nearest
  posture's reason.
Nothing here moves the simulation; the study sets the arm and hand where this says.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.cspace import CollisionChecker
from controllers.fine_reach import GRASP_DEPTH, project_to_surface
from controllers.finger_samples import FingerSamples
from controllers.hand_reach import (
    PAD_NORMAL_LOCAL,
    FingerContacts,
    HandReach,
    PerceivedPrism,
    finger_contacts,
    fingertips_at,
    grip_targets,
    reachable_contacts,
)
from controllers.posture import HandIndices, solve_posture
from controllers.reach import PRESHAPE, ReachTarget
from hand_sim import robot
from hand_sim.world import World

#: Heights (m) of the palm face (the ``palm_center`` site) above the block's top: contacts are
#: taken 4 cm below the top (the task cycle's grasp depth). Chosen by looking at the quick run
#: (trapezoid, irregular hexagon, 24 grasps): 0 of 24 placed with 5 mm alone, 4 with 2 cm alone,
#: 0 with 4 cm (the fingers run out of flexion or turn their pads away).
PALM_GAPS = (0.005, 0.02)
#: Wrist yaws (equally spaced over a turn) the palm may take over the block.
YAWS = 12
#: Hand postures checked per grasp (nearest first), and finger assignments per posture.
POSTURES_TRIED = 12
ASSIGNMENTS_TRIED = 2
#: Arm IK seed (shoulder, elbow, wrist pitch, wrist roll) of a palm-down posture over the table;
#: the waist is turned towards the block.
ARM_SEED = (0.3, 1.5, 1.3, 0.0)


@dataclass(frozen=True, eq=False)
class HandPosture:
    """The arm holding the palm over the block at ``yaw``, the hand pre-shaped on its faces."""

    yaw: float  #: rad, palm yaw about the vertical
    qpos: NDArray[np.float64]  #: full world qpos (arm, hand; the rest as the world has it)
    tips: NDArray[np.float64]  #: (4, 3) fingertip positions there


@dataclass(frozen=True, eq=False)
class Placement:
    """Where the hand takes a grasp: ``reachable`` with the posture and the fingers' contacts,
    or not, with the reason (of the nearest posture)."""

    reachable: bool
    reason: str
    posture: HandPosture | None
    contacts: FingerContacts | None
    reach: HandReach | None


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
) -> list[HandPosture]:
    """The palm-down postures over ``target`` (those the arm's IK reaches), from the world's
    current state; each hand pre-shaped with its fingertips on the block's faces."""
    if yaws < 1:
        raise ValueError(f"yaws must be >= 1, got {yaws}")
    model = world.model
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    m = world.model
    arm_adr = [m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.ARM_JOINTS]
    hand_adr = HandIndices.of(m).finger_qpos.ravel()
    base = world.data.xpos[
        mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, robot.arm_name("arm_base"))
    ]
    waist = float(np.arctan2(target.position_xy[1] - base[1], target.position_xy[0] - base[0]))
    out = []
    for gap, k in itertools.product(palm_gaps, range(yaws)):
        pos = np.array([*target.position_xy, target.top_z + gap])
        yaw = target.yaw + 2.0 * np.pi * k / yaws
        ik = checker.solve_ik(pos, _palm_down(yaw), [waist, *ARM_SEED])
        if not ik.found:
            continue
        qpos = world.data.qpos.copy()
        qpos[arm_adr] = ik.q
        qpos[hand_adr] = PRESHAPE
        # the preshape's tips, raised (or lowered) to the grasp depth below the top
        at_depth = fingertips_at(model, qpos)
        at_depth[:, 2] = target.top_z - GRASP_DEPTH
        surface = project_to_surface(target, at_depth, table_z=world.scene.table.height)
        tips, centres = grip_targets(surface.points, surface.normals, 0.0)
        hand = solve_posture(
            world, tips, optimize=False, joints="hand", qpos=qpos, pad_centres=centres
        )
        qpos[hand_adr] = hand.hand_q
        out.append(HandPosture(float(yaw), qpos, fingertips_at(model, qpos)))
    return out


def place_hand(
    world: World,
    prism: PerceivedPrism,
    target: ReachTarget,
    theta: ArrayLike,
    postures: list[HandPosture],
    *,
    tries: int = POSTURES_TRIED,
    assignments: int = ASSIGNMENTS_TRIED,
    samples: FingerSamples | None = None,
) -> Placement:
    """The first of the ``tries`` postures nearest to contacts ``theta`` (contact coordinates on
    ``target``'s polygon) from which the hand reaches them (see the module docstring);
    ``samples``: the sampled finger postures (default: drawn with their fixed seed)."""
    if not postures:
        return Placement(
            False, "the arm reaches no palm-down posture over the block", None, None, None
        )
    th = np.asarray(theta, dtype=float)
    table_z = prism.bottom
    if samples is None:
        samples = FingerSamples.draw(pad_normal_local=PAD_NORMAL_LOCAL)

    def distance(p: HandPosture) -> float:
        given = finger_contacts(target, th, p.tips, table_z)
        return float(((given.points - p.tips) ** 2).sum())

    ranked = sorted(postures, key=distance)
    first: Placement | None = None
    for p in ranked[:tries]:
        contacts, reach = reachable_contacts(
            world, prism, target, th, qpos=p.qpos, tries=assignments, samples=samples
        )
        placed = Placement(reach.reachable, reach.reason, p, contacts, reach)
        if reach.reachable:
            return placed
        if first is None:
            first = placed
    assert first is not None
    return first
