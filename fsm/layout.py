"""Where an episode starts and where blocks go: the scene for a seed, and free place slots for
``--cycles all``.

Seeds: :func:`episode_scene` (:mod:`hand_sim.scene_seed`, shared with ``vision`` and
``hand_sim.show``) draws a random scene from its seed and jitters a scene file's block poses for
a seed > 0; :func:`episode_perturbation` draws how the simulated world differs from it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hand_sim.geometry import convex_polygon_distance
from hand_sim.perturb import Perturbation, PerturbSpec, for_episode
from hand_sim.scene import Scene, TableSpec
from hand_sim.scene_seed import episode_scene

__all__ = [
    "ASKED_CLEARANCE",
    "SLOT_CLEARANCE",
    "SLOT_SEARCH_RADIUS",
    "SLOT_SPACING",
    "episode_perturbation",
    "episode_scene",
    "free_slot",
    "place_is_free",
]

#: Place slots: spacing (m) of the candidate grid, clearance (m) kept between a slot's block
#: and any other block's footprint, and the largest distance (m) searched from the first place.
SLOT_SPACING = 0.08
SLOT_CLEARANCE = 0.03
#: A place point the user or the scene asked for is refused only when the block could not stand
#: there at all (closer than the scenes' smallest block gap to another block).
ASKED_CLEARANCE = 0.005
SLOT_SEARCH_RADIUS = 0.35


def episode_perturbation(perturb: str | None, seed: int, scene: Scene) -> Perturbation | None:
    """How an episode's simulated world differs from ``scene`` (:mod:`hand_sim.perturb`):
    ``perturb`` (``--perturb NAME[=SCALE],...`` or ``none``) or, when None, the scene file's
    ``[perturb]`` table, drawn from the episode's ``seed``; None when nothing is perturbed."""
    spec = scene.perturb if perturb is None else PerturbSpec.parse(perturb)
    return for_episode(spec, seed, scene.block_names)


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
