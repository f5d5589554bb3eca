"""The scene a command runs for ``--scene NAME --seed N``: the same layout for every command
(``fsm.run``, ``experiments.bench``, ``vision``, ``hand_sim.show``).

A random scene is drawn from its seed (:mod:`hand_sim.random_scene`). A scene file is a fixed
layout; seed 0 runs it exactly as written, and seed N > 0 runs it with every block's pose jittered
(position by up to :data:`JITTER_POSITION`, yaw by up to :data:`JITTER_YAW_DEG`, uniform, drawn
from the seed), as a table laid out by hand twice is never the same (section 5's blocks are placed
by hand). A jitter that would break the scene's rules (gaps, table edge) is drawn again, up to
:data:`JITTER_ATTEMPTS` times; after that the file's own layout is used.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hand_sim.errors import SceneError
from hand_sim.scene import RANDOM_SCENE, Scene, load_scene, validate_scene

#: Pose jitter of scene files for seeds > 0: position (m, per axis) and yaw (deg).
JITTER_POSITION = 0.01
JITTER_YAW_DEG = 20.0
JITTER_ATTEMPTS = 100


def episode_scene(name: str, seed: int, blocks: int | None = None) -> Scene:
    """The scene an episode runs: ``random`` drawn from ``seed``, a scene file jittered for
    ``seed`` > 0 (see the module docstring). ``blocks`` applies to ``random`` only."""
    if name == RANDOM_SCENE:
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
