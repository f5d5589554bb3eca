"""The polygon of one block's top face, in image pixels (section 5.2, Select/Model: the Hough
contour "modelled as a polygon").

Steps (all in pixels):

1. the face's outline with a sub-pixel edge point per outline pixel (:mod:`vision.edges`);
   points next to an occluder (the arm) or the image border are not trusted;
2. two passes of the sequential Hough transform (:mod:`vision.hough`): the first measures the
   edge points' noise, the second fits points within FIT_SIGMAS of it;
3. model selection fixes the edge count: a run of outline points the polygon misses proposes a
   line; a short edge missed between two found ones is added when three lines beat two by far;
   neighbouring edges one line explains are merged; edges shorter than a minimum (a blurred
   corner) and mostly unseen edges that nothing hides (a spurious line at a sharp tip) are
   dropped when the other lines explain their points;
4. the result is checked: every edge must be seen, little of the polygon may be hidden, and the
   polygon must match the top face; when it does not, :class:`ExtractionError` says why instead
   of returning a made-up shape.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from vision import edges
from vision.errors import ExtractionError
from vision.hough import (
    COARSE_FIT_DISTANCE,
    LOOSE_FIT_DISTANCE,
    MIN_EDGE_PX,
    MIN_SUPPORT,
    Line,
    clip_halfplanes,
    hough_lines,
    line_from_run,
    longest_run,
    merge_lines,
    robust_fit,
)

#: Margin (px) of the crop around a top face.
CROP_MARGIN = 8
#: Pass 2 fits points within FIT_SIGMAS edge-noise sigmas of a line, at least FIT_DISTANCE px.
FIT_SIGMAS = 3.5
FIT_DISTANCE = 0.2
#: Smallest edge-point noise assumed (px): aliasing of the anti-aliased render.
MIN_EDGE_NOISE = 0.04
#: Two neighbouring edges are one when fitting them as one line raises the residual sum of
#: squares by less than this many edge-noise variances (a chi-square test, generous because
#: neighbouring edge points share pixels).
MERGE_CHI2 = 30.0
#: A short edge between two found ones is added when three lines beat two by SPLIT_CHI2
#: edge-noise variances (far above MERGE_CHI2: the best of many cuts, and blurred corners, gain
#: tens of variances without an edge; tuned on the benchmark's random polygons); spans of more
#: than MAX_SPLIT_POINTS outline points are not searched.
SPLIT_CHI2 = 250.0
MAX_SPLIT_POINTS = 400
#: Outline points farther than this (px), or UNEXPLAINED_SIGMAS edge-noise sigmas, from the
#: polygon are unexplained (a missed edge).
UNEXPLAINED_DISTANCE = 0.3
UNEXPLAINED_SIGMAS = 4.5
#: ... and farther than this (px) for points from the depth mask (whole pixels).
COARSE_UNEXPLAINED = 0.9
#: Extra lines proposed for unexplained outline points, at most.
MAX_EXTRA_LINES = 4
#: A line is dropped only if the remaining polygon passes within this distance (px) of its points.
PRUNE_EXPLAINED = 0.8
#: ... and within this distance (px) for a line whose edge is mostly unseen, or within the
#: shortest edge length (at least this) for a line whose edge is too short to be a block's.
SHORT_EXPLAINED = 2.0
#: Outline pixels this close (px) to an occluder or the image border are not trusted.
UNTRUSTED_RADIUS = 2
#: Each edge must be seen over at least this fraction of its length (or it is hidden); edges
#: seen over less than PRUNE_SEEN with nothing hiding them are dropped if the others explain
#: their points.
MIN_EDGE_SEEN = 0.25
PRUNE_SEEN = 0.5
#: Rounds of merging and pruning, at most.
CLEANUP_ROUNDS = 3
#: Neighbouring edges turning by less than this (rad) are one edge (the random polygons' smallest
#: turns are about 14 deg; a few degrees come from the render's aliasing along long edges).
MIN_TURN = np.deg2rad(8.0)
#: Largest fraction of the top face's pixels that may lie more than MISMATCH_DISTANCE (px)
#: outside the polygon, and of polygon pixels that many pixels inside it missing from the face.
MAX_OUTLINE_MISMATCH = 0.03
MISMATCH_DISTANCE = 1.0
#: Largest part of the polygon (fraction of the face's area) that may lie under an occluder: a
#: hidden vertex is inferred from its two seen edges, a hidden edge is refused.
MAX_HIDDEN_FRACTION = 0.05
#: Errors mention occlusion when more than this fraction of the outline is not trusted.
HIDDEN_HINT = 0.05


@dataclass(frozen=True)
class PixelPolygon:
    """A block's top-face polygon in image pixels."""

    vertices: NDArray[np.float64]  #: (k, 2) pixel coordinates (u, v)
    lines: tuple[Line, ...]  #: line i carries the edge from vertex i to vertex i + 1
    seen: NDArray[np.float64]  #: (k,) fraction of each edge backed by trusted edge points
    refined: NDArray[np.bool_]  #: (k,) edge placed from colour (else from the depth mask)
    edge_points: NDArray[np.float64]  #: (N, 2) trusted sub-pixel edge points


def _polygon(lines: list[Line], box: NDArray[np.float64]) -> tuple[NDArray, list[int]]:
    """Polygon of the lines and the index of the line carrying each edge; raises if not closed."""
    verts, tags = clip_halfplanes(lines, box)
    if len(verts) < 3:
        raise ExtractionError("the Hough lines enclose no area")
    if min(tags) < 0:
        raise ExtractionError(
            "the Hough lines do not close around the face: an edge is missing (hidden by "
            "something above the block, such as the arm, or outside the image)"
        )
    return verts, tags


def _boundary_distance(pts: NDArray[np.float64], verts: NDArray[np.float64]) -> NDArray:
    """Distance of points to the polygon's boundary."""
    a = verts
    b = np.roll(verts, -1, axis=0)
    ab = b - a
    t = np.clip(((pts[:, None] - a[None]) * ab[None]).sum(-1) / (ab**2).sum(-1)[None], 0, 1)
    proj = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(pts[:, None] - proj, axis=2).min(axis=1)


def _crop(
    top_mask: NDArray[np.bool_],
    untrusted: NDArray[np.bool_],
    bbox: tuple[int, int, int, int] | None = None,
) -> tuple[tuple[int, int, int, int], NDArray[np.uint8], NDArray[np.bool_]]:
    h, w = top_mask.shape
    if bbox is None:
        bu, bv, bw, bh = cv2.boundingRect(top_mask.astype(np.uint8))
        bbox = (bu, bv, bu + bw, bv + bh)
    x0, x1 = max(0, bbox[0] - CROP_MARGIN), min(w, bbox[2] + CROP_MARGIN)
    y0, y1 = max(0, bbox[1] - CROP_MARGIN), min(h, bbox[3] + CROP_MARGIN)
    mask = top_mask[y0:y1, x0:x1].astype(np.uint8)
    bad = np.zeros((y1 - y0 + 2, x1 - x0 + 2), np.uint8)
    bad[1:-1, 1:-1] = untrusted[y0:y1, x0:x1]
    if x0 == 0:
        bad[:, :2] = 1
    if y0 == 0:
        bad[:2, :] = 1
    if x1 == w:
        bad[:, -2:] = 1
    if y1 == h:
        bad[-2:, :] = 1
    ksize = 2 * UNTRUSTED_RADIUS + 1
    bad_d = cv2.dilate(bad, np.ones((ksize, ksize), np.uint8))[1:-1, 1:-1] > 0
    return (x0, y0, x1, y1), mask, bad_d


def fit_polygon(
    top_mask: NDArray[np.bool_],
    rgb: NDArray[np.uint8],
    untrusted: NDArray[np.bool_],
    noise_sigma: float | None = None,
    bbox: tuple[int, int, int, int] | None = None,
    min_edge_px: float = MIN_EDGE_PX,
    mask_slack_px: float = 0.0,
) -> PixelPolygon:
    """The convex polygon of one top face, in image pixels.

    ``untrusted`` marks pixels whose outline is not the block's (occluders, no depth); outline
    points near them or the image border are ignored. ``noise_sigma`` (grey levels) is the
    image noise; by default it is measured on the top face, which is one flat colour. ``bbox``
    (u0, v0, u1, v1) bounds the face (found when not given). Edges shorter than ``min_edge_px``
    are taken for blurred corners, not edges. ``mask_slack_px`` is how far the depth mask may
    reach past the top face's edge (side-face pixels within the plateau's height tolerance).
    Raises :class:`ExtractionError` saying why when no polygon fits.
    """
    (x0, y0, x1, y1), mask, bad = _crop(top_mask, untrusted, bbox)
    if int(mask.sum()) < 3 * MIN_SUPPORT:
        raise ExtractionError(f"the top face has only {int(mask.sum())} pixels; too small to model")
    img = rgb[y0:y1, x0:x1].astype(np.float32)
    sigma = edges.noise_sigma(img, mask) if noise_sigma is None else noise_sigma
    out = edges.outline(mask, img, bad, sigma)
    pts = out.point
    # colour edges when the colour works (most points); the depth mask's pixels otherwise
    usable = out.trusted & out.refined if out.refined.mean() >= 0.5 else out.trusted.copy()
    if usable.sum() < 3 * MIN_SUPPORT:
        raise ExtractionError(
            f"only {int(usable.sum())} outline pixels of the block are visible (the rest is "
            "occluded or outside the image); cannot model it"
        )
    ys, xs = np.nonzero(mask)
    centre = np.array([xs.mean(), ys.mean()])
    box = np.array([[-1.0, -1.0], [x1 - x0, -1.0], [x1 - x0, y1 - y0], [-1.0, y1 - y0]])
    # pass 1 with a generous tolerance measures the edge points' noise, pass 2 uses it
    loose = np.where(out.refined, LOOSE_FIT_DISTANCE, COARSE_FIT_DISTANCE)
    lines, members = hough_lines(pts, usable, centre, loose)
    sigma_e = _edge_noise(lines, members, pts, out.refined)
    fit_distance = np.where(
        out.refined, np.clip(FIT_SIGMAS * sigma_e, FIT_DISTANCE, LOOSE_FIT_DISTANCE), loose
    )
    lines, members = hough_lines(pts, usable, centre, fit_distance)
    if len(lines) < 3:
        hidden = 1.0 - float(out.trusted.mean())
        why = (
            f"; {100 * hidden:.0f}% of the outline is hidden by something above the block (the "
            "arm?) or outside the image"
            if hidden > HIDDEN_HINT
            else ""
        )
        raise ExtractionError(
            f"found {len(lines)} straight edges on the block's outline, need 3{why}"
        )
    far_distance = np.where(
        out.refined, max(UNEXPLAINED_DISTANCE, UNEXPLAINED_SIGMAS * sigma_e), COARSE_UNEXPLAINED
    )
    lines, members = _add_missed_lines(
        lines, members, pts, usable, centre, box, far_distance, fit_distance
    )
    lines, members = _split_junctions(
        lines, members, pts, usable, centre, box, sigma_e, min_edge_px
    )
    verts, tags = _polygon(lines, box)
    for _ in range(CLEANUP_ROUNDS):  # each removal can expose another
        before = len(lines)
        lines, members, verts, tags = _merge_adjacent(lines, members, pts, centre, box, sigma_e)
        lines, members, verts, tags = _prune_short(lines, members, pts, box, min_edge_px)
        lines, members, verts, tags = _prune_unseen(lines, members, pts, usable, box, bad)
        if len(lines) == before:
            break
    used = [lines[t] for t in tags]
    refined = np.array([out.refined[members[t]].mean() > 0.5 for t in tags])
    trusted_pts = pts[usable]
    seen = _edge_seen(verts, trusted_pts)
    _check(verts, used, seen, mask, bad, MISMATCH_DISTANCE + mask_slack_px)
    offset = np.array([x0, y0], float)
    return PixelPolygon(
        verts + offset,
        tuple(ln.shifted(offset) for ln in used),
        seen,
        refined,
        trusted_pts + offset,
    )


def _add_missed_lines(
    lines: list[Line],
    members: list[NDArray[np.int64]],
    pts: NDArray,
    usable: NDArray[np.bool_],
    centre: NDArray,
    box: NDArray,
    far_distance: NDArray[np.float64],
    fit_distance: NDArray[np.float64],
) -> tuple[list[Line], list[NDArray[np.int64]]]:
    """Add a line for the longest run of outline points, on no line, that the polygon misses by
    more than ``far_distance`` (a short edge the transform did not find); at most
    MAX_EXTRA_LINES times."""
    verts, _ = _polygon(lines, box)
    for _ in range(MAX_EXTRA_LINES):
        far = usable & (_boundary_distance(pts, verts) > far_distance)
        for m in members:
            far[m] = False
        extra = line_from_run(pts, longest_run(far), centre)
        if extra is None:
            break
        run = longest_run(usable & (np.abs(extra.distance(pts)) < fit_distance))
        extra = line_from_run(pts, run, centre) or extra
        lines, members = merge_lines([*lines, extra], [*members, run], pts, centre)
        verts, _ = _polygon(lines, box)
    return lines, members


def _edge_noise(
    lines: list[Line], members: list[NDArray[np.int64]], pts: NDArray, refined: NDArray
) -> float:
    """Noise (px) of the colour edge points about their lines: the median over lines of each
    line's robust residual spread (a line straddling two true edges is an outlier)."""
    sigmas = []
    for ln, m in zip(lines, members, strict=True):
        r = ln.distance(pts[m[refined[m]]])
        if r.size >= MIN_SUPPORT:
            sigmas.append(1.4826 * float(np.median(np.abs(r - np.median(r)))))
    if not sigmas:
        return MIN_EDGE_NOISE
    return max(MIN_EDGE_NOISE, float(np.median(sigmas)))


def _rss(pts: NDArray, centre: NDArray) -> tuple[Line, float]:
    n, c, keep = robust_fit(pts, centre)
    r = pts @ n - c
    return Line(n, c, int(keep.sum())), float((r**2).sum())


def _segment_rss(pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """RSS[i, j] of the total-least-squares line through points i..j-1 (inf when j - i is below
    MIN_SUPPORT), for every i < j, from prefix sums."""
    n = len(pts)
    x, y = pts[:, 0] - pts[:, 0].mean(), pts[:, 1] - pts[:, 1].mean()
    cums = [np.concatenate([[0.0], np.cumsum(v)]) for v in (np.ones(n), x, y, x * x, y * y, x * y)]
    i, j = np.triu_indices(n + 1, 1)
    c, sx, sy, sxx, syy, sxy = ((cs[j] - cs[i]) for cs in cums)
    with np.errstate(invalid="ignore", divide="ignore"):
        a = sxx - sx * sx / c
        b = syy - sy * sy / c
        h = sxy - sx * sy / c
        rss = 0.5 * (a + b) - np.sqrt(0.25 * (a - b) ** 2 + h * h)
    rss = np.where(c >= MIN_SUPPORT, np.maximum(rss, 0.0), np.inf)
    out = np.full((n + 1, n + 1), np.inf)
    out[i, j] = rss
    return out


def _best_split(rss: NDArray[np.float64], parts: int) -> tuple[float, list[int]]:
    """Best cut of points 0..n-1 into ``parts`` (2 or 3) consecutive segments: (RSS, cuts)."""
    n = rss.shape[0] - 1
    if parts == 2:
        k = np.arange(1, n)
        total = rss[0, k] + rss[k, n]
        best = int(np.argmin(total))
        return float(total[best]), [int(k[best])]
    k1, k2 = np.triu_indices(n, 1)
    ok = k1 >= 1
    k1, k2 = k1[ok], k2[ok]
    total = rss[0, k1] + rss[k1, k2] + rss[k2, n]
    best = int(np.argmin(total))
    return float(total[best]), [int(k1[best]), int(k2[best])]


def _chain_span(first: NDArray[np.int64], second: NDArray[np.int64], n: int) -> NDArray[np.int64]:
    """Outline indices from the start of run ``first`` to the end of run ``second`` (cyclic)."""
    length = (int(second[-1]) - int(first[0])) % n + 1
    return (int(first[0]) + np.arange(length)) % n


def _split_junctions(
    lines: list[Line],
    members: list[NDArray[np.int64]],
    pts: NDArray,
    usable: NDArray,
    centre: NDArray,
    box: NDArray,
    sigma_e: float,
    min_edge_px: float,
) -> tuple[list[Line], list[NDArray[np.int64]]]:
    """Find short edges the transform missed between two neighbouring edges: where the outline
    points from one edge's start to the next one's end fit three lines much better than two
    (residual sum of squares lower by SPLIT_CHI2 sigma^2), the middle line is added."""
    n_pts = len(pts)
    _, tags = _polygon(lines, box)
    new_lines, new_members = list(lines), list(members)
    for i in range(len(tags)):
        a, b = tags[i], tags[(i + 1) % len(tags)]
        ra, rb = members[a], members[b]
        if len(ra) == 0 or len(rb) == 0:
            continue
        # walk the outline the short way from one run to the other
        if (int(rb[0]) - int(ra[-1])) % n_pts > (int(ra[0]) - int(rb[-1])) % n_pts:
            ra, rb = rb, ra
        span = _chain_span(ra, rb, n_pts)
        span = span[usable[span]]
        if len(span) > MAX_SPLIT_POINTS or len(span) < 3 * MIN_SUPPORT:
            continue
        rss = _segment_rss(pts[span])
        rss2, _ = _best_split(rss, 2)
        rss3, cuts = _best_split(rss, 3)
        if rss2 - rss3 < SPLIT_CHI2 * sigma_e**2:
            continue
        middle = span[cuts[0] : cuts[1]]
        if np.linalg.norm(pts[middle[-1]] - pts[middle[0]]) < min_edge_px:
            continue
        line = line_from_run(pts, middle, centre)
        if line is None or min(_turn(line, lines[a]), _turn(line, lines[b])) < MIN_TURN:
            continue
        new_lines.append(line)
        new_members.append(middle)
    return new_lines, new_members


def _turn(a: Line, b: Line) -> float:
    """Angle (rad) between two lines' normals."""
    return float(abs(np.angle(np.exp(1j * (a.angle - b.angle)))))


def _merge_adjacent(
    lines: list[Line],
    members: list[NDArray[np.int64]],
    pts: NDArray,
    centre: NDArray,
    box: NDArray,
    sigma_e: float,
) -> tuple[list[Line], list[NDArray[np.int64]], NDArray, list[int]]:
    """Merge neighbouring edges when one line explains their points as well as two do, within
    the edge-point noise (the residual sum of squares may grow by at most MERGE_CHI2 sigma^2), or
    when they turn by less than MIN_TURN. Repeats (smallest growth first) until none qualify."""
    verts, tags = _polygon(lines, box)
    while len(tags) > 3:
        best, best_cost = None, MERGE_CHI2 * sigma_e**2
        for i in range(len(tags)):
            a, b = tags[i], tags[(i + 1) % len(tags)]
            joined = np.concatenate([members[a], members[b]])
            line, rss_joint = _rss(pts[joined], centre)
            cost = rss_joint - _rss(pts[members[a]], centre)[1] - _rss(pts[members[b]], centre)[1]
            if _turn(lines[a], lines[b]) < MIN_TURN:
                cost = min(cost, 0.0)
            if cost < best_cost:
                best, best_cost = (a, b, line, joined), cost
        if best is None:
            break
        a, b, line, joined = best
        keep = [i for i in range(len(lines)) if i not in (a, b)]
        lines = [lines[i] for i in keep] + [line]
        members = [members[i] for i in keep] + [joined]
        verts, tags = _polygon(lines, box)
    return lines, members, verts, tags


def _try_drop(
    lines: list[Line],
    members: list[NDArray[np.int64]],
    drop: int,
    pts: NDArray,
    box: NDArray,
    explained: float = 0.0,
) -> tuple[list[Line], list[NDArray[np.int64]], NDArray, list[int]] | None:
    """The lines without line ``drop``, if they still close a polygon that passes within
    ``explained`` px (default PRUNE_EXPLAINED) of the dropped line's points; else None."""
    explained = explained or PRUNE_EXPLAINED
    rest_l = [ln for j, ln in enumerate(lines) if j != drop]
    rest_m = [m for j, m in enumerate(members) if j != drop]
    verts, tags = clip_halfplanes(rest_l, box)
    if len(verts) < 3 or min(tags) < 0:
        return None
    if len(members[drop]) and _boundary_distance(pts[members[drop]], verts).max() > explained:
        return None
    return rest_l, rest_m, verts, tags


def _prune(
    lines: list[Line],
    members: list[NDArray[np.int64]],
    pts: NDArray,
    box: NDArray,
    weak: Callable[[NDArray, list[int]], NDArray[np.bool_]],
    explained: float = 0.0,
) -> tuple[list[Line], list[NDArray[np.int64]], NDArray, list[int]]:
    """Drop, one at a time, lines whose polygon edge ``weak(verts, tags)`` flags, when the other
    lines explain their points (see :func:`_try_drop`)."""
    verts, tags = _polygon(lines, box)
    while len(tags) > 3:
        flagged = np.flatnonzero(weak(verts, tags))
        for i in flagged:
            done = _try_drop(lines, members, tags[i], pts, box, explained)
            if done is not None:
                lines, members, verts, tags = done
                break
        else:
            break
    return lines, members, verts, tags


def _prune_short(
    lines: list[Line],
    members: list[NDArray[np.int64]],
    pts: NDArray,
    box: NDArray,
    min_edge_px: float,
) -> tuple[list[Line], list[NDArray[np.int64]], NDArray, list[int]]:
    """Drop lines whose polygon edge is shorter than ``min_edge_px`` (a corner's blur, not an
    edge of the block), shortest first."""

    def short(verts: NDArray, tags: list[int]) -> NDArray[np.bool_]:
        length = np.linalg.norm(np.roll(verts, -1, axis=0) - verts, axis=1)
        order = np.argsort(length)
        flags = np.zeros(len(tags), bool)
        flags[order[length[order] < min_edge_px][:1]] = True
        return flags

    return _prune(lines, members, pts, box, short, max(SHORT_EXPLAINED, min_edge_px))


def _prune_unseen(
    lines: list[Line],
    members: list[NDArray[np.int64]],
    pts: NDArray,
    usable: NDArray[np.bool_],
    box: NDArray,
    bad: NDArray[np.bool_],
) -> tuple[list[Line], list[NDArray[np.int64]], NDArray, list[int]]:
    """Drop lines whose edge is mostly unseen although nothing hides it (a spurious line at a
    sharp corner); edges next to an occluder are kept (and refused later)."""

    def unseen(verts: NDArray, tags: list[int]) -> NDArray[np.bool_]:
        seen = _edge_seen(verts, pts[usable])
        k = len(verts)
        return np.array(
            [
                seen[i] < PRUNE_SEEN and not _near_bad(verts[i], verts[(i + 1) % k], bad)
                for i in range(k)
            ]
        )

    return _prune(lines, members, pts, box, unseen, SHORT_EXPLAINED)


def _near_bad(a: NDArray, b: NDArray, bad: NDArray[np.bool_]) -> bool:
    """Whether the segment a-b passes over (or next to) untrusted pixels."""
    n = max(2, int(np.ceil(np.linalg.norm(b - a))) + 1)
    p = np.rint(a + (b - a) * np.linspace(0, 1, n)[:, None]).astype(int)
    h, w = bad.shape
    inside = (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)
    return bool((~inside).any() or bad[p[inside, 1], p[inside, 0]].any())


def _edge_seen(verts: NDArray, pts: NDArray) -> NDArray[np.float64]:
    """Fraction of each edge's length with a trusted edge point within 1 px."""
    k = len(verts)
    seen = np.zeros(k)
    for i in range(k):
        a, b = verts[i], verts[(i + 1) % k]
        n_s = max(2, int(np.ceil(2.0 * np.linalg.norm(b - a))))
        samples = a + (b - a) * np.linspace(0, 1, n_s)[:, None]
        d = np.linalg.norm(samples[:, None] - pts[None], axis=2).min(axis=1)
        seen[i] = float((d <= 1.0).mean())
    return seen


def _check(
    verts: NDArray, lines: list[Line], seen: NDArray, mask: NDArray, bad: NDArray, slack: float
) -> None:
    """Refuse polygons with unseen edges or an outline that does not match the top face (both
    judged on visible pixels only)."""
    for i, frac in enumerate(seen):
        if frac < MIN_EDGE_SEEN:
            raise ExtractionError(
                f"edge {i} of the polygon is seen over only {100 * frac:.0f}% of its length; the "
                "block is occluded there or the edge is spurious"
            )
    h, w = mask.shape
    vy, vx = np.mgrid[0:h, 0:w]
    grid = np.stack([vx.ravel(), vy.ravel()], axis=1).astype(float)
    depth_in = np.max(np.stack([ln.distance(grid) for ln in lines], axis=1), axis=1).reshape(h, w)
    visible = ~bad
    m = mask.astype(bool)
    outside = int((m & (depth_in > slack) & visible).sum())
    missing = int((~m & (depth_in < -MISMATCH_DISTANCE) & visible).sum())
    area = max(1, int(m.sum()))
    hidden = int((~m & (depth_in < 0) & bad).sum())
    if hidden > MAX_HIDDEN_FRACTION * area:
        raise ExtractionError(
            f"{100 * hidden / area:.0f}% of the polygon lies where the face is hidden (by "
            "something "
            "above it, such as the arm, or the image border); its shape there is not seen"
        )
    if outside > MAX_OUTLINE_MISMATCH * area or missing > MAX_OUTLINE_MISMATCH * area:
        raise ExtractionError(
            f"the polygon does not match the top face ({outside} face pixels outside it, "
            f"{missing} polygon pixels not on the face, of {area}); the face is not one convex "
            "block (touching blocks of the same colour?)"
        )
