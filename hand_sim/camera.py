"""The overhead camera: a fixed pinhole camera looking straight down at the table (section 5.2,
"Select/Model": the objects are found on the overhead image of the table).

Images are rendered headless with ``mujoco.Renderer`` (EGL). Pixel coordinates ``(u, v)`` are
(column, row) with integer values at pixel centres, row 0 at the top of the image. The camera
frame follows OpenCV: x right, y down, z along the optical axis; ``K`` maps camera-frame points to
pixels, and the depth image holds each pixel's z in that frame, in metres.
"""

from __future__ import annotations

import importlib
import math
import os

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from hand_sim.assembly import CAMERA_NAME, MAX_RENDER_HEIGHT, MAX_RENDER_WIDTH
from hand_sim.errors import HandSimError
from hand_sim.lifetime import ClosesOnExit
from hand_sim.world import World

#: MuJoCo's camera frame looks along -z with y up; OpenCV's along +z with y down.
MUJOCO_TO_OPENCV = np.diag([1.0, -1.0, -1.0])


def ensure_gl_backend() -> None:
    """Make MuJoCo's renderer use the backend ``MUJOCO_GL`` names (``egl`` by default).

    MuJoCo fixes its GL backend when it is first imported; a program that imports ``mujoco``
    before ``hand_sim`` (which sets ``MUJOCO_GL=egl``) would get GLFW, which fails without a
    display. Re-evaluating MuJoCo's backend choice fixes that.
    """
    from mujoco.rendering.classic import gl_context

    if os.environ.setdefault("MUJOCO_GL", "egl").lower() != "egl":
        return
    from mujoco.egl import GLContext as EglContext

    if gl_context.GLContext is not EglContext:
        importlib.reload(gl_context)


def focal_length(model: mujoco.MjModel, camera_id: int, height: int) -> float:
    """Focal length (pixels) of camera ``camera_id`` of ``model`` in an image ``height`` pixels
    high (MuJoCo's ``fovy`` is the vertical field of view)."""
    fovy = math.radians(float(model.cam_fovy[camera_id]))
    return 0.5 * height / math.tan(0.5 * fovy)


def intrinsics(focal_px: float, width: int, height: int) -> NDArray[np.float64]:
    """The 3x3 pinhole matrix K (pixels): square pixels, principal point at the image centre."""
    f = focal_px
    return np.array([[f, 0.0, 0.5 * width - 0.5], [0.0, f, 0.5 * height - 0.5], [0.0, 0.0, 1.0]])


def camera_pose(data: mujoco.MjData, camera_id: int) -> NDArray[np.float64]:
    """4x4 camera-to-world transform (OpenCV camera axes) of camera ``camera_id`` in ``data``'s
    kinematics: the pose the renderer draws from, or, in a model the robot believes in, the
    pose its calibration says."""
    T = np.eye(4)
    T[:3, :3] = data.cam_xmat[camera_id].reshape(3, 3) @ MUJOCO_TO_OPENCV
    T[:3, 3] = data.cam_xpos[camera_id]
    return T


def close_renderer(renderer: mujoco.Renderer) -> None:
    """Close ``renderer`` with its own GL context current: ``mujoco.Renderer.close`` frees its GL
    objects in whatever context is current, and with another renderer's current it deletes that
    renderer's framebuffers (the same object ids), which then draws garbage."""
    context = getattr(renderer, "_gl_context", None)
    if context is not None:
        context.make_current()
    renderer.close()


class OverheadCamera(ClosesOnExit):
    """RGB, depth and segmentation images of the world's ``overhead`` camera, with its
    intrinsics ``K`` and pose, and conversions between pixels and world points."""

    def __init__(self, world: World, width: int = 640, height: int = 480) -> None:
        if not (0 < width <= MAX_RENDER_WIDTH and 0 < height <= MAX_RENDER_HEIGHT):
            raise HandSimError(
                f"image size {width}x{height} is not allowed; width must be 1..{MAX_RENDER_WIDTH} "
                f"and height 1..{MAX_RENDER_HEIGHT}"
            )
        self.world = world
        self.width, self.height = width, height
        self.camera_id = int(world.model.camera(CAMERA_NAME).id)
        ensure_gl_backend()
        # no text is drawn: the smallest font makes the renderer ~50 ms faster to set up
        self._renderer: mujoco.Renderer | None = mujoco.Renderer(
            world.model, height, width, font_scale=mujoco.mjtFontScale.mjFONTSCALE_50
        )
        flags = self._renderer.scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        # the table fills the camera's whole view: without the skybox pass the images are the
        # same to the bit (tests/hand_sim/test_camera.py) and a 640x480 frame ~1 ms cheaper
        flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False
        self.focal_px = focal_length(world.model, self.camera_id, height)

    # --- geometry --------------------------------------------------------------------------
    @property
    def intrinsics(self) -> NDArray[np.float64]:
        """The 3x3 pinhole matrix K (pixels): square pixels, principal point at the image centre."""
        return intrinsics(self.focal_px, self.width, self.height)

    @property
    def pose(self) -> NDArray[np.float64]:
        """4x4 camera-to-world transform (OpenCV camera axes), from the current simulation state."""
        return camera_pose(self.world.data, self.camera_id)

    def world_to_pixel(self, xyz: ArrayLike) -> NDArray[np.float64]:
        """Pixel (u, v) of world points ``xyz`` (..., 3)."""
        p = np.asarray(xyz, dtype=float)
        T = self.pose
        cam = (p - T[:3, 3]) @ T[:3, :3]
        uvw = cam @ self.intrinsics.T
        return uvw[..., :2] / uvw[..., 2:3]

    def rays(self, uv: ArrayLike) -> NDArray[np.float64]:
        """World-frame directions (..., 3) through pixels ``uv``, scaled to unit camera z."""
        q = np.asarray(uv, dtype=float)
        K = self.intrinsics
        cam = np.stack(
            [
                (q[..., 0] - K[0, 2]) / K[0, 0],
                (q[..., 1] - K[1, 2]) / K[1, 1],
                np.ones(q.shape[:-1]),
            ],
            -1,
        )
        return cam @ self.pose[:3, :3].T

    def pixel_to_world(self, uv: ArrayLike, z_world: float | ArrayLike) -> NDArray[np.float64]:
        """World points (..., 3) where the rays through pixels ``uv`` meet the plane
        z = ``z_world``."""
        d = self.rays(uv)
        origin = self.pose[:3, 3]
        s = (np.asarray(z_world, dtype=float) - origin[2]) / d[..., 2]
        return origin + s[..., None] * d

    def deproject(self, uv: ArrayLike, depth: ArrayLike) -> NDArray[np.float64]:
        """World points (..., 3) of pixels ``uv`` whose depth-image values are ``depth`` (m)."""
        d = self.rays(uv)
        return self.pose[:3, 3] + np.asarray(depth, dtype=float)[..., None] * d

    def depth_to_points(self, depth: NDArray[np.float32]) -> NDArray[np.float64]:
        """(H, W, 3) world points of a whole depth image."""
        v, u = np.mgrid[0 : self.height, 0 : self.width]
        return self.deproject(np.stack([u, v], axis=-1), depth)

    # --- rendering -------------------------------------------------------------------------
    def _render(self) -> mujoco.Renderer:
        if self._renderer is None:
            raise HandSimError("this OverheadCamera is closed")
        self._renderer.update_scene(self.world.data, camera=self.camera_id)
        return self._renderer

    def rgb(self) -> NDArray[np.uint8]:
        """(H, W, 3) colour image of the current state."""
        return self._render().render().copy()

    def depth(self) -> NDArray[np.float32]:
        """(H, W) depth image: camera-frame z (m) of each pixel; the far plane where nothing is."""
        r = self._render()
        r.enable_depth_rendering()
        try:
            return r.render().astype(np.float32, copy=True)
        finally:
            r.disable_depth_rendering()

    def segmentation(self) -> NDArray[np.int32]:
        """(H, W) id of the geom seen at each pixel (-1 for background)."""
        r = self._render()
        r.enable_segmentation_rendering()
        try:
            seg = r.render()
        finally:
            r.disable_segmentation_rendering()
        ids = seg[..., 0].astype(np.int32)
        ids[seg[..., 1] != int(mujoco.mjtObj.mjOBJ_GEOM)] = -1
        return ids

    def body_mask(self, body_id: int) -> NDArray[np.bool_]:
        """(H, W) pixels showing a geom of body ``body_id``."""
        seg = self.segmentation()
        geom_body = np.append(self.world.model.geom_bodyid, -1)
        return geom_body[seg] == body_id

    # --- lifetime --------------------------------------------------------------------------
    def close(self) -> None:
        """Release the renderer's GL context (call before exit or EGL complains)."""
        if self._renderer is not None:
            close_renderer(self._renderer)
            self._renderer = None
