"""The polygon the Hough lines close, and the checks it must pass (section 5.2, Select/Model;
step 4 of :mod:`vision.contour`): every edge must be seen, little of the polygon may be hidden,
and the polygon must match the top face; when it does not, :class:`ExtractionError` says why
instead of returning a made-up shape. Also the measures the edge-count model selection
(:mod:`vision.edge_count`) uses: distance to the polygon's boundary, fraction of each edge seen.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from vision.errors import ExtractionError
from vision.hough import Line, clip_halfplanes

#: Each edge must be seen over at least this fraction of its length (or it is hidden).
MIN_EDGE_SEEN = 0.25
#: Largest fraction of the top face's pixels that may lie more than MISMATCH_DISTANCE (px)
#: outside the polygon, and of polygon pixels that many pixels inside it missing from the face.
MAX_OUTLINE_MISMATCH = 0.03
MISMATCH_DISTANCE = 1.0
#: Largest part of the polygon (fraction of the face's area) that may lie under an occluder: a
#: hidden vertex is inferred from its two seen edges, a hidden edge is refused.
MAX_HIDDEN_FRACTION = 0.05


def polygon_of_lines(lines: list[Line], box: NDArray[np.float64]) -> tuple[NDArray, list[int]]:
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


def boundary_distance(pts: NDArray[np.float64], verts: NDArray[np.float64]) -> NDArray:
    """Distance of points to the polygon's boundary."""
    a = verts
    b = np.roll(verts, -1, axis=0)
    ab = b - a
    length2 = np.maximum((ab**2).sum(-1), 1e-18)  # a zero-length edge is its vertex
    t = np.clip(((pts[:, None] - a[None]) * ab[None]).sum(-1) / length2[None], 0, 1)
    proj = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(pts[:, None] - proj, axis=2).min(axis=1)


def edge_seen(verts: NDArray, pts: NDArray) -> NDArray[np.float64]:
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


def check_polygon(
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
