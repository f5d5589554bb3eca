"""Coarse reach (section 5.2): a harmonic-function path in the arm's 4-D configuration space
from the current posture to a posture with the hand above (top grasp) or beside (lateral grasp)
the target block, avoiding the table, the other blocks, the target itself and the robot's own
links; executed on the simulated arm's position servos.

"The path computed determines whether a top or lateral grasp will be executed": both approaches
are planned and the one whose path exists and is shorter (in joint space) is chosen. This module
holds the target, the goal poses of each approach, their IK goals and :func:`plan_coarse_reach`.
The path planner and its execution live in :mod:`controllers.reach.arm_path` (the same planner moves
the arm, hand and object to a delivery posture, :mod:`controllers.deliver.plan`); their public names
are re-exported here so that ``from controllers.reach.coarse import plan_arm_path`` works too.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.errors import ReachError
from controllers.grasp.polygon import Polygon
from controllers.planning.cspace import DEFAULT_CLEARANCE, CollisionChecker, IKResult
from controllers.reach.arm_path import (
    DEFAULT_RESOLUTION,
    ROLL,
    ArmPath,
    plan_arm_path,
)
from hand_sim import robot
from hand_sim.world import World

#: The approaches of section 5.2 ("top or lateral grasp").
APPROACHES: tuple[str, ...] = ("top", "lateral")
#: Hand pre-shape while reaching (HAND_JOINTS order): fingers flexed at the MCP so that they
#: point along the approach axis, slightly splayed, around a ~5-8 cm block.
PRESHAPE: tuple[float, ...] = (0.0, 1.3, 0.15, 0.1) * 3 + (0.0, 1.3, 0.15, 0.1)
#: Reach of the pre-shaped fingertips beyond the palm face along the approach axis (m).
FINGER_REACH = 0.11
#: Free space kept between the pre-shaped fingertips and the block at the goal (m).
APPROACH_GAP = 0.04
#: Lateral approach: height of the palm centre below the block's top (m). The palm's finger row
#: is horizontal (thumb below, fingers above, or the reverse), so the thumb knuckle sits 4.5 cm
#: below the palm centre and the middle finger's 5.8 cm above it: 0.10 m puts all four fingertips
#: on a 20 cm block's side faces with the palm's lower edge 5 cm above the table.
LATERAL_DEPTH = 0.10
#: Lateral goals tried, in order, when the one at (LATERAL_DEPTH, APPROACH_GAP) has no
#: collision-free posture: (palm depth below the top, gap between the pre-shaped fingertips and
#: the block, m; approach axis pitched down from the horizontal, rad). For a block nearer the
#: arm's base than about 0.57 m the 5-joint arm reaches the nominal lateral goal only with its
#: wrist pitched so far that the palm and fingers hit its own forearm; a palm closer to the block
#: or higher unfolds the wrist. The depths keep the middle finger's knuckle (5.8 cm above the
#: palm centre) below the top. Then the axis pitched down by LATERAL_TILTS: 15 deg unfolds the
#: wrist for a block 0.44-0.50 m from the base, 30-45 deg lifts the hand over a neighbour on the
#: radial line.
#: Chosen by the lateral goals the bench lacked: docs/findings.md, "Lateral goal fallbacks".
LATERAL_TILTS: tuple[float, ...] = (np.deg2rad(15.0), np.deg2rad(30.0), np.deg2rad(45.0))
#: A lateral goal pitched more than this (rad) is one of LATERAL_TILTS': with ``auto`` it is
#: taken only where the top approach has no path.
PITCH_TOLERANCE = np.deg2rad(1.0)
LATERAL_GOAL_FALLBACKS: tuple[tuple[float, float, float], ...] = (
    (LATERAL_DEPTH, 0.02, 0.0),
    (LATERAL_DEPTH, 0.0, 0.0),
    (0.07, 0.02, 0.0),
    (0.07, 0.0, 0.0),
    *(
        (depth, gap, tilt)
        for tilt in LATERAL_TILTS
        for depth, gap in ((LATERAL_DEPTH, APPROACH_GAP), (LATERAL_DEPTH, 0.02), (0.07, 0.02))
    ),
)


class PerceivedBlock(Protocol):
    """What :meth:`ReachTarget.from_object_model` reads of a ``vision.ObjectModel``."""

    polygon: Polygon
    centroid: NDArray[np.float64]
    yaw: float


@dataclass(frozen=True, eq=False)
class ReachTarget:
    """The block to reach: its footprint polygon (metres, object frame), world centre of the
    footprint ``(x, y)``, yaw (rad) and the height (z) of its top face."""

    polygon: Polygon
    position_xy: tuple[float, float]
    yaw: float
    top_z: float

    @classmethod
    def from_world(cls, world: World, name: str) -> ReachTarget:
        """The block ``name`` where the world's physics has it now."""
        spec = world.scene.block(name)
        pos, quat = world.block_pose(name)
        yaw = 2.0 * float(np.arctan2(quat[3], quat[0]))
        return cls(
            spec.polygon, (float(pos[0]), float(pos[1])), yaw, float(pos[2]) + spec.height / 2
        )

    @classmethod
    def from_object_model(cls, obj: PerceivedBlock) -> ReachTarget:
        """The block as vision sees it (a ``vision.ObjectModel``: polygon, centroid = world
        (x, y, z_top), yaw)."""
        c = np.asarray(obj.centroid, dtype=float)
        return cls(obj.polygon, (float(c[0]), float(c[1])), float(obj.yaw), float(c[2]))

    def footprint(self) -> NDArray[np.float64]:
        """World (x, y) vertices of the footprint."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return self.polygon.vertices @ np.array([[c, s], [-s, c]]) + np.asarray(self.position_xy)

    @property
    def radius(self) -> float:
        """Largest distance (m) of a footprint vertex from the centroid."""
        return float(np.linalg.norm(self.polygon.vertices, axis=1).max())


@dataclass(frozen=True, eq=False)
class ApproachGoal:
    """A goal posture of one approach: arm joints and the palm pose they give."""

    approach: str
    q: NDArray[np.float64]  #: (5,) arm joints
    palm_position: NDArray[np.float64]  #: (3,)
    palm_rotation: NDArray[np.float64]  #: (3, 3), columns = hand x, y, z (z = approach axis)

    @property
    def pitch(self) -> float:
        """The approach axis's angle below the horizontal (rad): pi/2 for a top goal, 0 for a
        level lateral one (:func:`axis_pitch`)."""
        return axis_pitch(self.palm_rotation)


def axis_pitch(rotation: NDArray[np.float64]) -> float:
    """The angle (rad) below the horizontal of a palm rotation's approach axis (its z column)."""
    return float(np.arcsin(np.clip(-rotation[2, 2], -1.0, 1.0)))


@dataclass(frozen=True, eq=False)
class CoarseReachPlan:
    """The chosen approach and its path, with every approach's attempt in ``candidates``."""

    found: bool
    approach: str  #: "top", "lateral" or "" when none was found
    path: ArmPath | None
    goal: ApproachGoal | None
    hand_q: NDArray[np.float64]  #: hand posture held while reaching
    candidates: dict[str, ArmPath] = field(default_factory=dict)
    reason: str = ""
    no_goal: tuple[str, ...] = ()  #: approaches with no collision-free goal posture (IK)
    #: Why ``approach`` was taken, for the transition log (:func:`choice_reason`).
    choice: str = ""


def choice_reason(
    approaches: tuple[str, ...],
    candidates: dict[str, ArmPath],
    no_goal: tuple[str, ...],
    best: str,
) -> str:
    """Why ``best`` was taken among ``approaches`` (section 5.2: the paths decide): the only one
    asked for, the only one with a path (each other one's reason named: no collision-free goal
    posture, or its planner's), the shortest path (the lengths compared, rad), or a level goal's
    path over a shorter one to a lateral goal only pitched down."""
    if len(approaches) == 1:
        return f"the only approach asked for (--approach {best})"
    others = [a for a in approaches if a != best]
    lost = {a: "no collision-free goal posture" for a in others if a in no_goal}
    lost |= {a: candidates[a].reason for a in others if a in candidates and not candidates[a].found}
    if len(lost) == len(others):
        why = "; ".join(f"{a}: {r}" for a, r in lost.items())
        return f"the only approach with a path ({why})"
    lengths = ", ".join(
        f"{a} {candidates[a].length:.2f} rad"
        for a in approaches
        if a in candidates and candidates[a].found
    )
    shorter = [
        a
        for a in others
        if a in candidates
        and candidates[a].found
        and candidates[a].length < candidates[best].length
    ]
    if shorter:  # a shorter path whose lateral goal is only pitched down
        return f"a level goal first: lateral's is only pitched down ({lengths})"
    return f"the shortest path in joint space ({lengths})"


def _grasp_axis(target: ReachTarget) -> NDArray[np.float64]:
    """Horizontal unit vector across the block's narrowest width (fingers close along it)."""
    normals = np.stack([np.cos(target.polygon.normal_angle), np.sin(target.polygon.normal_angle)])
    widths = np.ptp(target.polygon.vertices @ normals, axis=0)
    a = float(target.polygon.normal_angle[int(np.argmin(widths))]) + target.yaw
    return np.array([np.cos(a), np.sin(a), 0.0])


def _frame(y: NDArray[np.float64], z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation with columns (y x z, y, z)."""
    return np.column_stack([np.cross(y, z), y, z])


def goal_poses(
    target: ReachTarget, base_xy: ArrayLike
) -> dict[str, list[tuple[NDArray[np.float64], NDArray[np.float64]]]]:
    """Palm poses (position, rotation) of each approach: two top candidates (the hand turned by
    pi about its approach axis) and one lateral (:func:`lateral_fallback_poses` are tried when
    it has no collision-free posture).

    Top: palm down, the thumb-to-middle-finger axis (hand y) across the block's narrowest width.
    Lateral: palm facing the block along the arm's radial direction, hand y vertical, so the
    finger row (hand x) is horizontal: the first and ring fingers close on the block's sides
    from left and right while the middle finger and the thumb face it from above and below the
    palm centre. (With the finger row vertical instead, three fingers stack on one face against
    the thumb, a grasp S_G rejects: ``benchmarks.hand_reachability`` finds lateral grasps with
    S_G <= 0.3 for this roll only.) Hand y points up, the thumb below: turned the other way,
    the middle finger reaches down the block to within a few centimetres of the table and its
    links collide with it."""
    centre = np.array([*target.position_xy, 0.0])
    radial = _radial(target, base_xy)
    down = np.array([0.0, 0.0, -1.0])
    top_pos = centre + np.array([0.0, 0.0, target.top_z + FINGER_REACH + APPROACH_GAP])
    axis = _grasp_axis(target)
    return {
        "top": [(top_pos, _frame(s * axis, down)) for s in (1.0, -1.0)],
        "lateral": [lateral_pose(target, radial, LATERAL_DEPTH, APPROACH_GAP)],
    }


def _radial(target: ReachTarget, base_xy: ArrayLike) -> NDArray[np.float64]:
    """Horizontal unit vector from the arm's base to the block's centre."""
    radial = np.array([*target.position_xy, 0.0]) - np.array([*np.asarray(base_xy, float), 0.0])
    return radial / np.linalg.norm(radial)


def lateral_pose(
    target: ReachTarget, radial: NDArray[np.float64], depth: float, gap: float, tilt: float = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The lateral palm pose (position, rotation) facing the block along ``radial`` with the
    pre-shaped fingertips ``gap`` from it and the approach axis through the point ``depth``
    below its top on its vertical axis; the axis pitched ``tilt`` (rad) down from the
    horizontal, hand y in the vertical plane through it (:func:`lateral_frame`)."""
    aim = np.array([*target.position_xy, target.top_z - depth])
    standoff = target.radius + FINGER_REACH + gap
    rot = lateral_frame(radial, tilt)
    return aim - standoff * rot[:, 2], rot


def lateral_frame(
    radial: NDArray[np.float64], tilt: float, roll: float = 0.0
) -> NDArray[np.float64]:
    """A lateral palm rotation: approach axis (z) along the horizontal ``radial`` pitched
    ``tilt`` (rad) down, hand y up in the vertical plane through it (the finger row horizontal),
    then turned ``roll`` (rad) about the axis."""
    up = np.array([0.0, 0.0, 1.0])
    z = np.cos(tilt) * radial - np.sin(tilt) * up
    y0 = np.cos(tilt) * up + np.sin(tilt) * radial
    y = np.cos(roll) * y0 + np.sin(roll) * np.cross(up, radial)
    return _frame(y, z)


def lateral_fallback_poses(
    target: ReachTarget, base_xy: ArrayLike, tilt: float | None = None, *, far: bool = False
) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """The lateral goals of :data:`LATERAL_GOAL_FALLBACKS`, in their order (only those pitched
    ``tilt`` down, rad, when given); ``far``: from the block's far side, the palm beyond it
    facing back towards the base."""
    radial = _radial(target, base_xy)
    return [
        lateral_pose(target, -radial if far else radial, d, g, t)
        for d, g, t in LATERAL_GOAL_FALLBACKS
        if tilt is None or abs(t - tilt) < 1e-9
    ]


#: Seeds of the arm IK (waist is set towards the target): elbow-up reaching postures.
IK_SEEDS: tuple[tuple[float, float, float, float], ...] = (
    (0.3, 1.5, 1.3, 0.0),
    (0.0, 1.2, 0.4, 0.0),
    (-0.3, 2.2, 0.6, 0.0),
    (1.6, -1.0, 1.5, 0.0),
)


def solve_goal(
    checker: CollisionChecker,
    approach: str,
    poses: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    q_start: NDArray[np.float64],
) -> ApproachGoal | None:
    """A collision-free IK solution for one of ``poses``, nearest the start posture."""
    best: ApproachGoal | None = None
    best_dist = np.inf
    for pos, rot in poses:
        for ik in seeded_postures(checker, pos, rot, (q_start[ROLL], 0.0)):
            dist = float(np.linalg.norm(ik.q - q_start))
            if dist < best_dist:
                best_dist = dist
                best = ApproachGoal(approach, ik.q, pos, rot)
    return best


def seeded_postures(
    checker: CollisionChecker,
    position: NDArray[np.float64],
    rotation: NDArray[np.float64],
    rolls: tuple[float, ...],
) -> Iterator[IKResult]:
    """The IK solutions (found, collision-free) holding the palm at ``position`` with
    ``rotation``, solved from each of :data:`IK_SEEDS` with the waist towards ``position`` and
    each wrist roll of ``rolls``, in that order."""
    base = checker.data.xpos[
        mujoco.mj_name2id(checker.model, mujoco.mjtObj.mjOBJ_BODY, robot.arm_name("arm_base"))
    ]
    waist = float(np.arctan2(position[1] - base[1], position[0] - base[0]))
    for seed in IK_SEEDS:
        for roll in rolls:
            r = checker.solve_ik(position, rotation, [waist, *seed[:3], roll])
            if r.found and not checker.collides(r.q):
                yield r


def _base_xy(world: World) -> NDArray[np.float64]:
    """World (x, y) of the arm's waist axis."""
    body = mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_BODY, robot.arm_name("arm_base"))
    return world.data.xpos[body][:2]


def _first_goal(
    checker: CollisionChecker,
    poses: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    q_start: NDArray[np.float64],
) -> ApproachGoal | None:
    """The lateral goal of the first of ``poses`` with a collision-free posture
    (:func:`solve_goal`), or None."""
    goals = (solve_goal(checker, "lateral", [pose], q_start) for pose in poses)
    return next((g for g in goals if g is not None), None)


def pitched_lateral_goal(
    world: World,
    target: ReachTarget,
    tilt: float,
    *,
    hand_q: ArrayLike = PRESHAPE,
    clearance: float = DEFAULT_CLEARANCE,
    model: mujoco.MjModel | None = None,
) -> ApproachGoal | None:
    """The lateral goal :func:`plan_coarse_reach` with ``lateral_tilt=tilt`` plans its path to
    (the same checker, the same start), without planning the path: the first of
    :data:`LATERAL_GOAL_FALLBACKS` pitched ``tilt`` (rad) down with a collision-free posture."""
    checker = CollisionChecker(world, clearance=clearance, hand_q=hand_q, model=model)
    poses = lateral_fallback_poses(target, _base_xy(world), tilt)
    return _first_goal(checker, poses, world.arm_qpos())


def plan_coarse_reach(
    world: World,
    target: ReachTarget,
    *,
    resolution: int = DEFAULT_RESOLUTION,
    hand_q: ArrayLike = PRESHAPE,
    approaches: tuple[str, ...] = APPROACHES,
    clearance: float = DEFAULT_CLEARANCE,
    model: mujoco.MjModel | None = None,
    lateral_tilt: float | None = None,
) -> CoarseReachPlan:
    """Plan the coarse reach to ``target`` from the world's current arm posture, holding the hand
    at ``hand_q``: every approach is planned and the shortest existing path wins (a lateral goal
    only pitched down, :data:`LATERAL_TILTS`, only where no top path exists). ``model`` is
    the model collisions are checked in (default the world's; the task cycle passes the
    planning model holding the perceived target, :mod:`controllers.planning.belief`).
    ``lateral_tilt``: the lateral goals are only those of :data:`LATERAL_GOAL_FALLBACKS`
    pitched this far down (rad), e.g. one of :data:`LATERAL_TILTS`.

    Where no lateral goal on the base's side of the block has a collision-free posture (and
    no ``lateral_tilt`` is asked for), the same goals are tried from its far side: the palm
    beyond the block, facing back towards the base along the radial line. The 5-joint arm's
    approach axis stays in its waist's vertical plane, so the radial line's two ends are the
    only directions a lateral palm can face; a neighbour within about 18 cm of the block on
    the base's side leaves no near goal, and the far goals found are pitched 30-45 deg down,
    the forearm passing over the block (docs/findings.md, "A lateral palm from the far side")."""
    unknown = [a for a in approaches if a not in APPROACHES]
    if unknown or not approaches:
        raise ReachError(
            f"unknown approach {unknown or approaches!r}; valid: {', '.join(APPROACHES)}"
        )
    checker = CollisionChecker(world, clearance=clearance, hand_q=hand_q, model=model)
    q_start = world.arm_qpos()
    base_xy = _base_xy(world)
    poses = goal_poses(target, base_xy)
    candidates: dict[str, ArmPath] = {}
    goals: dict[str, ApproachGoal] = {}
    for approach in approaches:
        pitched_only = approach == "lateral" and lateral_tilt is not None
        goal = None if pitched_only else solve_goal(checker, approach, poses[approach], q_start)
        if goal is None and approach == "lateral":
            # the first fallback with a collision-free posture (nearer or higher palm)
            goal = _first_goal(
                checker, lateral_fallback_poses(target, base_xy, lateral_tilt), q_start
            )
        if goal is None and approach == "lateral" and lateral_tilt is None:
            # none on the base's side: the palm beyond the block, facing back
            far = lateral_fallback_poses(target, base_xy, far=True)
            goal = _first_goal(checker, far, q_start)
        if goal is None:
            continue
        goals[approach] = goal
        candidates[approach] = plan_arm_path(checker, q_start, goal.q, resolution=resolution)
    found = {a: p for a, p in candidates.items() if p.found}
    hand = np.asarray(hand_q, dtype=float)
    missing = tuple(a for a in approaches if a not in goals)
    if not found:
        reasons = "; ".join(f"{a}: {p.reason}" for a, p in candidates.items())
        if missing:
            reasons += "; no collision-free goal posture for " + ", ".join(missing)
        return CoarseReachPlan(
            False, "", None, None, hand, candidates, reasons.strip("; "), missing
        )
    # a lateral goal only pitched down (LATERAL_TILTS) is a last resort: any level path first
    pitched = {a: goals[a].pitch > PITCH_TOLERANCE for a in found if a == "lateral"}
    best = min(found, key=lambda a: (pitched.get(a, False), found[a].length))
    return CoarseReachPlan(
        True,
        best,
        found[best],
        goals[best],
        hand,
        candidates,
        "reached goal",
        missing,
        choice_reason(approaches, candidates, missing, best),
    )
