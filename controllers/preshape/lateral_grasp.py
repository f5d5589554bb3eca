"""A lateral grasp the hand can take, chosen by S_G among its sampled finger postures (section
5.2: Fine Reach and Wrench Closure after a lateral approach; docs/findings.md, "Sampled
contacts first").

A lateral hand faces the block along the arm's radius with its finger row horizontal; which points
of the block's outline its fingers can press with their pads depends on the block's width and turn,
and a fixed pinch pre-shape's fingertips, projected across the approach axis, land on points the
hand cannot take on most blocks that are not the rectangle it was found on. Here, at a palm pose
beside the block, every sampled posture of each finger
(:class:`controllers.hand.finger_samples.FingerSamples`) whose fingertip lies ``squeeze`` inside a
side face of the perceived prism and that meets the reachability criteria of
:mod:`controllers.hand.reachability` (pad facing the face, not sideways, the contact on the palmar
half, no link in the block) gives that finger a candidate contact. Of the combinations of one
candidate per finger whose pads fit (their centres :data:`CONTACT_SEPARATION` apart where they take
their contacts, heights included), the one with the lowest S_G (Eq. 13, planar, on the unit-moment
polygon, section 3.4) is the grasp; the reach test then confirms it with the hand's own inverse
kinematics.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import partial

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.grasp.polygon import Polygon
from controllers.grasp.score import grasp_score
from controllers.hand.finger_assignment import pressing_fingers
from controllers.hand.finger_geometry import PerceivedPrism
from controllers.hand.finger_samples import Criteria, FingerSamples
from controllers.hand.reachability import (
    BOTTOM_MARGIN,
    CONTACT_SEPARATION,
    MAX_LINK_PENETRATION,
    MAX_PAD_ANGLE,
    MAX_PAD_SIDEWAYS,
    MIN_PAD_PALMAR,
    TOP_MARGIN,
)
from hand_sim import robot
from hand_sim.geometry import place_polygon, rotation_2d


@dataclass(frozen=True)
class LateralSampling:
    """How the candidates are found and combined."""

    #: A sampled fingertip counts when it lies up to ``tolerance`` (m) beyond its place
    #: ``squeeze`` inside a side face, or ``shortfall`` short of it: the reach test's hand IK then
    #: brings it there (a finger that reaches further takes the contact with room to spare; one
    #: short of it is at the edge of its workspace, where the IK stalls millimetres away).
    tolerance: float = 0.006
    shortfall: float = 0.001
    #: Candidate contacts stay this far (m) from a face's vertical edges.
    edge_inset: float = 0.004
    #: Every finger link of a candidate stays this far (m) above the table: a lateral hand's
    #: thumb reaches down towards it (on single_irregular_pentagon its links otherwise meet the
    #: table and its touch guard stops it in Fine Reach).
    table_clearance: float = 0.01
    #: Candidates of one finger on one face closer than this (m) along it count as one (the
    #: best-scored sample of the bin is kept).
    bin_length: float = 0.005
    #: At most this many candidates per finger, and per finger and face, are combined.
    per_finger: int = 10
    per_face: int = 4
    #: Combinations scored by S_G's program: the ones whose unit normal forces leave the least
    #: net wrench.
    scored: int = 30
    #: A candidate's worst criterion share (pad angle, sideways lean, palmar side, link
    #: penetration, as shares of the reach test's limits) is below this: room for the hand IK,
    #: which then moves the fingertip onto the contact exactly.
    max_share: float = 1.0


DEFAULT_SAMPLING = LateralSampling()


@dataclass(frozen=True, eq=False)
class SampledGrasp:
    """A lateral grasp found among the sampled finger postures: each pressing finger's contact
    coordinate (``theta``, rad, order ff, mf, rf, th), world contact point, the hand's joints
    (the four samples), S_G of the contacts and the worst criterion share of the samples
    (``load``, below 1)."""

    theta: NDArray[np.float64]
    points: NDArray[np.float64]
    hand_q: NDArray[np.float64]
    s_g: float
    load: float
    #: a three-contact grasp's finger that presses nothing (held clear of the block in its
    #: ``hand_q`` posture; ``theta`` and ``points`` are then the other three fingers'), or None
    idle: int | None = None

    def contacts_label(self) -> str:
        """Which fingers take the contacts, for a log."""
        if self.idle is None:
            return "sampled contacts"
        fingers = ", ".join(robot.FINGERS[f] for f in pressing_fingers(self.idle))
        return f"three sampled contacts ({fingers}; {robot.FINGERS[self.idle]} held clear)"


#: A three-contact grasp's idle finger stays this far (m) from the block and the other fingers.
IDLE_CLEARANCE = 0.008
#: Samples of the idle finger tested at a time (:func:`_idle_posture`).
IDLE_CHUNK = 256


@dataclass(frozen=True, eq=False)
class _Candidates:
    """One finger's candidate contacts: sample index, edge, position along the edge (m),
    contact coordinate (rad), world point (k, 3) and criterion share."""

    sample: NDArray[np.int64]
    edge: NDArray[np.int64]
    along: NDArray[np.float64]
    theta: NDArray[np.float64]
    point: NDArray[np.float64]
    share: NDArray[np.float64]


#: Every finger's candidate contacts (:func:`finger_candidates`) by palm pose and squeeze: one
#: search's, whose samples, block and sampling parameters do not change.
CandidateCache = dict[bytes, list[_Candidates]]


def finger_candidates(
    samples: FingerSamples,
    finger: int,
    palm: tuple[NDArray[np.float64], NDArray[np.float64]],
    prism: PerceivedPrism,
    polygon: Polygon,
    pose_xy: tuple[NDArray[np.float64], float],
    criteria: Criteria,
    params: LateralSampling = DEFAULT_SAMPLING,
) -> _Candidates:
    """The contacts ``finger`` can take with the palm at ``palm`` (world position, rotation):
    its samples whose fingertip lies ``criteria.squeeze`` inside a side face of the perceived
    block (``polygon`` at ``pose_xy`` = (centroid, yaw), standing as ``prism``), between the
    reach test's height margins and ``params.edge_inset`` in from the face's ends, and that meet
    the reachability criteria; one per ``params.bin_length`` of each face, the best-scored."""
    p0, R0 = palm
    centre, yaw = pose_xy
    tips = samples.tip[:, finger] @ R0.T + p0
    # measured where a tip may lie deep enough in the block (+inf elsewhere: not)
    inside = -prism.signed_distance_near(tips, params.shortfall - criteria.squeeze)
    low, high = prism.bottom + BOTTOM_MARGIN, prism.top - TOP_MARGIN
    near = np.flatnonzero(
        (inside >= criteria.squeeze - params.shortfall)
        & (inside <= criteria.squeeze + params.tolerance)
        & (tips[:, 2] >= low)
        & (tips[:, 2] <= high)
    )
    local = (tips[near, :2] - centre) @ rotation_2d(yaw)  # world -> object frame
    normals = np.column_stack([np.cos(polygon.normal_angle), np.sin(polygon.normal_angle)])
    edge = np.argmax(local @ normals.T - polygon.offset, axis=1)
    v = polygon.vertices
    start, end = v[edge], np.roll(v, -1, axis=0)[edge]
    length = np.linalg.norm(end - start, axis=1)
    foot = local - ((local * normals[edge]).sum(1) - polygon.offset[edge])[:, None] * normals[edge]
    along = ((foot - start) * (end - start)).sum(1) / length
    keep = (along >= params.edge_inset) & (along <= length - params.edge_inset)
    near, edge, foot, along = near[keep], edge[keep], foot[keep], along[keep]
    n_world = place_polygon(normals[edge], (0.0, 0.0), yaw)
    n_local = np.column_stack([n_world, np.zeros(len(near))]) @ R0
    off = np.abs(inside[near] - criteria.squeeze) / params.tolerance
    # a link's penetration counts only where it is inside the block: measured within reach
    measure = partial(prism.signed_distance_near, within=float(samples.radius[finger].max()))
    share = np.maximum(
        off, samples.posture_shares(finger, near, p0, R0, n_local, measure, criteria)
    )
    links = samples.links[near, finger] @ R0.T + p0
    above = (links[..., 2] - samples.radius[finger]).min(axis=1) - prism.bottom
    good = (share < params.max_share) & (above >= params.table_clearance)
    near, edge, foot, along, share = near[good], edge[good], foot[good], along[good], share[good]
    # the best sample of each bin along each face, the bins best-first
    order = np.lexsort((share, np.floor(along / params.bin_length), edge))
    bins = np.column_stack([edge, np.floor(along / params.bin_length)])[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = np.any(bins[1:] != bins[:-1], axis=1)
    pick = order[first]
    pick = pick[np.argsort(share[pick], kind="stable")]
    chosen: list[int] = []
    per_edge: dict[int, int] = {}
    for i in pick:
        k = int(edge[i])
        if per_edge.get(k, 0) < params.per_face and len(chosen) < params.per_finger:
            chosen.append(int(i))
            per_edge[k] = per_edge.get(k, 0) + 1
    idx = np.asarray(chosen, dtype=np.int64)
    world_xy = place_polygon(foot[idx], centre, yaw)
    point = np.column_stack([world_xy, tips[near[idx], 2]])
    theta = np.arctan2(foot[idx, 1], foot[idx, 0])
    return _Candidates(near[idx], edge[idx], along[idx], theta, point, share[idx])


def _pad_centres(polygon: Polygon, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Object-frame pad centres (..., 2) in the plane: one pad radius out from each contact."""
    frames = polygon.locate(theta)
    return frames.point + robot.PAD_RADIUS * frames.normal


def sampled_lateral_grasp(
    model: mujoco.MjModel,
    qpos: NDArray[np.float64],
    samples: FingerSamples,
    prism: PerceivedPrism,
    polygon: Polygon,
    pose_xy: tuple[NDArray[np.float64], float],
    squeeze: float,
    params: LateralSampling = DEFAULT_SAMPLING,
    cache: CandidateCache | None = None,
) -> SampledGrasp | None:
    """The lowest-S_G grasp of one sampled candidate contact per finger (:func:`finger_candidates`)
    with the arm at ``qpos``'s posture (``model``, the planning model), the pads apart; None when a
    finger has no candidate or no combination fits. ``cache``: the candidates of earlier searches at
    the same palm pose (:data:`CandidateCache`)."""
    palm = _palm(model, qpos)
    per = _all_candidates(samples, palm, prism, polygon, pose_xy, squeeze, params, cache)
    best = _lowest_s_g(per, polygon, params)
    if best is None:
        return None
    s_g, load, pick = best
    fingers = list(range(len(robot.FINGERS)))
    sample_of = {f: int(per[f].sample[k]) for f, k in zip(fingers, pick, strict=True)}
    return _grasp(samples, per, fingers, pick, sample_of, s_g, load)


def three_contact_lateral_grasp(
    model: mujoco.MjModel,
    qpos: NDArray[np.float64],
    samples: FingerSamples,
    prism: PerceivedPrism,
    polygon: Polygon,
    pose_xy: tuple[NDArray[np.float64], float],
    squeeze: float,
    params: LateralSampling = DEFAULT_SAMPLING,
    cache: CandidateCache | None = None,
) -> SampledGrasp | None:
    """The lowest-S_G grasp of three contacts, the thumb's and two fingers' (the paper's grasp
    controller takes any number of contacts, section 3 and Appendix B), at the palm pose of
    ``qpos``: as :func:`sampled_lateral_grasp` over the three fingers, the fourth (``idle``, one of
    ff, mf, rf) held in a sampled posture whose every link stays :data:`IDLE_CLEARANCE` outside the
    perceived block, above the table and clear of the other fingers' links. A thumb against three
    fingers on parallel faces scores S_G 0.5 under Eq. 13's unit normal forces (it must push as hard
    as the three together), a thumb against two 0.33. ``theta`` and ``points`` are the three
    pressing fingers', in finger order. None when no idle finger has such a posture or no
    combination fits."""
    palm = _palm(model, qpos)
    per = _all_candidates(samples, palm, prism, polygon, pose_xy, squeeze, params, cache)
    thumb = len(robot.FINGERS) - 1
    best = None
    for idle in range(thumb):
        pressing = pressing_fingers(idle).tolist()
        found = _lowest_s_g([per[f] for f in pressing], polygon, params)
        if found is None:
            continue
        s_g, load, pick = found
        sample_of = {f: int(per[f].sample[k]) for f, k in zip(pressing, pick, strict=True)}
        parked = _idle_posture(samples, idle, sample_of, palm, prism, params)
        if parked is not None and (best is None or (s_g, load) < best[:2]):
            best = (s_g, load, idle, pressing, pick, sample_of | {idle: parked})
    if best is None:
        return None
    s_g, load, idle, pressing, pick, sample_of = best
    return _grasp(samples, per, pressing, pick, sample_of, s_g, load, idle)


def _grasp(
    samples: FingerSamples,
    per: list[_Candidates],
    pressing: list[int],
    pick: tuple[int, ...],
    sample_of: dict[int, int],
    s_g: float,
    load: float,
    idle: int | None = None,
) -> SampledGrasp:
    """The grasp of candidate ``pick[i]`` of each pressing finger ``pressing[i]`` (``per``:
    every finger's candidates), the hand in the samples ``sample_of`` (every finger's)."""
    hand = np.concatenate([samples.q[sample_of[f], f] for f in range(len(robot.FINGERS))])
    points = np.stack([per[f].point[k] for f, k in zip(pressing, pick, strict=True)])
    theta = np.array([per[f].theta[k] for f, k in zip(pressing, pick, strict=True)])
    return SampledGrasp(theta, points, hand, s_g, load, idle)


def _palm(
    model: mujoco.MjModel, qpos: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The palm body's world position and rotation at ``qpos``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    palm_id = model.body(robot.hand_name(robot.PALM_BODY)).id
    return data.xpos[palm_id].copy(), data.xmat[palm_id].reshape(3, 3).copy()


def _all_candidates(
    samples: FingerSamples,
    palm: tuple[NDArray[np.float64], NDArray[np.float64]],
    prism: PerceivedPrism,
    polygon: Polygon,
    pose_xy: tuple[NDArray[np.float64], float],
    squeeze: float,
    params: LateralSampling,
    cache: CandidateCache | None = None,
) -> list[_Candidates]:
    """Every finger's candidate contacts (:func:`finger_candidates`) with the palm at ``palm``;
    taken from ``cache`` where this palm pose's are in it, else searched and put in it."""
    key = palm[0].tobytes() + palm[1].tobytes() + np.float64(squeeze).tobytes()
    if cache is not None and key in cache:
        return cache[key]
    criteria = Criteria(
        params.tolerance,
        MAX_PAD_ANGLE,
        MAX_PAD_SIDEWAYS,
        MIN_PAD_PALMAR,
        MAX_LINK_PENETRATION,
        squeeze,
    )
    per = [
        finger_candidates(samples, f, palm, prism, polygon, pose_xy, criteria, params)
        for f in range(len(robot.FINGERS))
    ]
    if cache is not None:
        cache[key] = per
    return per


def _lowest_s_g(
    per: list[_Candidates], polygon: Polygon, params: LateralSampling
) -> tuple[float, float, tuple[int, ...]] | None:
    """Of the combinations of one candidate from each of ``per`` whose pads fit, the one of
    lowest S_G (Eq. 13; ties to the lower load): its S_G, load and candidate indices; None when
    a finger has no candidate or no combination fits or is feasible."""
    if any(len(c.sample) == 0 for c in per):
        return None
    combos = np.array(list(itertools.product(*(range(len(c.sample)) for c in per))))
    theta = np.column_stack([c.theta[combos[:, f]] for f, c in enumerate(per)])
    # the pads where they take their contacts, at their heights: fingers stacked on one face
    # (the middle finger above the palm's centre, the ring finger level with it) are apart
    pads = np.concatenate(
        [
            _pad_centres(polygon, theta),
            np.column_stack([c.point[combos[:, f], 2] for f, c in enumerate(per)])[..., None],
        ],
        axis=-1,
    )
    fits = np.ones(len(combos), dtype=bool)
    for i, j in itertools.combinations(range(theta.shape[1]), 2):
        fits &= np.linalg.norm(pads[:, i] - pads[:, j], axis=1) >= CONTACT_SEPARATION
    combos, theta = combos[fits], theta[fits]
    if len(combos) == 0:
        return None
    unit = polygon.unit_moment()
    frames = unit.locate(theta)
    force = -frames.normal
    moment = frames.point[..., 0] * force[..., 1] - frames.point[..., 1] * force[..., 0]
    net = np.linalg.norm(np.column_stack([force.sum(1), moment.sum(1)]), axis=1)
    best: tuple[float, float, int] | None = None
    for k in np.argsort(net, kind="stable")[: params.scored]:
        score = grasp_score(frames.point[k], frames.normal[k])
        if not score.feasible:
            continue
        load = max(float(c.share[combos[k, f]]) for f, c in enumerate(per))
        key = (float(score.s_g), load, int(k))
        if best is None or key < best:
            best = key
    if best is None:
        return None
    s_g, load, k = best
    return s_g, load, tuple(int(i) for i in combos[k])


def _idle_posture(
    samples: FingerSamples,
    idle: int,
    sample_of: dict[int, int],
    palm: tuple[NDArray[np.float64], NDArray[np.float64]],
    prism: PerceivedPrism,
    params: LateralSampling,
) -> int | None:
    """The sample of finger ``idle`` that keeps it out of a three-contact grasp: its links and
    fingertip at least :data:`IDLE_CLEARANCE` outside the perceived block, ``table_clearance``
    above the table and :data:`IDLE_CLEARANCE` from the pressing fingers' links (their samples
    ``sample_of``); of those, the one nearest the straight finger (joints at zero), which
    sweeps least on the way. None when no sample is clear."""
    p0, R0 = palm
    order = np.argsort(np.abs(samples.q[:, idle]).sum(axis=1), kind="stable")
    radius = samples.radius[idle]
    others = [(samples.links[k, f] @ R0.T + p0, samples.radius[f]) for f, k in sample_of.items()]
    # nearest the straight first, a chunk at a time: the first clear sample ends the search
    for chunk in np.array_split(order, max(1, len(order) // IDLE_CHUNK)):
        links = samples.links[chunk, idle] @ R0.T + p0  # (k, P, 3)
        tips = samples.tip[chunk, idle] @ R0.T + p0
        # only whether each is IDLE_CLEARANCE clear counts: measured within that
        clear = np.minimum(
            (prism.signed_distance_near(links, radius.max() + IDLE_CLEARANCE) - radius).min(1),
            prism.signed_distance_near(tips, robot.PAD_RADIUS + IDLE_CLEARANCE) - robot.PAD_RADIUS,
        )
        above = (links[..., 2] - radius).min(axis=1) - prism.bottom
        for i in np.flatnonzero((clear >= IDLE_CLEARANCE) & (above >= params.table_clearance)):
            if all(
                (
                    np.linalg.norm(links[i][:, None] - other[None], axis=-1)
                    - radius[:, None]
                    - r[None, :]
                ).min()
                >= IDLE_CLEARANCE
                for other, r in others
            ):
                return int(chunk[i])
    return None
