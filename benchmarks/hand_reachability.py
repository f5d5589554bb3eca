"""Can the hand of models/hand.xml reach balanced four-finger grasps of the paper's nine prisms?

For each paper object this samples hand joint configurations (seeded, uniform in the joint ranges),
computes forward kinematics with MuJoCo (``mj_kinematics``) and searches block poses relative to
the palm for configurations whose four fingertip sites (``ff_tip`` ... ``th_tip``) lie on the
prism's vertical side faces, then scores the contact set with S_G (Eq. 13, ``grasp_score`` on the
unit-moment polygon).

A fingertip "contacts" a face when
  * its tip site (on the pad) is within ``--tolerance`` (3 mm) of the face, inside or outside,
    at least ``EDGE_MARGIN`` from the face's vertical edges,
  * its pad normal points into the face (angle < ``MAX_PAD_ANGLE``),
  * no collision capsule of that finger penetrates the prism by more than ``MAX_PENETRATION``
    (soft pad), nor the palm the prism.
Two grasp kinds (section 5.2):
  * top: palm parallel to the prism's top face, palm face ``TOP_CLEARANCE`` above it, contacts
    between 1 and 12 cm below the top (the prism axis is the palm normal);
  * lateral: the prism axis lies in the palm plane at angle phi to the finger row (wrist roll),
    palm face ``LATERAL_CLEARANCE`` from the prism.
The block's yaw about its axis relative to the hand is swept over ``--yaws`` values; for each yaw
the search keeps the best S_G over block positions and fingertip placements. Printed per object and
grasp kind: the best S_G over yaws, the median over yaws of the best S_G, and the share of yaws with
a successful (S_G <= 0.4) grasp. Fingers are independent given the block pose, so N sampled hand
configurations give N^4 candidate combinations; a combination is kept only when no two fingers'
capsules overlap.

Usage: .venv/bin/python -m benchmarks.hand_reachability [--samples 6000] [--yaws 12] [--seed 0]
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.grasp import PAPER_OBJECTS, Polygon, grasp_score, paper_object
from hand_sim import clitools as cli
from hand_sim.resources import models_dir

HAND_XML = models_dir() / "hand.xml"
FINGERS = ("ff", "mf", "rf", "th")

#: Contact tolerance: tip site within this distance of a face (m).
TOLERANCE = 0.003
#: Contacts must stay this far from a face's vertical edges (m).
EDGE_MARGIN = 0.003
#: Largest angle between the pad normal and the face's inward normal (rad).
MAX_PAD_ANGLE = np.deg2rad(60.0)
#: Largest penetration of a finger capsule into the prism (m): the pad is soft.
MAX_PENETRATION = 0.0015
#: Pad normal in the distal body frame (the tip site sits 30 deg from the palmar normal).
PAD_NORMAL_LOCAL = np.array([0.0, np.sin(np.pi / 6), np.cos(np.pi / 6)])
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
#: Arc-length bin (m): contacts of one finger closer than this along the perimeter are merged.
ARC_BIN = 0.003
#: Random contact sets scored for the "ideal" column.
IDEAL_SETS = 1000
#: Most fingertip contacts per finger combined at one placement, and candidates scored by LP.
MAX_REPRESENTATIVES = 8
CANDIDATES = 6
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
        return (0.0, BLOCK_HEIGHT) if self.top else (-0.5 * BLOCK_HEIGHT, 0.5 * BLOCK_HEIGHT)

    def to_block(self, p: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        d = p - self.origin
        return np.stack([d @ self.e1, d @ self.e2], axis=-1), d @ self.axis


def rot2(v: NDArray, ang: float) -> NDArray:
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


@dataclass(frozen=True)
class GraspFound:
    s_g: float
    qpos: NDArray[np.float64]  #: hand configuration assembled from the four fingers' samples
    placement: Placement | None = None


@dataclass(frozen=True)
class Verification:
    """A found grasp rebuilt in MuJoCo (hand + fixed prism, ``mj_forward``)."""

    pad_distance: NDArray[np.float64]  #: signed distance of each fingertip pad to the prism (m)
    deepest: float  #: largest penetration of any hand geom into the prism (m)

    @property
    def ok(self) -> bool:
        pads = np.all(
            (self.pad_distance <= TOLERANCE) & (self.pad_distance >= -2.0 * MAX_PENETRATION)
        )
        return bool(pads and self.deepest <= 2.0 * MAX_PENETRATION)


def verify(poly: Polygon, found: GraspFound, xml: Path = HAND_XML) -> Verification:
    """Put the prism at the found placement next to the hand in the found configuration and let
    MuJoCo's collision detection and touch sensors judge the contacts."""
    pl = found.placement
    assert pl is not None
    spec = mujoco.MjSpec.from_file(str(xml))
    rot = np.stack([pl.e1, pl.e2, pl.axis], axis=1)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, rot.ravel())
    z0, z1 = pl.axial_range
    verts = np.concatenate(
        [
            np.c_[poly.vertices, np.full(poly.n_edges, z0)],
            np.c_[poly.vertices, np.full(poly.n_edges, z1)],
        ]
    )
    spec.add_mesh(name="prism", uservert=verts.ravel().tolist())
    body = spec.worldbody.add_body(name="prism", pos=pl.origin.tolist(), quat=quat.tolist())
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="prism")
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:] = found.qpos
    mujoco.mj_forward(model, data)
    prism = model.body("prism").id
    g_prism = int(np.flatnonzero(model.geom_bodyid == prism)[0])
    fromto = np.zeros(6)
    pads = np.array(
        [
            mujoco.mj_geomDistance(model, data, model.geom(f"{f}_pad").id, g_prism, 0.05, fromto)
            for f in FINGERS
        ]
    )
    deepest = 0.0
    for c in data.contact[: data.ncon]:
        if prism in (model.geom_bodyid[c.geom[0]], model.geom_bodyid[c.geom[1]]):
            deepest = max(deepest, -float(c.dist))
    return Verification(pads, deepest)


def frictionless_score(
    points: NDArray[np.float64], normals: NDArray[np.float64]
) -> NDArray[np.float64]:
    """S_G without friction (an upper bound of S_G) of contact sets (K, 4, 2), inf if the normal
    forces alone cannot balance. Null space of the 3x4 grasp map by SVD; when it is 2-D (e.g. two
    pairs on parallel faces) the best positive combination is found on a grid of directions."""
    m = -normals
    moment = points[..., 0] * m[..., 1] - points[..., 1] * m[..., 0]
    w = np.stack([m[..., 0], m[..., 1], moment], axis=1)  # (K, 3, 4)
    _, sv, vt = np.linalg.svd(w)
    scale = sv[:, :1] + 1e-12
    out = np.full(len(w), np.inf)
    rank3 = sv[:, 2] > 1e-6 * scale[:, 0]
    v = vt[:, 3]
    v = v * np.sign(v[:, :1] + 1e-300)
    pos = rank3 & np.all(v > 1e-9, axis=1)
    out[pos] = v[pos].sum(1) / v[pos].min(1) / 4.0 - 1.0
    r2 = np.flatnonzero(~rank3)
    if r2.size:
        phi = np.linspace(0.0, 2.0 * np.pi, 181)
        comb = (
            np.cos(phi)[None, :, None] * vt[r2, 2][:, None, :]
            + np.sin(phi)[None, :, None] * vt[r2, 3][:, None, :]
        )
        ok = np.all(comb > 1e-9, axis=2)
        cost = np.where(ok, comb.sum(2) / np.where(ok, comb.min(2), 1.0) / 4.0 - 1.0, np.inf)
        out[r2] = cost.min(1)
    return out


def best_at(
    poly: Polygon, pl: Placement, hs: HandSamples, candidates: list[NDArray[np.int64]]
) -> GraspFound | None:
    """The lowest-S_G four-finger grasp found at one placement, scored on the actual tips;
    ``candidates[f]``: samples of finger f worth checking."""
    if any(c.size == 0 for c in candidates):
        return None
    per = [finger_contacts(poly, pl, hs, f, TOLERANCE, candidates[f]) for f in range(4)]
    if any(c.index.size == 0 for c in per):
        return None
    reps = []
    for c in per:  # one representative sample per arc bin, at most MAX_REPRESENTATIVES
        _, first = np.unique((c.arc / ARC_BIN).astype(int), return_index=True)
        if first.size > MAX_REPRESENTATIVES:
            first = first[np.linspace(0, first.size - 1, MAX_REPRESENTATIVES).astype(int)]
        reps.append(first)
    grid = np.stack(np.meshgrid(*reps, indexing="ij"), axis=-1).reshape(-1, 4)
    scale = 1.0 / poly.max_moment
    pts = np.stack([per[f].point[grid[:, f]] for f in range(4)], axis=1) * scale
    nrm = np.stack([per[f].normal[grid[:, f]] for f in range(4)], axis=1)
    proxy = frictionless_score(pts, nrm)
    order = np.argsort(proxy)[:CANDIDATES]
    best: GraspFound | None = None
    for k in order:
        if not np.isfinite(proxy[k]) and best is not None:
            break
        choice = np.array([per[f].index[grid[k, f]] for f in range(4)])
        if fingers_overlap(hs, choice):
            continue
        score = grasp_score(pts[k], nrm[k])
        if score.feasible and (best is None or score.s_g < best.s_g):
            q = np.zeros(hs.qpos.shape[1])
            for f in range(4):
                q[4 * f : 4 * f + 4] = hs.qpos[choice[f], 4 * f : 4 * f + 4]
            best = GraspFound(score.s_g, q, pl)
    return best


def evaluate(
    name: str, kind: str, hs: HandSamples, yaws: NDArray
) -> tuple[NDArray[np.float64], GraspFound | None]:
    """Best S_G for each relative yaw (inf when no four-finger grasp was found), and the best
    grasp of all."""
    poly = paper_object(name)
    best = np.full(len(yaws), np.inf)
    overall: GraspFound | None = None
    for k, yaw in enumerate(yaws):
        placements = top_placements(poly, yaw) if kind == "top" else lateral_placements(poly, yaw)
        near = [near_faces(poly, placements, hs.tip[:, f], TOLERANCE) for f in range(4)]
        for p, pl in enumerate(placements):
            found = best_at(poly, pl, hs, [np.flatnonzero(near[f][p]) for f in range(4)])
            if found is not None and found.s_g < best[k]:
                best[k] = found.s_g
                if overall is None or found.s_g < overall.s_g:
                    overall = found
    return best, overall


def ideal_score(poly: Polygon, rng: np.random.Generator, count: int = IDEAL_SETS) -> float:
    """Lowest S_G of ``count`` random four-contact sets (uniform polar angles): what any hand
    could reach on this polygon."""
    unit = poly.unit_moment()
    best = np.inf
    for _ in range(count):
        frames = unit.locate(rng.uniform(-np.pi, np.pi, 4))
        best = min(best, grasp_score(frames.point, frames.normal).s_g)
    return float(best)


def _cell(best: NDArray[np.float64], checked: str) -> str:
    return f"{best.min():8.3f} {np.median(best):7.3f} {np.mean(best <= 0.4):5.2f} {checked:>5s}"


PROG = "python -m benchmarks.hand_reachability"


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark with the command line ``argv``; returns the exit status."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=cli.ERRORS)


def _run(argv: list[str] | None) -> int:
    ap = cli.ArgumentParser(prog=PROG, description=cli.first_paragraph(__doc__))
    ap.add_argument(
        "--samples",
        type=cli.integer(10, 20_000),
        default=4000,
        help="hand configurations sampled, 10..20000",
    )
    ap.add_argument(
        "--yaws", type=cli.integer(1, 360), default=12, help="relative block yaws per object"
    )
    ap.add_argument("--seed", type=cli.seed, default=0, help=f"random seed, 0..{cli.SEED_MAX}")
    ap.add_argument(
        "--objects",
        nargs="+",
        choices=PAPER_OBJECTS,
        default=list(PAPER_OBJECTS),
        metavar="OBJECT",
        help=f"paper objects to check: {', '.join(PAPER_OBJECTS)}",
    )
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    hs = sample_hand(args.samples, rng)
    print(f"# {args.samples} hand samples ({time.perf_counter() - t0:.1f} s), {args.yaws} yaws")
    print("# best: lowest S_G; median: median over yaws of the best; ok: share of yaws with")
    print("# S_G <= 0.4; mj: best grasp confirmed by MuJoCo distances; ideal: lowest S_G of")
    print(f"# {IDEAL_SETS} random four-contact sets (any hand)")
    print(f"{'':20s} | {'':6s} | {'top grasps':^29s} | {'lateral grasps':^29s}")
    head = f"{'best':>8s} {'median':>7s} {'ok':>5s} {'mj':>5s}"
    print(f"{'object':20s} | {'ideal':>6s} | {head} | {head}")
    yaws = np.linspace(0.0, 2.0 * np.pi, args.yaws, endpoint=False)
    for name in args.objects:
        ideal = ideal_score(paper_object(name), np.random.default_rng(args.seed))
        row = [f"{name:20s}", f"{ideal:6.3f}"]
        for kind in ("top", "lateral"):
            best, found = evaluate(name, kind, hs, yaws)
            checked = (
                "-" if found is None else "yes" if verify(paper_object(name), found).ok else "NO"
            )
            row.append(_cell(best, checked))
        print(" | ".join(row), flush=True)
    print(f"# total {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
