"""What the states ask of the running episode (section 5.2's task cycle): whether this cycle's
approach is lateral, and the episode's view of the controllers' explicit inputs (the motion
primitives' :class:`~controllers.preshape.moves.BlockSite`, the palm-pose search's
:class:`~controllers.preshape.palm_search.ReachQuery`, the set-down check's
:class:`~controllers.preshape.set_down_check.SetDownQuery`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.deliver.plan import RISE_STEP, SET_DOWN_CLEARANCE, rise_until_clear
from controllers.grasp.synthesis3d import GraspSynthesis3D
from controllers.hand import friction_reserve
from controllers.hand.finger_assignment import FingerContacts
from controllers.hand.finger_samples import PAD_NORMAL_LOCAL, FingerSamples
from controllers.hand.reachability import SQUEEZE_REACH
from controllers.planning.cspace import CollisionChecker
from controllers.preshape.lateral_search import arcs_of
from controllers.preshape.moves import ApproachPlan, BlockSite, approach_plan
from controllers.preshape.palm_candidates import (
    approach_origin,
    face_arcs,
    lateral_arcs,
    robot_base_xy,
)
from controllers.preshape.palm_search import ReachQuery
from controllers.preshape.set_down_check import SetDownQuery
from controllers.reach.arm_path import execute_path
from fsm.context import Episode
from hand_sim import robot
from hand_sim.geometry import place_polygon


def is_lateral(ep: Episode) -> bool:
    """Whether this cycle's approach is lateral. Its contacts then slide up and down their
    faces: in a lateral grasp the finger row is horizontal and the thumb below it, so the hand's
    shape, not a depth below the top, sets each finger's height on the block (a top grasp keeps
    its fingers at the depth they reached)."""
    return ep.coarse is not None and ep.coarse.approach == "lateral"


def top_to_clear(ep: Episode) -> float | None:
    """The block's top (world z) a lateral hand's fingertips rise above before it backs off
    from a block left standing (:func:`controllers.deliver.carry.retreat`), None for a top grasp
    or with ``lateral_retreat_rise`` off."""
    return ep.target.top_z if is_lateral(ep) and ep.config.lateral_retreat_rise else None


def rise_clear(ep: Episode, clear: CollisionChecker) -> float | None:
    """Raise the palm straight up until the arm is clear of everything by ``clear``
    (:func:`controllers.deliver.plan.rise_until_clear`, each step kept
    :data:`~controllers.deliver.plan.SET_DOWN_CLEARANCE` from everything with the hand as it is)
    and move it there; how far (m), or None when it cannot rise clear (the arm stays)."""
    tight = CollisionChecker(ep.world, clearance=SET_DOWN_CLEARANCE, model=clear.model)
    start = ep.world.arm_qpos()
    risen = rise_until_clear(clear, tight, start)
    if risen is None:
        return None
    execute_path(ep.world, np.vstack([start[None], risen]))
    return len(risen) * RISE_STEP


def finger_samples(ep: Episode) -> FingerSamples:
    """Sampled finger postures, IK starts for a palm-pose search (drawn once an episode)."""
    if ep.finger_samples is None:
        ep.finger_samples = FingerSamples.draw(pad_normal_local=PAD_NORMAL_LOCAL)
    return ep.finger_samples


def squeeze_reach(ep: Episode) -> float:
    """How far past its contact each fingertip must reach in this cycle's grasp."""
    return ep.config.lateral_squeeze_reach if is_lateral(ep) else SQUEEZE_REACH


def sampled_preshape(ep: Episode) -> bool:
    """Whether this cycle's lateral pre-shape took sampled contacts (``ep.preshape_hand_q`` is
    the posture that took them): each stays on its own face at its height, the reach tests start
    from that posture and the arm holds the pre-shape's palm pose."""
    return is_lateral(ep) and ep.preshape_hand_q is not None


def idle_finger(ep: Episode) -> int | None:
    """The finger that takes no contact in this cycle's grasp (a three-contact lateral
    pre-shape's, :func:`controllers.preshape.lateral_grasp.three_contact_lateral_grasp`), or
    None."""
    return ep.preshape_contacts.idle if sampled_preshape(ep) else None


def block_centre(ep: Episode) -> NDArray[np.float64]:
    """The perceived block's centre of mass (world, m): its footprint's centroid, half its
    height below its top."""
    return np.array([*ep.target.position_xy, ep.target.top_z - 0.5 * ep.model.height])


def planar_normal_forces(ep: Episode, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """The normal forces (n,) of the S_G linear programme (Eq. 13) for contacts ``theta`` on the
    perceived polygon, in its unit-moment frame: the squeeze's shares (a lateral squeeze's
    prior; :func:`controllers.hand.friction_reserve.planar_normal_forces`)."""
    return friction_reserve.planar_normal_forces(ep.target.polygon, theta)


def block_site(ep: Episode) -> BlockSite:
    """The motion primitives' inputs for this cycle's block: the approach axis is the coarse
    reach's (straight down for a top grasp, along the arm's radius for a lateral one)."""
    return BlockSite(
        ep.world,
        ep.planning,
        ep.target,
        ep.world.block_body_id(ep.target_name),
        ep.coarse.goal.palm_rotation[:, 2],
        lateral=is_lateral(ep),
        params=ep.config.motion,
    )


def reach_query(ep: Episode) -> ReachQuery:
    """The reach test's inputs for this cycle's block. In a lateral grasp the contacts slide on
    their faces and the hand IK starts from the episode's sampled finger postures (drawn when
    first needed: the reach test searches them for sliding contacts only), unless the pre-shape's
    contacts were sampled: those are taken at their heights; a top 3-D grasp's contacts are
    taken at their own heights."""
    lateral = is_lateral(ep)
    sampled = sampled_preshape(ep)
    # a lateral hand's fingers slide to the heights they can take (a lateral 3-D grasp then
    # takes those heights), but keep the heights of sampled pre-shape contacts (each finger on
    # its own face, where its sampled posture took it); a top 3-D grasp's fingers go to its
    # contacts' heights
    if sampled:
        contacts = ep.preshape_contacts
        heights = contacts.points[contacts.pressing, 2].copy()
    else:
        heights = None if lateral else contact_heights(ep)
    return ReachQuery(
        ep.world,
        ep.planning,
        ep.prism,
        ep.target,
        slide=lateral and not sampled,
        samples=finger_samples(ep) if lateral else None,
        squeeze=squeeze_reach(ep),
        heights=heights,
        idle=idle_finger(ep),
    )


def reach_start(ep: Episode) -> NDArray[np.float64] | None:
    """Where a reach test of this cycle starts its hand IK: the world's configuration with the
    hand in the posture that took the sampled pre-shape's contacts (a lateral hand at the edge of
    its workspace: from the hand's present posture the IK stalls millimetres short), or None
    (the world's configuration)."""
    if not sampled_preshape(ep):
        return None
    qpos = ep.world.data.qpos.copy()
    qpos[robot.hand_qpos_addresses(ep.world.model)] = ep.preshape_hand_q
    return qpos


def contact_heights(ep: Episode) -> NDArray[np.float64] | None:
    """World z of the 3-D grasp's contacts (None for a planar grasp: the fingers' heights)."""
    syn = ep.synthesis
    if not isinstance(syn, GraspSynthesis3D):
        return None
    return ep.prism.centre_z + syn.heights


def plan_approach(
    ep: Episode, qpos: NDArray[np.float64], contacts: FingerContacts
) -> ApproachPlan | None:
    """:func:`controllers.preshape.moves.approach_plan` for this cycle's block and grasp."""
    return approach_plan(block_site(ep), qpos, contacts, squeeze_reach(ep))


def contact_points(ep: Episode, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """World points (n, 3) of contacts ``theta`` on the perceived polygon, at a 3-D grasp's
    contact heights, else at the top's height less 3 cm (for drawing)."""
    frames = ep.target.polygon.locate(theta)
    xy = place_polygon(frames.point, ep.target.position_xy, ep.target.yaw)
    z = contact_heights(ep)
    return np.column_stack([xy, np.full(len(xy), ep.target.top_z - 0.03) if z is None else z])


def side_arcs(ep: Episode) -> NDArray[np.float64]:
    """The stretches of the perceived block's outline this cycle's lateral hand can take
    (:func:`controllers.preshape.palm_candidates.lateral_arcs`; row 0 left of the approach axis,
    row 1 right), from the base's side of the block or, as the coarse reach's palm, its far
    side."""
    return lateral_arcs(ep.target, approach_from(ep), ep.config.palm_pose)


def approach_from(ep: Episode) -> NDArray[np.float64]:
    """Where this cycle's lateral approach axis comes from in the table plane
    (:func:`controllers.preshape.palm_candidates.approach_origin`)."""
    return approach_origin(robot_base_xy(ep.world), ep.target, ep.coarse.goal.palm_rotation)


def contact_arcs(ep: Episode, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each lateral contact's arc (n, 2): the pre-shape contact's own face when they were sampled
    (:func:`controllers.preshape.palm_candidates.face_arcs`), else its side's
    (:func:`controllers.preshape.lateral_search.arcs_of` of :func:`side_arcs`)."""
    if sampled_preshape(ep):
        inset = ep.config.palm_pose.side_inset
        contacts = ep.preshape_contacts
        return face_arcs(ep.target.polygon, contacts.theta[contacts.pressing], inset)
    return arcs_of(side_arcs(ep), theta)


def set_down_query(ep: Episode) -> SetDownQuery | None:
    """The set-down check's inputs for this cycle's block and place point (None without a place
    point): the hand may set the block down nearer its neighbours at a point the user or the
    scene asked for (the first cycle's)."""
    if ep.place is None:
        return None
    return SetDownQuery(
        ep.world,
        ep.planning,
        ep.target,
        ep.target_name,
        ep.place,
        ep.model.height,
        ep.cycle == 0,
        ep.config.palm_pose,
    )
