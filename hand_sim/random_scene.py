"""Seeded random scenes: K paper-object blocks in a collision-free layout within the arm's reach.

The paper's task (section 5) places blocks "over a table at arbitrary positions"; this generator
draws such layouts reproducibly. Its defaults (region, reach, gap) live in ``scenes/random.toml``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from controllers.grasp import PAPER_OBJECTS, paper_object
from hand_sim.errors import SceneError
from hand_sim.geometry import convex_polygon_distance, place_polygon
from hand_sim.scene_file import parse_table
from hand_sim.scene_spec import (
    COLOURS,
    MIN_BLOCK_GAP,
    RANDOM_SCENE,
    SCENES_DIR,
    BlockSpec,
    Scene,
    TableSpec,
    validate_scene,
)
from hand_sim.tomlfields import TomlFields, read_toml

#: File of the generator's defaults.
GENERATOR_FILE = SCENES_DIR / f"{RANDOM_SCENE}.toml"
_GENERATOR_KEYS = {
    "blocks",
    "shapes",
    "region_x",
    "region_y",
    "reach_centre",
    "reach",
    "min_gap",
    "max_attempts",
}
#: Most blocks a random scene may hold.
MAX_RANDOM_BLOCKS = 12


@dataclass(frozen=True)
class GeneratorConfig:
    """Parameters of :func:`random_scene` (units: metres)."""

    blocks: int
    shapes: tuple[str, ...]
    region_x: tuple[float, float]
    region_y: tuple[float, float]
    reach_centre: tuple[float, float]
    reach: tuple[float, float]
    min_gap: float
    max_attempts: int
    table: TableSpec


def load_generator_config(path: Path = GENERATOR_FILE) -> GeneratorConfig:
    """Read the ``[generator]`` (and optional ``[table]``) sections of ``path``."""
    raw: dict[str, Any] = read_toml(path)
    src = str(path)
    TomlFields(src, "", raw, {"generator", "table"})
    f = TomlFields(src, "generator", raw.get("generator", {}), _GENERATOR_KEYS)
    shapes = f.table.get("shapes", list(PAPER_OBJECTS))
    if not isinstance(shapes, list) or not shapes or any(s not in PAPER_OBJECTS for s in shapes):
        f.fail("shapes", f"must be a non-empty list of {', '.join(PAPER_OBJECTS)}; got {shapes!r}")
    region_x, region_y = f.pair("region_x"), f.pair("region_y")
    reach = f.pair("reach")
    for key, (lo, hi) in (("region_x", region_x), ("region_y", region_y), ("reach", reach)):
        if not lo < hi:
            f.fail(key, f"must be [low, high] with low < high, got {[lo, hi]}")
    return GeneratorConfig(
        blocks=int(f.number("blocks", 3, lo=1, hi=MAX_RANDOM_BLOCKS)),
        shapes=tuple(shapes),
        region_x=region_x,
        region_y=region_y,
        reach_centre=f.pair("reach_centre"),
        reach=reach,
        min_gap=f.number("min_gap", 0.03, lo=MIN_BLOCK_GAP, hi=0.5),
        max_attempts=int(f.number("max_attempts", 2000, lo=1, hi=1e6)),
        table=parse_table(src, raw.get("table", {})),
    )


def _in_reach(cfg: GeneratorConfig, xy: np.ndarray) -> bool:
    r = float(np.hypot(*(xy - np.asarray(cfg.reach_centre))))
    return cfg.reach[0] <= r <= cfg.reach[1]


def _draw_point(cfg: GeneratorConfig, rng: np.random.Generator) -> np.ndarray:
    return np.array([rng.uniform(*cfg.region_x), rng.uniform(*cfg.region_y)])


def random_scene(
    seed: int | np.random.Generator,
    n_blocks: int | None = None,
    config: GeneratorConfig | None = None,
) -> Scene:
    """A random scene of ``n_blocks`` paper-object blocks (distinct shapes while there are enough),
    random yaw, centroids uniform in the region and within reach, footprints at least
    ``min_gap`` apart and on the table; a random target and a place point the target fits at.

    Raises :class:`SceneError` when the blocks do not fit within ``max_attempts`` draws.
    """
    cfg = config or load_generator_config()
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    k = cfg.blocks if n_blocks is None else int(n_blocks)
    if not 1 <= k <= MAX_RANDOM_BLOCKS:
        raise SceneError(f"random scene: blocks must be 1..{MAX_RANDOM_BLOCKS}, got {n_blocks!r}")
    order = [cfg.shapes[i] for i in rng.permutation(len(cfg.shapes))]
    shapes = [order[i % len(order)] for i in range(k)]
    palette = list(COLOURS.values())
    colours = [palette[i] for i in rng.permutation(len(palette))]
    blocks: list[BlockSpec] = []
    footprints: list[np.ndarray] = []
    for i, shape in enumerate(shapes):
        polygon = paper_object(shape)
        for _ in range(cfg.max_attempts):
            xy, yaw = _draw_point(cfg, rng), float(rng.uniform(-np.pi, np.pi))
            fp = place_polygon(polygon.vertices, xy, yaw)
            if not (_in_reach(cfg, xy) and cfg.table.contains(fp)):
                continue
            if all(convex_polygon_distance(fp, other) >= cfg.min_gap for other in footprints):
                break
        else:
            raise SceneError(
                f"random scene (seed {seed!r}): could not place block {i + 1} of {k} with a "
                f"{cfg.min_gap} m gap in {cfg.max_attempts} attempts; ask for fewer blocks"
            )
        name = f"{shape}_{i}"
        blocks.append(
            BlockSpec(
                name, polygon, (float(xy[0]), float(xy[1])), yaw, rgba=colours[i % len(colours)]
            )
        )
        footprints.append(fp)
    target = blocks[int(rng.integers(k))]
    place = _draw_place(cfg, rng, target, blocks, footprints, seed)
    scene = Scene(
        name=f"{RANDOM_SCENE}_s{seed if not isinstance(seed, np.random.Generator) else 'rng'}_k{k}",
        table=cfg.table,
        blocks=tuple(blocks),
        target=target.name,
        place=place,
        description=f"random layout of {k} blocks",
    )
    validate_scene(scene, f"random scene (seed {seed!r})")
    return scene


def _draw_place(
    cfg: GeneratorConfig,
    rng: np.random.Generator,
    target: BlockSpec,
    blocks: list[BlockSpec],
    footprints: list[np.ndarray],
    seed: object,
) -> tuple[float, float]:
    """A point in reach where the target, at any yaw (the disc of its circumradius), clears the
    others by ``min_gap``: the hand sets it down with its fingers around it."""
    others = [fp for b, fp in zip(blocks, footprints, strict=True) if b.name != target.name]
    radius = float(np.linalg.norm(target.polygon.vertices, axis=1).max())
    ring = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    for _ in range(cfg.max_attempts):
        xy = _draw_point(cfg, rng)
        disc = np.asarray(xy) + radius * np.column_stack([np.cos(ring), np.sin(ring)])
        if not (_in_reach(cfg, xy) and cfg.table.contains(disc)):
            continue
        if all(convex_polygon_distance(disc, o) >= cfg.min_gap for o in others):
            return float(xy[0]), float(xy[1])
    raise SceneError(f"random scene (seed {seed!r}): no free place point for {target.name!r}")
