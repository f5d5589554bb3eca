"""Planar geometry of block footprints on the table (section 5.1: prisms on a table).

Footprints are convex polygons (CCW vertex arrays, metres, world frame). These helpers place a
polygon at a pose, measure the gap between two footprints and test containment in the table top;
:mod:`hand_sim.scene` uses them to refuse overlapping or off-table blocks.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def rotation_2d(angle: float) -> NDArray[np.float64]:
    """The 2x2 matrix rotating column vectors by ``angle`` radians (CCW)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def place_polygon(vertices: ArrayLike, position: ArrayLike, yaw: float) -> NDArray[np.float64]:
    """Vertices (object frame, (k, 2)) rotated by ``yaw`` rad about the origin, then translated to
    ``position`` (x, y): the footprint in the world frame."""
    v = np.asarray(vertices, dtype=float)
    return v @ rotation_2d(yaw).T + np.asarray(position, dtype=float)


def _point_segment_distance(
    p: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64]
) -> float:
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def convex_polygons_intersect(a: ArrayLike, b: ArrayLike) -> bool:
    """True when the convex polygons ``a`` and ``b`` overlap or touch (separating axis theorem)."""
    pa, pb = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    for poly in (pa, pb):
        edges = np.roll(poly, -1, axis=0) - poly
        axes = np.stack([edges[:, 1], -edges[:, 0]], axis=1)
        proj_a, proj_b = pa @ axes.T, pb @ axes.T
        separated = (proj_a.max(axis=0) < proj_b.min(axis=0)) | (
            proj_b.max(axis=0) < proj_a.min(axis=0)
        )
        if np.any(separated):
            return False
    return True


def convex_polygon_distance(a: ArrayLike, b: ArrayLike) -> float:
    """Smallest distance between two convex polygons (metres); 0 when they overlap or touch."""
    pa, pb = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if convex_polygons_intersect(pa, pb):
        return 0.0
    best = np.inf
    for p, q in ((pa, pb), (pb, pa)):
        for point in p:
            for i in range(len(q)):
                best = min(best, _point_segment_distance(point, q[i], q[(i + 1) % len(q)]))
    return float(best)


def point_in_convex_polygon(point: ArrayLike, polygon: ArrayLike) -> bool:
    """True when ``point`` lies inside or on the CCW convex ``polygon``."""
    p = np.asarray(point, dtype=float)
    v = np.asarray(polygon, dtype=float)
    e = np.roll(v, -1, axis=0) - v
    r = p - v
    return bool(np.all(e[:, 0] * r[:, 1] - e[:, 1] * r[:, 0] >= 0.0))


def inside_rectangle(
    points: ArrayLike, centre: ArrayLike, size: ArrayLike, margin: float = 0.0
) -> bool:
    """True when every point lies in the axis-aligned rectangle of full ``size`` (x, y) centred at
    ``centre``, at least ``margin`` metres from its border."""
    p = np.atleast_2d(np.asarray(points, dtype=float))
    half = 0.5 * np.asarray(size, dtype=float) - margin
    return bool(np.all(np.abs(p - np.asarray(centre, dtype=float)) <= half + 1e-12))
