"""One lateral episode as the bench runs it, for the end-to-end tests of issue 23."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from experiments.bench.jobs import blocks_for_seed
from fsm.config import DEFAULT_CONFIG, TaskConfig
from fsm.context import EpisodeOptions
from fsm.machine import EpisodeResult, run_episode

#: The lateral squeeze before the holding forces (issue 23, twenty-third session): the balanced
#: shares, the pre-shape search blind to the friction reserve (the regrasp after a slip too).
#: The episodes written to show a recovery (a slip at the lift, a squeeze that falls short, a
#: retreat that drags) run with it: with the holding squeeze their first grasp is another, or
#: holds, and the recovery never runs.
BALANCED_SQUEEZE = replace(
    DEFAULT_CONFIG,
    lateral_holding_forces=False,
    lateral_reserve_first=False,
    lateral_retry_by_reserve=False,
)


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
