"""One lateral episode as the bench runs it, for the end-to-end tests of issue 23."""

from __future__ import annotations

from pathlib import Path

from experiments.bench.jobs import blocks_for_seed
from fsm.config import DEFAULT_CONFIG, TaskConfig
from fsm.context import EpisodeOptions
from fsm.machine import EpisodeResult, run_episode


def lateral_episode(
    out: Path, scene: str, seed: int, config: TaskConfig = DEFAULT_CONFIG
) -> EpisodeResult:
    """``scene`` at ``seed`` with --approach lateral and the pi controller, unrecorded, tuned by
    ``config``; a random scene with the bench's block count for the seed (1-3 blocks)."""
    options = EpisodeOptions(
        scene=scene,
        seed=seed,
        blocks=blocks_for_seed(seed, 1, 3) if scene == "random" else None,
        controller="pi",
        approach="lateral",
        out=out,
        record=False,
        config=config,
    )
    return run_episode(options)
