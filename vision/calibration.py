"""The overhead camera checks its calibration against the table it looks at (section 5.3:
"calibration drifts"): the table's top is a known plane of known size, and the depth image shows
it against the floor 75 cm below.

From one overhead view (:func:`calibrate`):

1. the table's plane in the camera's frame, fitted to the depth image's points near the table's
   height (least squares, outliers past four robust sigmas left out, twice): its normal gives the
   camera's tilt, its distance the camera's height above the top;
2. the table's outline: the boundary of the pixels on that plane (the blocks on it filled in),
   away from the image's border, each boundary pixel's ray cut with the plane;
3. the camera's yaw and horizontal position: the rotation and shift that put those outline points
   on the known rectangle (least squares on their distances to it, robust to a few points that
   are not the table's edge, e.g. under the arm).

The estimate replaces the calibrated pose only where it differs from it by more than
:data:`SHIFT_TOLERANCE` or :data:`TURN_TOLERANCE` (the estimate's own error is a small share of
these): a camera that has not drifted keeps its calibration, and its views are unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from vision.geometry import CameraGeometry
from vision.observation import Observation

#: The calibrated pose is kept unless the estimate differs from it by more than these (m, rad).
SHIFT_TOLERANCE = 0.001
TURN_TOLERANCE = np.radians(0.05)
#: Pixels within this height (m) of the table's calibrated height seed the plane fit (the
#: calibration's own error at the table's far corners stays well inside it; the blocks' tops
#: are 10 cm or more above, the floor 75 cm below).
SEED_BAND = 0.05
#: Outliers of the plane fit: more than this many robust sigmas, or this far (m), off it.
PLANE_SIGMAS = 4.0
PLANE_FLOOR = 0.002
#: Outline pixels this close (px) to the image's border are the image's edge, not the table's.
BORDER = 3
#: Every n-th pixel (each way) takes part in the plane fit.
STRIDE = 4


@dataclass(frozen=True)
class Calibration:
    """The camera's pose as the table shows it."""

    geometry: CameraGeometry  #: the geometry to use: the estimate, or the calibrated one
    estimated: NDArray[np.float64]  #: (4, 4) the estimated camera-to-world pose
    shift: float  #: m, estimated position minus calibrated
    turn: float  #: rad, estimated orientation against calibrated
    outline_rms: float  #: m, RMS distance of the outline points to the table's rectangle
    points: int  #: outline points fitted
    corrected: bool  #: whether the estimate replaced the calibrated pose


def _rotation_between(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """The smallest rotation taking unit vector ``a`` to unit vector ``b``."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    s = float(np.linalg.norm(v))
    if s < 1e-15:
        return np.eye(3)
    k = v / s
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * K + (1.0 - c) * K @ K


def _rot_z(theta: float) -> NDArray[np.float64]:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _camera_points(obs: Observation, stride: int) -> NDArray[np.float64]:
    """Camera-frame points (h', w', 3) of every ``stride``-th pixel."""
    g = obs.geometry
    v, u = np.mgrid[0 : g.height : stride, 0 : g.width : stride]
    z = obs.depth[::stride, ::stride].astype(np.float64)
    x = (u - g.K[0, 2]) / g.K[0, 0] * z
    y = (v - g.K[1, 2]) / g.K[1, 1] * z
    return np.stack([x, y, z], axis=-1)


def _fit_plane(points: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """Unit normal n and offset d of the plane n . p = d through ``points`` (k, 3), n pointing
    towards the camera (the origin)."""
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre, full_matrices=False)
    n = vt[2]
    d = float(n @ centre)
    if d > 0:  # the camera (origin) on the normal's side: n . 0 - d > 0
        n, d = -n, -d
    return n, d


def _rect_distance(xy: NDArray[np.float64], half: tuple[float, float]) -> NDArray[np.float64]:
    """Signed distance of points (k, 2) to the boundary of the rectangle centred at the origin
    with half-sizes ``half`` (negative inside)."""
    q = np.abs(xy) - np.asarray(half)
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = np.minimum(np.maximum(q[:, 0], q[:, 1]), 0.0)
    return outside + inside


def calibrate(
    obs: Observation,
    table_centre: tuple[float, float],
    table_size: tuple[float, float],
    table_height: float,
) -> Calibration:
    """The camera's pose as the table shows it in ``obs`` (module docstring): the table's top
    centred at ``table_centre`` (world xy, m), ``table_size`` (x, y) m, ``table_height`` m above
    the floor, its edges along the world axes. ``obs.geometry`` is the calibrated camera."""
    g = obs.geometry
    R0, t0 = g.rotation, g.position
    # 1. the table's plane, in the camera's frame
    pts = _camera_points(obs, STRIDE)
    world_z = pts @ R0[2] + t0[2]
    keep = np.isfinite(world_z) & (np.abs(world_z - table_height) < SEED_BAND)
    sample = pts[keep]
    n, d = _fit_plane(sample)
    for _ in range(2):
        r = sample @ n - d
        sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
        sample = sample[np.abs(r) < max(PLANE_SIGMAS * sigma, PLANE_FLOOR)]
        n, d = _fit_plane(sample)
    up_world = np.array([0.0, 0.0, 1.0])
    # the smallest change of the calibrated orientation that levels the table
    R_level = _rotation_between(R0 @ n, up_world) @ R0
    height = -d  # the camera's distance to the plane (d < 0: the camera above it)
    # 2. the table's outline, on that plane
    full = _camera_points(obs, 1)
    r = full @ n - d
    sigma = 1.4826 * float(np.median(np.abs(r[np.isfinite(r)][:: STRIDE * STRIDE])))
    on_table = np.isfinite(r) & (np.abs(r) < max(PLANE_SIGMAS * sigma, PLANE_FLOOR))
    mask = on_table.astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    outline = max(contours, key=cv2.contourArea).reshape(-1, 2).astype(float)
    inner = (
        (outline[:, 0] >= BORDER)
        & (outline[:, 0] < g.width - BORDER)
        & (outline[:, 1] >= BORDER)
        & (outline[:, 1] < g.height - BORDER)
    )
    outline = outline[inner]
    rays = np.column_stack(
        [
            (outline[:, 0] - g.K[0, 2]) / g.K[0, 0],
            (outline[:, 1] - g.K[1, 2]) / g.K[1, 1],
            np.ones(len(outline)),
        ]
    )
    on_plane = rays * (d / (rays @ n))[:, None]
    level = on_plane @ R_level.T  # camera at the origin, z up
    # 3. yaw and horizontal position that put the outline on the table's rectangle
    centre = np.asarray(table_centre, dtype=float)
    half = (0.5 * table_size[0], 0.5 * table_size[1])

    def residual(x: NDArray[np.float64]) -> NDArray[np.float64]:
        c, s = np.cos(x[0]), np.sin(x[0])
        xy = level[:, :2] @ np.array([[c, s], [-s, c]]) + x[1:3] - centre
        return _rect_distance(xy, half)

    fit = least_squares(residual, np.array([0.0, t0[0], t0[1]]), loss="soft_l1", f_scale=0.002)
    yaw, tx, ty = fit.x
    R = _rot_z(yaw) @ R_level
    t = np.array([tx, ty, table_height + height])
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = R, t
    shift = float(np.linalg.norm(t - t0))
    turn = float(np.arccos(np.clip((np.trace(R0.T @ R) - 1.0) / 2.0, -1.0, 1.0)))
    corrected = shift > SHIFT_TOLERANCE or turn > TURN_TOLERANCE
    geometry = CameraGeometry(g.K, pose, g.width, g.height) if corrected else g
    rms = float(np.sqrt(np.mean(residual(fit.x) ** 2)))
    return Calibration(geometry, pose, shift, turn, rms, len(level), corrected)
