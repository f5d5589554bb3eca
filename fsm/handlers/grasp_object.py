"""Grasp Object (section 5.2): the fingers close from their approach posture onto the
synthesized contacts and squeeze to the grip force."""

from __future__ import annotations

import numpy as np

from controllers.hand.grip import GRIP_FORCE, close, move_hand, plan_grip, squeeze
from controllers.hand.lateral_squeeze import lateral_squeeze
from controllers.preshape.moves import preshape, retract
from fsm.context import Episode
from fsm.episode_queries import (
    block_centre,
    block_site,
    is_lateral,
    planar_normal_forces,
    squeeze_reach,
)
from fsm.recovery import regrasp_or_fail
from fsm.states import Failure, State, Step
from hand_sim import robot


def grasp_object(ep: Episode) -> Step:
    """Grasp Object: the fingers go from their approach posture to the synthesized contacts,
    each stopping when its pad feels the block, then squeeze to the grip force; a finger that
    misses, or a squeeze that does not reach the force, opens the hand for a regrasp."""
    world = ep.world
    contacts = ep.contacts
    lateral = is_lateral(ep)
    site = block_site(ep)
    open_time = ep.config.motion.preshape_time
    pressing = contacts.pressing  # all four, or a three-contact grasp's three
    taken = planar_normal_forces(ep, contacts.theta[pressing])
    grip_force = GRIP_FORCE
    reserve = ""
    if lateral:
        taken, grip_force, reserve = _lateral_squeeze(ep, taken)
    shares = np.zeros(len(robot.FINGERS))
    shares[pressing] = taken
    retract(site)
    world.step(round(0.2 / world.model.opt.timestep))
    ep.empty_hand_force = world.wrist_wrench()[0]
    ep.grip = plan_grip(
        world,
        contacts.points,
        contacts.normals,
        shares,
        grip_force=grip_force,
        model=ep.planning,
        prism=ep.prism,
        along_normal=lateral,
        # lateral: from the posture the reachability check found (a local IK from the retracted
        # hand may turn a pad that reaches round a corner onto its side)
        start=ep.reach.hand_q if lateral else None,
        squeeze_reach=squeeze_reach(ep),
        idle=contacts.idle,
    )
    preshape(site, ep.grip.q_pre)
    closing = close(world, ep.grip)
    if not closing.all_touched:
        missing = [f for f, t in zip(robot.FINGERS, closing.touched, strict=True) if not t]
        # open to the approach posture and regrasp (the fingers that touched only stopped there)
        move_hand(world, ep.grip.q_pre, open_time)
        ep.grip.progress[:] = 0.0  # where the hand now is (a release then opens from here)
        return regrasp_or_fail(
            ep,
            f"{', '.join(missing)} did not touch the block",
            Failure.FINGERS_CANNOT_REACH,
            look=True,
        )
    result = squeeze(world, ep.grip, seek=lateral and ep.config.lateral_squeeze_seek)
    ep.record.grip_forces = result.touch.round(3).tolist()
    ep.record.grip_target = result.target.round(3).tolist()
    if not result.settled:
        weak = [
            f"{f} {t:.1f} N"
            for f, t, g in zip(robot.FINGERS, result.touch, result.target, strict=True)
            if t < 0.5 * g
        ]
        move_hand(world, ep.grip.q_pre, open_time)  # open, and regrasp
        ep.grip.progress[:] = 0.0
        return regrasp_or_fail(
            ep,
            f"the squeeze did not reach the grip force ({', '.join(weak) or 'unsettled'} of "
            f"{result.target.mean():.1f} N)",
            Failure.FINGERS_CANNOT_REACH,
            look=True,
        )
    touching = "all four pads touch" if contacts.idle is None else "the three pads touch"
    world.hold(ep.target_name)  # the robot's belief: the block moves with the palm from now on
    return Step(
        # interactive mode: the user gives the delivery point now (section 5.2, Deliver)
        State.DELIVER if ep.user is None else State.WAIT_FOR_PLACE,
        f"{touching}; squeezed to {np.round(result.touch, 1).tolist()} N "
        f"(mean target {result.target.mean():.1f} N{reserve})",
    )


def _lateral_squeeze(ep: Episode, planar: np.ndarray) -> tuple[np.ndarray, float, str]:
    """A lateral grasp's squeeze (:func:`controllers.hand.lateral_squeeze.lateral_squeeze`, sharing
    its total out to hold the weight with ``config.lateral_holding_forces``): the pressing
    fingers' forces, their mean (N) and, for the log, the contacts' friction reserve, which
    the record keeps."""
    contacts = ep.contacts
    squeeze = lateral_squeeze(
        contacts.points[contacts.pressing],
        contacts.normals[contacts.pressing],
        planar,
        ep.expected_load,
        block_centre(ep),
        holding=ep.config.lateral_holding_forces,
    )
    if squeeze.reserve is None:
        ep.record.squeeze_reserve = None  # this grasp's, not an earlier one's
        return squeeze.forces, squeeze.grip_force, "; no forces hold the weight by the 3-D model"
    ep.record.squeeze_reserve = round(squeeze.reserve, 3)
    return squeeze.forces, squeeze.grip_force, f"; friction reserve {squeeze.reserve:.2f} N"
