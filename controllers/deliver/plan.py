"""Delivery (section 5.2, "Deliver"): carry a grasped block to a place point on the table.

"The path is computed by the same harmonic path planning algorithm used in the coarse reach
module" (:func:`controllers.reach.arm_path.plan_arm_path`), with the block moving rigidly with the
palm: straight up to :data:`CARRY_HEIGHT` (higher when a taller neighbour is still within the
planning clearance there: :func:`rise_until_clear`), a harmonic transit, and straight down until
the block hovers :data:`SET_DOWN_HOVER` above the table (the rest of the set-down is sensed,
:mod:`controllers.deliver.carry`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq

from controllers.deliver.set_down_aim import MAX_AIM_OFFSET, DescentMiss, descent_miss
from controllers.errors import ReachError
from controllers.planning.cspace import (
    DEFAULT_CLEARANCE,
    CollisionChecker,
    IKResult,
    rotation_error,
)
from controllers.reach.arm_path import (
    DEFAULT_RESOLUTION,
    ROLL_AT_START_COLLIDES,
    ArmPath,
    dedupe_path,
    first_collision,
    plan_arm_path,
    risen_postures,
    roll_turned_above,
)
from controllers.reach.coarse import seeded_postures
from hand_sim import robot
from hand_sim.world import World

#: Delivery: height (m) of the carried block's bottom above the table during the transit (not
#: the grasp's lift, :data:`controllers.deliver.carry.LIFT_HEIGHT`), and where the planned set-down
#: ends (the last part is sensed: controllers.deliver.carry).
CARRY_HEIGHT = 0.05
SET_DOWN_HOVER = 0.02
#: Clearance (m) the hand keeps from everything but the table all the way down to the hover.
SET_DOWN_CLEARANCE = 0.003
#: When the block held at the carry height still leaves the hand within the planning clearance
#: of something (a neighbour taller than the block, which the hand grasped beside it), the palm
#: rises further, RISE_STEP at a time and at most MAX_EXTRA_RISE (m), keeping
#: SET_DOWN_CLEARANCE on the way, until the transit can start clear.
RISE_STEP = 0.02
MAX_EXTRA_RISE = 0.30
#: Yaws (rad) the carried block may be set down at beyond the two first tried (as held, and
#: turned with the arm's waist): turned further about the vertical through its centre, nearest
#: first. The task asks for a place point, not a yaw (the judge measures the distance and the
#: tilt), and a hand turned about the block may clear a neighbour the first two do not.
SET_DOWN_TURNS = tuple(np.deg2rad([45.0, -45.0, 90.0, -90.0, 135.0, -135.0, 180.0]))
#: Sine of the held hand's tool axis's tilt from the vertical below which any turn about the
#: vertical is within the 5-joint arm's reach (:func:`reachable_turns`). When no turn of
#: SET_DOWN_TURNS gives a set-down, each is moved to the nearest turn the arm can hold a hand
#: tilted more than this at, and those are tried.
ALIGNED_TILT = 1e-3
#: Set-downs aimed off the place point tried at most (controllers.deliver.set_down_aim).
MAX_AIMED = 12
#: Turns (rad) closer than this are the same turn.
SAME_TURN = 1e-3
#: Turns (over a full circle) sampled to bracket the reachable turns before Brent's method.
TURN_SAMPLES = 720


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
    #: "" when the set-down keeps the planning clearance with the hand as it holds the block
    #: (or turned with the waist), else how it is lowered instead (:func:`_set_down_path` with
    #: ``rise``) and how far the hand is turned about the place point, "; "-separated
    set_down: str = ""


def _rotate_z(angle: float) -> NDArray[np.float64]:
    """Rotation by ``angle`` (rad) about the world z axis."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def reachable_turns(
    pivot: NDArray[np.float64],
    shift: NDArray[np.float64],
    flange: NDArray[np.float64],
    axis: NDArray[np.float64],
    base: NDArray[np.float64],
) -> list[float] | None:
    """The turns (rad) at which the 5-joint arm can hold the hand turned about the vertical
    through ``pivot`` (the held block's centre) and moved by ``shift``; None when any turn is.

    The arm's shoulder, elbow and wrist pitch turn about parallel horizontal axes, so its tool
    axis (the wrist roll's, through the flange) always lies in a vertical plane through the
    waist axis at ``base``. Turning a hand that points straight down keeps it there at any turn
    (None); a tilted hand (the held grasp's palm ``ALIGNED_TILT`` or more off the vertical, or a
    lateral grasp's horizontal palm) turned about the vertical leaves that plane except where
    the horizontal projection of its tool axis, through the moved ``flange`` along the turned
    ``axis``, passes through ``base``: the zeros of a cross product over the turn, bracketed on
    :data:`TURN_SAMPLES` turns and found by Brent's method."""
    a = np.asarray(axis, dtype=float)[:2]
    if np.linalg.norm(a) < ALIGNED_TILT:
        return None
    lever = np.asarray(flange, dtype=float)[:2] - pivot[:2]
    origin = pivot[:2] + shift[:2] - base[:2]

    def off_plane(t: float) -> float:
        c, s = np.cos(t), np.sin(t)
        rot = np.array([[c, -s], [s, c]])
        f, d = origin + rot @ lever, rot @ a
        return float(f[0] * d[1] - f[1] * d[0])

    grid = np.linspace(-np.pi, np.pi, TURN_SAMPLES + 1)
    values = np.array([off_plane(t) for t in grid])
    return [
        float(brentq(off_plane, grid[i], grid[i + 1])) if values[i + 1] != 0.0 else grid[i + 1]
        for i in np.flatnonzero(values[:-1] * values[1:] <= 0.0)
    ]


def reachable_turn(
    turn: float,
    pivot: NDArray[np.float64],
    shift: NDArray[np.float64],
    flange: NDArray[np.float64],
    axis: NDArray[np.float64],
    base: NDArray[np.float64],
) -> float:
    """The turn (rad) nearest ``turn`` of :func:`reachable_turns` (``turn`` itself when any
    turn is reachable or none is)."""
    return _nearest_turn(turn, reachable_turns(pivot, shift, flange, axis, base))


def _wrap(angle: ArrayLike) -> NDArray[np.float64]:
    """``angle`` (rad) wrapped into (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(angle, dtype=float)))


def _nearest_turn(turn: float, turns: list[float] | None) -> float:
    """Of ``turns`` the one nearest ``turn`` round the circle; ``turn`` for None or none."""
    if not turns:
        return float(turn)
    gap = np.abs(_wrap(np.array(turns) - turn))
    return float(turns[int(np.argmin(gap))])


def rise_until_clear(
    checker: CollisionChecker, tight: CollisionChecker, q_from: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """Postures of the palm risen straight up from ``q_from`` (k, 5), ending at the first one
    clear of everything by ``checker``'s clearance, each rise collision-free by ``tight``'s;
    None when none is found within :data:`MAX_EXTRA_RISE` (or the arm cannot rise)."""
    risen = []
    for q in risen_postures(tight, q_from, step=RISE_STEP, max_rise=MAX_EXTRA_RISE):
        risen.append(q)
        if not checker.collides(q):
            return np.stack(risen)
    return None


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
    nearer: bool = True,
    qpos: ArrayLike | None = None,
    with_transit: bool = True,
    check_lift: bool = True,
) -> DeliveryPlan:
    """Plan to carry ``block`` (held by the hand now, on the table or already lifted) to
    ``place_xy`` on the table (section 5.2, "Deliver": "the path is computed by the same harmonic
    path planning algorithm used in the coarse reach module").

    Heights come from the table and the block's height (``block_height``, e.g. the perceived
    one; default the scene's), not from where the block is now: the transit carries the block's
    bottom at least ``lift`` above the table, and the path ends with it ``hover`` above the table
    at the place point (the rest of the set-down is sensed). Postures are checked with the block
    moving rigidly with the palm; where it is within ``2 * clearance`` of the table (lift-off and
    set-down) the block-table pair is exempt.

    ``nearer``: when no turn keeps ``clearance``, try them again lowered at
    :data:`SET_DOWN_CLEARANCE` (:func:`_set_down_path`); off, such a place point fails.
    ``qpos``: the configuration the plan starts from, the block held as it is there (default
    the world's now). Without ``with_transit`` only the lift and the set-down are planned, not
    the harmonic transit between them (whether a grasp can set its block down at all); the
    plan's path is then the lift followed by the set-down, a check's, not one to follow.
    Without ``check_lift`` the lift is solved but not checked for collision (Deliver's own lift
    is sensed as it rises, not planned: whether a grasp can set its block down asks only of the
    way from the lifted block to the place point)."""
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
    state = np.array(world.data.qpos if qpos is None else qpos, dtype=float)
    hand_q = state[robot.hand_qpos_addresses(world.model)]
    checker = CollisionChecker(world, clearance=clearance, hand_q=hand_q, carried=block, qpos=state)
    # the set-down's last 2 * clearance is exempt above (the block nears the table); the hand's
    # links must still keep SET_DOWN_CLEARANCE from everything else all the way down (a finger's
    # middle link may otherwise land on a block delivered earlier, as in clutter5's third cycle)
    descent = CollisionChecker(
        world, clearance=SET_DOWN_CLEARANCE, hand_q=hand_q, carried=block, qpos=state
    )
    q0 = state[robot.arm_qpos_addresses(world.model)]
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
    lead = [q0]
    if up[2] > 1e-4:
        lift_ik = checker.solve_ik(p0 + up, R0, q0)
        # the block may touch the table in the first 2 * clearance of the lift
        clear = min(up[2], 2.0 * clearance)
        free_ik = checker.solve_ik(p0 + np.array([0.0, 0.0, clear]), R0, q0)
        if not (lift_ik.found and free_ik.found):
            return fail("the block cannot be lifted straight up from here")
        if check_lift and first_collision(checker, np.stack([free_ik.q, lift_ik.q])) is not None:
            return fail("lifting the block collides")
        start = lift_ik.q
        lead.append(start)
    if checker.collides(start):
        risen = rise_until_clear(checker, descent, start)
        if risen is not None:
            lead += list(risen)
            start = risen[-1]
            carry_z = float(checker.carried_pose(start)[0][2])
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id]
    turn = float(
        np.arctan2(place[1] - base[1], place[0] - base[0])
        - np.arctan2(b0[1] - base[1], b0[0] - base[0])
    )
    shift = np.array([*(place - b0[:2]), carry_z - b0[2]])
    drop = np.array([0.0, 0.0, down_z - carry_z])
    first_failure: DeliveryPlan | None = None
    # first every turn with the hand clear of everything by the planning clearance at the carry
    # height and on the way down; then, if none is, every turn again lowered at
    # SET_DOWN_CLEARANCE, from above what the hand would pass within the planning clearance of
    # at the carry height (a neighbour as tall as the block); then both again at the turns a
    # tilted hand can be held at (_held_turns)
    seed = np.array([start[0] + turn, *start[1:]])
    turns = [0.0, turn, *(turn + t for t in SET_DOWN_TURNS)]
    passes = (False, True) if nearer else (False,)

    # a lowered way down that passed something by less than SET_DOWN_CLEARANCE: the pair, the
    # turn, the IK seed and how far that set-down was already aimed off the place point
    misses: list[tuple[DescentMiss, float, NDArray[np.float64], NDArray[np.float64]]] = []
    on_point = np.zeros(2)

    def candidates() -> Iterator[
        tuple[bool, float, NDArray[np.float64], NDArray[np.float64], DescentMiss | None]
    ]:
        yield from ((rise, t, seed, on_point, None) for rise in passes for t in turns)
        held = _held_turns(checker, q0, turns, b0, shift, base)
        seeds = [_turned_seed(checker, seed, t - turn, _rotate_z(t) @ R0) for t in held]
        yield from (
            (rise, t, s, on_point, None)
            for rise in passes
            for t, s in zip(held, seeds, strict=True)
        )
        # then each of those aimed off the place point, away from what it passed too near
        # (controllers.deliver.set_down_aim), in the order they were found; a set-down aimed off
        # that passes something else too near is aimed further, within MAX_AIM_OFFSET in all
        tried = 0
        while tried < min(len(misses), MAX_AIMED):  # misses grows as aimed ones are tried
            miss, t, s, aim = misses[tried]
            tried += 1
            offset = miss.offset()
            if offset is not None and np.linalg.norm(aim + offset) <= MAX_AIM_OFFSET:
                yield True, t, s, aim + offset, miss

    for candidate in candidates():
        rise, t, ik_seed, aim, cause = candidate
        R = _rotate_z(t) @ R0
        # the palm moves so that the block's centre lands above the place point (or the point
        # the set-down is aimed at)
        p_high = b0 + shift + np.array([*aim, 0.0]) + R @ R0.T @ (p0 - b0)
        found: list[DescentMiss] = []
        set_down = _set_down_path(
            checker, descent, p_high, drop, R, ik_seed, rise=rise, misses=found
        )
        misses.extend((miss, t, ik_seed, aim) for miss in found)
        if set_down is None:
            continue
        if not with_transit:
            break
        # a set-down posture the transit cannot reach (e.g. its wrist roll cannot turn beside
        # a tall neighbour at the start) gives way to the next one
        transit = plan_arm_path(checker, start, set_down[0], resolution=resolution)
        if not transit.found and transit.reason == ROLL_AT_START_COLLIDES:
            # the roll turns as ever at the transit's start, only higher up
            above = roll_turned_above(
                checker,
                start,
                set_down[0],
                step=RISE_STEP,
                max_rise=MAX_EXTRA_RISE,
                resolution=resolution,
            )
            transit = above or transit
        if transit.found:
            break
        first_failure = first_failure or fail(f"transit: {transit.reason}", transit)
    else:
        return first_failure or fail("no collision-free posture above the place point")
    down = set_down[-1]
    if with_transit:
        path = dedupe_path(np.vstack([*lead[:-1], transit.path, set_down[1:]]))
    else:
        transit, path = None, dedupe_path(np.vstack([*lead, set_down]))
    block_goal, _ = checker.carried_pose(down)
    how = []
    if rise:
        risen = checker.palm_pose(set_down[0])[0][2] - checker.palm_pose(set_down[-2])[0][2]
        how.append(
            f"lowered keeping {SET_DOWN_CLEARANCE * 1000:.0f} mm (not {clearance * 1000:.0f} "
            "mm) from everything"
            + (f", from {risen * 100:.0f} cm above the carry height" if risen > 1e-6 else "")
        )
    if cause is not None:
        how.append(
            f"aimed {np.linalg.norm(aim) * 1000:.1f} mm off the place point (a way down had "
            f"passed {cause.describe()})"
        )
    extra = float(_wrap(t - turn))
    if abs(extra) > SAME_TURN and abs(_wrap(t)) > SAME_TURN:
        how.append(f"turned {np.degrees(extra):+.0f} deg about the place point beyond the waist")
    return DeliveryPlan(True, path, transit, block_goal, "reached goal", "; ".join(how))


def _held_turns(
    checker: CollisionChecker,
    q0: NDArray[np.float64],
    turns: list[float],
    pivot: NDArray[np.float64],
    shift: NDArray[np.float64],
    base: NDArray[np.float64],
) -> list[float]:
    """Each of ``turns`` beyond the first two moved to the nearest turn the arm can hold the
    hand at (:func:`reachable_turns`, the hand as it is at ``q0``), once each, without the first
    two (within 1 mrad: the waist already holds the hand at those). One may equal a turn of
    ``turns``: it is tried again from another IK seed (:func:`_turned_seed`)."""
    flange = checker.model.body(robot.arm_name("flange")).id
    checker.palm_pose(q0)
    flange_at = checker.data.xpos[flange].copy()
    axis = checker.data.xmat[flange, 2::3].copy()
    reachable = reachable_turns(pivot, shift, flange_at, axis, base)
    held: list[float] = []
    for t in turns[2:]:
        h = _nearest_turn(t, reachable)
        if all(abs(_wrap(h - u)) > SAME_TURN for u in [*turns[:2], *held]):
            held.append(h)
    return held


def _turned_seed(
    checker: CollisionChecker, seed: NDArray[np.float64], extra: float, R: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The IK seed for a set-down with the palm at orientation ``R``, turned ``extra`` (rad)
    about the vertical beyond the waist's turn: ``seed`` with its wrist roll turned by ``extra``
    one way or the other, whichever puts the palm nearer ``R`` (the damped least squares from
    ``seed`` itself stalls far from a large turn)."""
    best, error = seed, np.inf
    for sign in (1.0, -1.0):
        q = seed.copy()
        q[-1] = np.clip(q[-1] + sign * extra, *checker.arm_limits[-1])
        e = float(np.linalg.norm(rotation_error(R, checker.palm_pose(q)[1])))
        if e < error:
            best, error = q, e
    return best


def set_down_ik(
    checker: CollisionChecker,
    p_high: NDArray[np.float64],
    R: NDArray[np.float64],
    seed: NDArray[np.float64],
) -> IKResult:
    """The arm posture holding the palm at ``p_high`` with orientation ``R``: by the damped least
    squares from ``seed`` (the transit's start turned with the waist), and where that stalls or
    collides, from the coarse reach's elbow-up seeds
    (:func:`controllers.reach.coarse.seeded_postures`, ``seed``'s wrist roll), the collision-free
    solution nearest ``seed``.

    From ``seed`` alone the least squares stalls where the waist's turn carries it past its
    limit: a lateral hand held with the waist near its end stop and turned further (the joint
    clips it, and the palm stays tens of centimetres short), or where its elbow folds the
    forearm into the palm (docs/task_cycle.md)."""
    first = checker.solve_ik(p_high, R, seed)
    if first.found and not checker.collides(first.q):
        return first
    near = min(
        seeded_postures(checker, p_high, R, (seed[-1],)),
        key=lambda ik: float(np.linalg.norm(ik.q - seed)),
        default=None,
    )
    return first if near is None else near


def _set_down_path(
    checker: CollisionChecker,
    descent: CollisionChecker,
    p_high: NDArray[np.float64],
    drop: NDArray[np.float64],
    R: NDArray[np.float64],
    seed: NDArray[np.float64],
    *,
    rise: bool,
    misses: list[DescentMiss] | None = None,
) -> NDArray[np.float64] | None:
    """Arm postures (k, 5) from the transit's goal down to the set-down's hover, with the palm
    at ``p_high`` (the carry height) and orientation ``R`` above the place point, or None.

    Without ``rise`` the transit ends at ``p_high``, clear by ``checker``'s clearance, and the
    set-down keeps that clearance until its last 2 * clearance (where the block nears the table)
    and ``descent``'s all the way. With ``rise`` the way down keeps only ``descent``'s
    clearance, and the posture at ``p_high`` may be within ``checker``'s of something: the
    transit then ends above it, where the hand is clear (:func:`rise_until_clear`). A way down
    that passes something nearer than ``descent``'s clearance appends the closest pair to
    ``misses`` (:func:`controllers.deliver.set_down_aim.descent_miss`), when given."""
    clearance = checker.clearance
    h = set_down_ik(checker, p_high, R, seed)
    d = checker.solve_ik(p_high + drop, R, h.q)
    if not (h.found and d.found):
        return None
    lowered = np.stack([h.q, d.q])
    if not rise:
        # the set-down may graze the table only in its last 2 * clearance
        near = checker.solve_ik(p_high + drop + np.array([0.0, 0.0, 2.0 * clearance]), R, h.q)
        if (
            checker.collides(h.q)
            or not near.found
            or first_collision(checker, np.stack([h.q, near.q])) is not None
            or first_collision(descent, lowered) is not None
        ):
            return None
        return lowered
    if first_collision(descent, lowered) is not None:
        if misses is not None:
            miss = descent_miss(descent, lowered)
            if miss is not None:
                misses.append(miss)
        return None
    if not checker.collides(h.q):
        return lowered  # clear at the carry height, the way down only at SET_DOWN_CLEARANCE
    risen = rise_until_clear(checker, descent, h.q)
    if risen is None:
        return None
    return np.vstack([risen[::-1], lowered])
