"""The scene as data: the table top, the prism blocks on it, the block to pick and the place point
(section 5.1: wooden prisms about 20 cm tall and 5 cm across on a table), their limits and
colours, and the checks every scene passes (:func:`validate_scene`), however it was made."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
from numpy.typing import NDArray

from controllers.grasp import Polygon
from hand_sim.errors import SceneError
from hand_sim.geometry import (
    convex_polygon_distance,
    inside_rectangle,
    place_polygon,
    point_in_convex_polygon,
)
from hand_sim.perturb import PerturbSpec
from hand_sim.resources import models_dir, scenes_dir

#: Directory holding the scene files (``<name>.toml``), found by :mod:`hand_sim.resources`.
SCENES_DIR = scenes_dir()
#: Name of the seeded random scene; its generator defaults live in ``scenes/random.toml``.
RANDOM_SCENE = "random"

#: Block height (m): "approximately 20 cm in height" (section 5.1).
BLOCK_HEIGHT = 0.20
#: Smallest gap (m) allowed between two block footprints.
MIN_BLOCK_GAP = 0.005
#: Smallest distance (m) between a block footprint or the place point and the table's edge.
TABLE_EDGE_MARGIN = 0.005
#: Limits on a block's size (m): extent of its footprint, and its height.
MIN_BLOCK_EXTENT, MAX_BLOCK_EXTENT = 0.01, 0.30
MIN_BLOCK_HEIGHT, MAX_BLOCK_HEIGHT = 0.01, 0.50

#: The table model: one source of truth for the table top's size and height (its collision box
#: ``table_top``); a scene may move the table (``position``) but not resize or raise it.
TABLE_MODEL_FILE = models_dir() / "table.xml"
TABLE_TOP_GEOM = "table_top"
#: Largest difference (m) tolerated between a scene's table ``size``/``height`` and the model's.
TABLE_TOLERANCE = 1e-3


def table_model_top(path: Path = TABLE_MODEL_FILE) -> tuple[tuple[float, float], float]:
    """Full size (x, y) and top height (m) of the table model's collision top, read from its MJCF
    (a box geom ``table_top`` under the table body, model frame on the floor)."""
    try:
        root = ElementTree.parse(path).getroot()
    except (OSError, ElementTree.ParseError) as e:
        raise SceneError(f"{path}: the table model cannot be read: {e}") from e
    geom = next((g for g in root.iter("geom") if g.get("name") == TABLE_TOP_GEOM), None)
    if geom is None or geom.get("type") != "box":
        raise SceneError(f"{path}: no box geom {TABLE_TOP_GEOM!r} (the table's collision top)")
    size = [float(v) for v in geom.get("size", "").split()]
    pos = [float(v) for v in geom.get("pos", "0 0 0").split()]
    if len(size) != 3 or len(pos) != 3:
        raise SceneError(f"{path}: geom {TABLE_TOP_GEOM!r} needs a 3-number size and pos")
    return (2.0 * size[0], 2.0 * size[1]), pos[2] + size[2]


#: Table top: full size x, y (m) and top height (m) from the model, centre x, y (m) by default.
DEFAULT_TABLE_SIZE, DEFAULT_TABLE_HEIGHT = table_model_top()
DEFAULT_TABLE_POSITION = (0.0, 0.0)

#: Named block colours (rgba in [0, 1]), all far from the table's light wood so that the overhead
#: image separates blocks from table; blocks without a colour take them in this order.
COLOURS: dict[str, tuple[float, float, float, float]] = {
    "red": (0.85, 0.15, 0.12, 1.0),
    "green": (0.15, 0.65, 0.2, 1.0),
    "blue": (0.15, 0.3, 0.85, 1.0),
    "yellow": (0.95, 0.8, 0.1, 1.0),
    "orange": (0.95, 0.5, 0.1, 1.0),
    "purple": (0.55, 0.2, 0.7, 1.0),
    "cyan": (0.1, 0.75, 0.8, 1.0),
    "magenta": (0.85, 0.2, 0.6, 1.0),
}


@dataclass(frozen=True)
class TableSpec:
    """The table top: full size (x, y) in m, height of its top surface above the floor (m) and the
    world (x, y) of its centre."""

    size_xy: tuple[float, float] = DEFAULT_TABLE_SIZE
    height: float = DEFAULT_TABLE_HEIGHT
    position_xy: tuple[float, float] = DEFAULT_TABLE_POSITION

    def contains(self, points: NDArray[np.float64], margin: float = TABLE_EDGE_MARGIN) -> bool:
        """True when every (x, y) point is on the table top, ``margin`` m from its edge."""
        return inside_rectangle(points, self.position_xy, self.size_xy, margin)


@dataclass(frozen=True, eq=False)
class BlockSpec:
    """One prism block: its footprint ``polygon`` (metres, centroid at the origin), the world
    (x, y) of the centroid, ``yaw`` (rad) about z, ``height`` (m) and colour ``rgba``."""

    name: str
    polygon: Polygon
    position: tuple[float, float]
    yaw: float = 0.0
    height: float = BLOCK_HEIGHT
    rgba: tuple[float, float, float, float] = COLOURS["red"]

    def footprint(self) -> NDArray[np.float64]:
        """World (x, y) vertices of the block's footprint, CCW."""
        return place_polygon(self.polygon.vertices, self.position, self.yaw)


@dataclass(frozen=True, eq=False)
class Scene:
    """A table, the blocks on it, the block to pick (``target``) and the place point (x, y);
    ``perturb``: how the simulated world is to differ from this nominal scene (the file's
    ``[perturb]`` table, :mod:`hand_sim.perturb`; none by default)."""

    name: str
    table: TableSpec
    blocks: tuple[BlockSpec, ...]
    target: str
    place: tuple[float, float]
    description: str = ""
    perturb: PerturbSpec = field(default_factory=PerturbSpec)

    @property
    def block_names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.blocks)

    def block(self, name: str) -> BlockSpec:
        """The block called ``name``; raises :class:`SceneError` listing the valid names."""
        for b in self.blocks:
            if b.name == name:
                return b
        raise SceneError(
            f"scene {self.name!r} has no block {name!r}; valid: {', '.join(self.block_names)}"
        )

    @property
    def target_block(self) -> BlockSpec:
        return self.block(self.target)


def validate_scene(scene: Scene, source: str) -> None:
    """Refuse duplicate names, blocks off the table or closer than :data:`MIN_BLOCK_GAP`, a
    ``target`` that is not a block and a ``place`` point off the table or inside another block."""
    names = scene.block_names
    for i, name in enumerate(names):
        if name in names[:i]:
            raise SceneError(f"{source}: blocks[{i}].name: duplicate block name {name!r}")
    footprints = [b.footprint() for b in scene.blocks]
    t = scene.table
    for i, (block, fp) in enumerate(zip(scene.blocks, footprints, strict=True)):
        if not t.contains(fp):
            raise SceneError(
                f"{source}: blocks[{i}].position: block {block.name!r} at {list(block.position)} "
                "is off the "
                f"table (table top {list(t.size_xy)} m centred at {list(t.position_xy)}, "
                f"edge margin {TABLE_EDGE_MARGIN} m)"
            )
    for i in range(len(footprints)):
        for j in range(i):
            gap = convex_polygon_distance(footprints[i], footprints[j])
            if gap < MIN_BLOCK_GAP:
                what = "overlaps" if gap == 0.0 else f"is {gap * 1000:.1f} mm from"
                raise SceneError(
                    f"{source}: blocks[{i}].position: block {names[i]!r} {what} block {names[j]!r} "
                    f"(blocks need a gap of at least {MIN_BLOCK_GAP * 1000:g} mm)"
                )
    if scene.target not in names:
        raise SceneError(
            f"{source}: target: {scene.target!r} is not a block; valid: {', '.join(names)}"
        )
    if not t.contains(np.array(scene.place)):
        raise SceneError(
            f"{source}: place: point {list(scene.place)} is off the table "
            f"(table top {list(t.size_xy)} m "
            f"centred at {list(t.position_xy)})"
        )
    for block, fp in zip(scene.blocks, footprints, strict=True):
        if block.name != scene.target and point_in_convex_polygon(scene.place, fp):
            raise SceneError(
                f"{source}: place: point {list(scene.place)} is inside block {block.name!r}"
            )
