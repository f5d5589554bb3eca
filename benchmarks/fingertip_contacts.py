"""Where sampled hand configurations touch a prism placed against the palm: the geometry behind
:mod:`benchmarks.hand_reachability`.

Hand configurations are sampled uniformly in the joint ranges of models/hand.xml and their
fingertips, pad normals and finger capsules expressed in the palm frame (:func:`sample_hand`).
A prism (section 5.1: a paper object's polygon extruded 20 cm) is placed over the palm (top
grasp) or beside it (lateral grasp, section 5.2) at a grid of offsets and gaps
(:func:`top_placements`, :func:`lateral_placements`). A fingertip "contacts" a face when its tip
site is within :data:`TOLERANCE` of the face, at least :data:`EDGE_MARGIN` from its vertical
edges, its pad normal points into the face (angle < :data:`MAX_PAD_ANGLE`) and no capsule of
that finger penetrates the prism by more than :data:`MAX_PENETRATION` (:func:`finger_contacts`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.grasp import Polygon
from controllers.hand.finger_samples import PAD_NORMAL_LOCAL
from hand_sim.resources import models_dir
from hand_sim.robot import FINGERS

HAND_XML = models_dir() / "hand.xml"

#: Contact tolerance: tip site within this distance of a face (m).
TOLERANCE = 0.003
#: Contacts must stay this far from a face's vertical edges (m).
EDGE_MARGIN = 0.003
#: Largest angle between the pad normal and the face's inward normal (rad).
MAX_PAD_ANGLE = np.deg2rad(60.0)
#: Largest penetration of a finger capsule into the prism (m): the pad is soft.
MAX_PENETRATION = 0.0015
#: Palm face height in the hand frame (m) and the gaps kept between it and the prism.
PALM_FACE_Z = 0.025
TOP_CLEARANCE = (0.005, 0.02, 0.035)
LATERAL_CLEARANCE = (0.003, 0.015, 0.03)
#: Prism height (m, section 5.1). Top grasps: contacts between these depths below the top face;
#: lateral grasps: the prism's middle faces the palm centre, contacts within this half span.
BLOCK_HEIGHT = 0.20
TOP_DEPTH_RANGE = (0.01, 0.12)
LATERAL_HALF_SPAN = 0.09
#: Block centre offsets searched in the palm plane (m), and lateral wrist-roll angles (rad).
CENTRE_OFFSETS = np.arange(-0.03, 0.0301, 0.01)
LATERAL_ROLLS = (0.0, np.pi / 4, np.pi / 2, 3 * np.pi / 4)
#: Points sampled along each collision capsule's axis.
POINTS_PER_CAPSULE = 4


@dataclass(frozen=True)
class HandSamples:
    """Forward kinematics of sampled hand configurations, hand frame (palm body frame)."""

    qpos: NDArray[np.float64]  #: (N, nq)
    tip: NDArray[np.float64]  #: (N, 4, 3) tip site positions
    pad: NDArray[np.float64]  #: (N, 4, 3) pad normals
    points: NDArray[np.float64]  #: (N, 4, P, 3) points on the capsule axes of each finger
    radius: NDArray[np.float64]  #: (4, P) capsule radius at each point


def sample_hand(n: int, rng: np.random.Generator, xml: Path = HAND_XML) -> HandSamples:
    """Uniform joint samples within the joint ranges and their forward kinematics."""
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    lo, hi = model.jnt_range[:, 0], model.jnt_range[:, 1]
    qpos = rng.uniform(lo, hi, size=(n, model.nq))
    tip_ids = [model.site(f"{f}_tip").id for f in FINGERS]
    distal = [model.body(f"{f}_distal").id for f in FINGERS]
    geoms: list[list[int]] = []
    for f in FINGERS:
        ids = [
            g
            for g in range(model.ngeom)
            if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE
            and (model.geom_contype[g] or model.geom_conaffinity[g])
            and model.body(model.geom_bodyid[g]).name.startswith(f + "_")
        ]
        geoms.append(ids)
    n_pts = max(len(g) for g in geoms) * POINTS_PER_CAPSULE
    frac = np.linspace(-1.0, 1.0, POINTS_PER_CAPSULE)
    radius = np.zeros((4, n_pts))
    for k, ids in enumerate(geoms):
        radius[k] = np.repeat(model.geom_size[ids, 0], POINTS_PER_CAPSULE)
    tip = np.zeros((n, 4, 3))
    pad = np.zeros((n, 4, 3))
    pts = np.zeros((n, 4, n_pts, 3))
    palm = model.body("palm").id
    for i in range(n):
        data.qpos[:] = qpos[i]
        mujoco.mj_kinematics(model, data)
        # Express in the palm frame (the palm is the root body, so this is the identity unless the
        # model is placed elsewhere in a scene).
        rp, pp = data.xmat[palm].reshape(3, 3), data.xpos[palm]
        tip[i] = (data.site_xpos[tip_ids] - pp) @ rp
        for k in range(4):
            pad[i, k] = (data.xmat[distal[k]].reshape(3, 3) @ PAD_NORMAL_LOCAL) @ rp
            ids = geoms[k]
            axis = data.geom_xmat[ids].reshape(-1, 3, 3)[:, :, 2]
            half = model.geom_size[ids, 1]
            p = data.geom_xpos[ids][:, None, :] + frac[None, :, None] * (
                half[:, None, None] * axis[:, None, :]
            )
            pts[i, k] = (p.reshape(-1, 3) - pp) @ rp
    return HandSamples(qpos, tip, pad, pts, radius)


def perimeter_frames(poly: Polygon) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Per edge: outward normal (E, 2), offset (E,), tangent coordinate of its start and end."""
    n = np.stack([np.cos(poly.normal_angle), np.sin(poly.normal_angle)], axis=1)
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    v = poly.vertices
    s0 = np.einsum("ij,ij->i", t, v)
    s1 = np.einsum("ij,ij->i", t, np.roll(v, -1, axis=0))
    return n, poly.offset, s0, s1


@dataclass(frozen=True)
class Contacts:
    """Fingertip contacts of one finger's samples at one placement (object frame)."""

    index: NDArray[np.int64]  #: sample indices
    arc: NDArray[np.float64]  #: perimeter position of the contact (m)
    point: NDArray[np.float64]  #: (k, 2) contact point on the face
    normal: NDArray[np.float64]  #: (k, 2) outward face normal


@dataclass(frozen=True)
class Placement:
    """A prism pose relative to the hand: maps hand-frame points to (2-D section, axial) coords."""

    origin: NDArray[np.float64]  #: a point of the prism axis, hand frame
    e1: NDArray[np.float64]  #: section x axis (hand frame)
    e2: NDArray[np.float64]  #: section y axis
    axis: NDArray[np.float64]  #: prism axis, pointing into the prism from its top face
    top: bool  #: True: prism from ``origin`` (top face) on; False: centred on ``origin``

    @property
    def axial_range(self) -> tuple[float, float]:
        """Axial extent (m) of the prism along ``axis`` from ``origin``."""
        return (0.0, BLOCK_HEIGHT) if self.top else (-0.5 * BLOCK_HEIGHT, 0.5 * BLOCK_HEIGHT)

    def to_block(self, p: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """Hand-frame points (..., 3) as section coordinates (..., 2) and axial coordinates."""
        d = p - self.origin
        return np.stack([d @ self.e1, d @ self.e2], axis=-1), d @ self.axis


def rot2(v: NDArray, ang: float) -> NDArray:
    """2-D vectors (..., 2) turned by ``ang`` (rad)."""
    c, s = np.cos(ang), np.sin(ang)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def top_placements(poly: Polygon, yaw: float) -> list[Placement]:
    """Palm down over the prism: axis = palm normal (+z), section = palm plane, yawed."""
    out = []
    c, s = np.cos(yaw), np.sin(yaw)
    e1, e2 = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    for gap in TOP_CLEARANCE:
        for x in CENTRE_OFFSETS:
            for y in CENTRE_OFFSETS:
                origin = np.array([x, y, PALM_FACE_Z + gap])
                out.append(Placement(origin, e1, e2, np.array([0.0, 0.0, 1.0]), True))
    return out


def lateral_placements(poly: Polygon, yaw: float) -> list[Placement]:
    """Palm beside the prism: axis in the palm plane at each wrist roll; the section plane is
    spanned by the in-palm direction across the axis and the palm normal."""
    out = []
    z = np.array([0.0, 0.0, 1.0])
    for phi in LATERAL_ROLLS:
        a = np.array([np.cos(phi), np.sin(phi), 0.0])
        b = np.array([-np.sin(phi), np.cos(phi), 0.0])
        c, s = np.cos(yaw), np.sin(yaw)
        e1, e2 = c * b + s * z, -s * b + c * z  # section frame (b, z) turned by yaw
        # Nearest prism point to the palm along z: min over vertices of their z coordinate.
        vz = poly.vertices[:, 0] * e1[2] + poly.vertices[:, 1] * e2[2]
        for gap in LATERAL_CLEARANCE:
            for u in CENTRE_OFFSETS:
                origin = u * b + (PALM_FACE_Z + gap - vz.min()) * z
                out.append(Placement(origin, e1, e2, a, False))
    return out


def near_faces(
    poly: Polygon, placements: list[Placement], tips: NDArray[np.float64], tol: float
) -> NDArray[np.bool_]:
    """(P, N): is tip n within ``tol`` of the prism's side surface at placement p (a cheap
    first filter over all placements at once; :func:`finger_contacts` checks the rest)."""
    origin = np.stack([pl.origin for pl in placements])
    frame = np.stack([np.stack([pl.e1, pl.e2, pl.axis]) for pl in placements])  # (P, 3, 3)
    local = (tips[None, :, :] - origin[:, None, :]) @ frame.transpose(0, 2, 1)
    n, off, _, _ = perimeter_frames(poly)
    sd = (local[..., :2] @ n.T - off).max(axis=-1)
    lo = np.array([TOP_DEPTH_RANGE[0] if pl.top else -LATERAL_HALF_SPAN for pl in placements])
    hi = np.array([TOP_DEPTH_RANGE[1] if pl.top else LATERAL_HALF_SPAN for pl in placements])
    ax = local[..., 2]
    return (np.abs(sd) <= tol) & (ax >= lo[:, None]) & (ax <= hi[:, None])


def finger_contacts(
    poly: Polygon,
    pl: Placement,
    hs: HandSamples,
    finger: int,
    tol: float,
    candidates: NDArray[np.int64] | None = None,
) -> Contacts:
    """Samples of ``finger`` (among ``candidates``, default all) whose tip touches a side face at
    placement ``pl``."""
    n, off, s0, s1 = perimeter_frames(poly)
    cand = np.arange(hs.tip.shape[0]) if candidates is None else candidates
    tip2, tip_ax = pl.to_block(hs.tip[cand, finger])
    sd_all = tip2 @ n.T - off
    j = np.argmax(sd_all, axis=1)
    sd = sd_all[np.arange(len(j)), j]
    t = np.stack([-n[j, 1], n[j, 0]], axis=1)
    s = np.einsum("ij,ij->i", tip2, t)
    ok = (np.abs(sd) <= tol) & (s >= s0[j] + EDGE_MARGIN) & (s <= s1[j] - EDGE_MARGIN)
    lo, hi = TOP_DEPTH_RANGE if pl.top else (-LATERAL_HALF_SPAN, LATERAL_HALF_SPAN)
    ok &= (tip_ax >= lo) & (tip_ax <= hi)
    idx = np.flatnonzero(ok)
    if idx.size:
        jj = j[idx]
        pad2, _ = pl.to_block(hs.pad[cand[idx], finger] + pl.origin)
        good = -np.einsum("ij,ij->i", pad2, n[jj]) >= np.cos(MAX_PAD_ANGLE)
        clear = link_clearance(poly, pl, hs.points[cand[idx], finger]) - hs.radius[finger]
        good &= clear.min(axis=1) >= -MAX_PENETRATION
        idx = idx[good]
    j, s, sd = j[idx], s[idx], sd[idx]
    cum = np.concatenate([[0.0], np.cumsum(s1 - s0)])
    point = tip2[idx] - sd[:, None] * n[j]  # projection of the tip onto its face
    return Contacts(cand[idx], cum[j] + s - s0[j], point, n[j])


def link_clearance(poly: Polygon, pl: Placement, pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from points (..., 3) to the prism (negative inside), approximate at vertices."""
    n, off, _, _ = perimeter_frames(poly)
    p2, ax = pl.to_block(pts)
    sd = (p2 @ n.T - off).max(axis=-1)
    lo, hi = pl.axial_range
    beyond = np.maximum(lo - ax, ax - hi)  # distance past an end face (> 0 outside)
    return np.where(beyond > 0.0, np.where(sd > 0.0, np.hypot(sd, beyond), beyond), sd)


def fingers_overlap(hs: HandSamples, choice: NDArray[np.int64]) -> bool:
    """True when capsules of two different fingers (each from its own sample) intersect."""
    for a in range(4):
        for b in range(a + 1, 4):
            pa, pb = hs.points[choice[a], a], hs.points[choice[b], b]
            d = np.linalg.norm(pa[:, None, :] - pb[None, :, :], axis=-1)
            if np.any(d < hs.radius[a][:, None] + hs.radius[b][None, :] - 0.001):
                return True
    return False
