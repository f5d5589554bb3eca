"""Sampled finger postures: where each finger of the hand can put its fingertip, and how its pad
and links lie there, for a global search of a finger posture that takes a contact.

The reachability check of section 5.2 (:func:`controllers.hand.reachability.check_reach`) solves the
hand's inverse kinematics from the posture the hand has; a finger with several ways of reaching
a contact (abduction against flexion, a pad turned sideways or not) then ends in whichever the
iterates find first. In a lateral grasp the fingers that reach round the block's corners have a
narrow set of postures that take a contact with the pad and no link in the block, and the local
IK misses most of them. :class:`FingerSamples` holds the forward kinematics of seeded uniform
samples of every finger's joints in the palm's frame (computed once with MuJoCo on
``models/hand.xml``); :meth:`FingerSamples.best` picks, for one contact, the sample that takes it
with the most margin on the reachability criteria, as the IK's starting posture.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.errors import ReachError
from hand_sim import robot
from hand_sim.resources import models_dir

#: Finger postures sampled (uniform in the joint ranges) and the generator's seed.
SAMPLES = 20_000
SEED = 0
#: Points sampled along each finger link capsule's axis for the link-penetration tests (here and
#: in :func:`controllers.hand.reachability.link_penetration`).
POINTS_PER_LINK = 7
#: A sample's height preference (:meth:`FingerSamples.best`): every HEIGHT_SCALE (m) between its
#: contact's height and the preferred one counts as much as the whole margin of one criterion.
HEIGHT_SCALE = 0.05
#: Pad normal in the distal link's frame: the tip site sits 30 deg from the palmar normal (+z)
#: towards the tip (+y) (models/hand.xml).
PAD_NORMAL_LOCAL = np.array([0.0, np.sin(np.pi / 6), np.cos(np.pi / 6)])


@dataclass(frozen=True)
class Criteria:
    """The reachability criteria a sample is scored on (:mod:`controllers.hand.reachability`)."""

    tolerance: float  #: m, largest distance of the fingertip from its contact line
    max_pad_angle: float  #: rad
    max_sideways: float  #: |flexion axis . face normal|
    min_palmar: float  #: least palmar component of the direction into the face
    max_penetration: float  #: m, deepest a proximal or middle link may be inside the block
    squeeze: float  #: m, how far inside the surface the fingertip is placed


@dataclass(frozen=True, eq=False)
class FingerSamples:
    """Forward kinematics of ``n`` sampled hand postures in the palm body's frame; finger axis
    order ff, mf, rf, th."""

    q: NDArray[np.float64]  #: (n, 4, 4) each finger's joints (abduction, MCP, PIP, DIP)
    tip: NDArray[np.float64]  #: (n, 4, 3) fingertip sites
    pad: NDArray[np.float64]  #: (n, 4, 3) pad normals
    palmar: NDArray[np.float64]  #: (n, 4, 3) distal links' palmar normals
    side: NDArray[np.float64]  #: (n, 4, 3) distal links' flexion axes
    links: NDArray[np.float64]  #: (n, 4, P, 3) points on the proximal and middle capsule axes
    radius: NDArray[np.float64]  #: (4, P) capsule radius at each of those points

    @classmethod
    def draw(
        cls,
        n: int = SAMPLES,
        seed: int = SEED,
        pad_normal_local: ArrayLike = PAD_NORMAL_LOCAL,
    ) -> FingerSamples:
        """Sample ``n`` hand postures uniformly in the joint ranges of ``models/hand.xml``
        (generator seeded with ``seed``); ``pad_normal_local`` is the pad normal in a distal
        link's frame."""
        if n < 1:
            raise ReachError(f"need at least one sample, got {n}")
        model = mujoco.MjModel.from_xml_path(str(models_dir() / "hand.xml"))
        data = mujoco.MjData(model)
        fingers = robot.FINGERS
        lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
        q = np.random.default_rng(seed).uniform(lo, hi, size=(n, model.nq))
        tips = [model.site(robot.FINGERTIP_SITES[k]).id for k in range(len(fingers))]
        distal = [model.body(f"{f}_distal").id for f in fingers]
        capsules = [
            [
                g
                for g in range(model.ngeom)
                if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE
                and (model.geom_contype[g] or model.geom_conaffinity[g])
                and model.body(model.geom_bodyid[g]).name in (f"{f}_proximal", f"{f}_middle")
            ]
            for f in fingers
        ]
        frac = np.linspace(-1.0, 1.0, POINTS_PER_LINK)
        palm = model.body(robot.PALM_BODY).id
        used = sorted({g for c in capsules for g in c})
        # the forward kinematics of every sample first (the loop does nothing else), then the
        # frames as stacked products (the same arithmetic, sample by sample, as one product each)
        site_pos = np.empty((n, len(fingers), 3))
        body_rot = np.empty((n, model.nbody, 3, 3))
        palm_pos = np.empty((n, 3))
        geom_pos = np.empty((n, model.ngeom, 3))
        geom_axis = np.empty((n, model.ngeom, 3))
        for i in range(n):
            data.qpos[:] = q[i]
            mujoco.mj_kinematics(model, data)
            site_pos[i] = data.site_xpos[tips]
            body_rot[i] = data.xmat.reshape(-1, 3, 3)
            palm_pos[i] = data.xpos[palm]
            geom_pos[i, used] = data.geom_xpos[used]
            geom_axis[i, used] = data.geom_xmat[used].reshape(-1, 3, 3)[:, :, 2]
        R0 = body_rot[:, palm]
        tip = np.matmul(site_pos - palm_pos[:, None], R0)
        R = np.matmul(R0.transpose(0, 2, 1)[:, None], body_rot[:, distal])  # (n, 4, 3, 3)
        pad = np.ascontiguousarray(np.matmul(R, np.asarray(pad_normal_local, dtype=float)))
        side = R[..., 0].copy()
        palmar = R[..., 2].copy()
        n_pts = max(len(c) for c in capsules) * POINTS_PER_LINK
        links = np.zeros((n, len(fingers), n_pts, 3))
        for k, caps in enumerate(capsules):
            for j, g in enumerate(caps):
                half = frac[:, None] * model.geom_size[g, 1]
                pts = geom_pos[:, g, None] + half[None] * geom_axis[:, g, None]
                links[:, k, j * POINTS_PER_LINK : (j + 1) * POINTS_PER_LINK] = np.matmul(
                    pts - palm_pos[:, None], R0
                )
        radius = np.array(
            [np.repeat(model.geom_size[c, 0], POINTS_PER_LINK) for c in capsules], dtype=float
        )
        per_finger = q.reshape(n, len(fingers), robot.JOINTS_PER_FINGER)
        return cls(per_finger, tip, pad, palmar, side, links, radius)

    def posture_shares(
        self,
        finger: int,
        index: NDArray[np.int64],
        palm_position: NDArray[np.float64],
        palm_rotation: NDArray[np.float64],
        normal_local: NDArray[np.float64],
        signed_distance,
        criteria: Criteria,
    ) -> NDArray[np.float64]:
        """For the samples ``index`` of ``finger`` (the palm at world ``palm_position``,
        ``palm_rotation``), each pressing a face with outward normal ``normal_local`` (3,) or
        (len(index), 3), in the palm's frame: the worst of its pad angle, its sideways lean, how
        far off the palmar half of the fingertip the contact lies and its links' penetration of
        the block (``signed_distance`` of world points, negative inside), each as a share of its
        limit in ``criteria`` (below 1: the reachability criteria of section 5.2 hold)."""
        n = np.asarray(normal_local, dtype=float)

        def along(vectors: NDArray[np.float64]) -> NDArray[np.float64]:
            return vectors @ n if n.ndim == 1 else np.einsum("ij,ij->i", vectors, n)

        angle = np.arccos(np.clip(-along(self.pad[index, finger]), -1.0, 1.0))
        sideways = np.abs(along(self.side[index, finger]))
        palmar = -along(self.palmar[index, finger])
        world_links = self.links[index, finger] @ palm_rotation.T + palm_position
        depth = (self.radius[finger] - signed_distance(world_links)).max(axis=1)
        return np.maximum.reduce(
            [
                angle / criteria.max_pad_angle,
                sideways / criteria.max_sideways,
                (1.0 - palmar) / (1.0 - criteria.min_palmar),
                np.maximum(depth, 0.0) / criteria.max_penetration,
            ]
        )

    def best(
        self,
        finger: int,
        palm_position: ArrayLike,
        palm_rotation: ArrayLike,
        point: ArrayLike,
        normal: ArrayLike,
        heights: tuple[float, float],
        signed_distance,
        criteria: Criteria,
        prefer: float | None = None,
    ) -> tuple[NDArray[np.float64] | None, float]:
        """Joints (4,) of the sample of ``finger`` that takes the contact at world ``point`` with
        outward face ``normal`` (horizontal) best, the palm at world ``palm_position`` and
        ``palm_rotation`` (3, 3), and its score: the worst of the fingertip's distance from the
        contact line (the vertical line ``criteria.squeeze`` inside the face at the contact, between
        ``heights``), its pad angle, its sideways lean, how far off the palmar half of the fingertip
        the contact lies and its links' penetration of the block (``signed_distance`` of world
        points (..., 3), negative inside), each as a share of its limit; (None, inf) when no
        sample's fingertip is on the line within the tolerance. With ``prefer`` (a world height, m),
        of the samples that meet every criterion the one whose score plus its contact's distance
        from that height over HEIGHT_SCALE is lowest: sliding contacts of opposed fingers then take
        one height, and the squeeze does not tip the block."""
        p0 = np.asarray(palm_position, dtype=float)
        R0 = np.asarray(palm_rotation, dtype=float)
        n = np.asarray(normal, dtype=float)
        target = np.asarray(point, dtype=float) - criteria.squeeze * n
        a = R0.T @ (target - p0)
        up = R0.T @ np.array([0.0, 0.0, 1.0])
        n_local = R0.T @ n
        tip = self.tip[:, finger]
        along = (tip - a) @ up
        off = np.linalg.norm(tip - a - along[:, None] * up, axis=1)
        z = target[2] + along
        near = np.flatnonzero((off < criteria.tolerance) & (z >= heights[0]) & (z <= heights[1]))
        if near.size == 0:
            return None, np.inf
        score = np.maximum(
            off[near] / criteria.tolerance,
            self.posture_shares(finger, near, p0, R0, n_local, signed_distance, criteria),
        )
        cost = score.copy()
        if prefer is not None and (score < 1.0).any():
            cost = np.where(score < 1.0, score + np.abs(z[near] - prefer) / HEIGHT_SCALE, np.inf)
        j = int(np.argmin(cost))
        return self.q[near[j], finger].copy(), float(score[j])
