"""Coarse reach (section 5.2): a harmonic-function path in the arm's 4-D configuration space
from the current posture to a posture with the hand above (top grasp) or beside (lateral grasp)
the target block, avoiding the table, the other blocks, the target itself and the robot's own
links; executed on the simulated arm's position servos.

"The path computed determines whether a top or lateral grasp will be executed": both approaches
are planned and the one whose path exists and is shorter (in joint space) is chosen. The same
planner (:func:`plan_arm_path`) moves the arm, hand and object to a delivery posture.

The c-space is the arm's first four joints (waist, shoulder, elbow, wrist pitch); the wrist roll
is turned to the goal's value at the start posture and held. The grid covers the box spanned by
the start and goal postures plus :data:`BOX_MARGIN`, within the joint limits. Obstacle nodes are
found with MuJoCo's collision detection (:class:`controllers.cspace.CollisionChecker`, with a
clearance); goal nodes are free nodes near the exact IK goal joined to it by a collision-free
straight segment (likewise the start). The extracted path is checked posture by posture at
:data:`VERIFY_STEP` with MuJoCo; a node next to a colliding posture is marked as an obstacle and
the harmonic function solved again (up to :data:`MAX_REPAIRS` times).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.cspace import DEFAULT_CLEARANCE, CollisionChecker
from controllers.errors import ReachError
from controllers.grasp.polygon import Polygon
from controllers.harmonic import GridSpec, ascend, solve_harmonic
from controllers.timing import CONTROL_PERIOD, SERVO_SETTLE_TIME, control_steps
from hand_sim import robot
from hand_sim.world import World

#: The approaches of section 5.2 ("top or lateral grasp").
APPROACHES: tuple[str, ...] = ("top", "lateral")
#: Nodes per axis of the 4-D grid (14^4 = 38,416 collision checks).
DEFAULT_RESOLUTION = 14
#: Joints of the planning c-space (indices into ARM_JOINTS) and the held wrist roll.
PLANNED_JOINTS = 4
ROLL = 4
#: Margin (rad) around the start/goal box of the grid.
BOX_MARGIN = 0.35
#: Largest joint step (rad) between postures checked when verifying or executing a path.
VERIFY_STEP = 0.01
#: Times a path is repaired (colliding node marked, potential solved again) before giving up.
MAX_REPAIRS = 8
#: Start and goal postures join the grid through up to LINKS free nodes within LINK_RADIUS cells
#: reachable by a collision-free straight segment (at most LINK_TRIES nodes are tried).
LINKS = 8
LINK_RADIUS = 2.0
LINK_TRIES = 48

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

#: Arm joint speed (rad/s) while executing a path.
MAX_JOINT_SPEED = 0.8


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


@dataclass(frozen=True, eq=False)
class ArmPath:
    """A planned arm path. ``found`` is False (with ``reason``) when no collision-free path
    exists on the grid. ``path`` (k, 5) starts at the start posture and ends at the goal."""

    found: bool
    path: NDArray[np.float64]
    reason: str
    grid: GridSpec | None
    n_obstacles: int  #: obstacle nodes of the grid
    n_repairs: int  #: nodes marked after a failed posture-by-posture check
    build_seconds: float  #: collision checks of every grid node
    solve_seconds: float  #: harmonic solves and path extraction (all repairs)

    @property
    def length(self) -> float:
        """Joint-space length (rad) of the path."""
        if len(self.path) < 2:
            return 0.0
        return float(np.linalg.norm(np.diff(self.path, axis=0), axis=1).sum())

    @property
    def straight_distance(self) -> float:
        """Straight-line joint distance (rad) from the first to the last posture."""
        return float(np.linalg.norm(self.path[-1] - self.path[0])) if len(self.path) else 0.0


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
    pi about its approach axis) and one lateral.

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
    radial = centre - np.array([*np.asarray(base_xy, float), 0.0])
    radial[2] = 0.0
    radial /= np.linalg.norm(radial)
    down = np.array([0.0, 0.0, -1.0])
    top_pos = centre + np.array([0.0, 0.0, target.top_z + FINGER_REACH + APPROACH_GAP])
    axis = _grasp_axis(target)
    up = np.array([0.0, 0.0, 1.0])
    standoff = target.radius + FINGER_REACH + APPROACH_GAP
    lat_pos = centre - standoff * radial + np.array([0.0, 0.0, target.top_z - LATERAL_DEPTH])
    return {
        "top": [(top_pos, _frame(s * axis, down)) for s in (1.0, -1.0)],
        "lateral": [(lat_pos, _frame(up, radial))],
    }


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
    base = checker.data.xpos[
        mujoco.mj_name2id(checker.model, mujoco.mjtObj.mjOBJ_BODY, robot.arm_name("arm_base"))
    ]
    for pos, rot in poses:
        waist = float(np.arctan2(pos[1] - base[1], pos[0] - base[0]))
        for seed in IK_SEEDS:
            for roll in (q_start[ROLL], 0.0):
                r = checker.solve_ik(pos, rot, [waist, *seed[:3], roll])
                if not r.found or checker.collides(r.q):
                    continue
                dist = float(np.linalg.norm(r.q - q_start))
                if dist < best_dist:
                    best_dist = dist
                    best = ApproachGoal(approach, r.q, pos, rot)
    return best


def _interpolate(path: NDArray[np.float64], max_step: float) -> NDArray[np.float64]:
    """Insert postures so that no joint moves more than ``max_step`` between rows."""
    out = [path[:1]]
    for a, b in itertools.pairwise(path):
        n = max(1, int(np.ceil(np.abs(b - a).max() / max_step)))
        out.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
    return np.vstack(out)


def first_collision(
    checker: CollisionChecker, path: NDArray[np.float64], *, max_step: float = VERIFY_STEP
) -> NDArray[np.float64] | None:
    """The first posture along ``path`` (checked every ``max_step`` rad) that collides, if any."""
    dense = _interpolate(np.asarray(path, float), max_step)
    for q in dense:
        if checker.collides(q):
            return q
    return None


def _grid_box(checker: CollisionChecker, points: NDArray[np.float64], resolution: int) -> GridSpec:
    lo = points[:, :PLANNED_JOINTS].min(axis=0) - BOX_MARGIN
    hi = points[:, :PLANNED_JOINTS].max(axis=0) + BOX_MARGIN
    limits = checker.arm_limits[:PLANNED_JOINTS]
    lo, hi = np.maximum(lo, limits[:, 0]), np.minimum(hi, limits[:, 1])
    return GridSpec(tuple(lo), tuple(hi), (resolution,) * PLANNED_JOINTS)


def _nearby_nodes(spec: GridSpec, q4: NDArray[np.float64]) -> list[tuple[int, ...]]:
    """Grid nodes within :data:`LINK_RADIUS` cells (Chebyshev) of ``q4``, nearest first."""
    x = spec.to_grid(q4)
    lo = np.maximum(np.ceil(x - LINK_RADIUS), 0).astype(int)
    hi = np.minimum(np.floor(x + LINK_RADIUS), np.asarray(spec.shape) - 1).astype(int)
    nodes = np.array(
        list(itertools.product(*(range(a, b + 1) for a, b in zip(lo, hi, strict=True))))
    )
    order = np.argsort(np.linalg.norm(nodes - x, axis=1))
    return [tuple(int(v) for v in nodes[i]) for i in order]


def _linked_nodes(
    checker: CollisionChecker,
    spec: GridSpec,
    free: NDArray[np.bool_],
    q: NDArray[np.float64],
    roll: float,
) -> list[tuple[int, ...]]:
    """Free nodes near posture ``q`` (5,) joined to it by a collision-free straight segment:
    up to :data:`LINKS` of them, trying at most :data:`LINK_TRIES` nearest free nodes."""
    out: list[tuple[int, ...]] = []
    tried = 0
    for c in _nearby_nodes(spec, q[:PLANNED_JOINTS]):
        if not free[c]:
            continue
        tried += 1
        node = np.array([*spec.to_config(c), roll])
        if first_collision(checker, np.stack([q, node])) is None:
            out.append(c)
        if len(out) >= LINKS or tried >= LINK_TRIES:
            break
    return out


def plan_arm_path(
    checker: CollisionChecker,
    q_start: ArrayLike,
    q_goal: ArrayLike,
    *,
    resolution: int = DEFAULT_RESOLUTION,
) -> ArmPath:
    """Harmonic path (Connolly & Grupen) from arm posture ``q_start`` (5,) to ``q_goal`` (5,).

    The wrist roll turns to ``q_goal``'s at the start; the other four joints follow the
    gradient of the harmonic function of a ``resolution^4`` grid. Every returned path has been
    checked collision-free posture by posture (``VERIFY_STEP``) with MuJoCo.
    """
    q_start = np.asarray(q_start, dtype=float)
    q_goal = np.asarray(q_goal, dtype=float)
    if resolution < 3:
        raise ReachError(f"grid resolution must be >= 3 nodes per axis, got {resolution}")
    t0 = time.perf_counter()
    spec = _grid_box(checker, np.stack([q_start, q_goal]), resolution)
    roll = q_goal[ROLL]
    nodes = spec.node_configs()
    configs = np.column_stack([nodes, np.full(len(nodes), roll)])
    free = ~checker.scan(configs).collides.reshape(spec.shape)
    build = time.perf_counter() - t0

    def fail(reason: str, repairs: int = 0) -> ArmPath:
        return ArmPath(
            False,
            np.stack([q_start]),
            reason,
            spec,
            int((~free).sum()),
            repairs,
            build,
            time.perf_counter() - t0 - build,
        )

    rolled = np.array([*q_start[:ROLL], roll])
    lead = np.stack([q_start, rolled])
    if checker.collides(q_start):
        return fail("the start posture is in collision")
    if first_collision(checker, lead) is not None:
        return fail("turning the wrist roll at the start collides")
    if checker.collides(q_goal):
        return fail("the goal posture is in collision")
    goal_mask = np.zeros(spec.shape, dtype=bool)
    for c in _linked_nodes(checker, spec, free, q_goal, roll):
        goal_mask[c] = True
    if not goal_mask.any():
        return fail("no grid node near the goal connects to it without collision")
    start_nodes = _linked_nodes(checker, spec, free, rolled, roll)
    if not start_nodes:
        return fail("no grid node near the start connects to it without collision")
    repairs = 0
    while True:
        field_ = solve_harmonic(free, goal_mask)
        reachable = [c for c in start_nodes if field_.reachable(c)]
        if not reachable:
            return fail("no path: the goal is not connected to the start on the grid", repairs)
        hp = ascend(field_, np.asarray(reachable[0], float))
        if not hp.found:
            return fail(f"gradient path failed: {hp.reason}", repairs)
        q4 = spec.to_config(hp.points)
        middle = np.column_stack([q4, np.full(len(q4), roll)])
        path = np.vstack([lead, middle, q_goal[None]])
        bad = first_collision(checker, path)
        if bad is None:
            return ArmPath(
                True,
                _dedupe(path),
                "reached goal",
                spec,
                int((~free).sum()),
                repairs,
                build,
                time.perf_counter() - t0 - build,
            )
        if repairs >= MAX_REPAIRS:
            return fail(f"path still collides after {repairs} repairs", repairs)
        node = spec.nearest_cell(bad[:PLANNED_JOINTS])
        if goal_mask[node] or node in start_nodes[:1]:
            # the collision lies in a connecting segment: drop that goal/start node instead
            goal_mask[node] = False
            start_nodes = [c for c in start_nodes if c != node]
            if not goal_mask.any() or not start_nodes:
                return fail("every node next to the start or goal collides on the way", repairs)
        free[node] = False
        goal_mask &= free
        repairs += 1


def _dedupe(path: NDArray[np.float64]) -> NDArray[np.float64]:
    keep = np.concatenate([[True], np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-9])
    return path[keep]


def plan_coarse_reach(
    world: World,
    target: ReachTarget,
    *,
    resolution: int = DEFAULT_RESOLUTION,
    hand_q: ArrayLike = PRESHAPE,
    approaches: tuple[str, ...] = APPROACHES,
    clearance: float = DEFAULT_CLEARANCE,
    model: mujoco.MjModel | None = None,
) -> CoarseReachPlan:
    """Plan the coarse reach to ``target`` from the world's current arm posture, holding the hand
    at ``hand_q``: every approach is planned and the shortest existing path wins. ``model`` is
    the model collisions are checked in (default the world's; the task cycle passes the
    planning model holding the perceived target, :mod:`controllers.planning_model`)."""
    unknown = [a for a in approaches if a not in APPROACHES]
    if unknown or not approaches:
        raise ReachError(
            f"unknown approach {unknown or approaches!r}; valid: {', '.join(APPROACHES)}"
        )
    checker = CollisionChecker(world, clearance=clearance, hand_q=hand_q, model=model)
    q_start = world.arm_qpos()
    base_xy = world.data.xpos[
        mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_BODY, robot.arm_name("arm_base"))
    ][:2]
    poses = goal_poses(target, base_xy)
    candidates: dict[str, ArmPath] = {}
    goals: dict[str, ApproachGoal] = {}
    for approach in approaches:
        goal = solve_goal(checker, approach, poses[approach], q_start)
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
    best = min(found, key=lambda a: found[a].length)
    return CoarseReachPlan(
        True, best, found[best], goals[best], hand, candidates, "reached goal", missing
    )


@dataclass(frozen=True, eq=False)
class Execution:
    """What happened while a path was executed on the simulated arm."""

    contacts: tuple[tuple[str, str], ...]  #: robot-vs-other geom pairs that touched, by name
    final_error: float  #: largest arm joint error (rad) at the end
    seconds: float  #: simulated time taken


def robot_contacts(world: World) -> set[tuple[str, str]]:
    """Geom pairs in contact now where at least one geom belongs to the robot and the other does
    not (robot-robot pairs inside the hand are its own business)."""
    m, d = world.model, world.data
    out = set()
    for c in d.contact[: d.ncon]:
        names = [m.body(m.geom_bodyid[g]).name for g in (c.geom1, c.geom2)]
        on_robot = [n.startswith(robot.ARM_PREFIX) for n in names]
        if on_robot[0] != on_robot[1]:
            out.add((m.geom(c.geom1).name, m.geom(c.geom2).name))
    return out


def execute_path(
    world: World,
    path: ArrayLike,
    *,
    hand_q: ArrayLike | None = None,
    max_joint_speed: float = MAX_JOINT_SPEED,
    settle: float = SERVO_SETTLE_TIME,
) -> Execution:
    """Drive the arm's position servos along ``path`` (k, 5) at ``max_joint_speed``, first
    setting the hand to ``hand_q`` (and letting it settle) if given. Returns the robot contacts
    seen on the way."""
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or path.shape[1] != len(robot.ARM_JOINTS) or len(path) == 0:
        raise ReachError(f"path must have shape (k, 5), got {path.shape}")
    steps = control_steps(world)
    t0 = world.time
    seen: set[tuple[str, str]] = set()
    if hand_q is not None:
        world.set_hand_targets(hand_q)
        for _ in range(round(settle / CONTROL_PERIOD)):
            world.step(steps)
            seen |= robot_contacts(world)
    dense = _interpolate(path, max_joint_speed * CONTROL_PERIOD)
    for q in dense:
        world.set_arm_targets(q)
        world.step(steps)
        seen |= robot_contacts(world)
    for _ in range(round(settle / CONTROL_PERIOD)):
        world.step(steps)
        seen |= robot_contacts(world)
    err = float(np.abs(world.arm_qpos() - path[-1]).max())
    return Execution(tuple(sorted(seen)), err, world.time - t0)


#: Delivery: height (m) of the carried block's bottom above the table during the transit (not
#: the grasp's lift, :data:`controllers.transport.LIFT_HEIGHT`), and where the planned set-down
#: ends (the last part is sensed: controllers.transport).
CARRY_HEIGHT = 0.05
SET_DOWN_HOVER = 0.02
#: Clearance (m) the hand keeps from everything but the table all the way down to the hover.
SET_DOWN_CLEARANCE = 0.003


@dataclass(frozen=True, eq=False)
class DeliveryPlan:
    """A path carrying a grasped block to a place point: straight up to the carry height (if the
    block is not there yet), harmonic transit (the coarse-reach planner with the block as part
    of the hand), straight down until the block's bottom hovers ``SET_DOWN_HOVER`` above the
    table."""

    found: bool
    path: NDArray[np.float64]  #: (k, 5) arm postures, start first
    transit: ArmPath | None  #: the harmonic part
    block_goal: NDArray[np.float64] | None  #: (3,) block centre at the end
    reason: str


def _rotate_z(angle: float) -> NDArray[np.float64]:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def plan_delivery(
    world: World,
    block: str,
    place_xy: ArrayLike,
    *,
    block_height: float | None = None,
    resolution: int = DEFAULT_RESOLUTION,
    lift: float = CARRY_HEIGHT,
    hover: float = SET_DOWN_HOVER,
    clearance: float = DEFAULT_CLEARANCE,
) -> DeliveryPlan:
    """Plan to carry ``block`` (held by the hand now, on the table or already lifted) to
    ``place_xy`` on the table (section 5.2, "Deliver": "the path is computed by the same harmonic
    path planning algorithm used in the coarse reach module").

    Heights come from the table and the block's height (``block_height``, e.g. the perceived
    one; default the scene's), not from where the block is now: the transit carries the block's
    bottom at least ``lift`` above the table, and the path ends with it ``hover`` above the table
    at the place point (the rest of the set-down is sensed). Postures are checked with the block
    moving rigidly with the palm; where it is within ``2 * clearance`` of the table (lift-off and
    set-down) the block-table pair is exempt."""
    place = np.asarray(place_xy, dtype=float)
    if place.shape != (2,) or not np.all(np.isfinite(place)):
        raise ReachError(f"place point must be a finite (x, y), got {place_xy!r}")
    if not clearance < lift < 0.5:
        raise ReachError(f"lift must lie in ({clearance}, 0.5) m, got {lift}")
    if not 0.0 <= hover < lift:
        raise ReachError(f"hover must lie in [0, lift = {lift}) m, got {hover}")
    height = world.scene.block(block).height if block_height is None else float(block_height)
    if not (np.isfinite(height) and height > 0):
        raise ReachError(f"block height must be a positive number of metres, got {block_height}")
    checker = CollisionChecker(world, clearance=clearance, hand_q=world.hand_qpos(), carried=block)
    # the set-down's last 2 * clearance is exempt above (the block nears the table); the hand's
    # links must still keep SET_DOWN_CLEARANCE from everything else all the way down (a finger's
    # middle link landed on a block delivered before, clutter5's third cycle)
    descent = CollisionChecker(
        world, clearance=SET_DOWN_CLEARANCE, hand_q=world.hand_qpos(), carried=block
    )
    q0 = world.arm_qpos()
    empty = np.stack([q0])

    def fail(reason: str, transit: ArmPath | None = None) -> DeliveryPlan:
        return DeliveryPlan(False, empty, transit, None, reason)

    p0, R0 = checker.palm_pose(q0)
    b0, _ = checker.carried_pose(q0)
    table = world.scene.table.height
    carry_z = max(b0[2], table + 0.5 * height + lift)
    down_z = table + 0.5 * height + hover
    up = np.array([0.0, 0.0, carry_z - b0[2]])
    start = q0
    if up[2] > 1e-4:
        lift_ik = checker.solve_ik(p0 + up, R0, q0)
        # the block may touch the table in the first 2 * clearance of the lift
        clear = min(up[2], 2.0 * clearance)
        free_ik = checker.solve_ik(p0 + np.array([0.0, 0.0, clear]), R0, q0)
        if not (lift_ik.found and free_ik.found):
            return fail("the block cannot be lifted straight up from here")
        if first_collision(checker, np.stack([free_ik.q, lift_ik.q])) is not None:
            return fail("lifting the block collides")
        start = lift_ik.q
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id]
    turn = float(
        np.arctan2(place[1] - base[1], place[0] - base[0])
        - np.arctan2(b0[1] - base[1], b0[0] - base[0])
    )
    shift = np.array([*(place - b0[:2]), carry_z - b0[2]])
    drop = np.array([0.0, 0.0, down_z - carry_z])
    high = down = None
    for R in (R0, _rotate_z(turn) @ R0):
        # the palm moves so that the block's centre lands above the place point
        p_high = b0 + shift + R @ R0.T @ (p0 - b0)
        seed = np.array([start[0] + turn, *start[1:]])
        h = checker.solve_ik(p_high, R, seed)
        d = checker.solve_ik(p_high + drop, R, h.q)
        ok = h.found and d.found and not checker.collides(h.q)
        # the set-down may graze the table only in its last 2 * clearance
        near = checker.solve_ik(p_high + drop + np.array([0.0, 0.0, 2.0 * clearance]), R, h.q)
        if (
            ok
            and near.found
            and first_collision(checker, np.stack([h.q, near.q])) is None
            and first_collision(descent, np.stack([h.q, d.q])) is None
        ):
            high, down = h.q, d.q
            break
    if high is None or down is None:
        return fail("no collision-free posture above the place point")
    transit = plan_arm_path(checker, start, high, resolution=resolution)
    if not transit.found:
        return fail(f"transit: {transit.reason}", transit)
    path = _dedupe(np.vstack([q0[None], transit.path, down[None]]))
    block_goal, _ = checker.carried_pose(down)
    return DeliveryPlan(True, path, transit, block_goal, "reached goal")
