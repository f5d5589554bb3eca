"""Select/Model (section 5.2): overhead image -> the selected block's polygon model.

``analyze(obs)`` segments the view; ``select(obs, pixel=... | name=... | world_point=...)`` (also
named ``extract_polygon``) returns an :class:`ObjectModel` or
raises a :class:`VisionError`. ``overhead_camera(world)`` sets up the camera as the vision needs.
"""

from vision.errors import ExtractionError, NotABlockError, VisionError
from vision.geometry import CameraGeometry
from vision.model import ObjectModel
from vision.observation import DEFAULT_HEIGHT, DEFAULT_WIDTH, Observation, overhead_camera
from vision.segment import BlockRegion, Segmentation, segment
from vision.select import Selection, analyze, select

extract_polygon = select

__all__ = [
    "DEFAULT_HEIGHT",
    "DEFAULT_WIDTH",
    "BlockRegion",
    "CameraGeometry",
    "ExtractionError",
    "NotABlockError",
    "ObjectModel",
    "Observation",
    "Segmentation",
    "Selection",
    "VisionError",
    "analyze",
    "extract_polygon",
    "overhead_camera",
    "segment",
    "select",
]
