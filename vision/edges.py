"""Sub-pixel edges of a block's top face from colour profiles (section 5.2, the edge detection
step before the Hough transform).

The rendered image is anti-aliased: a pixel the top face's edge crosses has a colour blended from
the face's colour and whatever lies just beyond the edge (table, shadow or the block's own side
face) in proportion to how much of it each covers. So along a profile across the edge, the colour's
distance from the face colour rises in proportion to the covered fraction, and the centroid of that
rise locates the edge to a fraction of a pixel without knowing what is outside.

All coordinates are pixels (``u`` right, ``v`` down, pixel centres at integers).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

#: Profiles reach this far inside the edge estimate and this far outside (px), sampled every
#: PROFILE_STEP px.
PROFILE_INSIDE = 3.0
PROFILE_OUTSIDE = 4.0
PROFILE_STEP = 0.25
#: The edge is searched up to this distance (px) beyond the current estimate.
OUTSIDE_OFFSET = 1.75
#: The rise that locates the edge is the run of slopes above this fraction of the steepest one.
RISE_FRACTION = 0.1
#: The colour contrast across an edge must exceed this many noise sigmas, and MIN_CONTRAST grey
#: levels whatever the noise.
MIN_CONTRAST_SIGMAS = 6.0
MIN_CONTRAST = 12.0
#: Half-length (in outline steps) of the chord that gives the outline's local direction.
TANGENT_HALF_SPAN = 3


@dataclass(frozen=True)
class Outline:
    """A top face's outline: one point per outline pixel, in order around the face."""

    pixel: NDArray[np.float64]  #: (N, 2) outline pixel centres (inside the face)
    normal: NDArray[np.float64]  #: (N, 2) outward unit normals (from the outline's direction)
    point: NDArray[np.float64]  #: (N, 2) sub-pixel edge points (pixel + half a pixel if unrefined)
    refined: NDArray[np.bool_]  #: (N,) edge found from colour (else from the depth mask)
    trusted: NDArray[np.bool_]  #: (N,) not next to an occluder or the image border


#: ``cv2.remap`` refuses maps with SHRT_MAX (32767) rows or more: points are sampled in rows of
#: this many (a long outline, such as two blocks' faces merged into one region, has more).
REMAP_ROW = 4096


def sample(img: NDArray[np.float32], pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """Bilinear samples of a colour image at points (..., 2)."""
    shape = pts.shape[:-1]
    flat = pts.reshape(-1, 2)
    n = len(flat)
    rows = max(1, -(-n // REMAP_ROW))
    grid = np.zeros((rows * REMAP_ROW, 2), np.float32)
    grid[:n] = flat
    grid = grid.reshape(rows, REMAP_ROW, 2)
    mx = np.ascontiguousarray(grid[..., 0])
    my = np.ascontiguousarray(grid[..., 1])
    out = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    out = out.reshape(rows * REMAP_ROW, img.shape[2])[:n]
    return out.reshape(*shape, img.shape[2]).astype(np.float64)


def profile_offsets() -> NDArray[np.float64]:
    return np.arange(-PROFILE_INSIDE, PROFILE_OUTSIDE + 1e-9, PROFILE_STEP)


def crossings(
    prof: NDArray[np.float64],
    d: NDArray[np.float64],
    c_in: NDArray[np.float64],
    e_est: NDArray[np.float64],
    min_contrast: float,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Edge position along each colour profile (S, D, 3) sampled at offsets ``d`` (D,).

    ``c_in`` is the face colour, ``e_est`` (S,) the current edge estimates. The colour's distance
    from the face colour rises across the edge; the edge is the centroid of that rise (the run of
    clearly rising samples around the steepest point, before ``e_est + OUTSIDE_OFFSET``). For a
    pixel-integrated (anti-aliased) step sampled by linear interpolation this is exact, whatever
    lies beyond the edge: a second, lower step (the side face's far edge) has a falling distance and
    is left out. Returns the offsets of the edges and which profiles gave one (a rise above
    ``min_contrast``, the inside looking like the face).
    """
    dist = np.linalg.norm(prof - c_in, axis=2)  # (S, D)
    slope = np.diff(dist, axis=1)  # rise between samples k and k + 1
    mid = 0.5 * (d[:-1] + d[1:])
    rows = np.arange(len(prof))
    allowed = mid[None, :] <= (e_est + OUTSIDE_OFFSET)[:, None]
    peak = np.argmax(np.where(allowed, slope, -np.inf), axis=1)
    # the whole rise around the steepest point: the run of clearly positive slope holding it
    rising = allowed & (slope > RISE_FRACTION * slope[rows, peak][:, None])
    run_id = np.cumsum(~rising, axis=1)
    rise = np.where(rising & (run_id == run_id[rows, peak][:, None]), slope, 0.0)
    total = rise.sum(axis=1)
    e = (rise * mid[None, :]).sum(axis=1) / np.maximum(total, 1e-9)
    inside = dist[:, 0] < 0.3 * np.maximum(total, 1e-9)
    ok = (total > min_contrast) & inside & (slope[rows, peak] > 0)
    return e, ok


def face_colour(img: NDArray[np.float32], mask: NDArray[np.uint8]) -> NDArray[np.float64]:
    """Median colour of the face's interior (the mask eroded by 2 px)."""
    inner = cv2.erode(mask, np.ones((5, 5), np.uint8)) > 0
    if inner.sum() < 4:
        inner = mask > 0
    return np.median(img[inner].reshape(-1, img.shape[2]), axis=0).astype(np.float64)


def noise_sigma(img: NDArray[np.float32], mask: NDArray[np.uint8]) -> float:
    """Image noise (grey levels): robust spread of differences of horizontal neighbours inside the
    face (a flat colour, so smooth shading cancels)."""
    inner = cv2.erode(mask, np.ones((5, 5), np.uint8)) > 0
    pair = np.zeros_like(inner)
    pair[:, :-1] = inner[:, :-1] & inner[:, 1:]
    ys, xs = np.nonzero(pair)
    if ys.size < 4:
        return 0.0
    diff = img[ys, xs] - img[ys, xs + 1]
    return float(1.4826 * np.median(np.abs(diff)) / np.sqrt(2.0))


def min_contrast(sigma: float) -> float:
    return max(MIN_CONTRAST, MIN_CONTRAST_SIGMAS * sigma)


def outline(
    mask: NDArray[np.uint8], img: NDArray[np.float32], bad: NDArray[np.bool_], sigma: float
) -> Outline:
    """The ordered outline of a face mask with a sub-pixel edge point per outline pixel.

    ``bad`` marks pixels whose neighbourhood is not the face's own outline (occluders, border).
    """
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    chain = max(contours, key=len).reshape(-1, 2).astype(np.float64)
    n = len(chain)
    k = min(TANGENT_HALF_SPAN, max(1, n // 4))
    tangent = np.roll(chain, -k, axis=0) - np.roll(chain, k, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    # orient outward: most points plus 2 normals must leave the mask
    probe = np.rint(chain + 2.0 * normal).astype(int)
    h, w = mask.shape
    inside = np.zeros(n, bool)
    okp = (probe[:, 0] >= 0) & (probe[:, 0] < w) & (probe[:, 1] >= 0) & (probe[:, 1] < h)
    inside[okp] = mask[probe[okp, 1], probe[okp, 0]] > 0
    if inside.mean() > 0.5:
        normal = -normal
    trusted = ~bad[chain[:, 1].astype(int), chain[:, 0].astype(int)]
    d = profile_offsets()
    prof = sample(img, chain[:, None, :] + d[None, :, None] * normal[:, None, :])
    c_in = face_colour(img, mask)
    e, ok = crossings(prof, d, c_in, np.full(n, 0.5), min_contrast(sigma))
    e = np.where(ok, e, 0.5)
    return Outline(chain, normal, chain + e[:, None] * normal, ok, trusted)
