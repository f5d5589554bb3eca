"""Fine reach (section 5.2): "another harmonic motion controller that postures the hand so as to
minimize the distance between the fingertips and points projected over the object surface".

Each fingertip gets a harmonic function (Connolly & Grupen) on a 3-D grid around the target block:
the block, grown by :data:`OBSTACLE_MARGIN`, the other blocks and the table are obstacles; the goal
is the free space just outside the fingertip's surface point. Every control period the fingertip's
next position is a short step along the gradient (straight at the target once within
:data:`FINAL_APPROACH` of it); the four next positions become servo targets by mink's differential
IK (:func:`controllers.posture.solver.solve_posture`, arm and fingers), and the simulation runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.errors import ReachError
from controllers.planning.harmonic import GridSpec, HarmonicField, Interpolator, solve_harmonic
from controllers.posture.solver import solve_posture
from controllers.reach.coarse import ReachTarget
from controllers.timing import CONTROL_PERIOD, control_steps
from hand_sim import robot
from hand_sim.contacts import pad_object_forces
from hand_sim.world import TOUCH_TENDONS, World

#: Depth (m) below the block's top face of the highest default contact points, and the lowest
#: height (m) above the table they may have.
GRASP_DEPTH = 0.04
MIN_CONTACT_HEIGHT = 0.02
#: Depths (m below the block's top) a top grasp's contacts may take in the 3-D grasp model: from
#: GRASP_DEPTH to 6 cm.
#: Chosen by its effect on the physical study: docs/findings.md, "Depth of a top grasp's contacts".
TOP_GRASP_DEPTHS = (GRASP_DEPTH, 0.06)
#: Cell size (m) of the fingertip grids and their extent around the block (m).
FIELD_CELL = 0.005
FIELD_MARGIN_XY = 0.07
FIELD_BELOW = 0.06
FIELD_ABOVE = 0.10
#: Margin (m) of the grid around the fingertips and targets it must include.
FIELD_MARGIN = 0.03
#: Growth (m) of the block and the table in the fingertip grids (keeps the finger's skin off).
OBSTACLE_MARGIN = 0.006
#: Distance (m) of a fingertip's field goal outside its surface point (beyond the margin).
GOAL_STANDOFF = 0.001
#: The fingertips are steered this far (m) outside their surface points along the normal, so
#: that reaching touches the block without pushing it (the grasp controller squeezes later).
TOUCH_STANDOFF = 0.001
#: A fingertip stops when its pad feels more than this normal force (N): the touch guard.
TOUCH_GUARD = 0.05
#: Within this distance (m) of its target a fingertip moves straight at it.
FINAL_APPROACH = 0.02
#: Fingertip step (m) and IK iterations per control period.
TIP_STEP = 0.002
IK_ITERATIONS = 8
#: Default acceptance (m): every fingertip this close to its target ends the reach.
DEFAULT_TOLERANCE = 0.005
#: Simulated time (s) allowed before giving up.
MAX_TIME = 4.0


@dataclass(frozen=True, eq=False)
class SurfaceTargets:
    """Fingertip targets on the block's side faces, world frame, order ff, mf, rf, th."""

    points: NDArray[np.float64]  #: (4, 3) surface points
    normals: NDArray[np.float64]  #: (4, 3) outward unit normals (horizontal)
    theta: NDArray[np.float64]  #: (4,) contact coordinates (polar angle, object frame)


def _world_edges(target: ReachTarget) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Footprint vertices (k, 2) and outward edge normals (k, 2), world frame."""
    verts = target.footprint()
    ang = target.polygon.normal_angle + target.yaw
    return verts, np.stack([np.cos(ang), np.sin(ang)], axis=1)


def project_to_surface(
    target: ReachTarget,
    points: ArrayLike,
    *,
    depth: float = GRASP_DEPTH,
    table_z: float | None = None,
) -> SurfaceTargets:
    """ "Points projected over the object surface": the nearest points of the block's side faces
    to ``points`` (n, 3). Horizontally the nearest outline point; vertically the point's own
    height, kept at least ``depth`` below the top (and :data:`MIN_CONTACT_HEIGHT` above
    ``table_z`` when given), so a top approach touches the faces ``depth`` below the top and a
    lateral approach touches them at the fingertips' heights."""
    pts = np.asarray(points, dtype=float)
    p = pts[:, :2]
    verts, normals = _world_edges(target)
    a, b = verts, np.roll(verts, -1, axis=0)
    ab = b - a
    t = np.clip(np.einsum("nkd,kd->nk", p[:, None] - a, ab) / (ab * ab).sum(1), 0.0, 1.0)
    closest = a + t[..., None] * ab  # (n, k, 2)
    dist = np.linalg.norm(closest - p[:, None], axis=2)
    edge = np.argmin(dist, axis=1)
    xy = closest[np.arange(len(p)), edge]
    # at a vertex, t is 0 or 1: keep the edge whose normal faces the fingertip best
    n = normals[edge]
    z = np.minimum(pts[:, 2], target.top_z - depth)
    if table_z is not None:
        z = np.maximum(z, table_z + MIN_CONTACT_HEIGHT)
    return _targets(target, xy, n, z)


def _targets(
    target: ReachTarget, xy: NDArray[np.float64], n: NDArray[np.float64], z: ArrayLike
) -> SurfaceTargets:
    pts = np.column_stack([xy, np.broadcast_to(np.asarray(z, dtype=float), (len(xy),))])
    normals = np.column_stack([n, np.zeros(len(xy))])
    local = xy - np.asarray(target.position_xy)
    theta = np.arctan2(local[:, 1], local[:, 0]) - target.yaw
    return SurfaceTargets(pts, normals, np.mod(theta + np.pi, 2 * np.pi) - np.pi)


def contact_targets(
    target: ReachTarget, theta: ArrayLike, *, depth: float = GRASP_DEPTH
) -> SurfaceTargets:
    """Targets at contact coordinates ``theta`` (4,) of the block's polygon (e.g. from
    ``controllers.grasp``), at ``depth`` below the top."""
    frames = target.polygon.locate(np.asarray(theta, dtype=float))
    c, s = np.cos(target.yaw), np.sin(target.yaw)
    R = np.array([[c, -s], [s, c]])
    xy = frames.point @ R.T + np.asarray(target.position_xy)
    return _targets(target, xy, frames.normal @ R.T, target.top_z - depth)


@dataclass(frozen=True, eq=False)
class FingertipField:
    """A fingertip's harmonic function over the grid around the block."""

    spec: GridSpec
    field: HarmonicField
    target: NDArray[np.float64]  #: (3,) where the fingertip is steered: TOUCH_STANDOFF outside

    def direction(self, x: ArrayLike) -> NDArray[np.float64] | None:
        """Unit direction of steepest descent of ``u`` at world point ``x``; None outside the
        grid, in a goal cell, or where the potential is zero (in an obstacle, cut off from the
        goal)."""
        g = self.spec.to_grid(x)
        if np.any(g < 0) or np.any(g > np.asarray(self.spec.shape) - 1):
            return None
        if self.field.goal[tuple(int(i) for i in np.rint(g))]:
            return None  # arrived in the goal region: the final approach is straight
        value, grad = Interpolator(self.field.log_phi)(g)
        world_grad = grad / self.spec.spacing
        norm = float(np.linalg.norm(world_grad))
        if not np.isfinite(value) or norm == 0.0:
            return None
        return world_grad / norm


def obstacle_grid(
    world: World, target: ReachTarget, spec: GridSpec, target_name: str | None = None
) -> NDArray[np.bool_]:
    """Free cells of the fingertip grid: outside every block grown by OBSTACLE_MARGIN and above
    the table top plus the margin. Block ``target_name`` is ``target`` as perceived; the other
    blocks are where the world has them now."""
    nodes = spec.node_configs()
    free = nodes[:, 2] > world.scene.table.height + OBSTACLE_MARGIN
    for block in world.scene.blocks:
        other = target if block.name == target_name else ReachTarget.from_world(world, block.name)
        verts, normals = _world_edges(other)
        signed = (nodes[:, None, :2] - verts[None]) @ normals.T  # (N, k, k)
        edge_dist = np.einsum("nkk->nk", signed)
        inside = edge_dist.max(axis=1) < OBSTACLE_MARGIN
        below_top = nodes[:, 2] < other.top_z + OBSTACLE_MARGIN
        free &= ~(inside & below_top)
    return free.reshape(spec.shape)


def fingertip_fields(
    world: World,
    target: ReachTarget,
    targets: SurfaceTargets,
    *,
    cell: float = FIELD_CELL,
    include: ArrayLike | None = None,
    target_name: str | None = None,
    standoff: float = TOUCH_STANDOFF,
) -> list[FingertipField]:
    """One harmonic field per fingertip over a grid around the target block (and around the
    points ``include`` (n, 3), e.g. the fingertips now, plus FIELD_MARGIN). Each fingertip is
    steered ``standoff`` m outside its surface point; block ``target_name`` is ``target`` as
    perceived in the obstacle grid."""
    verts, _ = _world_edges(target)
    lo = np.array([*(verts.min(axis=0) - FIELD_MARGIN_XY), target.top_z - FIELD_BELOW])
    hi = np.array([*(verts.max(axis=0) + FIELD_MARGIN_XY), target.top_z + FIELD_ABOVE])
    extra = targets.points if include is None else np.vstack([targets.points, include])
    lo = np.minimum(lo, extra.min(axis=0) - FIELD_MARGIN)
    hi = np.maximum(hi, extra.max(axis=0) + FIELD_MARGIN)
    lo[2] = max(lo[2], world.scene.table.height - FIELD_MARGIN)
    shape = tuple(int(np.ceil((h - lo_) / cell)) + 1 for lo_, h in zip(lo, hi, strict=True))
    spec = GridSpec(tuple(lo), tuple(lo + (np.asarray(shape) - 1) * cell), shape)
    free = obstacle_grid(world, target, spec, target_name)
    nodes = spec.node_configs().reshape(*spec.shape, 3)
    out = []
    for p, n in zip(targets.points, targets.normals, strict=True):
        goal_point = p + n * (max(OBSTACLE_MARGIN, standoff) + GOAL_STANDOFF + cell)
        goal = (np.linalg.norm(nodes - goal_point, axis=-1) <= cell) & free
        if not goal.any():
            raise ReachError(
                f"fingertip target {p.round(4).tolist()} has no free grid cell near it"
            )
        out.append(FingertipField(spec, solve_harmonic(free, goal), p + standoff * n))
    return out


@dataclass(frozen=True, eq=False)
class FineReachResult:
    """Outcome of :func:`fine_reach`: ``reached`` when every fingertip ended within the
    tolerance of its target (measured in the simulation)."""

    reached: bool
    tip_error: NDArray[np.float64]  #: (4,) m, final
    targets: SurfaceTargets
    periods: int  #: control periods run
    max_penetration: float  #: deepest hand-block contact seen (m, >= 0)
    other_contacts: tuple[tuple[str, str], ...]  #: robot contacts with anything but the target
    stopped_on_touch: tuple[str, ...] = ()  #: fingers the touch guard stopped before their target


def _reach_result(
    err: NDArray[np.float64],
    stopped: NDArray[np.bool_],
    tolerance: float,
    targets: SurfaceTargets,
    periods: int,
    depth: float,
    others: set[tuple[str, str]],
) -> FineReachResult:
    """A reach's result: reached when every fingertip is within ``tolerance`` of its goal
    (``err``, m) or was stopped by the touch guard."""
    return FineReachResult(
        reached=bool(np.all((err < tolerance) | stopped)),
        tip_error=err,
        targets=targets,
        periods=periods,
        max_penetration=depth,
        other_contacts=tuple(sorted(others)),
        stopped_on_touch=tuple(f for f, s in zip(robot.FINGERS, stopped, strict=True) if s),
    )


def _hand_contacts(world: World, target_body: int) -> tuple[float, set[tuple[str, str]]]:
    m, d = world.model, world.data
    depth, others = 0.0, set()
    for c in d.contact[: d.ncon]:
        bodies = [int(m.geom_bodyid[g]) for g in (c.geom1, c.geom2)]
        on_robot = [m.body(b).name.startswith(robot.ARM_PREFIX) for b in bodies]
        if on_robot[0] == on_robot[1]:
            continue
        if target_body in bodies:
            depth = max(depth, -float(c.dist))
        else:
            others.add((m.geom(c.geom1).name, m.geom(c.geom2).name))
    return depth, others


def touch_guard(world: World) -> NDArray[np.bool_]:
    """(4,) fingers the touch guard stops: with touch pads, a pad pressing on anything but the
    robot above :data:`TOUCH_GUARD` (:func:`hand_sim.contacts.pad_object_forces`); the tendon
    hand, which senses no contact directly, a finger whose tensions need a pad force above it
    whatever its stuck joints' friction (``World.touch_felt``)."""
    if world.touch_source == TOUCH_TENDONS:
        return world.touch_felt(TOUCH_GUARD)
    return world.touch_felt(TOUCH_GUARD, forces=pad_object_forces(world))


def fine_reach(
    world: World,
    target_name: str,
    targets: SurfaceTargets | None = None,
    *,
    seen: ReachTarget | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    max_time: float = MAX_TIME,
    standoff: float = TOUCH_STANDOFF,
    model: mujoco.MjModel | None = None,
    touchable: str | None = None,
) -> FineReachResult:
    """Bring the fingertips to ``targets`` on block ``target_name`` (default: the fingertips'
    current positions projected on its side faces, :func:`project_to_surface`), following each
    fingertip's harmonic field, in the simulation. ``seen`` is the block as perceived (e.g.
    :meth:`ReachTarget.from_object_model`); default: where the physics has it.

    Each fingertip is steered ``standoff`` m outside its surface point. Touch guard: a fingertip
    whose pad presses on anything but the hand itself (above :data:`TOUCH_GUARD`; the tendon hand:
    whose tensions need a pad force above it, :func:`touch_guard`) stops where it is, so a finger
    arriving early does not push the block before the others arrive.

    ``model`` (e.g. the planning model holding the perceived block,
    :mod:`controllers.planning.belief`) turns on collision avoidance in the IK: the hand's links
    keep clear of the table and the blocks, and only the pads may touch the geom named
    ``touchable``. Arm and hand follow the fields."""
    if tolerance <= 0:
        raise ReachError(f"tolerance must be > 0 m, got {tolerance}")
    target = ReachTarget.from_world(world, target_name) if seen is None else seen
    target_body = world.block_body_id(target_name)
    tips = world.fingertip_positions()
    if targets is None:
        targets = project_to_surface(target, tips, table_z=world.scene.table.height)
    fields = fingertip_fields(
        world, target, targets, include=tips, target_name=target_name, standoff=standoff
    )
    goals = targets.points + standoff * targets.normals
    stopped = np.zeros(len(tips), dtype=bool)
    steps = control_steps(world)
    depth, others = 0.0, set()
    periods = 0
    for _ in range(round(max_time / CONTROL_PERIOD)):
        tips = world.fingertip_positions()
        stopped |= touch_guard(world)
        err = np.linalg.norm(tips - goals, axis=1)
        if np.all((err < 0.5 * tolerance) | stopped):
            break
        periods += 1
        nxt = np.empty_like(tips)
        for f, (tip, ff) in enumerate(zip(tips, fields, strict=True)):
            to_goal = ff.target - tip
            dist = float(np.linalg.norm(to_goal))
            direction = None if dist < FINAL_APPROACH else ff.direction(tip)
            if direction is None:
                direction = to_goal / max(dist, 1e-12)
            nxt[f] = tip if stopped[f] else tip + direction * min(TIP_STEP, dist)
        sol = solve_posture(
            world,
            nxt,
            optimize=False,
            reach_iterations=IK_ITERATIONS,
            model=model,
            avoid_collisions=model is not None,
            touchable=touchable,
        )
        # position servos sag under load: add their steady-state error to the new targets
        world.set_arm_targets(sol.arm_q + 0.5 * (world.arm_targets() - world.arm_qpos()))
        world.set_hand_targets(sol.hand_q + 0.5 * (world.hand_targets() - world.hand_qpos()))
        world.step(steps)
        d, o = _hand_contacts(world, target_body)
        depth, others = max(depth, d), others | o
    err = np.linalg.norm(world.fingertip_positions() - goals, axis=1)
    return _reach_result(err, stopped, tolerance, targets, periods, depth, others)


#: Simulated time (s) of a reach along the fingers' backing-off lines
#: (:func:`reach_along_normals`), and the time (s) the servos then settle.
NORMAL_REACH_TIME = 1.0
NORMAL_SETTLE_TIME = 0.3


def reach_along_normals(
    world: World,
    target_name: str,
    hand_to: ArrayLike,
    targets: SurfaceTargets,
    *,
    standoff: float = TOUCH_STANDOFF,
    tolerance: float = DEFAULT_TOLERANCE,
    duration: float = NORMAL_REACH_TIME,
) -> FineReachResult:
    """Fine reach of a hand whose palm already faces its contacts and whose posture ``hand_to``
    (16,) puts each fingertip ``standoff`` outside its contact (``targets``) on block
    ``target_name``: the hand's servo targets move on the straight joint-space line from where they
    are to ``hand_to``, the arm held. When the hand starts backed off from ``hand_to``'s contact
    posture along the fingers' squeeze directions (:func:`controllers.hand.grip.backed_off_hand`),
    that line brings each fingertip in along its contact's normal, where the approach was checked
    clear: unlike the harmonic fields' IK (:func:`fine_reach`), no link sweeps round the block or
    into the table. The touch guard (:func:`touch_guard`) holds a finger that touches early where it
    is. The result's ``tip_error`` is each fingertip's distance from its goal along the contact's
    normal."""
    if tolerance <= 0:
        raise ReachError(f"tolerance must be > 0 m, got {tolerance}")
    q0 = world.hand_targets()
    q1 = np.asarray(hand_to, dtype=float)
    goals = targets.points + standoff * targets.normals
    steps = control_steps(world)
    held = q0.copy()
    stopped = np.zeros(len(robot.FINGERS), dtype=bool)
    n = max(1, round(duration / CONTROL_PERIOD))
    settle = round(NORMAL_SETTLE_TIME / CONTROL_PERIOD)
    target_body = world.block_body_id(target_name)
    depth, others = 0.0, set()
    periods = 0
    for k in range(1, n + settle + 1):
        touched = touch_guard(world) & ~stopped
        for f in np.flatnonzero(touched):
            # a finger that touched holds the joints it has reached
            held[robot.FINGER_JOINT_SLICES[f]] = world.hand_qpos()[robot.FINGER_JOINT_SLICES[f]]
        stopped |= touched
        s = 0.5 - 0.5 * np.cos(np.pi * min(k, n) / n)
        q = q0 + s * (q1 - q0)
        for f in np.flatnonzero(stopped):
            q[robot.FINGER_JOINT_SLICES[f]] = held[robot.FINGER_JOINT_SLICES[f]]
        world.set_hand_targets(q)
        world.step(steps)
        periods += 1
        d, o = _hand_contacts(world, target_body)
        depth, others = max(depth, d), others | o
    # along the normal: the posture took each contact on the fingertip's rounded end wherever
    # its pad faced the face, not at the tip site
    err = np.abs(np.sum((world.fingertip_positions() - goals) * targets.normals, axis=1))
    return _reach_result(err, stopped, tolerance, targets, periods, depth, others)
