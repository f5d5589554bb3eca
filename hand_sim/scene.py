"""Scene files: the table, the prism blocks on it, the block to pick and the place point.

Section 5 of the paper: wooden prisms about 20 cm tall and 5 cm across (Figure 6's nine shapes)
stand on a table; the user picks one block and a delivery point on the overhead image. A scene
file fixes those choices in TOML (schema in docs/world.md); :func:`load_scene` reads and checks
one, and ``load_scene("random", seed=N, blocks=K)`` draws a collision-free layout.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np
from numpy.typing import NDArray

from controllers.grasp import PAPER_OBJECTS, GraspError, Polygon, paper_object
from hand_sim.errors import SceneError
from hand_sim.geometry import (
    convex_polygon_distance,
    inside_rectangle,
    place_polygon,
    point_in_convex_polygon,
)
from hand_sim.resources import models_dir, scenes_dir
from hand_sim.tomlfields import TomlFields, read_toml

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

_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_TOP_KEYS = {"name", "description", "table", "blocks", "target", "place"}
_TABLE_KEYS = {"size", "height", "position"}
_BLOCK_KEYS = {"name", "shape", "vertices", "position", "yaw_deg", "height", "colour", "rgba"}


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
    """A table, the blocks on it, the block to pick (``target``) and the place point (x, y)."""

    name: str
    table: TableSpec
    blocks: tuple[BlockSpec, ...]
    target: str
    place: tuple[float, float]
    description: str = ""

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


# --- listing and loading ----------------------------------------------------------------------


def scene_names() -> tuple[str, ...]:
    """Names accepted by :func:`load_scene`: the files of ``scenes/`` and ``random``."""
    return tuple(sorted(p.stem for p in SCENES_DIR.glob("*.toml")))


def load_scene(
    name_or_path: str | Path, *, seed: int | None = None, blocks: int | None = None
) -> Scene:
    """Read a scene by name (a file of ``scenes/``), by path, or draw ``random`` with a seed.

    ``seed`` and ``blocks`` apply to ``random`` only (defaults in ``scenes/random.toml``).
    Raises :class:`SceneError` naming the file, the field and the problem.
    """
    text = str(name_or_path)
    if text == RANDOM_SCENE:
        from hand_sim.random_scene import random_scene

        return random_scene(seed=0 if seed is None else seed, n_blocks=blocks)
    if seed is not None or blocks is not None:
        raise SceneError(
            f"seed and blocks apply to the {RANDOM_SCENE!r} scene only, not to {text!r}"
        )
    path = Path(name_or_path)
    if path.suffix != ".toml" and path.parent == Path("."):
        path = SCENES_DIR / f"{text}.toml"
        if not path.is_file():
            raise SceneError(f"unknown scene {text!r}; valid: {', '.join(scene_names())}")
    if not path.is_file():
        raise SceneError(f"{path}: scene file not found")
    return parse_scene(read_toml(path), source=str(path), default_name=path.stem)


# --- parsing ------------------------------------------------------------------------------


def parse_table(source: str, raw: Any) -> TableSpec:
    """The ``[table]`` section (every key optional). The table model (models/table.xml) fixes the
    top's size and height: a ``size`` or ``height`` that disagrees with it is refused, so that the
    table drawn, the table blocks stand on and the table the scene checks are one table."""
    f = TomlFields(source, "table", raw, _TABLE_KEYS)
    size = f.pair("size", DEFAULT_TABLE_SIZE)
    if max(abs(a - b) for a, b in zip(size, DEFAULT_TABLE_SIZE, strict=True)) > TABLE_TOLERANCE:
        f.fail(
            "size",
            f"{list(size)} m differs from the table model's top "
            f"({DEFAULT_TABLE_SIZE[0]:g} x {DEFAULT_TABLE_SIZE[1]:g} m, models/table.xml); "
            "leave 'size' out or match the model",
        )
    height = f.number("height", DEFAULT_TABLE_HEIGHT, lo=0.0, hi=2.0)
    if abs(height - DEFAULT_TABLE_HEIGHT) > TABLE_TOLERANCE:
        f.fail(
            "height",
            f"{height:g} m differs from the table model's top height "
            f"({DEFAULT_TABLE_HEIGHT:g} m, models/table.xml); "
            "leave 'height' out or match the model",
        )
    position = f.pair("position", DEFAULT_TABLE_POSITION)
    return TableSpec(size_xy=size, height=height, position_xy=position)


def parse_block(source: str, index: int, raw: Any) -> BlockSpec:
    """One ``[[blocks]]`` entry."""
    f = TomlFields(source, f"blocks[{index}]", raw, _BLOCK_KEYS)
    name = f.string("name")
    if not _NAME_RE.match(name):
        f.fail("name", f"{name!r} must start with a letter and hold only letters, digits and '_'")
    if f.has("shape") == f.has("vertices"):
        f.fail("shape", "give exactly one of 'shape' (a paper object) or 'vertices' (metres)")
    if f.has("shape"):
        shape = f.string("shape")
        if shape not in PAPER_OBJECTS:
            f.fail("shape", f"unknown shape {shape!r}; valid: {', '.join(PAPER_OBJECTS)}")
        polygon = paper_object(shape)
    else:
        vertices = f.points("vertices", 3)
        try:
            polygon = Polygon.from_vertices(vertices, name=name)
        except GraspError as e:
            f.fail("vertices", str(e))
    extent = float(np.ptp(polygon.vertices, axis=0).max())
    if not MIN_BLOCK_EXTENT <= extent <= MAX_BLOCK_EXTENT:
        f.fail(
            "vertices",
            f"footprint is {extent:.3f} m across; blocks must be "
            f"{MIN_BLOCK_EXTENT:g}..{MAX_BLOCK_EXTENT:g} m"
            " (vertices are in metres)",
        )
    position = f.pair("position")
    yaw = math.radians(f.number("yaw_deg", 0.0, lo=-360.0, hi=360.0))
    height = f.number("height", BLOCK_HEIGHT, lo=MIN_BLOCK_HEIGHT, hi=MAX_BLOCK_HEIGHT)
    rgba = parse_colour(f, index)
    return BlockSpec(name, polygon, position, yaw, height, rgba)


def parse_colour(f: TomlFields, index: int) -> tuple[float, float, float, float]:
    """``colour`` (a name of :data:`COLOURS`) or ``rgba`` (4 numbers in [0, 1]); by default the
    ``index``-th palette colour."""
    if f.has("colour") and f.has("rgba"):
        f.fail("colour", "give at most one of 'colour' and 'rgba'")
    if f.has("colour"):
        name = f.string("colour")
        if name not in COLOURS:
            f.fail("colour", f"unknown colour {name!r}; valid: {', '.join(COLOURS)}")
        return COLOURS[name]
    if f.has("rgba"):
        rgba = f.vector("rgba", 4)
        if min(rgba) < 0.0 or max(rgba) > 1.0:
            f.fail("rgba", f"components must be in [0, 1], got {list(rgba)}")
        return rgba[0], rgba[1], rgba[2], rgba[3]
    palette = list(COLOURS.values())
    return palette[index % len(palette)]


def parse_scene(raw: Mapping[str, Any], source: str, default_name: str) -> Scene:
    """Build and check a :class:`Scene` from a parsed TOML document."""
    f = TomlFields(source, "", raw, _TOP_KEYS)
    name = f.string("name", default_name)
    description = f.string("description", "")
    table = parse_table(source, raw.get("table", {}))
    raw_blocks = raw.get("blocks")
    if not isinstance(raw_blocks, list) or not raw_blocks:
        f.fail("blocks", "missing or empty: give at least one [[blocks]] entry")
    blocks = tuple(parse_block(source, i, b) for i, b in enumerate(raw_blocks))
    target = f.string("target")
    place = f.pair("place")
    scene = Scene(name, table, blocks, target, place, description)
    validate_scene(scene, source)
    return scene


# --- validation ---------------------------------------------------------------------------


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
