"""Fine Reach (section 5.2): harmonic fields bring each fingertip near its projection on the
perceived block's surface."""

from __future__ import annotations

import numpy as np

from controllers.fine_reach import GRASP_DEPTH, SurfaceTargets, contact_targets, fine_reach
from controllers.grasp.session import keep_contacts
from controllers.hand_reach import CONTACT_SEPARATION
from controllers.planning_model import PERCEIVED_GEOM
from fsm.context import Episode
from fsm.handlers.common import contact_arcs, sampled_preshape, slides
from fsm.handlers.regrasp import regrasp_or_fail
from fsm.states import Failure, State, Step
from hand_sim import robot


def fine_reach_state(ep: Episode) -> Step:
    """Fine Reach: harmonic fields bring each fingertip near its projection on the perceived
    block's surface (a touch guard stops a finger that arrives early). A fingertip left more
    than ``config.fine_reach_give_up`` from its point starts a regrasp
    (:func:`fsm.handlers.regrasp.regrasp_or_fail`)."""
    world = ep.world
    config = ep.config
    # each fingertip's contact coordinate (its polar angle about the perceived centroid,
    # Appendix B), the contacts kept a pad spacing apart: three fingers projected onto one small
    # face would crowd each other
    tips = world.fingertip_positions()
    local = tips[:, :2] - np.asarray(ep.target.position_xy)
    theta = np.arctan2(local[:, 1], local[:, 0]) - ep.target.yaw
    if slides(ep) and ep.preshape_contacts is not None:
        # the lateral pre-shape's contacts, which the reach test passed at this palm pose
        theta = ep.preshape_contacts.theta.copy()
    # a lateral hand's contacts stay on the faces it can take (its side's arc, or its own face)
    arcs = contact_arcs(ep, theta) if slides(ep) else None
    theta = keep_contacts(ep.target.polygon, theta, CONTACT_SEPARATION, robot.PAD_RADIUS, arcs)
    spread = contact_targets(ep.target, theta)
    z = np.clip(tips[:, 2], world.scene.table.height + 0.02, ep.target.top_z - GRASP_DEPTH)
    targets = SurfaceTargets(
        np.column_stack([spread.points[:, :2], z]), spread.normals, spread.theta
    )
    result = fine_reach(
        world,
        ep.target_name,
        targets,
        seen=ep.target,
        tolerance=config.fine_reach_tolerance,
        standoff=config.fine_reach_standoff,
        model=ep.planning,
        touchable=PERCEIVED_GEOM,
        # a sampled lateral pre-shape's palm pose was chosen for its contacts: the arm holds it
        joints="hand" if sampled_preshape(ep) else "arm+hand",
    )
    worst = float(result.tip_error.max())
    if not result.reached and worst > config.fine_reach_give_up:
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
        + (
            f", stopped on touch: {', '.join(result.stopped_on_touch)}"
            if result.stopped_on_touch
            else ""
        ),
    )
