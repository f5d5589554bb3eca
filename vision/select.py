"""Selecting the block to grasp (section 5.2, Select/Model: "this selection is done directly on
the overhead image, by clicking on the object image"), by pixel, by block name, or nearest to a
world point."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.errors import NotABlockError, VisionError
from vision.extract import model_from_region
from vision.model import ObjectModel
from vision.observation import Observation
from vision.segment import BlockRegion, Segmentation, segment

#: A named block must have a segmented top face within this distance (m) of its true position.
NAME_MATCH_RADIUS = 0.03


@dataclass(frozen=True)
class Selection:
    """A segmented overhead view ready for selections; build it with :func:`analyze`."""

    observation: Observation
    segmentation: Segmentation
    noise_sigma: float | None  #: image noise (grey levels); None: measured per block
    names: tuple[str | None, ...]  #: scene name of each block, None when unknown
    #: each block's model (or why it has none) once computed: a view is modelled once
    _models: dict[int, ObjectModel | VisionError] = field(
        default_factory=dict, compare=False, repr=False
    )

    @property
    def blocks(self) -> tuple[BlockRegion, ...]:
        return self.segmentation.blocks

    def block_centres(self) -> NDArray[np.float64]:
        """(n, 3) world point at the middle of each top face (from its pixels, approximate)."""
        uv = np.array([b.pixel_centroid for b in self.blocks]).reshape(-1, 2)
        z = np.array([b.z_top for b in self.blocks])
        g = self.observation.geometry
        return np.array([g.pixel_to_plane(p, zz) for p, zz in zip(uv, z, strict=True)]).reshape(
            -1, 3
        )

    def model(self, index: int) -> ObjectModel:
        """The object model of block ``index``; raises ExtractionError saying why if none fits."""
        if not 0 <= index < len(self.blocks):
            raise VisionError(f"block index {index} out of range: {len(self.blocks)} blocks found")
        if index not in self._models:
            try:
                self._models[index] = model_from_region(
                    self.observation,
                    self.segmentation,
                    self.blocks[index],
                    self.names[index],
                    self.noise_sigma,
                )
            except VisionError as e:
                self._models[index] = e
        found = self._models[index]
        if isinstance(found, VisionError):
            raise found
        return found

    def index_of_model(self, model: ObjectModel) -> int | None:
        """The block whose model (:meth:`model`) ``model`` is, or None when it is not one of
        this view's."""
        return next((i for i, m in self._models.items() if m is model), None)

    def _describe(self) -> str:
        h, w = self.segmentation.labels.shape
        if not self.blocks:
            return f"no blocks were found in the {w}x{h} image"
        return f"blocks in the {w}x{h} image are at pixels " + ", ".join(
            f"({b.pixel_centroid[0]:.0f}, {b.pixel_centroid[1]:.0f})" + (f" {name}" if name else "")
            for b, name in zip(self.blocks, self.names, strict=True)
        )

    def index_at_pixel(self, pixel: ArrayLike) -> int:
        """Block under an image pixel (u, v) (its top or a side face)."""
        u, v = (round(float(c)) for c in np.asarray(pixel, dtype=float).reshape(2))
        h, w = self.segmentation.labels.shape
        if not (0 <= u < w and 0 <= v < h):
            raise NotABlockError(
                f"pixel ({u}, {v}) is outside the {w}x{h} image; {self._describe()}"
            )
        label = int(self.segmentation.labels[v, u])
        if label == 0:
            raise NotABlockError(
                f"pixel ({u}, {v}) is on the table (or the floor), not on a block; "
                f"{self._describe()}"
            )
        if label < 0:
            raise NotABlockError(
                f"pixel ({u}, {v}) is on something above the blocks (the arm?), not on a block; "
                f"{self._describe()}"
            )
        return label - 1

    def index_near(self, world_point: ArrayLike) -> int:
        """Block whose top face centre is nearest (in xy) to a world point."""
        if not self.blocks:
            raise NotABlockError("no blocks were found in the image")
        p = np.asarray(world_point, dtype=float).reshape(-1)[:2]
        d = np.linalg.norm(self.block_centres()[:, :2] - p, axis=1)
        return int(np.argmin(d))

    def index_of_name(self, name: str) -> int:
        if name not in self.names:
            valid = sorted(n for n in self.names if n is not None)
            raise NotABlockError(f"no visible block is named {name!r}; visible blocks: {valid}")
        return self.names.index(name)

    def select_pixel(self, pixel: ArrayLike) -> ObjectModel:
        return self.model(self.index_at_pixel(pixel))

    def select_near(self, world_point: ArrayLike) -> ObjectModel:
        return self.model(self.index_near(world_point))

    def select_name(self, name: str) -> ObjectModel:
        return self.model(self.index_of_name(name))


def analyze(
    obs: Observation,
    block_positions: Mapping[str, ArrayLike] | None = None,
    noise_sigma: float | None = None,
    depth_tolerance: float | None = None,
) -> Selection:
    """Segment ``obs``; ``block_positions`` (scene name -> world xy) names the blocks found (the
    nearest within NAME_MATCH_RADIUS), as a simulator's object labels would."""
    seg = segment(obs) if depth_tolerance is None else segment(obs, depth_tolerance)
    names: list[str | None] = [None] * len(seg.blocks)
    sel = Selection(obs, seg, noise_sigma, tuple(names))
    if block_positions:
        centres = sel.block_centres()[:, :2]
        for name, pos in block_positions.items():
            if len(centres) == 0:
                break
            d = np.linalg.norm(centres - np.asarray(pos, dtype=float).reshape(-1)[:2], axis=1)
            i = int(np.argmin(d))
            if d[i] <= NAME_MATCH_RADIUS and names[i] is None:
                names[i] = name
        sel = Selection(obs, seg, noise_sigma, tuple(names))
    return sel


def select(
    obs: Observation,
    *,
    pixel: ArrayLike | None = None,
    name: str | None = None,
    world_point: ArrayLike | None = None,
    block_positions: Mapping[str, ArrayLike] | None = None,
    noise_sigma: float | None = None,
) -> ObjectModel:
    """The model of one block chosen by exactly one of ``pixel`` (u, v), ``name`` (needs
    ``block_positions``) or ``world_point`` (x, y[, z]).

    Raises :class:`NotABlockError` when the choice is not on a block (a click on the table) and
    :class:`ExtractionError` when the block's polygon cannot be extracted.
    """
    given = [
        k
        for k, v in (("pixel", pixel), ("name", name), ("world_point", world_point))
        if v is not None
    ]
    if len(given) != 1:
        raise VisionError(
            f"select one block by exactly one of pixel, name or world_point; got {given}"
        )
    sel = analyze(obs, block_positions, noise_sigma)
    if pixel is not None:
        return sel.select_pixel(pixel)
    if name is not None:
        return sel.select_name(name)
    return sel.select_near(world_point)
