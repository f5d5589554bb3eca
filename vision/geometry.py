"""Pinhole geometry of the overhead camera: pixels <-> world points (section 5.2, Select/Model).

Conventions (OpenCV): pixel ``(u, v)`` has ``u`` to the right and ``v`` down, and the *centre* of
the top-left pixel is ``(0, 0)``. The camera frame has x right, y down, z along the optical axis;
``cam_to_world`` maps it to the world frame (z up). Depth images hold the distance along the
optical axis (z-depth), as MuJoCo renders it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.errors import VisionError

#: MuJoCo cameras look along their -z axis with y up; OpenCV cameras along +z with y down.
MUJOCO_TO_OPENCV = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class CameraGeometry:
    """Intrinsics and pose of a pinhole camera.

    ``K`` is the 3x3 intrinsic matrix (pixel-centre convention above), ``cam_to_world`` the 4x4
    pose of the OpenCV camera frame in the world, ``width``/``height`` the image size in pixels.
    """

    K: NDArray[np.float64]
    cam_to_world: NDArray[np.float64]
    width: int
    height: int

    @classmethod
    def from_mujoco(
        cls, fovy_deg: float, cam_pos: ArrayLike, cam_xmat: ArrayLike, width: int, height: int
    ) -> CameraGeometry:
        """Geometry of a MuJoCo camera (``fovy`` in degrees, ``cam_xpos``, ``cam_xmat``)."""
        f = 0.5 * height / np.tan(0.5 * np.deg2rad(fovy_deg))
        K = np.array([[f, 0.0, 0.5 * width - 0.5], [0.0, f, 0.5 * height - 0.5], [0.0, 0.0, 1.0]])
        pose = np.eye(4)
        pose[:3, :3] = np.asarray(cam_xmat, dtype=float).reshape(3, 3) @ MUJOCO_TO_OPENCV
        pose[:3, 3] = np.asarray(cam_pos, dtype=float).reshape(3)
        return cls(K, pose, int(width), int(height))

    @property
    def rotation(self) -> NDArray[np.float64]:
        return self.cam_to_world[:3, :3]

    @property
    def position(self) -> NDArray[np.float64]:
        return self.cam_to_world[:3, 3]

    def rays(self, uv: ArrayLike) -> NDArray[np.float64]:
        """World directions (camera-z component 1, not unit) through pixels ``uv`` (..., 2)."""
        p = np.asarray(uv, dtype=float)
        k = self.K
        x = (p[..., 0] - k[0, 2]) / k[0, 0]
        y = (p[..., 1] - k[1, 2]) / k[1, 1]
        d_cam = np.stack([x, y, np.ones_like(x)], axis=-1)
        return d_cam @ self.rotation.T

    def backproject(self, depth: NDArray[np.floating]) -> NDArray[np.float64]:
        """World point (H, W, 3) seen at every pixel of a z-depth image (H, W) in metres."""
        h, w = depth.shape
        v, u = np.mgrid[0:h, 0:w]
        return self.position + self.rays(np.stack([u, v], axis=-1)) * depth[..., None]

    def height_map(self, depth: NDArray[np.floating]) -> NDArray[np.float32]:
        """World z (H, W) of every pixel of a z-depth image: cheaper than :meth:`backproject`."""
        h, w = depth.shape
        k, r = self.K, self.rotation
        x = ((np.arange(w) - k[0, 2]) / k[0, 0]).astype(np.float32)
        y = ((np.arange(h) - k[1, 2]) / k[1, 1]).astype(np.float32)
        ray_z = (
            np.float32(r[2, 0]) * x[None, :]
            + np.float32(r[2, 1]) * y[:, None]
            + np.float32(r[2, 2])
        )
        return np.float32(self.position[2]) + depth.astype(np.float32) * ray_z

    def pixel_to_plane(self, uv: ArrayLike, z_world: float) -> NDArray[np.float64]:
        """World points (..., 3) where the rays through pixels ``uv`` meet the plane z = z_world."""
        d = self.rays(uv)
        dz = d[..., 2]
        if np.any(np.abs(dz) < 1e-12):
            raise VisionError(
                f"a pixel ray is parallel to the plane z = {z_world:g} m; "
                "the camera must look down at the table"
            )
        t = (z_world - self.position[2]) / dz
        return self.position + d * t[..., None]

    def world_to_pixel(self, xyz: ArrayLike) -> NDArray[np.float64]:
        """Pixel coordinates (..., 2) of world points (..., 3)."""
        p = np.asarray(xyz, dtype=float) - self.position
        c = p @ self.rotation
        proj = c @ self.K.T
        return proj[..., :2] / proj[..., 2:3]
