"""Can the hand of models/hand.xml reach balanced four-finger grasps of the paper's nine prisms?

For each paper object this samples hand joint configurations (seeded, uniform in the joint ranges),
computes forward kinematics with MuJoCo (``mj_kinematics``) and searches block poses relative to
the palm for configurations whose four fingertip sites (``ff_tip`` ... ``th_tip``) lie on the
prism's vertical side faces, then scores the contact set with S_G (Eq. 13, ``grasp_score`` on the
unit-moment polygon).

A fingertip "contacts" a face when
  * its tip site (on the pad) is within ``TOLERANCE`` (3 mm) of the face, inside or outside,
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

The sampling, the placements and the contact test are in :mod:`benchmarks.fingertip_contacts`
(re-exported here); this module scores the contacts, searches, verifies in MuJoCo and prints.

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

from benchmarks.fingertip_contacts import (
    BLOCK_HEIGHT,
    CENTRE_OFFSETS,
    EDGE_MARGIN,
    FINGERS,
    HAND_XML,
    LATERAL_CLEARANCE,
    LATERAL_HALF_SPAN,
    LATERAL_ROLLS,
    MAX_PAD_ANGLE,
    MAX_PENETRATION,
    PAD_NORMAL_LOCAL,
    PALM_FACE_Z,
    POINTS_PER_CAPSULE,
    TOLERANCE,
    TOP_CLEARANCE,
    TOP_DEPTH_RANGE,
    Contacts,
    HandSamples,
    Placement,
    finger_contacts,
    fingers_overlap,
    lateral_placements,
    link_clearance,
    near_faces,
    perimeter_frames,
    rot2,
    sample_hand,
    top_placements,
)
from controllers.grasp import PAPER_OBJECTS, Polygon, grasp_score, paper_object
from hand_sim import clitools as cli

#: The search, plus the sampling, placement and contact names of benchmarks.fingertip_contacts
#: (re-exported here).
__all__ = [
    "ARC_BIN",
    "BLOCK_HEIGHT",
    "CANDIDATES",
    "CENTRE_OFFSETS",
    "EDGE_MARGIN",
    "FINGERS",
    "HAND_XML",
    "IDEAL_SETS",
    "LATERAL_CLEARANCE",
    "LATERAL_HALF_SPAN",
    "LATERAL_ROLLS",
    "MAX_PAD_ANGLE",
    "MAX_PENETRATION",
    "MAX_REPRESENTATIVES",
    "PAD_NORMAL_LOCAL",
    "PALM_FACE_Z",
    "POINTS_PER_CAPSULE",
    "PROG",
    "TOLERANCE",
    "TOP_CLEARANCE",
    "TOP_DEPTH_RANGE",
    "Contacts",
    "GraspFound",
    "HandSamples",
    "Placement",
    "Verification",
    "best_at",
    "evaluate",
    "finger_contacts",
    "fingers_overlap",
    "frictionless_score",
    "ideal_score",
    "lateral_placements",
    "link_clearance",
    "main",
    "near_faces",
    "perimeter_frames",
    "rot2",
    "sample_hand",
    "top_placements",
    "verify",
]

#: Arc-length bin (m): contacts of one finger closer than this along the perimeter are merged.
ARC_BIN = 0.003
#: Random contact sets scored for the "ideal" column.
IDEAL_SETS = 1000
#: Most fingertip contacts per finger combined at one placement, and candidates scored by LP.
MAX_REPRESENTATIVES = 8
CANDIDATES = 6


@dataclass(frozen=True)
class GraspFound:
    """A four-finger grasp found by the search: its S_G, hand configuration and prism pose."""

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
    """One grasp kind's columns of a table row: best, median, ok share, MuJoCo check."""
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
