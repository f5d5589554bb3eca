"""Fine Reach (section 5.2): harmonic fields bring each fingertip near its projection on the
perceived block's surface (after a sampled lateral pre-shape: the fingers come in along their
contacts' normals)."""

from __future__ import annotations

import numpy as np

from controllers.grasp.synthesis import keep_contacts
from controllers.hand.grip import backed_off_hand
from controllers.hand.reachability import CONTACT_SEPARATION
from controllers.planning.belief import PERCEIVED_GEOM
from controllers.reach.fine import (
    GRASP_DEPTH,
    FineReachResult,
    SurfaceTargets,
    contact_targets,
    fine_reach,
    reach_along_normals,
)
from fsm.context import Episode
from fsm.episode_queries import contact_arcs, is_lateral, sampled_preshape, squeeze_reach
from fsm.recovery import regrasp_or_fail
from fsm.states import Failure, State, Step
from hand_sim import robot


def fine_reach_state(ep: Episode) -> Step:
    """Fine Reach: the fingertips brought near their points on the perceived block's surface (a
    touch guard stops a finger that arrives early): by harmonic fields (:func:`_reach_by_fields`)
    or, after a sampled lateral pre-shape, along the contacts' normals (:func:`_reach_sampled`).
    A fingertip left more than ``config.fine_reach_give_up`` from its point starts a regrasp
    (:func:`fsm.recovery.regrasp_or_fail`)."""
    result = _reach_sampled(ep) if sampled_preshape(ep) else _reach_by_fields(ep)
    worst = float(result.tip_error.max())
    if not result.reached and worst > ep.config.fine_reach_give_up:
        # a finger held off its surface point (a neighbour, the block's edge): Figure 14's
        # recovery, the regrasp from other contacts, until the regrasps run out
        finger = robot.FINGERS[int(np.argmax(result.tip_error))]
        return regrasp_or_fail(
            ep,
            f"{finger} stayed {worst * 1000:.0f} mm from its surface point",
            Failure.FINGERS_CANNOT_REACH,
        )
    ep.posture_mode = "hold"
    return Step(
        State.POSTURE_CONTROL,
        f"fingertips {np.round(result.tip_error * 1000, 1).tolist()} mm from their targets"
        + (" along the contact normals" if sampled_preshape(ep) else "")
        + (
            f", stopped on touch: {', '.join(result.stopped_on_touch)}"
            if result.stopped_on_touch
            else ""
        ),
    )


def _reach_by_fields(ep: Episode) -> FineReachResult:
    """Fine Reach by the fingertips' harmonic fields (:func:`controllers.reach.fine.fine_reach`,
    arm and hand) to the fingertips' projections on the perceived block (a lateral pinch
    pre-shape: its contacts)."""
    world = ep.world
    config = ep.config
    # each fingertip's contact coordinate (its polar angle about the perceived centroid,
    # Appendix B), the contacts kept a pad spacing apart: three fingers projected onto one small
    # face would crowd each other
    tips = world.fingertip_positions()
    local = tips[:, :2] - np.asarray(ep.target.position_xy)
    theta = np.arctan2(local[:, 1], local[:, 0]) - ep.target.yaw
    if is_lateral(ep) and ep.preshape_contacts is not None:
        # the lateral pre-shape's contacts, which the reach test passed at this palm pose
        theta = ep.preshape_contacts.theta.copy()
    # a lateral hand's contacts stay on the faces it can take (its side's arc)
    arcs = contact_arcs(ep, theta) if is_lateral(ep) else None
    theta = keep_contacts(ep.target.polygon, theta, CONTACT_SEPARATION, robot.PAD_RADIUS, arcs)
    spread = contact_targets(ep.target, theta)
    z = np.clip(tips[:, 2], world.scene.table.height + 0.02, ep.target.top_z - GRASP_DEPTH)
    targets = SurfaceTargets(
        np.column_stack([spread.points[:, :2], z]), spread.normals, spread.theta
    )
    return fine_reach(
        world,
        ep.target_name,
        targets,
        seen=ep.target,
        tolerance=config.fine_reach_tolerance,
        standoff=config.fine_reach_standoff,
        model=ep.planning,
        touchable=PERCEIVED_GEOM,
    )


def _reach_sampled(ep: Episode) -> FineReachResult:
    """Fine Reach after a sampled lateral pre-shape: the hand, backed off from the posture that
    takes the pre-shape's contacts, moves back in along the same lines to
    ``config.fine_reach_standoff`` outside them
    (:func:`controllers.reach.fine.reach_along_normals`); the arm holds the palm pose chosen for
    those contacts."""
    contacts = ep.preshape_contacts
    qpos = ep.world.data.qpos.copy()
    qpos[robot.hand_qpos_addresses(ep.world.model)] = ep.preshape_hand_q
    standoff = ep.config.fine_reach_standoff
    hand_to = backed_off_hand(ep.planning, qpos, contacts.normals, standoff + squeeze_reach(ep))
    return reach_along_normals(
        ep.world,
        ep.target_name,
        hand_to,
        SurfaceTargets(contacts.points, contacts.normals, contacts.theta),
        standoff=standoff,
        tolerance=ep.config.fine_reach_tolerance,
    )
