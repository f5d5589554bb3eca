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

This module runs the steps (:func:`fit_polygon`); step 3 is :mod:`vision.edge_count`, step 4
:mod:`vision.polygon_check`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from vision import edges
from vision.edge_count import (
    add_missed_lines,
    merge_adjacent,
    prune_short,
    prune_unseen,
    split_junctions,
)
from vision.errors import ExtractionError
from vision.hough import (
    COARSE_FIT_DISTANCE,
    LOOSE_FIT_DISTANCE,
    MIN_EDGE_PX,
    MIN_SUPPORT,
    Line,
    hough_lines,
)
from vision.polygon_check import MISMATCH_DISTANCE, check_polygon, edge_seen, polygon_of_lines

__all__ = ["PixelPolygon", "fit_polygon"]

#: Margin (px) of the crop around a top face.
CROP_MARGIN = 8
#: Pass 2 fits points within FIT_SIGMAS edge-noise sigmas of a line, at least FIT_DISTANCE px.
FIT_SIGMAS = 3.5
FIT_DISTANCE = 0.2
#: Smallest edge-point noise assumed (px): aliasing of the anti-aliased render.
MIN_EDGE_NOISE = 0.04
#: Outline points farther than this (px), or UNEXPLAINED_SIGMAS edge-noise sigmas, from the
#: polygon are unexplained (a missed edge).
UNEXPLAINED_DISTANCE = 0.3
UNEXPLAINED_SIGMAS = 4.5
#: ... and farther than this (px) for points from the depth mask (whole pixels).
COARSE_UNEXPLAINED = 0.9
#: Outline pixels this close (px) to an occluder or the image border are not trusted.
UNTRUSTED_RADIUS = 2
#: Rounds of merging and pruning, at most.
CLEANUP_ROUNDS = 3
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


def _crop(
    top_mask: NDArray[np.bool_],
    untrusted: NDArray[np.bool_],
    bbox: tuple[int, int, int, int] | None = None,
) -> tuple[tuple[int, int, int, int], NDArray[np.uint8], NDArray[np.bool_]]:
    """The crop (x0, y0, x1, y1) around the face (``bbox`` plus :data:`CROP_MARGIN`), the face's
    mask in it, and its untrusted pixels: ``untrusted`` and the image border, dilated by
    :data:`UNTRUSTED_RADIUS`."""
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
    lines, members = add_missed_lines(
        lines, members, pts, usable, centre, box, far_distance, fit_distance
    )
    lines, members = split_junctions(lines, members, pts, usable, centre, box, sigma_e, min_edge_px)
    verts, tags = polygon_of_lines(lines, box)
    for _ in range(CLEANUP_ROUNDS):  # each removal can expose another
        before = len(lines)
        lines, members, verts, tags = merge_adjacent(lines, members, pts, centre, box, sigma_e)
        lines, members, verts, tags = prune_short(lines, members, pts, box, min_edge_px)
        lines, members, verts, tags = prune_unseen(lines, members, pts, usable, box, bad)
        if len(lines) == before:
            break
    used = [lines[t] for t in tags]
    refined = np.array([out.refined[members[t]].mean() > 0.5 for t in tags])
    trusted_pts = pts[usable]
    seen = edge_seen(verts, trusted_pts)
    check_polygon(verts, used, seen, mask, bad, MISMATCH_DISTANCE + mask_slack_px)
    offset = np.array([x0, y0], float)
    return PixelPolygon(
        verts + offset,
        tuple(ln.shifted(offset) for ln in used),
        seen,
        refined,
        trusted_pts + offset,
    )


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
