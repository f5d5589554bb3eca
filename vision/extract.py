"""From a segmented top face to an :class:`ObjectModel` in world units (section 5.2).

The image polygon's vertices are cast as rays onto the horizontal plane of the top face
(``z_top`` from depth), which undoes the perspective: the top face is 20 cm nearer the camera
than the table, so using the table plane would make the block look ~20 % too large.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.grasp import Polygon, PolygonError
from vision.contour import PixelPolygon, fit_polygon
from vision.errors import ExtractionError
from vision.hough import MIN_EDGE_PX
from vision.model import ObjectModel
from vision.observation import Observation
from vision.segment import BlockRegion, Segmentation

#: Shortest block edge the model keeps (m): shorter ones are blurred corners. The paper objects'
#: shortest edge is 21 mm; random convex polygons have edges down to about 5 mm.
MIN_EDGE_LENGTH = 0.0035
#: A polygon enclosing less than this (m^2, 1 mm^2) is no block's top face.
MIN_AREA = 1e-6


def _mask_slack(obs: Observation, seg: Segmentation, region: BlockRegion) -> float:
    """How far (px) side-face pixels within the plateau tolerance reach past the top face's
    edge: a point ``tolerance`` below the top appears displaced towards the image centre by
    ``r * tolerance / (camera height above the top)`` where r is its distance from the centre."""
    g = obs.geometry
    r = float(np.hypot(region.pixel_centroid[0] - g.K[0, 2], region.pixel_centroid[1] - g.K[1, 2]))
    half_size = 0.5 * float(max(region.bbox[2] - region.bbox[0], region.bbox[3] - region.bbox[1]))
    return (r + half_size) * seg.tolerance / (g.position[2] - region.z_top)


def _world_polygon(px: PixelPolygon, obs: Observation, z_top: float) -> NDArray[np.float64]:
    return obs.geometry.pixel_to_plane(px.vertices, z_top)[:, :2]


def _yaw_of(vertices: NDArray[np.float64]) -> float:
    """Outward normal angle of the longest edge of a CCW polygon."""
    e = np.roll(vertices, -1, axis=0) - vertices
    i = int(np.argmax(np.linalg.norm(e, axis=1)))
    return float(np.arctan2(-e[i, 0], e[i, 1]))


def model_from_region(
    obs: Observation,
    seg: Segmentation,
    region: BlockRegion,
    name: str | None = None,
    noise_sigma: float | None = None,
) -> ObjectModel:
    """Fit the Hough polygon of ``region`` and express it in world and object coordinates.

    Raises :class:`ExtractionError` (naming the block and the reason) when no polygon fits.
    """
    label = name or f"block{region.index}"
    u, v = region.pixel_centroid
    try:
        g = obs.geometry
        min_edge_px = MIN_EDGE_LENGTH * g.K[0, 0] / (g.position[2] - region.z_top)
        px = fit_polygon(
            region.top_mask,
            obs.rgb,
            seg.occluder,
            noise_sigma,
            region.bbox,
            max(MIN_EDGE_PX, min_edge_px),
            _mask_slack(obs, seg, region),
        )
    except ExtractionError as e:
        raise ExtractionError(f"block {label!r} at pixel ({u:.0f}, {v:.0f}): {e}") from e
    world = _world_polygon(px, obs, region.z_top)
    if not np.all(np.isfinite(world)) or abs(_signed_area(world)) < MIN_AREA:
        raise ExtractionError(
            f"block {label!r} at pixel ({u:.0f}, {v:.0f}): its polygon encloses no area "
            f"({abs(_signed_area(world)) * 1e6:.2f} mm^2)"
        )
    centroid_xy = _area_centroid(world)
    # Polygon.from_vertices orders CCW; keep the image contour in the same order
    ccw = _signed_area(world) > 0
    world_ccw = world if ccw else world[::-1]
    contour = px.vertices if ccw else px.vertices[::-1]
    yaw = _yaw_of(world_ccw)
    c, s = np.cos(yaw), np.sin(yaw)
    local = (world_ccw - centroid_xy) @ np.array([[c, -s], [s, c]])
    try:
        polygon = Polygon.from_vertices(local, label)
    except PolygonError as e:
        raise ExtractionError(f"block {label!r} at pixel ({u:.0f}, {v:.0f}): {e}") from e
    return ObjectModel(
        name=label,
        polygon=polygon,
        centroid=np.array([centroid_xy[0], centroid_xy[1], region.z_top]),
        yaw=yaw,
        height=region.z_top - seg.table_z,
        n_edges=polygon.n_edges,
        pixel_contour=contour.copy(),
        world_vertices=world_ccw.copy(),
        refined_edges=int(px.refined.sum()),
    )


def _signed_area(v: NDArray[np.float64]) -> float:
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float((x * np.roll(y, -1) - np.roll(x, -1) * y).sum())


def _area_centroid(v: NDArray[np.float64]) -> NDArray[np.float64]:
    x, y = v[:, 0], v[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = 0.5 * cross.sum()
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * a)
