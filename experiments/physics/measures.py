"""What the grasp metrics say about a grasp as the hand really holds it.

At the end of the squeeze the fingers touch the block where MuJoCo says they do, not exactly where
the controller put the contacts. :func:`held_contacts` reads those points (each finger's
force-weighted mean contact point with the block, in the block's centre-of-mass frame) and
:func:`grasp_measures` scores them three ways:

- ``planar_sg``: S_G of Eq. 13 in the plane (the contacts' polar angles on the unit-moment
  polygon, heights ignored), the verdict the planar study tested;
- ``sg3d``: S_G with 6-D wrenches and the round friction cone (mu = 1), the null grasp;
- ``worst_sg3d``: the largest 3-D S_G over the physical test's own task wrenches (the hang and
  m*g at the centre of mass along +-x, +-y, +-z, :func:`controllers.grasp.physical_tasks`), with
  m*g in units of the grip force per finger (the program's unit normal force), and its stage.

Lengths are those of the planar trials (unit-moment polygon: divided by the polygon's largest
moment). A grasp where some finger does not touch the block at the end of the squeeze is not
scored (None).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.polygon import Polygon
from controllers.grasp.prism3d import worst_task_score
from controllers.grasp.score import grasp_score
from controllers.grasp.score3d import grasp_score_3d
from hand_sim import robot
from hand_sim.contacts import robot_contacts
from hand_sim.world import World


@dataclass(frozen=True)
class GraspMeasures:
    """The three scores of one held grasp and where its contacts are (m, block CoM frame)."""

    planar_sg: float | None
    sg3d: float | None
    worst_sg3d: float | None
    worst_stage: str
    heights: list[float]  #: contact heights above the block's centre of mass (m), ff mf rf th

    def to_json(self) -> dict:
        return asdict(self)


def held_contacts(world: World, block: str) -> NDArray[np.float64] | None:
    """(4, 3) each finger's (ff, mf, rf, th) contact point with ``block`` in the block's
    centre-of-mass frame (its force-weighted mean over the finger's links), or None when a
    finger does not touch it."""
    body = world.block_body_id(block)
    com = world.data.xpos[body]  # a block body's origin is its centre of mass
    R = world.data.xmat[body].reshape(3, 3)
    out = np.zeros((len(robot.FINGERS), 3))
    for i, f in enumerate(robot.FINGERS):
        cs = [c for c in robot_contacts(world, body) if c.finger == f and c.normal_force > 0]
        if not cs:
            return None
        w = np.array([c.normal_force for c in cs])
        p = np.array([c.position for c in cs])
        out[i] = R.T @ ((w[:, None] * p).sum(0) / w.sum() - com)
    return out


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def grasp_measures(
    points: NDArray[np.float64], polygon: Polygon, block_yaw: float, load: float
) -> GraspMeasures:
    """Score contact ``points`` (n, 3, block CoM frame, m) on a block with footprint
    ``polygon`` (m, centroid at the origin) turned by ``block_yaw`` in the world; ``load`` is
    m*g over the grip force per finger. Each point is put on the side face its polar angle
    meets (the fingers press the sides), at its own height."""
    scale = polygon.max_moment
    unit = polygon.unit_moment()
    theta = np.arctan2(points[:, 1], points[:, 0])
    frames = unit.locate(theta)
    planar = grasp_score(frames.point, frames.normal)
    p3 = np.column_stack([frames.point, points[:, 2] / scale])
    n3 = np.column_stack([frames.normal, np.zeros(len(theta))])
    s3 = grasp_score_3d(p3, n3)
    # the world's x axis in the block's frame is at angle -yaw
    stage, worst = worst_task_score(p3, n3, load, yaw=-block_yaw)
    return GraspMeasures(
        planar_sg=_finite(planar.s_g),
        sg3d=_finite(s3.s_g),
        worst_sg3d=_finite(worst.s_g),
        worst_stage=stage,
        heights=[round(float(z), 5) for z in points[:, 2]],
    )
