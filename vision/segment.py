"""Segment the blocks from the table in the overhead view (section 5.2, Select/Model: "the total
number of objects and their approximate position on the table is determined by analyzing the
overhead image").

Depth does the segmenting, colour only splits touching blocks:

1. every pixel is back-projected to a world point; the table is the most common height;
2. the blocks' top faces are flat plateaus of height above the table (peaks of the height
   histogram); pixels within ``top_tolerance`` of a plateau form top faces, so side faces seen in
   perspective and anything lower are left out;
3. each connected top face is one block, unless its colour is cut by an edge across its interior
   (two blocks of different colours touching), then a watershed splits it;
4. anything higher than a top face next to it (the arm) is an *occluder*: its outline is not a
   block edge;
5. a flat face that touches the image border is not a block either: the table lies inside the
   view, so such a face is off the table (the parked arm's base at the image's left edge) or only
   partly seen; it is labelled an occluder.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from vision.errors import VisionError
from vision.observation import Observation

#: Height bins of the table and plateau histograms (m).
HEIGHT_BIN = 0.001
#: A pixel this much above the table is not table (m).
MIN_ELEVATION = 0.01
#: Blocks are at most this tall (m); taller flat things (the arm) are not blocks.
MAX_BLOCK_HEIGHT = 0.5
#: A top face has at least this many pixels, and at least MIN_TOP_AREA (m^2).
MIN_TOP_PIXELS = 40
MIN_TOP_AREA = 1e-4
#: Width (m, on the top face) of the square neighbourhood over which a flat (top face) pixel's
#: height may not vary; at least 3 pixels.
FLAT_WINDOW = 0.004
#: Default tolerance of a top plateau (m): covers depth quantization and rendering noise.
TOP_TOLERANCE = 0.003
#: Heights within this distance (m) of the table estimate the depth noise.
NOISE_WINDOW = 0.01
#: The plateau tolerance is at least this many depth-noise sigmas.
TOLERANCE_SIGMAS = 4.0
#: Occluders are this much higher than the top face they cover (m).
OCCLUDER_MARGIN = 0.01
#: Canny thresholds (on a blurred grey image) of edges that split touching blocks.
SPLIT_CANNY = (40, 100)
#: An interior colour edge must have this many pixels to split a top face.
MIN_SPLIT_EDGE_PIXELS = 12


@dataclass(frozen=True)
class BlockRegion:
    """One block's top face in the image."""

    index: int  #: 0-based, in order of decreasing area
    top_mask: NDArray[np.bool_]  #: (H, W) pixels of the top face
    z_top: float  #: height of the top face (world z, m)
    pixel_centroid: tuple[float, float]  #: (u, v) centroid of the top-face pixels
    area_px: int
    bbox: tuple[int, int, int, int]  #: (u0, v0, u1, v1) of the top face, u1/v1 exclusive


@dataclass(frozen=True)
class Segmentation:
    """Blocks and table found in one observation."""

    table_z: float  #: world z of the table top (m)
    depth_sigma: float  #: depth noise measured on the table (m)
    tolerance: float  #: half-width (m) of the top plateaus' height band
    height: NDArray[np.float64]  #: (H, W) world z of every pixel (nan where nothing was hit)
    blocks: tuple[BlockRegion, ...]
    labels: NDArray[np.int32]  #: (H, W): 0 table or below, k > 0 block k - 1, -1 occluder
    occluder: NDArray[np.bool_]  #: (H, W) pixels higher than the blocks next to them, or no hit


def world_height(obs: Observation) -> NDArray[np.float64]:
    """World z of every pixel (nan where the depth is not a positive number). The far plane,
    where nothing was hit, comes out far below the table, like the floor."""
    depth = obs.depth
    z = obs.geometry.height_map(depth).astype(np.float64)
    return np.where(np.isfinite(depth) & (depth > 0), z, np.nan)


def _mode(values: NDArray[np.float64], bin_width: float) -> float:
    lo = float(values.min())
    idx = np.floor((values - lo) / bin_width).astype(np.int64)
    counts = np.bincount(idx)
    k = int(np.argmax(counts))
    near = values[np.abs(values - (lo + (k + 0.5) * bin_width)) <= 2.0 * bin_width]
    return float(np.median(near))


def table_height(z: NDArray[np.float64]) -> tuple[float, float]:
    """World z of the table (the most common height of the visible points) and the depth noise
    (robust standard deviation of the heights near it)."""
    valid = z[np.isfinite(z)]
    if valid.size == 0:
        raise VisionError("the depth image shows nothing (every pixel at the far plane)")
    table_z = _mode(valid, HEIGHT_BIN)
    near = valid[np.abs(valid - table_z) < NOISE_WINDOW] - table_z
    sigma = 1.4826 * float(np.median(np.abs(near))) if near.size else 0.0
    return table_z, sigma


def plateau_heights(
    z: NDArray[np.float64], table_z: float, tolerance: float = TOP_TOLERANCE, window: int = 5
) -> list[float]:
    """Heights of flat horizontal plateaus above the table with at least MIN_TOP_PIXELS pixels.

    Only *flat* pixels vote (height range over their ``window`` x ``window`` neighbourhood below
    2 x ``tolerance``): side faces seen in perspective change height across it and do not.
    """
    zz = np.nan_to_num(z, nan=-1e3).astype(np.float32)
    kernel = np.ones((window, window), np.uint8)
    spread = cv2.dilate(zz, kernel) - cv2.erode(zz, kernel)
    flat = np.isfinite(z) & (spread < 2.0 * tolerance)
    flat &= (z > table_z + MIN_ELEVATION) & (z < table_z + MAX_BLOCK_HEIGHT)
    elevated = z[flat]
    if elevated.size < MIN_TOP_PIXELS:
        return []
    window = max(1, round(tolerance / HEIGHT_BIN))
    lo = float(elevated.min()) - 2 * window * HEIGHT_BIN
    counts = np.bincount(np.floor((elevated - lo) / HEIGHT_BIN).astype(np.int64))
    counts = np.concatenate([counts, np.zeros(2 * window + 1, counts.dtype)])
    smooth = np.convolve(counts, np.ones(2 * window + 1), mode="same")
    heights: list[float] = []
    taken = np.zeros(smooth.size, dtype=bool)
    for k in np.argsort(smooth, kind="stable")[::-1]:
        if smooth[k] < MIN_TOP_PIXELS:
            break
        if taken[max(0, k - 2 * window) : k + 2 * window + 1].any():
            continue
        taken[k] = True
        k = max(0, k - window) + int(np.argmax(counts[max(0, k - window) : k + window + 1]))
        near = elevated[np.abs(elevated - (lo + (k + 0.5) * HEIGHT_BIN)) <= tolerance]
        heights.append(float(np.median(near)))
    return sorted(heights)


def _split_by_colour(rgb: NDArray[np.uint8], comp: NDArray[np.bool_]) -> list[NDArray[np.bool_]]:
    """Split a top face cut by a colour edge across its interior (touching blocks)."""
    ys, xs = np.nonzero(comp)
    y0, y1 = max(0, ys.min() - 3), min(comp.shape[0], ys.max() + 4)
    x0, x1 = max(0, xs.min() - 3), min(comp.shape[1], xs.max() + 4)
    sub = comp[y0:y1, x0:x1].astype(np.uint8)
    img = cv2.GaussianBlur(rgb[y0:y1, x0:x1], (5, 5), 1.0)
    edges = cv2.Canny(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY), *SPLIT_CANNY) > 0
    for c in range(3):  # colour edges that grey levels miss
        edges |= cv2.Canny(np.ascontiguousarray(img[..., c]), *SPLIT_CANNY) > 0
    interior = cv2.erode(sub, np.ones((5, 5), np.uint8)) > 0
    cut = edges & interior
    if int(cut.sum()) < MIN_SPLIT_EDGE_PIXELS:
        return [comp]
    seeds = sub.astype(bool) & ~(cv2.dilate(cut.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(seeds.astype(np.uint8), connectivity=4)
    keep = [i for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= MIN_TOP_PIXELS // 2]
    if len(keep) < 2:
        return [comp]
    markers = np.zeros(sub.shape, np.int32)
    for j, i in enumerate(keep):
        markers[lab == i] = j + 1
    markers[sub == 0] = len(keep) + 1  # outside the face: its own basin
    cv2.watershed(np.ascontiguousarray(img), markers)
    parts = []
    for j in range(len(keep)):
        part = np.zeros_like(comp)
        part[y0:y1, x0:x1] = (markers == j + 1) & sub.astype(bool)
        parts.append(part)
    return parts


def _touches_border(mask: NDArray[np.bool_]) -> bool:
    return bool(mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any())


def _fill_holes(mask: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The mask with every hole filled (outer contours drawn solid)."""
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros_like(mask)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    return filled


def segment(obs: Observation, tolerance: float | None = None) -> Segmentation:
    """Find the table and every block's top face in ``obs``.

    ``tolerance`` (m) is the half-width of a top plateau; by default TOP_TOLERANCE or
    TOLERANCE_SIGMAS times the depth noise measured on the table, whichever is larger.
    """
    z = world_height(obs)
    table_z, depth_sigma = table_height(z)
    if tolerance is None:
        tolerance = max(TOP_TOLERANCE, TOLERANCE_SIGMAS * depth_sigma)
    z_med = cv2.medianBlur(np.nan_to_num(z, nan=-1.0).astype(np.float32), 3).astype(np.float64)
    z_med[~np.isfinite(z)] = np.nan
    regions: list[tuple[NDArray[np.bool_], float]] = []
    off_table: list[NDArray[np.bool_]] = []
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))
    z_raw = np.nan_to_num(z, nan=-1.0)
    g = obs.geometry
    # the flatness window in pixels, at the height of the nearest possible top
    near = g.position[2] - (table_z + MIN_ELEVATION)
    window = max(3, 2 * round(0.5 * FLAT_WINDOW * g.K[0, 0] / max(near, 1e-6)) + 1)
    for h in plateau_heights(z_med, table_z, tolerance, window):
        pixel_area = ((g.position[2] - h) / g.K[0, 0]) * ((g.position[2] - h) / g.K[1, 1])
        min_pixels = max(MIN_TOP_PIXELS, MIN_TOP_AREA / pixel_area)
        # raw heights for the outline (a median filter would round corners), holes filled
        plateau = (np.abs(z_raw - h) <= tolerance).astype(np.uint8)
        plateau = cv2.morphologyEx(plateau, cv2.MORPH_CLOSE, kernel)
        n, lab, stats, _ = cv2.connectedComponentsWithStats(plateau, connectivity=4)
        for i in range(1, n):
            if stats[i, cv2.CC_STAT_AREA] < min_pixels:
                continue
            comp = _fill_holes((lab == i).astype(np.uint8)).astype(bool)
            for part in _split_by_colour(obs.rgb, comp):
                if part.sum() >= min_pixels:
                    if _touches_border(part):
                        off_table.append(part)
                        continue
                    top = part & (np.abs(z_raw - h) <= tolerance)
                    if not top.any():  # only pixels the closing filled in: no height of its own
                        continue
                    regions.append((part, float(np.median(z[top]))))
    regions.sort(key=lambda r: -int(r[0].sum()))
    blocks = []
    for k, (mask, zt) in enumerate(regions):
        ys, xs = np.nonzero(mask)
        bbox = (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1)
        blocks.append(
            BlockRegion(k, mask, zt, (float(xs.mean()), float(ys.mean())), int(xs.size), bbox)
        )
    labels, occluder = _label_pixels(z_med, table_z, blocks)
    for mask in off_table:
        labels[mask] = -1
        occluder |= mask
    return Segmentation(table_z, depth_sigma, tolerance, z, tuple(blocks), labels, occluder)


def _label_pixels(
    z: NDArray[np.float64], table_z: float, blocks: list[BlockRegion]
) -> tuple[NDArray[np.int32], NDArray[np.bool_]]:
    """Label every pixel: table (0), the block whose top face is nearest (k + 1), occluder (-1)."""
    h, w = z.shape
    labels = np.zeros((h, w), np.int32)
    no_hit = ~np.isfinite(z)
    if not blocks:
        return np.where(no_hit, -1, 0).astype(np.int32), no_hit
    top = np.zeros((h, w), np.int32)
    for b in blocks:
        top[b.top_mask] = b.index + 1
    # nearest top face of every pixel
    dist, nearest = cv2.distanceTransformWithLabels(
        (top == 0).astype(np.uint8), cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL
    )
    ys, xs = np.nonzero(top)
    lookup = np.zeros(int(nearest.max()) + 1, np.int32)
    lookup[nearest[ys, xs]] = top[ys, xs]
    owner = lookup[nearest]
    z_top = np.array([0.0] + [b.z_top for b in blocks])[owner]
    elevated = np.isfinite(z) & (z > table_z + MIN_ELEVATION)
    occluder = no_hit | (elevated & (z > z_top + OCCLUDER_MARGIN))
    labels[elevated] = owner[elevated]
    labels[occluder] = -1
    del dist
    return labels, occluder
