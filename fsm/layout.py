"""Where an episode starts and where blocks go: the scene for a seed, and free place slots for
``--cycles all``.

Seeds: a random scene is drawn from its seed (``hand_sim.random_scene``). A scene file is a fixed
layout; seed 0 runs it exactly as written, and seed N > 0 runs it with every block's pose jittered
(position by up to :data:`JITTER_POSITION`, yaw by up to :data:`JITTER_YAW_DEG`, uniform, drawn
from the seed), as a table laid out by hand twice is never the same. A jitter that would break
the scene's rules (gaps, table edge) is drawn again, up to :data:`JITTER_ATTEMPTS` times.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hand_sim.errors import SceneError
from hand_sim.geometry import convex_polygon_distance
from hand_sim.scene import Scene, TableSpec, load_scene, validate_scene

#: Pose jitter of scene files for seeds > 0: position (m, per axis) and yaw (deg).
JITTER_POSITION = 0.01
JITTER_YAW_DEG = 20.0
JITTER_ATTEMPTS = 100
#: Place slots: spacing (m) of the candidate grid, clearance (m) kept between a slot's block
#: and any other block's footprint, and the largest distance (m) searched from the first place.
SLOT_SPACING = 0.08
SLOT_CLEARANCE = 0.03
#: A place point the user or the scene asked for is refused only when the block could not stand
#: there at all (closer than the scenes' smallest block gap to another block).
ASKED_CLEARANCE = 0.005
SLOT_SEARCH_RADIUS = 0.35


def episode_scene(name: str, seed: int, blocks: int | None = None) -> Scene:
    """The scene an episode runs: ``random`` drawn from ``seed``, a scene file jittered for
    ``seed`` > 0 (see the module docstring)."""
    if name == "random":
        return load_scene(name, seed=seed, blocks=blocks)
    if blocks is not None:
        raise SceneError("--blocks applies to the random scene only")
    scene = load_scene(name)
    if seed == 0:
        return scene
    rng = np.random.default_rng(seed)
    for _ in range(JITTER_ATTEMPTS):
        moved = tuple(
            dataclasses.replace(
                b,
                position=tuple(
                    float(v)
                    for v in np.asarray(b.position) + rng.uniform(-1, 1, 2) * JITTER_POSITION
                ),
                yaw=b.yaw + math.radians(float(rng.uniform(-1, 1)) * JITTER_YAW_DEG),
            )
            for b in scene.blocks
        )
        candidate = dataclasses.replace(scene, blocks=moved)
        try:
            validate_scene(candidate, f"{scene.name} (seed {seed})")
        except SceneError:
            continue
        return candidate
    return scene


def place_is_free(
    place: ArrayLike,
    radius: float,
    footprints: list[NDArray[np.float64]],
    table: TableSpec,
    clearance: float = SLOT_CLEARANCE,
) -> bool:
    """Whether a block of circumradius ``radius`` (m) centred at ``place`` stays ``clearance``
    from every footprint (world (k, 2) vertices) and on the table."""
    p = np.asarray(place, dtype=float)
    if not table.contains(p[None], margin=radius + 0.005):
        return False
    angles = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
    disc = p + radius * np.column_stack([np.cos(angles), np.sin(angles)])
    return all(convex_polygon_distance(disc, fp) >= clearance for fp in footprints)


def free_slot(
    first: ArrayLike,
    radius: float,
    footprints: list[NDArray[np.float64]],
    table: TableSpec,
    reach: tuple[ArrayLike, float, float] | None = None,
) -> NDArray[np.float64] | None:
    """The free place nearest ``first`` on a grid of :data:`SLOT_SPACING` around it (``first``
    itself when free), or None. ``reach`` = (centre xy, r_min, r_max) keeps slots within the
    arm's horizontal reach."""
    f = np.asarray(first, dtype=float)
    n = int(SLOT_SEARCH_RADIUS / SLOT_SPACING)
    offsets = np.array([(i, j) for i in range(-n, n + 1) for j in range(-n, n + 1)], float)
    candidates = f + SLOT_SPACING * offsets
    order = np.argsort(np.linalg.norm(candidates - f, axis=1), kind="stable")
    for c in candidates[order]:
        if reach is not None:
            d = float(np.linalg.norm(c - np.asarray(reach[0], dtype=float)))
            if not reach[1] <= d <= reach[2]:
                continue
        if place_is_free(c, radius, footprints, table):
            return c
    return None
