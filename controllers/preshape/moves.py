"""The hand's motion primitives near the block (section 5.2: the moves between Coarse Reach,
Posture Control and Grasp Object): retract the fingers, move arm and hand together, reposition
the arm without sweeping a finger through the block, pre-shape the hand, and the straight
approach of a new arm posture along the palm's axis (planned, then made).

Every primitive moves the simulation through ``world`` (its step hook records and clocks each
step) and takes what it needs explicitly: the world, the planning model (the world with the
perceived block in place of the real one), the perceived block, and :class:`MotionParams`.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.deliver.carry import move_palm
from controllers.deliver.plan import MAX_EXTRA_RISE, RISE_STEP
from controllers.errors import ReachError
from controllers.hand.finger_assignment import FingerContacts
from controllers.hand.grip import PRE_CONTACT, backed_off_hand, move_hand
from controllers.planning.belief import PERCEIVED_GEOM
from controllers.planning.cspace import CollisionChecker
from controllers.posture.solver import SERVO_CORRECTIONS, solve_posture
from controllers.reach.arm_path import (
    ROLL_AT_START_COLLIDES,
    execute_path,
    first_collision,
    plan_arm_path,
    roll_turned_above,
)
from controllers.reach.coarse import ReachTarget
from controllers.reach.fine import project_to_surface
from controllers.timing import SERVO_SETTLE_TIME
from hand_sim import robot
from hand_sim.blocks import GEOM_SUFFIX
from hand_sim.contacts import robot_contacts
from hand_sim.world import World


@dataclass(frozen=True)
class MotionParams:
    """Distances and times of the motion primitives."""

    #: Fingers retract this far (m) from the block before the arm changes posture or the hand
    #: pre-shapes for the grasp.
    retract: float = 0.015
    retract_tries: int = 3
    #: Posture Control changes the arm's posture backed out by this much (m) along the approach
    #: axis, each straight move out and in taking ``backoff_time`` (s): the fingers stay clear of
    #: the block.
    backoff: float = 0.08
    backoff_time: float = 0.8
    #: Clearance (m) of the harmonic path between the backed-out postures.
    reposition_clearance: float = 0.0
    #: The arm moves between the backed-out postures in a straight joint-space line, without
    #: planning a harmonic path, when every posture on that line (checked every
    #: ``arm_path.VERIFY_STEP``) keeps this far (m) from the perceived world, the retracted hand
    #: included: more than the harmonic path's ``reposition_clearance``, for the servos' lag
    #: off the line.
    #: Chosen by its effect on Posture Control's time: docs/findings.md, "Straight arm moves".
    direct_clearance: float = 0.01
    #: Times (s) of the hand's moves.
    retract_time: float = 0.4
    preshape_time: float = 0.6
    arm_move_time: float = 1.0
    #: A lateral pre-shape moves the fingertips to their pre-contact positions along straight
    #: lines in ``preshape_waypoints`` steps, each a hand IK with collision avoidance.
    preshape_waypoints: int = 10
    preshape_ik_iterations: int = 40
    #: Fingertip distances (m) outside the contacts of the hand postures a new arm posture may be
    #: approached with, tried in order (a block standing at an angle to the approach axis needs
    #: the fingers wider open); at the posture the fingers then close to PRE_CONTACT.
    approach_standoffs: tuple[float, ...] = (PRE_CONTACT, 0.02, 0.03)
    #: The straight approach of a new posture (the last ``backoff`` of it) must keep the hand
    #: this far (m) from the perceived block and everything else, checked every
    #: ``approach_step`` (m).
    approach_clearance: float = 0.003
    approach_step: float = 0.01
    #: A lateral reposition backs the new posture out as far as its straight approach is clear
    #: (:func:`clear_back`); False: as far as the hand backs out of where it is.
    #: Chosen by its effect on the lateral bench: docs/findings.md, "Backing in as far as clear".
    backin_as_clear: bool = True


@dataclass(frozen=True, eq=False)
class BlockSite:
    """Where the hand works: the world, the planning model, the perceived block and the real
    block's body (to feel the fingers on it), and the coarse reach's approach axis (world unit
    vector: straight down for a top grasp, along the arm's radius for a lateral one).
    ``lateral``: a lateral grasp (its pre-shape and repositioning differ)."""

    world: World
    planning: mujoco.MjModel
    target: ReachTarget
    block_body: int
    axis: NDArray[np.float64]
    lateral: bool = False
    params: MotionParams = field(default_factory=MotionParams)


@dataclass(frozen=True, eq=False)
class ApproachPlan:
    """A new arm posture and how the hand approaches it: ``wide`` while the palm moves in
    along the approach axis, then ``hand_pre`` (the pre-contact posture) there."""

    arm_q: NDArray[np.float64]
    wide: NDArray[np.float64]
    hand_pre: NDArray[np.float64]


def retract(site: BlockSite) -> None:
    """Move every fingertip ``retract`` straight out from the perceived block's nearest face,
    and again, each time ``retract`` further (up to ``retract_tries`` times in all), while any
    finger still touches the block: a finger left on it (a thumb's middle link pressed on a
    face, say) would drag it, or wedge it against the palm and lift it, when the palm backs
    away."""
    world, p = site.world, site.params
    for k in range(p.retract_tries):
        tips = world.fingertip_positions()
        out = project_to_surface(site.target, tips, table_z=world.scene.table.height)
        sol = solve_posture(
            world,
            tips + (k + 1) * p.retract * out.normals,
            optimize=False,
            joints="hand",
            model=site.planning,
            avoid_collisions=True,
            touchable=PERCEIVED_GEOM,
        )
        move_hand(world, sol.hand_q, p.retract_time)
        if not any(c.finger in robot.FINGERS for c in robot_contacts(world, site.block_body)):
            return


def move_arm_and_hand(
    world: World, arm_q: NDArray[np.float64], hand_q: NDArray[np.float64], duration: float
) -> None:
    """Move the arm's and the hand's servo targets together to ``arm_q`` and ``hand_q`` over
    ``duration`` (s, cosine profile, 20 ms periods), then let them settle 0.3 s."""
    a0, h0 = world.arm_targets(), world.hand_targets()
    steps = max(1, round(0.02 / world.model.opt.timestep))
    n = max(1, round(duration / 0.02))
    for k in range(1, n + 1):
        s = 0.5 - 0.5 * np.cos(np.pi * k / n)
        world.set_arm_targets(a0 + s * (arm_q - a0))
        world.set_hand_targets(h0 + s * (hand_q - h0))
        world.step(steps)
    world.step(round(0.3 / world.model.opt.timestep))


def _approach_steps(p: MotionParams) -> NDArray[np.float64]:
    """The distances (m) along the approach axis the straight approach is checked at:
    ``approach_step`` to ``backoff``."""
    return np.arange(p.approach_step, p.backoff + 1e-9, p.approach_step)


def backed_out(
    checker: CollisionChecker, q: NDArray[np.float64], axis: NDArray[np.float64], backs: NDArray
) -> Iterator[tuple[float, NDArray[np.float64] | None]]:
    """The arm postures with the palm moved ``-back * axis`` from where ``q`` puts it, orientation
    kept, for each of ``backs`` in order (each IK started from the one before): (back, posture),
    and (back, None) once the IK finds none, which ends the walk."""
    palm, R = checker.palm_pose(q)
    q = np.asarray(q, dtype=float)
    for back in backs:
        ik = checker.solve_ik(palm - back * axis, R, q)
        if not ik.found:
            yield float(back), None
            return
        q = ik.q
        yield float(back), q


def clear_backoff(site: BlockSite) -> float:
    """How far (m, at most ``backoff``, in ``approach_step`` steps) the palm backs out along the
    approach axis from where the arm is, the hand held as it is, without a link touching the
    perceived world (:func:`clear_back` of the arm's posture): a lateral hand backing out
    towards the arm's base may otherwise push a neighbour standing between the base and the
    block (docs/findings.md, "Backing out as far as clear")."""
    return clear_back(site, site.world.arm_qpos(), site.world.hand_qpos())


def clear_back(site: BlockSite, arm_q: NDArray[np.float64], hand_q: NDArray[np.float64]) -> float:
    """How far (m, at most ``backoff``, in ``approach_step`` steps) the palm of the arm posture
    ``arm_q`` backs out along the approach axis, the hand held at ``hand_q``, every step clear
    of the perceived world (``reposition_clearance``); the full ``backoff`` when the hand
    touches it at ``arm_q`` already (a finger on the block). :func:`reposition` backs a lateral
    hand out of where it is this far, and the new posture before its straight approach: a hand
    that backs out only a little from where it is must not move to the new posture backed out
    as little, or the joint-space move there sweeps the fingers through the block
    (docs/findings.md, "Backing in as far as clear")."""
    p = site.params
    checker = CollisionChecker(
        site.world, model=site.planning, hand_q=hand_q, clearance=p.reposition_clearance
    )
    if checker.collides(arm_q):
        return p.backoff
    clear = 0.0
    for back, out in backed_out(checker, arm_q, site.axis, _approach_steps(p)):
        if out is None or checker.collides(out):
            break
        clear = back
    return clear


def reposition(site: BlockSite, arm_q: NDArray[np.float64], hand_q: NDArray[np.float64]) -> None:
    """Take the arm and hand to a new posture near the block without sweeping a finger through
    it: retract the fingers, back the palm out along the approach by ``backoff`` (a lateral
    hand only as far as it stays clear, :func:`clear_backoff`), move the arm to the new
    posture backed out likewise (a lateral one as far as its approach is clear,
    :func:`clear_back`; :func:`move_backed_out`), shape the hand there, and approach in a
    straight line."""
    world, p = site.world, site.params
    checker = CollisionChecker(world, model=site.planning)
    retract(site)
    # out and back in along the coarse reach's approach (straight up for a top grasp, along the
    # arm's radius for a lateral one), whatever tilt Posture Control gave the palm: the fingers
    # then slide along the block's faces, not into them
    axis = site.axis
    back = clear_backoff(site) if site.lateral else p.backoff
    move_palm(world, checker, -back * axis, p.backoff_time)
    # the new posture backed out as far as its straight approach is clear (a lateral hand backs
    # out of where it is only as far as it stays clear, which may be much less)
    back_in = clear_back(site, arm_q, hand_q) if site.lateral and p.backin_as_clear else back
    p_new, R_new = checker.palm_pose(arm_q)
    raised = checker.solve_ik(p_new - back_in * axis, R_new, arm_q)
    if not raised.found:
        raise ReachError("the new arm posture cannot be approached along the hand's axis")
    move_backed_out(site, raised.q)
    move_hand(world, hand_q, p.preshape_time)  # then opens, clear of the block
    move_palm(world, checker, back_in * axis, p.backoff_time)
    if not site.lateral:
        return
    # lateral: the arm lags its targets and its servos sag under the hand's weight, which moves
    # a horizontal finger row off its faces: let it settle and take out the steady-state error,
    # as apply_posture does (a top grasp's fingers close from above and do not need it; it costs
    # 1.5 s of simulated time)
    settle = round(SERVO_SETTLE_TIME / world.model.opt.timestep)
    world.step(settle)
    for _ in range(SERVO_CORRECTIONS):
        world.set_arm_targets(world.arm_targets() + arm_q - world.arm_qpos())
        world.step(settle)


def move_backed_out(site: BlockSite, arm_q: NDArray[np.float64]) -> str:
    """Move the arm, the hand keeping its shape, from where it is to the backed-out posture
    ``arm_q``, and say how: ``"straight"``, in a straight joint-space line, when every posture on it
    keeps ``direct_clearance`` from the perceived world; else ``"harmonic"``, on a collision-free
    harmonic path (:func:`controllers.reach.arm_path.plan_arm_path`; where turning the wrist roll
    first would sweep the hand through a neighbour, the roll turns at the goal, the empty hand
    tilting nothing, or above the start, :func:`controllers.reach.arm_path.roll_turned_above`); else
    ``"unplanned"`` (e.g. the backed-out hand already grazes a neighbour): straight there anyway."""
    world, p = site.world, site.params
    start = world.arm_qpos()
    direct = np.stack([start, arm_q])
    wide = CollisionChecker(
        world, model=site.planning, hand_q=world.hand_qpos(), clearance=p.direct_clearance
    )
    if first_collision(wide, direct) is None:
        execute_path(world, direct, settle=0.2)
        return "straight"
    mover = CollisionChecker(
        world, model=site.planning, hand_q=world.hand_qpos(), clearance=p.reposition_clearance
    )
    path = plan_arm_path(mover, start, arm_q)
    if not path.found and path.reason == ROLL_AT_START_COLLIDES:
        # the hand is empty: its roll may turn at the goal, or else above the start
        at_goal = plan_arm_path(mover, start, arm_q, roll_at_goal=True)
        if at_goal.found:
            execute_path(world, at_goal.path, settle=0.2)
            return "harmonic, the wrist roll turned at the goal"
        above = roll_turned_above(mover, start, arm_q, step=RISE_STEP, max_rise=MAX_EXTRA_RISE)
        if above is not None:
            execute_path(world, above.path, settle=0.2)
            return "harmonic, the wrist roll turned above"
    if path.found:
        execute_path(world, path.path, settle=0.2)
        return "harmonic"
    move_arm_and_hand(world, arm_q, world.hand_targets(), p.arm_move_time)
    return "unplanned"


def approach_clear(
    site: BlockSite, arm_q: NDArray[np.float64], hand_q: NDArray[np.float64]
) -> bool:
    """Whether the palm's straight approach to ``arm_q`` along the approach axis over
    ``backoff`` (as :func:`reposition` makes it), the hand held at ``hand_q``, stays
    ``approach_clearance`` clear of the perceived world."""
    p = site.params
    checker = CollisionChecker(
        site.world, model=site.planning, hand_q=hand_q, clearance=p.approach_clearance
    )
    if checker.collides(arm_q):
        return False
    return all(
        q is not None and not checker.collides(q)
        for _, q in backed_out(checker, arm_q, site.axis, _approach_steps(p))
    )


def approach_touches(
    site: BlockSite, arm_q: NDArray[np.float64], hand_q: NDArray[np.float64]
) -> tuple[str, ...]:
    """The blocks other than the target that the hand, held at ``hand_q``, touches on the
    straight approach :func:`reposition` makes to ``arm_q`` (the last ``backoff`` along the
    approach axis, checked every ``approach_step``): names of the blocks whose geoms the hand's
    or arm's touch in the planning model (no clearance), the perceived target and the table left
    out. Empty when the approach passes clear of every neighbour."""
    p = site.params
    checker = CollisionChecker(site.world, model=site.planning, hand_q=hand_q, clearance=0.0)
    target = site.world.model.body(site.block_body).name
    touched: list[str] = []
    backs = np.concatenate([[0.0], _approach_steps(p)])
    for _, q in backed_out(checker, arm_q, site.axis, backs):
        if q is None:
            break
        for c in checker.contacts(q, clearance=0.0):
            for name in (c.geom1, c.geom2):
                robotic = name.startswith((robot.HAND_PREFIX, robot.ARM_PREFIX))
                block = name.removesuffix(GEOM_SUFFIX)
                if robotic or block == target or name == PERCEIVED_GEOM or "table" in name:
                    continue
                if block not in touched:
                    touched.append(block)
    return tuple(touched)


def approach_plan(
    site: BlockSite, qpos: NDArray[np.float64], contacts: FingerContacts, squeeze_reach: float
) -> ApproachPlan | None:
    """The arm posture of ``qpos``, a hand posture whose straight approach to it along the
    palm's axis clears the perceived block (:func:`approach_clear`; the fingertips
    ``approach_standoffs`` outside their contacts) and the hand's pre-contact posture there
    (PRE_CONTACT outside); None when no approach clears. ``qpos``'s hand takes ``contacts``
    (``squeeze_reach`` inside); the fingers back off from it along their squeeze directions
    (:func:`controllers.hand.grip.backed_off_hand`)."""
    arm_q = qpos[robot.arm_qpos_addresses(site.world.model)]

    def hand_at(standoff: float) -> NDArray[np.float64]:
        # back from the posture that takes the contacts, along the fingers' squeeze directions
        # (a finger reaching round a corner cannot hold its pad facing a point further out)
        return backed_off_hand(site.planning, qpos, contacts.normals, standoff + squeeze_reach)

    hand_pre = hand_at(PRE_CONTACT)
    for standoff in site.params.approach_standoffs:
        wide = hand_pre if standoff == PRE_CONTACT else hand_at(standoff)
        if approach_clear(site, arm_q, wide):
            return ApproachPlan(arm_q, wide, hand_pre)
    return None


def approach(site: BlockSite, plan: ApproachPlan) -> None:
    """:func:`reposition` with the hand at ``plan.wide``, then the fingers close to
    ``plan.hand_pre``."""
    reposition(site, plan.arm_q, plan.wide)
    if not np.array_equal(plan.wide, plan.hand_pre):
        move_hand(site.world, plan.hand_pre, site.params.preshape_time)


def preshape(site: BlockSite, q_pre: NDArray[np.float64]) -> None:
    """Pre-shape the hand to ``q_pre`` for closing. In a lateral grasp the middle finger and the
    thumb reach round the block's near corners, and a straight line in joint space from where
    the fingers retracted to cuts through a corner: there the fingertips and pad centres move
    along straight lines to where ``q_pre`` puts them, through ``preshape_waypoints`` hand IK
    solutions that keep every link clear of the perceived block (collision avoidance), and the
    hand then settles on ``q_pre``."""
    world, p = site.world, site.params
    if site.lateral:
        m = site.planning
        tip_sites = [m.site(robot.qualified(s)).id for s in robot.FINGERTIP_SITES]
        pad_sites = [m.site(robot.qualified(s)).id for s in robot.PAD_CENTRE_SITES]
        hand_adr = robot.hand_qpos_addresses(m)
        data = mujoco.MjData(m)
        data.qpos[:] = world.data.qpos
        data.qpos[hand_adr] = q_pre
        mujoco.mj_kinematics(m, data)
        tips1, pads1 = data.site_xpos[tip_sites].copy(), data.site_xpos[pad_sites].copy()
        qpos = world.data.qpos.copy()
        qpos[hand_adr] = world.hand_targets()
        data.qpos[:] = qpos
        mujoco.mj_kinematics(m, data)
        tips0, pads0 = data.site_xpos[tip_sites].copy(), data.site_xpos[pad_sites].copy()
        for k in range(1, p.preshape_waypoints + 1):
            s = k / p.preshape_waypoints
            sol = solve_posture(
                world,
                tips0 + s * (tips1 - tips0),
                optimize=False,
                joints="hand",
                model=m,
                avoid_collisions=True,
                pad_centres=pads0 + s * (pads1 - pads0),
                qpos=qpos,
                reach_iterations=p.preshape_ik_iterations,
            )
            qpos[hand_adr] = sol.hand_q
            move_hand(world, sol.hand_q, p.preshape_time / p.preshape_waypoints)
    move_hand(world, q_pre, p.preshape_time)
