"""Harmonic arm paths (section 5.2, "Coarse Reach" and "Deliver"): planning in the arm's 4-D
configuration space and execution on the simulated arm's position servos.

The c-space is the arm's first four joints (waist, shoulder, elbow, wrist pitch); the wrist roll
is turned to the goal's value at the start posture and held. The grid covers the box spanned by
the start and goal postures plus :data:`BOX_MARGIN`, within the joint limits. Obstacle nodes are
found with MuJoCo's collision detection (:class:`controllers.planning.cspace.CollisionChecker`, with
a clearance); goal nodes are free nodes near the exact IK goal joined to it by a collision-free
straight segment (likewise the start). The extracted path is checked posture by posture at
:data:`VERIFY_STEP` with MuJoCo; a node next to a colliding posture is marked as an obstacle and
the harmonic function solved again (up to :data:`MAX_REPAIRS` times).

The coarse reach (:mod:`controllers.reach.coarse`) and the delivery
(:mod:`controllers.deliver.plan`) both plan with :func:`plan_arm_path` and move the arm with
:func:`execute_path`.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.errors import ReachError
from controllers.planning.cspace import CollisionChecker
from controllers.planning.harmonic import GridSpec, ascend, solve_harmonic
from controllers.timing import CONTROL_PERIOD, SERVO_SETTLE_TIME, control_steps
from hand_sim import robot
from hand_sim.world import World

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

#: Arm joint speed (rad/s) while executing a path.
MAX_JOINT_SPEED = 0.8

#: :class:`ArmPath` ``reason`` of a plan whose start posture is within the clearance of something.
START_IN_COLLISION = "the start posture is in collision"
#: ... of a plan whose wrist roll cannot turn to the goal's where it starts.
ROLL_AT_START_COLLIDES = "turning the wrist roll at the start collides"
#: The end of the reason of a path whose roll turned above its start (:func:`roll_turned_above`).
ROLL_TURNED_ABOVE = "the wrist roll turned above the start"


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


def interpolate_path(path: NDArray[np.float64], max_step: float) -> NDArray[np.float64]:
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
    dense = interpolate_path(np.asarray(path, float), max_step)
    for q in dense:
        if checker.collides(q):
            return q
    return None


def _grid_box(checker: CollisionChecker, points: NDArray[np.float64], resolution: int) -> GridSpec:
    """The grid over the planned joints' box around ``points`` plus :data:`BOX_MARGIN`, clipped
    to the joint limits, with ``resolution`` nodes per axis."""
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
    roll_at_goal: bool = False,
) -> ArmPath:
    """Harmonic path (Connolly & Grupen) from arm posture ``q_start`` (5,) to ``q_goal`` (5,).

    The wrist roll turns to ``q_goal``'s at the start (``roll_at_goal``: at the goal, the other
    joints there; only for an empty hand, whose roll tilts nothing it holds); the other four
    joints follow the gradient of the harmonic function of a ``resolution^4`` grid. Every
    returned path has been checked collision-free posture by posture (``VERIFY_STEP``) with
    MuJoCo.
    """
    q_start = np.asarray(q_start, dtype=float)
    q_goal = np.asarray(q_goal, dtype=float)
    if resolution < 3:
        raise ReachError(f"grid resolution must be >= 3 nodes per axis, got {resolution}")
    t0 = time.perf_counter()
    spec = _grid_box(checker, np.stack([q_start, q_goal]), resolution)
    roll = q_start[ROLL] if roll_at_goal else q_goal[ROLL]
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
    arrived = np.array([*q_goal[:ROLL], roll])  # the goal before the roll turns there
    lead = np.stack([q_start, rolled])
    tail = np.stack([arrived, q_goal])
    if checker.collides(q_start):
        return fail(START_IN_COLLISION)
    if first_collision(checker, lead) is not None:
        return fail(ROLL_AT_START_COLLIDES)
    if checker.collides(q_goal):
        return fail("the goal posture is in collision")
    if roll_at_goal and first_collision(checker, tail) is not None:
        return fail("turning the wrist roll at the goal collides")
    goal_mask = np.zeros(spec.shape, dtype=bool)
    for c in _linked_nodes(checker, spec, free, arrived, roll):
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
        path = np.vstack([lead, middle, tail])
        bad = first_collision(checker, path)
        if bad is None:
            return ArmPath(
                True,
                dedupe_path(path),
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


def risen_postures(
    checker: CollisionChecker, q_from: ArrayLike, *, step: float, max_rise: float
) -> Iterator[NDArray[np.float64]]:
    """The arm postures with the palm risen straight up from where ``q_from`` puts it,
    orientation kept, ``step`` (m) at a time up to ``max_rise`` (m), each IK started from the
    one before; the walk ends where a rise has no IK or collides by ``checker``."""
    q = np.asarray(q_from, dtype=float)
    p, R = checker.palm_pose(q)
    for k in range(1, round(max_rise / step) + 1):
        ik = checker.solve_ik(p + np.array([0.0, 0.0, k * step]), R, q)
        if not ik.found or first_collision(checker, np.stack([q, ik.q])) is not None:
            return
        q = ik.q
        yield q


def roll_turned_above(
    checker: CollisionChecker,
    q_start: ArrayLike,
    q_goal: ArrayLike,
    *,
    step: float,
    max_rise: float,
    resolution: int = DEFAULT_RESOLUTION,
) -> ArmPath | None:
    """A collision-free path from ``q_start`` to ``q_goal`` where the wrist roll cannot
    turn at the start (:data:`ROLL_AT_START_COLLIDES`: the fingers, or a held block, would sweep
    through a neighbour): the palm rises straight up, orientation kept, ``step`` (m) at a time,
    to the first height where the roll turns to ``q_goal``'s clear of everything and a harmonic
    path leads on from there (:func:`plan_arm_path`, the roll turning at its start as ever;
    the rise comes first in the returned path, whose reason says so). None when none is found
    within ``max_rise`` (m), or a rise collides or has no IK."""
    q_goal = np.asarray(q_goal, dtype=float)
    risen = [np.asarray(q_start, dtype=float)]
    for q in risen_postures(checker, q_start, step=step, max_rise=max_rise):
        risen.append(q)
        turned = np.array([*q[:ROLL], q_goal[ROLL]])
        if first_collision(checker, np.stack([q, turned])) is not None:
            continue
        on = plan_arm_path(checker, q, q_goal, resolution=resolution)
        if on.found:
            path = dedupe_path(np.vstack([np.stack(risen), on.path]))
            return replace(on, path=path, reason=f"{on.reason}, {ROLL_TURNED_ABOVE}")
    return None


def dedupe_path(path: NDArray[np.float64]) -> NDArray[np.float64]:
    """``path`` without postures that repeat the one before them."""
    keep = np.concatenate([[True], np.linalg.norm(np.diff(path, axis=0), axis=1) > 1e-9])
    return path[keep]


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
    dense = interpolate_path(path, max_joint_speed * CONTROL_PERIOD)
    for q in dense:
        world.set_arm_targets(q)
        world.step(steps)
        seen |= robot_contacts(world)
    for _ in range(round(settle / CONTROL_PERIOD)):
        world.step(steps)
        seen |= robot_contacts(world)
    err = float(np.abs(world.arm_qpos() - path[-1]).max())
    return Execution(tuple(sorted(seen)), err, world.time - t0)
