"""One overhead view: RGB, z-depth and the camera geometry that took them (section 5.2)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vision.errors import VisionError
from vision.geometry import CameraGeometry

#: The image size the vision asks for: 0.54 mm per pixel on the blocks' top faces (the largest
#: hand_sim.camera allows; see docs/vision.md for what smaller images cost).
DEFAULT_WIDTH, DEFAULT_HEIGHT = 1920, 1440
#: Multisample anti-aliasing of the render: a real camera integrates light over each pixel, so
#: an edge crossing a pixel blends the colours on both sides; the sub-pixel edges rely on it.
MSAA_SAMPLES = 4


@dataclass(frozen=True)
class Observation:
    """An overhead image pair: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 z-depth in metres
    (the far plane where nothing was hit), and the ``geometry`` of the camera."""

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    geometry: CameraGeometry

    def __post_init__(self) -> None:
        if self.rgb.ndim != 3 or self.rgb.shape[2] != 3 or self.rgb.dtype != np.uint8:
            raise VisionError(
                f"rgb must be an (H, W, 3) uint8 image, got shape {self.rgb.shape} {self.rgb.dtype}"
            )
        if self.depth.shape != self.rgb.shape[:2]:
            raise VisionError(
                f"depth shape {self.depth.shape} differs from the rgb image's "
                f"{self.rgb.shape[:2]}; "
                "render both from the same camera"
            )
        if (self.geometry.height, self.geometry.width) != self.depth.shape:
            raise VisionError(
                f"camera geometry is {self.geometry.width}x{self.geometry.height} but the images "
                "are "
                f"{self.depth.shape[1]}x{self.depth.shape[0]}"
            )

    @classmethod
    def capture(cls, camera: Any) -> Observation:
        """Render an observation with a :class:`hand_sim.camera.OverheadCamera`."""
        rgb = np.ascontiguousarray(camera.rgb(), dtype=np.uint8)
        depth = np.ascontiguousarray(camera.depth(), dtype=np.float32)
        return cls(rgb, depth, geometry_of(camera, depth.shape))


def overhead_camera(world: Any, width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT) -> Any:
    """A hand_sim ``OverheadCamera`` of ``world`` set up as the vision needs it: MSAA_SAMPLES
    multisampling (set on the model before the renderer exists) and the default image size.
    Close it (or use it as a context manager) when done."""
    from hand_sim.camera import OverheadCamera

    world.model.vis.quality.offsamples = MSAA_SAMPLES
    return OverheadCamera(world, width, height)


def geometry_of(camera: Any, shape: tuple[int, int]) -> CameraGeometry:
    """:class:`CameraGeometry` of a hand_sim ``OverheadCamera`` (``intrinsics`` K and ``pose``,
    camera-to-world in the OpenCV convention)."""
    K = np.asarray(camera.intrinsics, dtype=float)
    pose = np.asarray(camera.pose, dtype=float)
    return CameraGeometry(K, pose, int(shape[1]), int(shape[0]))
