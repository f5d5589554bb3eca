"""One lateral episode as the bench runs it, for the end-to-end tests of issue 23."""

from __future__ import annotations

import pickle
from dataclasses import replace
from pathlib import Path

from experiments.bench.jobs import blocks_for_seed
from fsm.config import DEFAULT_CONFIG, TaskConfig
from fsm.context import EpisodeOptions
from fsm.machine import EpisodeResult, run_episode
from tests.session import session_lock

#: The lateral squeeze before the holding forces (issue 23, twenty-third session): the balanced
#: shares, the pre-shape search blind to the friction reserve (the regrasp after a slip too).
#: The episodes written to show a recovery (a slip at the lift, a squeeze that falls short, a
#: retreat that drags) run with it: with the holding squeeze their first grasp is another, or
#: holds, and the recovery never runs.
BALANCED_SQUEEZE = replace(
    DEFAULT_CONFIG,
    lateral_holding_forces=False,
    lateral_reserve_first=False,
    lateral_reserve_before_bands=False,
    lateral_retry_by_reserve=False,
)


#: The pre-shape search before the reserve margin (``lateral_reserve_margin`` 0, issue 23,
#: thirty-second session): the grasps that keep any friction reserve first. The episodes
#: written to show what follows a grasp that keeps too little (a slip at the lift, the regrasp
#: after it) run with it: with the margin their first grasp is another, and holds.
NO_MARGIN = replace(DEFAULT_CONFIG, lateral_reserve_margin=0.0)


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


def shared_lateral_episode(
    tmp_path_factory, scene: str, seed: int, config: TaskConfig = DEFAULT_CONFIG, label: str = ""
) -> EpisodeResult:
    """:func:`lateral_episode` (the default config, or ``config`` named by ``label``), run once
    per test session for every test that reads it (the workers of ``pytest -n`` share it
    through a lock and the pickled result in the session's folder): tests of different features
    that start from the same episode do not each run it again."""
    if (config == DEFAULT_CONFIG) == bool(label):
        raise ValueError("a shared episode's config other than the default needs a label")
    name = f"lateral-{scene}-{seed}" + (f"-{label}" if label else "")
    with session_lock(tmp_path_factory, name) as root:
        saved = root / f"{name}.pickle"
        if not saved.is_file():
            result = lateral_episode(root / name, scene, seed, config)
            partial = saved.with_suffix(".partial")
            partial.write_bytes(pickle.dumps(result))
            partial.replace(saved)
        return pickle.loads(saved.read_bytes())
