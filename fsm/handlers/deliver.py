"""Deliver (section 5.2): lift the grasped block, carry it to the place point, set it down,
release and retreat; the placement is then judged physically (:mod:`fsm.judge`)."""

from __future__ import annotations

from collections import deque

import numpy as np

from controllers.deliver.carry import (
    LIFT_HEIGHT,
    LIFT_TIME,
    carry,
    held_load,
    lift,
    lower_until_supported,
    move_palm,
    retreat,
)
from controllers.deliver.plan import plan_delivery
from controllers.hand.grip import CONTROL_PERIOD, release
from controllers.planning.cspace import CollisionChecker
from controllers.preshape.palm_candidates import robot_base_xy
from controllers.reach.arm_path import ROLL_TURNED_ABOVE
from fsm.config import TaskConfig
from fsm.context import CycleRecord, Episode
from fsm.episode_queries import is_lateral, top_to_clear
from fsm.judge import block_clearance_now, block_height_now, block_tilt_now, judge
from fsm.layout import free_slot
from fsm.recovery import grasp_again_or_fail, lift_retry_left, park_arm
from fsm.states import Failure, State, Step, TaskFailedError
from hand_sim import robot


def _elsewhere_note(record: CycleRecord) -> str:
    """``; delivered elsewhere: ...`` naming the asked and the used point and their distance,
    when the block goes to another point than the one asked for; else nothing."""
    if not record.delivered_elsewhere or record.place_asked is None:
        return ""
    asked, used = record.place_asked, record.place_used
    return (
        f"; delivered elsewhere (--place-fallback nearest): asked ({asked[0]:.3f}, "
        f"{asked[1]:.3f}), used ({used[0]:.3f}, {used[1]:.3f}), {record.place_moved_mm:.0f} mm "
        "apart"
    )


def _unreachable_detail(ep: Episode, tried: list[np.ndarray], reason: str) -> str:
    """Why no set-down was found: at the point asked for (with the flag that would try
    another), or at every slot the task cycle tried."""
    where = tried[-1].round(3).tolist()
    asked = ep.record.place_asked is not None
    if asked and len(tried) == 1 and not ep.record.delivered_elsewhere:
        hint = (
            ""
            if ep.options.place_fallback == "nearest"
            else " (--place-fallback nearest would deliver to the nearest free slot)"
        )
        return f"no set-down posture at the place point asked for {where}: {reason}{hint}"
    slots = ", ".join(str(t.round(3).tolist()) for t in tried)
    return f"no set-down posture at {len(tried)} place slots ({slots}): {reason}"


def lift_held(
    load: float,
    expected: float,
    touch: np.ndarray,
    floor: float,
    forces: np.ndarray,
    lateral: bool,
    config: TaskConfig,
) -> bool:
    """Whether the hand holds the block after the lift, by what it senses: the wrist's ``load``
    (N) above ``config.closed_loop.held_floor`` (the hand holds something; a real block's
    density is not known, so not its ``expected`` weight; with ``closed_loop.sensed_weight`` off,
    ``config.min_held_share`` of it), and no more than one
    pad lost (``touch`` (4,) at or below ``floor``). In a ``lateral`` grasp only the pads the
    squeeze asked for at least ``config.carrying_share`` of its mean force (``forces`` (4,))
    count (the others only touch lightly and may let go as the block settles), and none count
    when the wrist weighs the block and two pads still feel it (the carry's own test): it has
    settled onto those pads, or against the palm."""
    loop = config.closed_loop
    if loop.sensed_weight:
        held = load >= loop.held_floor
    else:
        held = load >= config.min_held_share * expected
    lost = touch <= floor
    if lateral:
        lost &= forces >= config.carrying_share * forces.mean()
        if held and int((touch > floor).sum()) >= 2:
            return True
    return held and int(lost.sum()) <= 1


def _hold_lost(ep: Episode) -> str:
    """What the lifted hand senses when it does not hold its block (:func:`lift_held`); empty
    when it holds it."""
    world = ep.world
    load = held_load(world, ep.empty_hand_force)
    touch = world.touch()
    if lift_held(
        load, ep.expected_load, touch, world.touch_floor, ep.grip.forces, is_lateral(ep), ep.config
    ):
        ep.held_weight = load if ep.config.closed_loop.sensed_weight else ep.expected_load
        ep.record.lift_weight = round(load, 4)
        return ""
    return (
        f"the hand holds {load:.2f} N (the block's nominal weight {ep.expected_load:.2f} N); "
        f"touch {np.round(touch, 2).tolist()} N"
    )


def _turned_in_hand(ep: Episode, tip_motion: np.ndarray) -> str:
    """Why a lateral grasp's block counts as turned or slid in the hand at the lift: a pressing
    fingertip moved more than ``config.lateral_tip_motion_limit`` in the palm's frame
    (``tip_motion`` (4,), m); empty when none did, for a top grasp, or with the limit 0."""
    limit = ep.config.lateral_tip_motion_limit
    if not is_lateral(ep) or limit <= 0.0:
        return ""
    moved = np.zeros(len(tip_motion))
    pressing = ep.contacts.pressing  # a three-contact grasp's idle finger is held clear
    moved[pressing] = tip_motion[pressing]
    worst = int(np.argmax(moved))
    if moved[worst] <= limit:
        return ""
    return (
        "the block turned or slid in the hand as it rose: "
        f"{robot.FINGERS[worst]}'s fingertip moved {moved[worst] * 1000:.1f} mm in the palm's "
        f"frame (more than {limit * 1000:.1f} mm)"
    )


def _lower_back(ep: Episode, checker: CollisionChecker, rise: float, duration: float) -> str:
    """Lower a block still held after its lift back onto the table: the palm straight down by
    its ``rise`` (m) in ``duration`` (s), to where it grasped the block standing, so that the
    table turns a block that turned in the hand back onto its base before the hand lets go
    (docs/findings.md, "Lowered back to where it was grasped"); returns what was done, for the
    log."""
    move_palm(ep.world, checker, [0.0, 0.0, -rise], duration, grip=ep.grip)
    return f"the palm lowered back {rise * 100:.1f} cm to where it grasped the block"


class _DroppedError(Exception):
    """Fewer than two pads have felt the carried block for ``drop_window`` periods."""


def deliver(ep: Episode) -> Step:
    """Deliver: lift, carry along a harmonic path planned with the block in the hand, lower
    until the table takes the weight (wrist sensor), release along the contact normals, retreat;
    then judge the placement physically, at the point the block was taken to. A later cycle's
    place slot (chosen by the task cycle) the hand cannot set the block down at gives way to the
    next free one (up to ``config.max_place_slots``); so does the point asked for, but only with
    ``--place-fallback nearest``, and the block is then reported as delivered elsewhere."""
    world = ep.world
    name = ep.target_name
    record = ep.record
    config = ep.config
    checker = CollisionChecker(world)
    log = ep.recorder.log_transition
    truth = ep.simulated  # the summary's judged fields only: no decision reads them

    def clearance_now() -> float:
        return block_clearance_now(truth, name)

    start_z = block_height_now(truth, name)
    lifted = lift(world, checker, name, ep.grip, height=LIFT_HEIGHT, duration=LIFT_TIME)
    record.lift_height = block_height_now(truth, name) - start_z
    record.lift_slip = float(lifted.palm_rise - record.lift_height)
    record.lift_clearance = max(record.lift_clearance, clearance_now())
    record.lift_tip_motion_mm = (lifted.tip_motion * 1000.0).round(2).tolist()
    record.lift_tilt_deg = round(block_tilt_now(truth, name), 2)
    lost = _hold_lost(ep)
    if lost:
        return grasp_again_or_fail(ep, lost)
    turned = _turned_in_hand(ep, lifted.tip_motion)
    if turned and lift_retry_left(ep):
        # still held: set down where it was lifted from, then let go and grasp it again
        lowered = _lower_back(ep, checker, lifted.palm_rise, LIFT_TIME)
        return grasp_again_or_fail(ep, f"{turned}; {lowered}")
    # the last lift retry spent, a block still held is carried as it is held
    carried = f" ({turned}; no lift retry left: carried as held)" if turned else ""
    log(
        State.DELIVER.value,
        State.DELIVER.value,
        f"lifted: block rose {record.lift_height * 100:.1f} cm{carried}",
    )
    # the hand may set the block down nearer its neighbours at a point the user or the scene
    # asked for (the first cycle's, or every cycle's in interactive mode); a slot the task
    # cycle chose itself gives way to the next free one instead
    asked = record.place_asked is not None
    plan = plan_delivery(world, name, ep.place, block_height=ep.model.height, nearer=asked)
    tried = [np.asarray(ep.place, dtype=float)]
    # a place the task cycle chose itself (a later cycle's slot) may be free for the block but
    # not for the hand around it: take the next free slot; a place point asked for is moved only
    # when the user lets it (--place-fallback nearest), and the move is reported
    movable = not asked or ep.options.place_fallback == "nearest"
    while not plan.found and movable and len(tried) < config.max_place_slots:
        taken = [t + 0.001 * np.array([[1.0, 0.0], [-0.5, 0.87], [-0.5, -0.87]]) for t in tried]
        slot = free_slot(
            tried[0],
            ep.place_radius,
            [*ep.place_footprints, *taken],
            world.scene.table,
            (robot_base_xy(world), *config.place_reach),
        )
        if slot is None:
            break
        ep.use_place(slot)
        log(
            State.DELIVER.value,
            State.DELIVER.value,
            f"place slot {tried[-1].round(3).tolist()}: {plan.reason}; trying "
            f"{slot.round(3).tolist()}" + _elsewhere_note(record),
        )
        tried.append(slot)
        plan = plan_delivery(world, name, ep.place, block_height=ep.model.height, nearer=False)
    if not plan.found:
        raise TaskFailedError(
            Failure.PLACE_UNREACHABLE, _unreachable_detail(ep, tried, plan.reason)
        )

    lost: deque[bool] = deque(maxlen=config.drop_window)

    def watch(w) -> None:
        """Sensed, not judged: the pads (the wrist is weighed at rest, after the carry)."""
        record.lift_clearance = max(record.lift_clearance, clearance_now())
        lost.append(int((w.touch() > w.touch_floor).sum()) < 2)
        if len(lost) == config.drop_window and all(lost):
            raise _DroppedError

    try:
        carry(world, plan.path, ep.grip, on_period=watch)
    except _DroppedError as e:
        raise TaskFailedError(
            Failure.DROPPED_IN_TRANSPORT,
            f"fewer than two pads have felt the block since t = "
            f"{world.time - config.drop_window * CONTROL_PERIOD:.2f} s",
        ) from e
    world.step(round(config.weigh_time / world.model.opt.timestep))
    load = held_load(world, ep.empty_hand_force)
    if load < config.min_held_share * ep.held_weight:
        raise TaskFailedError(
            Failure.DROPPED_IN_TRANSPORT,
            f"after the carry the hand holds {load:.2f} N of the {ep.held_weight:.2f} N it "
            "weighed after the lift (wrist sensor, at rest)",
        )
    record.set_down = plan.set_down
    lowering = f" ({record.set_down})" if record.set_down else ""
    above = plan.transit is not None and plan.transit.reason.endswith(ROLL_TURNED_ABOVE)
    carried = f" ({ROLL_TURNED_ABOVE}: it would collide at the lift's top)" if above else ""
    log(
        State.DELIVER.value,
        State.DELIVER.value,
        f"carried to the place point{carried}; lowering{lowering}",
    )
    down = lower_until_supported(world, checker, ep.grip, ep.empty_hand_force)
    if not down.supported:
        raise TaskFailedError(
            Failure.SET_DOWN_NOT_SENSED,
            f"lowered {down.lowered * 100:.1f} cm; the hand still holds {down.load_after:.2f} N",
        )
    release(world, ep.grip)
    world.let_go()
    world.put(name, ep.place)
    retreat(world, checker, clear_top=top_to_clear(ep))
    world.step(round(0.5 / world.model.opt.timestep))
    verdict = judge(truth, name, ep.place, record.lift_clearance, ep.others_before)
    record.judgement = {
        "place_error_mm": verdict.place_error_mm,
        "tilt_deg": verdict.tilt_deg,
        "speed_m_s": verdict.speed,
        "spin_rad_s": verdict.spin,
        "lift_clearance_m": verdict.lift_clearance,
        "finger_contact": verdict.finger_contact,
        "palm_distance_m": verdict.palm_distance,
        "other_blocks_moved_m": verdict.other_motion,
        "final_position": verdict.final_position.round(5).tolist(),
        "final_quat_wxyz": verdict.final_quat.round(5).tolist(),
        "reasons": list(verdict.reasons),
    }
    if not verdict.success:
        raise TaskFailedError(Failure.NOT_PLACED, "; ".join(verdict.reasons))
    record.success = True
    ep.delivered.append(name)
    where = "free slot" if record.delivered_elsewhere else "place point"
    summary = (
        f"{name} placed {verdict.place_error_mm:.1f} mm from the {where} "
        f"({ep.place[0]:.3f}, {ep.place[1]:.3f}) ({record.place_chosen_by}), "
        f"tilt {verdict.tilt_deg:.1f} deg"
    ) + _elsewhere_note(record)
    if ep.user is not None:  # interactive: back to the user, "waiting for the next command"
        return Step(State.WAIT_FOR_BLOCK, f"{summary}; {park_arm(ep)}")
    cycles = ep.options.cycles
    if cycles is None or len(ep.cycles) < cycles:
        ep.cycle += 1
        return Step(State.SELECT_MODEL, f"{summary}; {park_arm(ep)}; next block")
    return Step(State.DONE, summary)
