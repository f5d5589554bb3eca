"""A lateral grasp's friction reserve by the 3-D model, before the hand takes it: the squeeze's
planar shares (the normal forces of the S_G linear programme, Eq. 13) and the reserve of
friction the contacts keep when the hand squeezes them as Grasp Object would
(:func:`controllers.hand.lateral_squeeze.lateral_squeeze`, section 5.2)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.polygon import Polygon
from controllers.grasp.score import grasp_score
from controllers.hand.lateral_squeeze import lateral_squeeze
from controllers.reach.coarse import ReachTarget
from hand_sim.geometry import place_polygon


def planar_normal_forces(polygon: Polygon, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """The normal forces (n,) of the S_G linear programme (Eq. 13) for contacts ``theta`` on
    ``polygon``, in its unit-moment frame: the squeeze's shares (a lateral squeeze's prior)."""
    frames = polygon.unit_moment().locate(theta)
    return grasp_score(frames.point, frames.normal).normal_forces


def friction_reserve(
    target: ReachTarget,
    theta: NDArray[np.float64],
    points: NDArray[np.float64],
    load: float,
    centre: NDArray[np.float64],
) -> float:
    """The friction reserve (N) by the 3-D model of a lateral grasp of contacts ``theta`` on
    the perceived block ``target`` (world ``points`` (n, 3)), squeezed as Grasp Object would
    squeeze it to hold ``load`` (N) at the block's centre of mass ``centre`` (world); -inf where
    no forces hold the weight."""
    polygon = target.polygon
    normals_xy = place_polygon(polygon.locate(theta).normal, (0.0, 0.0), target.yaw)
    normals = np.column_stack([normals_xy, np.zeros(len(theta))])
    planar = planar_normal_forces(polygon, theta)
    squeeze = lateral_squeeze(points, normals, planar, load, centre)
    return -np.inf if squeeze.reserve is None else squeeze.reserve
