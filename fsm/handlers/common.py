"""What several state handlers share: the episode's view of the controllers' explicit inputs
(the motion primitives' :class:`~controllers.motion.BlockSite`, the palm-pose search's
:class:`~controllers.palm_pose.ReachQuery`), whether this cycle's grasp is lateral, and the
lateral pre-shape (Coarse Reach, and a lateral regrasp)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.finger_geometry import fingertips_at
from controllers.finger_samples import PAD_NORMAL_LOCAL, FingerSamples
from controllers.grasp.session import keep_contacts
from controllers.grasp.session3d import GraspSynthesis3D
from controllers.hand_reach import CONTACT_SEPARATION, SQUEEZE_REACH, FingerContacts
from controllers.motion import ApproachPlan, BlockSite, approach, approach_plan
from controllers.palm_candidates import (
    PalmPose,
    PoseSetting,
    lateral_arcs,
    lateral_poses,
    robot_base_xy,
    side_contacts,
)
from controllers.palm_pose import ReachQuery, search_poses
from fsm.context import Episode
from hand_sim import robot
from hand_sim.geometry import place_polygon


def slides(ep: Episode) -> bool:
    """Whether the contacts may slide up and down their faces: in a lateral grasp the finger row
    is horizontal and the thumb below it, so the hand's shape, not a depth below the top, sets
    each finger's height on the block (a top grasp keeps its fingers at the depth they
    reached)."""
    return ep.coarse is not None and ep.coarse.approach == "lateral"


def finger_samples(ep: Episode) -> FingerSamples:
    """Sampled finger postures, IK starts for a palm-pose search (drawn once an episode)."""
    if ep.finger_samples is None:
        ep.finger_samples = FingerSamples.draw(pad_normal_local=PAD_NORMAL_LOCAL)
    return ep.finger_samples


def squeeze_reach(ep: Episode) -> float:
    """How far past its contact each fingertip must reach in this cycle's grasp."""
    return ep.config.lateral_squeeze_reach if slides(ep) else SQUEEZE_REACH


def block_site(ep: Episode) -> BlockSite:
    """The motion primitives' inputs for this cycle's block: the approach axis is the coarse
    reach's (straight down for a top grasp, along the arm's radius for a lateral one)."""
    return BlockSite(
        ep.world,
        ep.planning,
        ep.target,
        ep.world.block_body_id(ep.target_name),
        ep.coarse.goal.palm_rotation[:, 2],
        lateral=slides(ep),
        params=ep.config.motion,
    )


def reach_query(ep: Episode) -> ReachQuery:
    """The reach test's inputs for this cycle's block. In a lateral grasp the contacts slide on
    their faces and the hand IK starts from the episode's sampled finger postures (drawn when
    first needed: the reach test searches them for sliding contacts only); a top 3-D grasp's
    contacts are taken at their own heights."""
    lateral = slides(ep)
    return ReachQuery(
        ep.world,
        ep.planning,
        ep.prism,
        ep.target,
        slide=lateral,
        samples=finger_samples(ep) if lateral else None,
        squeeze=squeeze_reach(ep),
        # a lateral hand's fingers slide to the heights they can take (a lateral 3-D grasp
        # then takes those heights); a top 3-D grasp's fingers go to its contacts' heights
        heights=None if lateral else contact_heights(ep),
    )


def contact_heights(ep: Episode) -> NDArray[np.float64] | None:
    """World z of the 3-D grasp's contacts (None for a planar grasp: the fingers' heights)."""
    syn = ep.synthesis
    if not isinstance(syn, GraspSynthesis3D):
        return None
    return ep.prism.centre_z + syn.heights


def plan_approach(
    ep: Episode, qpos: NDArray[np.float64], contacts: FingerContacts
) -> ApproachPlan | None:
    """:func:`controllers.motion.approach_plan` for this cycle's block and grasp."""
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
    (:func:`controllers.palm_candidates.lateral_arcs`; row 0 left of the approach axis, row 1
    right)."""
    return lateral_arcs(ep.target, robot_base_xy(ep.world), ep.config.palm_pose)


def arcs_of(arcs: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each contact's arc (n, 2): the one of ``arcs`` (:func:`side_arcs`) it lies on or is
    nearest to (by contact coordinate)."""
    two_pi = 2.0 * np.pi

    def distance(t: float, arc: NDArray[np.float64]) -> float:
        span = float(np.mod(arc[1] - arc[0], two_pi))
        rel = float(np.mod(t - arc[0], two_pi))
        return 0.0 if rel <= span else min(rel - span, two_pi - rel)

    return np.array([min(arcs, key=lambda arc: distance(float(t), arc)) for t in theta])


def lateral_preshape(ep: Episode, skip: int = 0) -> str | None:
    """The lateral pre-shape: the palm pose beside the block from which the hand best reaches
    the surface points nearest the fingertips of the pinch pre-shape there (kept a pad spacing
    apart; :func:`controllers.palm_pose.search_poses` over
    :func:`controllers.palm_candidates.lateral_poses`); the hand pre-shapes outside those points
    and the palm moves there along its approach axis (``skip``: the next pose). The contacts, when
    the hand reaches them there, are kept (``ep.preshape_contacts``) for Fine Reach and the grasp
    controller. Returns what was done, for the log, or None when no pose is approached without
    collision."""
    base = robot_base_xy(ep.world)
    params = ep.config.palm_pose
    arcs = side_arcs(ep)

    def pinch_contacts(pose: PalmPose) -> NDArray[np.float64]:
        tips = fingertips_at(ep.planning, pose.qpos)
        theta = side_contacts(ep.target, base, tips, params.side_inset, arcs)
        # pads apart, each contact kept on its side's arc
        return keep_contacts(
            ep.target.polygon,
            theta,
            CONTACT_SEPARATION,
            robot.PAD_RADIUS,
            arcs_of(arcs, theta),
        )

    ep.preshape_contacts = None
    where = PoseSetting(ep.world, ep.planning, ep.target, ep.coarse.goal.palm_rotation)
    poses = lateral_poses(where, params, arcs)
    found = search_poses(
        reach_query(ep),
        poses,
        pinch_contacts,
        lambda qpos, contacts: plan_approach(ep, qpos, contacts),
        tries=params.pose_tries,
        reachable_only=False,
        skip=skip,
    )
    if not found.found:
        return None
    approach(block_site(ep), found.approach)
    if found.reach is not None and found.reach.reachable:
        ep.preshape_contacts = found.contacts
    return f"pinch pre-shape, {found.label} (reach load {found.load:.2f})"
