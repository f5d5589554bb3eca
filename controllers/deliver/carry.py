"""Deliver (section 5.2): lift the grasped block, carry it along a harmonic path, lower it until the
table takes its weight, and move the hand clear after the release.

Every motion of the arm here is a sequence of servo targets from the arm's inverse kinematics
(:class:`controllers.planning.cspace.CollisionChecker`) along a smooth (cosine) time profile, and
during a lift, carry or set-down the grip holds the fingers' servo targets
(:class:`controllers.hand.grip.Grip`). What happened is measured in the simulation, never read back
from a target: the block's rise against the palm's (slip), the wrist force/torque sensor (the table
taking the weight).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.errors import ReachError
from controllers.hand.grip import Grip
from controllers.planning.cspace import CollisionChecker
from controllers.timing import CONTROL_PERIOD, control_steps
from hand_sim import robot
from hand_sim.world import World

#: Lift: height (m) and duration (s); the block must rise with the palm within SLIP_TOLERANCE.
LIFT_HEIGHT = 0.10
LIFT_TIME = 1.5
SLIP_TOLERANCE = 0.01
#: Carrying: largest joint speed (rad/s) and acceleration (rad/s^2) along the path (a trapezoidal
#: speed profile: a carried block swings in the grip at every jerk).
CARRY_SPEED = 0.4
CARRY_ACCELERATION = 0.6
#: Set-down: lowering speed (m/s), the furthest it lowers (m) and the share of the block's weight
#: the table must take (from the wrist sensor) to count as supported.
LOWER_SPEED = 0.02
MAX_LOWER = 0.08
SUPPORTED_SHARE = 0.5
#: After the set-down the hand may push the block into the table (the arm's servos lag behind the
#: lowering): the palm rises in steps (m), each given UNLOAD_SETTLE (s) to settle, until the push
#: is below the tolerance (N), at most MAX_UNLOAD (m).
UNLOAD_STEP = 0.0002
UNLOAD_SETTLE = 0.1
UNLOAD_TOLERANCE = 1.0
MAX_UNLOAD = 0.005
#: Retreat: how far (m) the palm backs off along its approach axis, then rises, and the time each
#: takes (s).
RETREAT_BACK = 0.06
RETREAT_UP = 0.08
RETREAT_TIME = 1.0
#: A hand beside the block (a lateral grasp) first rises until its lowest fingertip is this far
#: (m) above the block's top (:func:`retreat`).
RETREAT_TOP_MARGIN = 0.01
#: Pause (s) after each motion of Deliver (lift, carry, set-down, unload, retreat), the grip
#: regulating if the hand holds the block: shorter than the servos' settling time after a reach
#: (:data:`controllers.timing.SERVO_SETTLE_TIME`).
DELIVER_SETTLE_TIME = 0.3


def _hold(world: World, grip: Grip | None, seconds: float) -> None:
    for _ in range(max(0, round(seconds / CONTROL_PERIOD))):
        if grip is not None:
            grip.regulate(world, CONTROL_PERIOD)
        world.step(control_steps(world))


def move_palm(
    world: World,
    checker: CollisionChecker,
    offset: ArrayLike,
    duration: float,
    *,
    grip: Grip | None = None,
    stop: Callable[[World], bool] | None = None,
) -> bool:
    """Move the palm by ``offset`` (3,) m in a straight line, orientation kept, over ``duration``
    s (cosine profile), regulating ``grip`` if given; stop early when ``stop(world)`` is true.
    Returns whether the whole move was made. Raises :class:`ReachError` when the arm's inverse
    kinematics cannot follow the line."""
    d = np.asarray(offset, dtype=float)
    # from the commanded posture: the servos sag under the hand's weight, and starting from the
    # measured one would first move the arm by that sag
    p0, R0 = checker.palm_pose(world.arm_targets())
    n = max(1, round(duration / CONTROL_PERIOD))
    seed = world.arm_targets()
    for k in range(1, n + 1):
        s = 0.5 - 0.5 * np.cos(np.pi * k / n)
        ik = checker.solve_ik(p0 + s * d, R0, seed)
        if not ik.found:
            raise ReachError(
                f"the arm cannot move the palm {np.linalg.norm(d) * 100:.0f} cm along "
                f"{np.round(d / max(np.linalg.norm(d), 1e-12), 2).tolist()} from here "
                f"(IK error {ik.position_error * 1000:.1f} mm at {s:.0%})"
            )
        seed = ik.q
        world.set_arm_targets(ik.q)
        if grip is not None:
            grip.regulate(world, CONTROL_PERIOD)
        world.step(control_steps(world))
        if stop is not None and stop(world):
            return False
    return True


@dataclass(frozen=True)
class LiftResult:
    """Rise (m) of the palm and of the block during :func:`lift`, and their difference; how far
    (m) each fingertip moved in the palm's frame (4,), ff, mf, rf, th: sensed, by the hand's
    kinematics (a held block keeps the pads where they pressed; one that turns or slides in the
    hand carries them along as the fingers keep pressing)."""

    palm_rise: float
    block_rise: float
    tip_motion: NDArray[np.float64] = field(default_factory=lambda: np.zeros(4))

    @property
    def slip(self) -> float:
        """How much less the block rose than the palm (m)."""
        return self.palm_rise - self.block_rise


def lift(
    world: World,
    checker: CollisionChecker,
    block: str,
    grip: Grip,
    *,
    height: float = LIFT_HEIGHT,
    duration: float = LIFT_TIME,
) -> LiftResult:
    """Lift the palm straight up by ``height`` while the grip holds the block (ramped, not a
    step: a step command slips the block by 2 cm), then hold still for a moment."""
    if not 0.0 < height < 0.5:
        raise ReachError(f"lift height must lie in (0, 0.5) m, got {height}")
    b0 = world.block_pose(block)[0][2]
    tips0, p0 = _tips_in_palm(world, checker)
    move_palm(world, checker, [0.0, 0.0, height], duration, grip=grip)
    _hold(world, grip, DELIVER_SETTLE_TIME)
    tips1, p1 = _tips_in_palm(world, checker)
    return LiftResult(
        palm_rise=float(p1[2] - p0[2]),
        block_rise=world.block_pose(block)[0][2] - b0,
        tip_motion=np.linalg.norm(tips1 - tips0, axis=1),
    )


def _tips_in_palm(
    world: World, checker: CollisionChecker
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The fingertips (4, 3) in the palm's frame, and the palm's position (3,), by the arm's and
    the hand's kinematics."""
    p, R = checker.palm_pose(world.arm_qpos())
    return (world.fingertip_positions() - p) @ R, p


def carry(
    world: World,
    path: ArrayLike,
    grip: Grip,
    *,
    max_joint_speed: float = CARRY_SPEED,
    on_period: Callable[[World], None] | None = None,
) -> None:
    """Drive the arm along ``path`` (k, 5) with a trapezoidal speed profile (at most
    ``max_joint_speed`` and CARRY_ACCELERATION on the largest joint) while the grip holds;
    ``on_period(world)`` is called every control period (e.g. to watch the block)."""
    for q in timed_path(path, max_joint_speed, CARRY_ACCELERATION, CONTROL_PERIOD):
        world.set_arm_targets(q)
        grip.regulate(world, CONTROL_PERIOD)
        world.step(control_steps(world))
        if on_period is not None:
            on_period(world)
    _hold(world, grip, DELIVER_SETTLE_TIME)


def timed_path(
    path: ArrayLike, max_speed: float, max_acceleration: float, period: float
) -> NDArray[np.float64]:
    """Postures (n, dof) at every ``period`` s along the polyline ``path`` (k, dof), moving with
    a trapezoidal profile of the path parameter (arc length in the max-norm of joint motion):
    accelerate at ``max_acceleration``, cruise at ``max_speed``, decelerate to rest."""
    p = np.asarray(path, dtype=float)
    if len(p) < 2:
        return p.copy()
    seg = np.abs(np.diff(p, axis=0)).max(axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(arc[-1])
    if total <= 0.0:
        return p[-1:].copy()
    v, a = float(max_speed), float(max_acceleration)
    t_acc = v / a
    if a * t_acc * t_acc > total:  # never reaches cruise speed: a triangle profile
        t_acc = float(np.sqrt(total / a))
        v = a * t_acc
    cruise = (total - a * t_acc * t_acc) / v
    duration = 2.0 * t_acc + cruise
    t = np.arange(1, int(np.ceil(duration / period)) + 1) * period
    t = np.minimum(t, duration)
    s = np.where(
        t < t_acc,
        0.5 * a * t**2,
        np.where(
            t < t_acc + cruise,
            0.5 * a * t_acc**2 + v * (t - t_acc),
            total - 0.5 * a * np.maximum(duration - t, 0.0) ** 2,
        ),
    )
    return np.column_stack([np.interp(s, arc, p[:, j]) for j in range(p.shape[1])])


def held_load(world: World, empty_hand_force: ArrayLike) -> float:
    """The weight (N) the hand carries beyond its own, from the wrist's sensors: the vertical
    wrist force divided by the wrist accelerometer's vertical reading is the mass the wrist
    carries (so the arm's own accelerations cancel out); less the hand's mass, from
    ``empty_hand_force`` (3,) measured with the hand empty and at rest."""
    force, _ = world.wrist_wrench()
    up = float(world.wrist_acceleration()[2])
    hand_mass = float(np.asarray(empty_hand_force, dtype=float)[2]) / robot.STANDARD_GRAVITY
    if up <= 1.0:  # falling freely: the load cannot be told
        return 0.0
    return (float(force[2]) / up - hand_mass) * robot.STANDARD_GRAVITY


@dataclass(frozen=True)
class SetDownResult:
    """Outcome of :func:`lower_until_supported`."""

    supported: bool  #: the table took at least SUPPORTED_SHARE of the block's weight
    lowered: float  #: how far the palm went down (m)
    load_before: float  #: N held before lowering
    load_after: float  #: N held at the end


def lower_until_supported(
    world: World,
    checker: CollisionChecker,
    grip: Grip,
    empty_hand_force: ArrayLike,
    *,
    max_lower: float = MAX_LOWER,
    speed: float = LOWER_SPEED,
) -> SetDownResult:
    """Lower the palm until the wrist sensor shows the table carrying the block (the load held
    falls below ``1 - SUPPORTED_SHARE`` of what it was), not to a height assumed in advance."""
    _hold(world, grip, DELIVER_SETTLE_TIME)
    before = held_load(world, empty_hand_force)
    if before <= 0.0:
        raise ReachError(f"the hand holds no load to set down (wrist sensor: {before:.2f} N)")
    z0 = checker.palm_pose(world.arm_qpos())[0][2]

    def supported(w: World) -> bool:
        return held_load(w, empty_hand_force) < (1.0 - SUPPORTED_SHARE) * before

    move_palm(world, checker, [0.0, 0.0, -max_lower], max_lower / speed, grip=grip, stop=supported)
    _hold(world, grip, DELIVER_SETTLE_TIME)
    # the arm's servos lag behind the lowering: take back any push into the table
    for _ in range(round(MAX_UNLOAD / UNLOAD_STEP)):
        if held_load(world, empty_hand_force) > -UNLOAD_TOLERANCE:
            break
        move_palm(world, checker, [0.0, 0.0, UNLOAD_STEP], CONTROL_PERIOD, grip=grip)
        _hold(world, grip, UNLOAD_SETTLE)
    _hold(world, grip, DELIVER_SETTLE_TIME)
    after = held_load(world, empty_hand_force)
    return SetDownResult(
        supported=after < (1.0 - SUPPORTED_SHARE) * before,
        lowered=z0 - checker.palm_pose(world.arm_qpos())[0][2],
        load_before=before,
        load_after=after,
    )


def retreat(
    world: World, checker: CollisionChecker, clear_top: float | None = None
) -> NDArray[np.float64]:
    """Back the palm off along its approach axis, then raise it; returns the palm position.

    A hand beside the block (a lateral grasp; ``clear_top``: the block's top, world z) first
    rises straight up until its lowest fingertip is RETREAT_TOP_MARGIN above that top, at the
    speed of the final rise: the released fingers stand round the block's side faces, some
    beyond its far corners, and backing off along the axis first would drag the block with
    them. Rising keeps every fingertip outside the block, whose side faces are vertical. Where
    the arm cannot rise that far, it backs off from as high as it got."""
    q = world.arm_qpos()
    _, R = checker.palm_pose(q)
    approach = R[:, 2]
    if clear_top is not None:
        rise = clear_top + RETREAT_TOP_MARGIN - float(world.fingertip_positions()[:, 2].min())
        if rise > 0.0:
            with contextlib.suppress(ReachError):
                move_palm(world, checker, [0.0, 0.0, rise], RETREAT_TIME * rise / RETREAT_UP)
    move_palm(world, checker, -RETREAT_BACK * approach, RETREAT_TIME)
    move_palm(world, checker, [0.0, 0.0, RETREAT_UP], RETREAT_TIME)
    _hold(world, None, DELIVER_SETTLE_TIME)
    return checker.palm_pose(world.arm_qpos())[0]
