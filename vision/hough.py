"""Straight edges of a block's outline by the Hough transform (section 5.2, Select/Model: "The
Hough edge detection algorithm is then used to extract a 2D object contour model").

All coordinates are pixels (``u`` right, ``v`` down, pixel centres at integers). The outline is a
closed, ordered sequence of sub-pixel edge points (:mod:`vision.edges`). A sequential Hough
transform of the points (``cv2.HoughLinesPointSet``) finds the edges: the most-voted line is
fitted (total least squares) to the longest run of consecutive outline points along it, those
points are removed, and the transform runs again on the rest; this keeps lines through two
edges' points (a corner's diagonals) from winning. Lines of nearly the same angle and offset are
merged, and :func:`clip_halfplanes` intersects the lines' inner half-planes into a convex polygon.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.errors import ExtractionError

#: Hough resolution: offset (px) and angle (rad); candidate lines examined per transform.
HOUGH_RHO = 0.5
HOUGH_THETA = np.pi / 360.0
HOUGH_CANDIDATES = 12
#: Hough accumulator threshold (votes = edge points on a line).
MIN_VOTES = 4
#: Edge points within this distance (px) of a Hough line support it; the line is refit to the points
#: within a given distance of its first fit: LOOSE_FIT_DISTANCE for sub-pixel colour points in
#: :mod:`vision.contour`'s pass 1, COARSE_FIT_DISTANCE for the depth mask's (whole pixels).
SUPPORT_DISTANCE = 0.8
LOOSE_FIT_DISTANCE = 0.6
COARSE_FIT_DISTANCE = 0.7
#: A line needs this many consecutive supporting points spanning at least MIN_EDGE_PX pixels.
MIN_SUPPORT = 4
MIN_EDGE_PX = 2.5
#: Consecutive outline points may skip this many points (noise) and still form one run.
MAX_RUN_GAP = 2
#: Lines whose normals differ by less than this (rad) and that lie within MERGE_OFFSET (px) of
#: each other at the face are one edge.
MERGE_ANGLE = np.deg2rad(3.0)
MERGE_OFFSET = 1.0


@dataclass(frozen=True)
class Line:
    """The line ``normal . p = offset`` in pixels; ``normal`` (unit) points out of the face."""

    normal: NDArray[np.float64]
    offset: float
    support: int  #: edge points supporting it

    @property
    def angle(self) -> float:
        return float(np.arctan2(self.normal[1], self.normal[0]))

    def distance(self, pts: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signed distance of points (N, 2): positive outside the face."""
        return pts @ self.normal - self.offset

    def shifted(self, offset: NDArray[np.float64]) -> Line:
        """The same line in coordinates where the origin moved to ``-offset``."""
        return Line(self.normal, self.offset + float(self.normal @ offset), self.support)


def fit_tls(pts: NDArray[np.float64], inside: NDArray[np.float64]) -> tuple[NDArray, float]:
    """Total-least-squares line through ``pts``; normal oriented away from ``inside``. Raises
    :class:`ExtractionError` for fewer than two distinct points (no line is defined)."""
    if len(pts) < 2 or not np.ptp(pts, axis=0).any():
        raise ExtractionError(
            f"an edge line was fitted to {len(pts)} edge point(s) with no extent; the region's "
            "outline is too short or degenerate to model"
        )
    mean = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - mean, full_matrices=False)
    n = vt[-1]
    if (inside - mean) @ n > 0:
        n = -n
    return n, float(n @ mean)


def runs(selected: NDArray[np.bool_], max_gap: int = MAX_RUN_GAP) -> list[NDArray[np.int64]]:
    """Runs of selected indices along a closed outline, allowing gaps of ``max_gap`` points."""
    idx = np.flatnonzero(selected)
    n = selected.size
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > max_gap + 1)
    groups = np.split(idx, breaks + 1)
    if len(groups) > 1 and idx[0] + n - idx[-1] <= max_gap + 1:  # wraps around
        groups[0] = np.concatenate([groups[-1], groups[0]])
        groups.pop()
    return groups


def longest_run(selected: NDArray[np.bool_]) -> NDArray[np.int64]:
    groups = runs(selected)
    return max(groups, key=len) if groups else np.zeros(0, np.int64)


def robust_fit(
    pts: NDArray[np.float64], centre: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float, NDArray[np.bool_]]:
    """TLS fit dropping outliers (residual beyond 4 robust sigmas, at least 0.25 px)."""
    keep = np.ones(len(pts), bool)
    n, c = fit_tls(pts, centre)
    for _ in range(2):
        r = pts @ n - c
        mad = float(np.median(np.abs(r[keep] - np.median(r[keep]))))
        keep = np.abs(r) < max(0.25, 4.0 * 1.4826 * mad)
        if keep.sum() < 2 or not np.ptp(pts[keep], axis=0).any():
            break
        n, c = fit_tls(pts[keep], centre)
    return n, c, keep


def line_from_run(
    pts: NDArray[np.float64], run: NDArray[np.int64], centre: NDArray[np.float64]
) -> Line | None:
    if len(run) < MIN_SUPPORT:
        return None
    p = pts[run]
    if np.linalg.norm(p.max(axis=0) - p.min(axis=0)) < MIN_EDGE_PX:
        return None
    n, c, keep = robust_fit(p, centre)
    if keep.sum() < MIN_SUPPORT:
        return None
    return Line(n, c, int(keep.sum()))


def _hough_point_set(pts: NDArray[np.float64], radius: float) -> NDArray[np.float64] | None:
    found = cv2.HoughLinesPointSet(
        pts.astype(np.float32).reshape(-1, 1, 2),
        HOUGH_CANDIDATES,
        MIN_VOTES,
        -radius,
        radius,
        HOUGH_RHO,
        0.0,
        np.pi,
        HOUGH_THETA,
    )
    return None if found is None else np.asarray(found, dtype=float).reshape(-1, 3)


def hough_lines(
    pts: NDArray[np.float64],
    usable: NDArray[np.bool_],
    centre: NDArray[np.float64],
    fit_distance: NDArray[np.float64],
) -> tuple[list[Line], list[NDArray[np.int64]]]:
    """Edges of an ordered outline by sequential Hough transforms (see the module docstring).

    ``fit_distance`` (N,) is how far each point may lie from its line. Returns the lines and,
    for each, the outline indices that support it.
    """
    avail = usable.copy()
    radius = float(np.abs(pts).max()) * 1.5 + 2.0
    lines: list[Line] = []
    members: list[NDArray[np.int64]] = []
    while avail.sum() >= MIN_SUPPORT:
        found = _hough_point_set(pts[avail], radius)
        if found is None:
            break
        accepted = False
        for _votes, rho, theta in found:
            n = np.array([np.cos(theta), np.sin(theta)])
            if rho - n @ centre < 0:
                n, rho = -n, -rho
            if rho - n @ centre < 1.0:  # a line through the middle of the face is no edge
                continue
            coarse = Line(n, float(rho), 0)
            run = longest_run(avail & (np.abs(coarse.distance(pts)) < SUPPORT_DISTANCE))
            first = line_from_run(pts, run, centre)
            if first is None:
                continue
            run = longest_run(avail & (np.abs(first.distance(pts)) < fit_distance))
            line = line_from_run(pts, run, centre)
            if line is None:
                continue
            lines.append(line)
            members.append(run)
            avail[run] = False
            accepted = True
            break
        if not accepted:
            break
    return merge_lines(lines, members, pts, centre)


def same_line(a: Line, b: Line, centre: NDArray[np.float64]) -> bool:
    """Normals within MERGE_ANGLE, and b within MERGE_OFFSET of a where a is nearest the centre."""
    dang = abs(np.angle(np.exp(1j * (a.angle - b.angle))))
    foot = centre - a.distance(centre[None])[0] * a.normal
    return dang < MERGE_ANGLE and abs(b.distance(foot[None])[0]) < MERGE_OFFSET


def merge_lines(
    lines: list[Line],
    members: list[NDArray[np.int64]],
    pts: NDArray[np.float64],
    centre: NDArray[np.float64],
) -> tuple[list[Line], list[NDArray[np.int64]]]:
    out_l: list[Line] = []
    out_m: list[NDArray[np.int64]] = []
    for ln, mem in zip(lines, members, strict=True):
        for j, other in enumerate(out_l):
            if same_line(ln, other, centre):
                joined = np.concatenate([out_m[j], mem])
                n, c, keep = robust_fit(pts[joined], centre)
                out_l[j] = Line(n, c, int(keep.sum()))
                out_m[j] = joined
                break
        else:
            out_l.append(ln)
            out_m.append(mem)
    return out_l, out_m


def clip_halfplanes(lines: list[Line], box: NDArray[np.float64]) -> tuple[NDArray, list[int]]:
    """Intersection of the inner half-planes of ``lines`` with the convex polygon ``box``.

    Returns the vertices and, for each edge (vertex i -> i + 1), the index of the line that
    carries it (-1 for an edge of ``box``).
    """
    poly = [np.asarray(p, dtype=float) for p in box]
    tags = [-1] * len(poly)
    for li, ln in enumerate(lines):
        out_pts: list[NDArray] = []
        out_tags: list[int] = []
        k = len(poly)
        for i in range(k):
            p, q, tag = poly[i], poly[(i + 1) % k], tags[i]
            dp, dq = float(ln.distance(p[None])[0]), float(ln.distance(q[None])[0])
            if dp <= 0:
                out_pts.append(p)
                out_tags.append(tag)
                if dq > 0:  # leaving: the cut point starts an edge on this line
                    out_pts.append(p + (q - p) * (dp / (dp - dq)))
                    out_tags.append(li)
            elif dq <= 0:  # entering
                out_pts.append(p + (q - p) * (dp / (dp - dq)))
                out_tags.append(tag)
        poly, tags = out_pts, out_tags
        if len(poly) < 3:
            return np.zeros((0, 2)), []
    verts = np.array(poly)
    keep = np.linalg.norm(np.roll(verts, -1, axis=0) - verts, axis=1) > 1e-9
    return verts[keep], [t for t, k in zip(tags, keep, strict=True) if k]
