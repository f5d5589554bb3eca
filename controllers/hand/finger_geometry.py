"""The perceived block and where the fingers are against it (section 5.2, "Wrench Closure": "finger
links penetrates the object"): the perceived prism and its exact signed distance, each finger's
clearance from it and its links' penetration into it, fingertip positions, and the distal links'
pad, palmar and sideways directions. The reachability test (:mod:`controllers.hand.reachability`)
and the grip (:mod:`controllers.hand.grip`) judge postures with these measures.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.hand.finger_samples import PAD_NORMAL_LOCAL, POINTS_PER_LINK
from controllers.reach.coarse import ReachTarget
from hand_sim import robot


@dataclass(frozen=True, eq=False)
class PerceivedPrism:
    """The block as perceived: its footprint polygon turned by ``yaw``, centred at
    ``position_xy``, standing from ``bottom`` to ``top`` (m, world z)."""

    footprint: NDArray[np.float64]  #: (k, 2) world vertices, CCW
    bottom: float
    top: float

    @classmethod
    def of(cls, target: ReachTarget, bottom: float) -> PerceivedPrism:
        """The prism of ``target``'s footprint from ``bottom`` up to its top face."""
        return cls(target.footprint(), float(bottom), float(target.top_z))

    @property
    def centre_z(self) -> float:
        """World z (m) of the prism's mid-height: the 3-D grasp model's centre of mass."""
        return 0.5 * (self.bottom + self.top)

    def signed_distance(self, points: ArrayLike) -> NDArray[np.float64]:
        """Exact signed distance (m) of points (..., 3) to the prism; negative inside. In the
        plane, the distance to the nearest footprint edge (each point projected onto each edge,
        x and y kept apart so that no (..., k, 2) arrays are built; the root taken once, of the
        nearest), negative inside every edge's half-plane (the footprint is convex, CCW)."""
        p = np.asarray(points, dtype=float)
        x, y = p[..., 0, None], p[..., 1, None]  # (..., 1) against the k edges
        a = self.footprint
        ab = np.roll(a, -1, axis=0) - a
        ax, ay, abx, aby = a[:, 0], a[:, 1], ab[:, 0], ab[:, 1]
        rx, ry = x - ax, y - ay
        t = np.clip((rx * abx + ry * aby) / (abx * abx + aby * aby), 0.0, 1.0)
        dx, dy = x - (ax + t * abx), y - (ay + t * aby)
        edge_dist = np.sqrt((dx * dx + dy * dy).min(axis=-1))
        inside_xy = np.all(abx * ry - aby * rx >= 0.0, axis=-1)
        d_xy = np.where(inside_xy, -edge_dist, edge_dist)
        d_z = np.maximum(self.bottom - p[..., 2], p[..., 2] - self.top)
        outside = np.hypot(np.maximum(d_xy, 0.0), np.maximum(d_z, 0.0))
        return np.where((d_xy > 0) | (d_z > 0), outside, np.maximum(d_xy, d_z))

    def signed_distance_near(self, points: ArrayLike, within: float) -> NDArray[np.float64]:
        """:meth:`signed_distance` of the points (..., 3) that may lie less than ``within`` (m)
        from the prism; +inf for the rest, which lie further out than ``within`` (outside the
        circle about the footprint's vertex mean that holds it, grown by ``within``, or above
        or below it by more): a search that asks only whether points are within ``within``
        measures only those that may be."""
        p = np.asarray(points, dtype=float)
        margin = max(float(within), 0.0)
        hub = self.footprint.mean(axis=0)
        reach = np.sqrt(((self.footprint - hub) ** 2).sum(axis=1).max()) + margin + 1e-9
        z = p[..., 2]
        near = (
            (((p[..., :2] - hub) ** 2).sum(axis=-1) <= reach * reach)
            & (z >= self.bottom - margin - 1e-9)
            & (z <= self.top + margin + 1e-9)
        )
        out = np.full(p.shape[:-1], np.inf)
        out[near] = self.signed_distance(p[near])
        return out


def _finger_capsules(model: mujoco.MjModel) -> list[tuple[str, int]]:
    """(finger, geom id) of every colliding capsule of the fingers."""
    out = []
    for g in range(model.ngeom):
        if model.geom_type[g] != mujoco.mjtGeom.mjGEOM_CAPSULE:
            continue
        if not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        name = model.body(model.geom_bodyid[g]).name
        for finger in robot.FINGERS:
            if name.startswith(robot.HAND_PREFIX + finger + "_"):
                out.append((finger, g))
    return out


def finger_clearance(
    model: mujoco.MjModel, data: mujoco.MjData, prism: PerceivedPrism
) -> NDArray[np.float64]:
    """(4,) smallest distance (m) of each finger's links, pads included, to ``prism`` (negative:
    inside) for the kinematics in ``data``, order ff, mf, rf, th."""
    frac = np.linspace(-1.0, 1.0, POINTS_PER_LINK)
    out = np.full(len(robot.FINGERS), np.inf)
    for finger, g in _finger_capsules(model):
        axis = data.geom_xmat[g].reshape(3, 3)[:, 2]
        radius, half = model.geom_size[g, 0], model.geom_size[g, 1]
        pts = data.geom_xpos[g] + frac[:, None] * half * axis
        f = robot.FINGERS.index(finger)
        out[f] = min(out[f], float(prism.signed_distance(pts).min() - radius))
    return out


def link_penetration(
    model: mujoco.MjModel, data: mujoco.MjData, prism: PerceivedPrism
) -> dict[str, float]:
    """Deepest penetration (m, >= 0) of each finger's proximal and middle links into ``prism``
    for the kinematics in ``data`` (capsule axes sampled at :data:`POINTS_PER_LINK` points; the
    distal pads are meant to press into it)."""
    frac = np.linspace(-1.0, 1.0, POINTS_PER_LINK)
    out = dict.fromkeys(robot.FINGERS, 0.0)
    for finger, g in _finger_capsules(model):
        if model.body(model.geom_bodyid[g]).name.endswith("_distal"):
            continue  # the pad presses into the block by design
        axis = data.geom_xmat[g].reshape(3, 3)[:, 2]
        radius, half = model.geom_size[g, 0], model.geom_size[g, 1]
        pts = data.geom_xpos[g] + frac[:, None] * half * axis
        depth = float((radius - prism.signed_distance(pts)).max())
        out[finger] = max(out[finger], depth)
    return out


def fingertips_at(model: mujoco.MjModel, qpos: ArrayLike) -> NDArray[np.float64]:
    """(4, 3) world fingertip positions (ff, mf, rf, th) of ``model`` at configuration ``qpos``."""
    data = mujoco.MjData(model)
    data.qpos[:] = np.asarray(qpos, dtype=float)
    mujoco.mj_kinematics(model, data)
    sites = [model.site(robot.qualified(s)).id for s in robot.FINGERTIP_SITES]
    return data.site_xpos[sites].copy()


def finger_palmar(model: mujoco.MjModel, data: mujoco.MjData) -> NDArray[np.float64]:
    """(4, 3) world direction of each distal link's palmar normal (z)."""
    bodies = [model.body(robot.hand_name(f"{f}_distal")).id for f in robot.FINGERS]
    return np.stack([data.xmat[b].reshape(3, 3)[:, 2] for b in bodies])


def finger_sideways(model: mujoco.MjModel, data: mujoco.MjData) -> NDArray[np.float64]:
    """(4, 3) world direction of each distal link's sideways axis (its flexion axis, x)."""
    bodies = [model.body(robot.hand_name(f"{f}_distal")).id for f in robot.FINGERS]
    return np.stack([data.xmat[b].reshape(3, 3)[:, 0] for b in bodies])


def pad_normals(model: mujoco.MjModel, data: mujoco.MjData) -> NDArray[np.float64]:
    """(4, 3) world pad normals (out of the pad) of the fingertips, order ff, mf, rf, th."""
    bodies = [model.body(robot.hand_name(f"{f}_distal")).id for f in robot.FINGERS]
    return np.stack([data.xmat[b].reshape(3, 3) @ PAD_NORMAL_LOCAL for b in bodies])
