"""The page's live view of the arm and hand: a perspective camera on the table, rendered small by
the thread that runs the task cycle (the one that owns MuJoCo) and sent to the page as JPEG
frames at a few frames per second of wall time. Rendering reads the simulation and changes
nothing in it; the frames are for the page only (the recording has its own cameras, on
simulated time)."""

from __future__ import annotations

import math
import time

import cv2
import mujoco
import numpy as np
from numpy.typing import NDArray

from hand_sim.camera import close_renderer, ensure_gl_backend
from hand_sim.world import World

#: Frame size (pixels) and JPEG quality of the live view.
WIDTH, HEIGHT = 480, 360
JPEG_QUALITY = 70
#: Frames per second of wall time while the arm moves (at most).
FRAME_RATE = 5.0
#: Where the view looks at and from, relative to the table top's centre (m): the recording's
#: 3-D view (fsm.recording: between the arm and the blocks, from in front and to the right of
#: the arm, raised), a little closer.
LOOK_OFFSET = (-0.12, 0.0, 0.12)
EYE_OFFSET = (0.55, -0.85, 0.62)


def encode_jpeg(rgb: NDArray[np.uint8], quality: int) -> bytes:
    """``rgb`` (H, W, 3) as JPEG bytes."""
    ok, buf = cv2.imencode(".jpg", rgb[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return buf.tobytes()


class LiveView:
    """A perspective camera on ``world``'s table; create, use and close it in the thread that
    steps the world (its GL context belongs to that thread)."""

    def __init__(
        self,
        world: World,
        width: int = WIDTH,
        height: int = HEIGHT,
        frame_rate: float = FRAME_RATE,
    ) -> None:
        ensure_gl_backend()
        self._renderer: mujoco.Renderer | None = mujoco.Renderer(
            world.model, height, width, font_scale=mujoco.mjtFontScale.mjFONTSCALE_50
        )
        flags = self._renderer.scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        table = world.scene.table
        centre = np.array([*table.position_xy, table.height])
        look = centre + np.array(LOOK_OFFSET)
        forward = look - (centre + np.array(EYE_OFFSET))
        camera = mujoco.MjvCamera()
        camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        camera.lookat[:] = look
        camera.distance = float(np.linalg.norm(forward))
        camera.azimuth = math.degrees(math.atan2(forward[1], forward[0]))
        camera.elevation = math.degrees(math.asin(forward[2] / camera.distance))
        self._camera = camera
        self._period = 1.0 / frame_rate
        self._last = -math.inf
        #: frames rendered so far
        self.frames = 0

    def due(self) -> bool:
        """Whether a frame is due (a frame period of wall time since the last)."""
        return time.perf_counter() - self._last >= self._period

    def frame(self, world: World) -> bytes:
        """The view of ``world`` now, as JPEG bytes."""
        if self._renderer is None:
            raise RuntimeError("the live view is closed")
        self._renderer.update_scene(world.data, camera=self._camera)
        rgb = self._renderer.render()
        self._last = time.perf_counter()
        self.frames += 1
        return encode_jpeg(rgb, JPEG_QUALITY)

    def close(self) -> None:
        """Release the renderer's GL context (idempotent)."""
        if self._renderer is not None:
            close_renderer(self._renderer)
            self._renderer = None
