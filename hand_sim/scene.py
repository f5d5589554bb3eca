"""Scene files: the table, the prism blocks on it, the block to pick and the place point.

Section 5 of the paper: wooden prisms about 20 cm tall and 5 cm across (Figure 6's nine shapes)
stand on a table; the user picks one block and a delivery point on the overhead image. A scene
file fixes those choices in TOML (schema in docs/world.md); :func:`load_scene` reads and checks
one, and ``load_scene("random", seed=N, blocks=K)`` draws a collision-free layout.
"""

from __future__ import annotations

from pathlib import Path

from hand_sim.errors import SceneError
from hand_sim.random_scene import random_scene
from hand_sim.scene_file import parse_block, parse_scene, parse_table
from hand_sim.scene_spec import (
    BLOCK_HEIGHT,
    COLOURS,
    MIN_BLOCK_GAP,
    RANDOM_SCENE,
    SCENES_DIR,
    TABLE_EDGE_MARGIN,
    BlockSpec,
    Scene,
    TableSpec,
    validate_scene,
)
from hand_sim.tomlfields import read_toml

#: The scene's data types and checks (:mod:`hand_sim.scene_spec`) and its file format
#: (:mod:`hand_sim.scene_file`), reachable from here too, where the loader's users look for them.
__all__ = [
    "BLOCK_HEIGHT",
    "COLOURS",
    "MIN_BLOCK_GAP",
    "RANDOM_SCENE",
    "SCENES_DIR",
    "TABLE_EDGE_MARGIN",
    "BlockSpec",
    "Scene",
    "TableSpec",
    "load_scene",
    "parse_block",
    "parse_scene",
    "parse_table",
    "scene_names",
    "validate_scene",
]


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
