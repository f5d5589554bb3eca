"""The edge count of a block's top-face polygon by model selection on the ordered edge points
(section 5.2, Select/Model; step 3 of :mod:`vision.contour`): a run of outline points the
polygon misses proposes a line; a short edge missed between two found ones is added when three
lines beat two by far; neighbouring edges one line explains are merged; edges shorter than a
minimum (a blurred corner) and mostly unseen edges that nothing hides (a spurious line at a sharp
tip) are dropped when the other lines explain their points.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from vision.hough import (
    MIN_SUPPORT,
    Line,
    clip_halfplanes,
    line_from_run,
    longest_run,
    merge_lines,
    robust_fit,
)
from vision.polygon_check import boundary_distance, edge_seen, polygon_of_lines

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
#: Extra lines proposed for unexplained outline points, at most.
MAX_EXTRA_LINES = 4
#: A line is dropped only if the remaining polygon passes within this distance (px) of its points.
PRUNE_EXPLAINED = 0.8
#: ... and within this distance (px) for a line whose edge is mostly unseen, or within the
#: shortest edge length (at least this) for a line whose edge is too short to be a block's.
SHORT_EXPLAINED = 2.0
#: Edges seen over less than PRUNE_SEEN of their length with nothing hiding them are dropped if
#: the others explain their points.
PRUNE_SEEN = 0.5
#: Neighbouring edges turning by less than this (rad) are one edge (the random polygons' smallest
#: turns are about 14 deg; a few degrees come from the render's aliasing along long edges).
MIN_TURN = np.deg2rad(8.0)


def add_missed_lines(
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
    verts, _ = polygon_of_lines(lines, box)
    for _ in range(MAX_EXTRA_LINES):
        far = usable & (boundary_distance(pts, verts) > far_distance)
        for m in members:
            far[m] = False
        far_run = longest_run(far)
        extra = line_from_run(pts, far_run, centre)
        if extra is None:
            break
        # refit to the points near the proposed line; when too few lie within the fit distance
        # (a noisy run), the line keeps the run it was proposed from: a line never carries an
        # empty set of points (merging two such lines would fit a line to no point at all)
        run = longest_run(usable & (np.abs(extra.distance(pts)) < fit_distance))
        refit = line_from_run(pts, run, centre)
        if refit is None:
            run = far_run
        else:
            extra = refit
        lines, members = merge_lines([*lines, extra], [*members, run], pts, centre)
        verts, _ = polygon_of_lines(lines, box)
    return lines, members


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


def split_junctions(
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
    _, tags = polygon_of_lines(lines, box)
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


def merge_adjacent(
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
    verts, tags = polygon_of_lines(lines, box)
    while len(tags) > 3:
        best, best_cost = None, MERGE_CHI2 * sigma_e**2
        for i in range(len(tags)):
            a, b = tags[i], tags[(i + 1) % len(tags)]
            if min(len(members[a]), len(members[b])) < MIN_SUPPORT:
                continue  # a line without its own points is not weighed against another
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
        verts, tags = polygon_of_lines(lines, box)
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
    if len(members[drop]) and boundary_distance(pts[members[drop]], verts).max() > explained:
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
    verts, tags = polygon_of_lines(lines, box)
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


def prune_short(
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


def prune_unseen(
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
        seen = edge_seen(verts, pts[usable])
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
