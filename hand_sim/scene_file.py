"""Scene files in TOML (schema in docs/world.md): the ``[table]`` section, the ``[[blocks]]``,
``target`` and ``place``, each field checked with the file, field and problem in the message."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from controllers.grasp import PAPER_OBJECTS, GraspError, Polygon, paper_object
from hand_sim.perturb import MAX_SCALE, NAMES, PerturbError, PerturbSpec
from hand_sim.scene_spec import (
    BLOCK_HEIGHT,
    COLOURS,
    DEFAULT_TABLE_HEIGHT,
    DEFAULT_TABLE_POSITION,
    DEFAULT_TABLE_SIZE,
    MAX_BLOCK_EXTENT,
    MAX_BLOCK_HEIGHT,
    MIN_BLOCK_EXTENT,
    MIN_BLOCK_HEIGHT,
    TABLE_TOLERANCE,
    BlockSpec,
    Scene,
    TableSpec,
    validate_scene,
)
from hand_sim.tomlfields import TomlFields

_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_TOP_KEYS = {"name", "description", "table", "blocks", "target", "place", "perturb"}
_TABLE_KEYS = {"size", "height", "position"}
_BLOCK_KEYS = {"name", "shape", "vertices", "position", "yaw_deg", "height", "colour", "rgba"}


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


def parse_perturb(source: str, raw: Any) -> PerturbSpec:
    """The ``[perturb]`` table: a scale (0..MAX_SCALE; 1 is the magnitudes of
    :mod:`hand_sim.perturb`) per perturbation name, e.g. ``camera = 1`` or ``woes = 0.5``."""
    f = TomlFields(source, "perturb", raw, set(NAMES))
    asked = {name: f.number(name, lo=0.0, hi=MAX_SCALE) for name in NAMES if f.has(name)}
    try:
        return PerturbSpec.of(asked)
    except PerturbError as e:
        f.fail("", str(e))


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
    perturb = parse_perturb(source, raw["perturb"]) if f.has("perturb") else PerturbSpec()
    scene = Scene(name, table, blocks, target, place, description, perturb)
    validate_scene(scene, source)
    return scene
