"""A reserve the squeeze can tell (issue 23; ``TaskConfig.lateral_reserve_margin``): the
lateral pre-shape search first takes only grasps whose friction reserve by the 3-D model is at
least the margin (1 N, about the tendon hand's pad-force estimate's 90th-percentile error), then
those that keep less but some, then the rest. On random scene 69 the search before the margin
(``NO_MARGIN``) takes a grasp that keeps about 0.3 N first, and the block slips out of it at the
lift; with the margin the first grasp keeps more than 1 N, holds at the first lift, and the
block is delivered, judged physically (fsm.judge)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fsm.config import DEFAULT_CONFIG, TaskConfig
from fsm.machine import EpisodeResult
from fsm.states import State
from tests.fsm.lateral import NO_MARGIN, lateral_episode, shared_lateral_episode

SEED = 69


@pytest.mark.parametrize("margin", [-0.1, float("nan"), float("inf")])
def test_a_reserve_margin_that_is_not_a_finite_force_of_zero_or_more_is_refused(
    margin: float,
) -> None:
    with pytest.raises(ValueError, match="lateral_reserve_margin must be"):
        TaskConfig(lateral_reserve_margin=margin)


def _first_reserve(result: EpisodeResult) -> float:
    """The friction reserve (N) Grasp Object's log gives for the episode's first squeeze."""
    reason = next(
        v.reason
        for v in result.visits
        if v.state == State.GRASP_OBJECT.value and v.next == State.DELIVER.value
    )
    found = re.search(r"friction reserve (-?[0-9.]+) N", reason)
    assert found is not None, reason
    return float(found.group(1))


@pytest.mark.e2e
def test_the_first_grasp_keeps_the_margin_and_holds_where_the_one_below_it_slipped(
    tmp_path: Path, tmp_path_factory
) -> None:
    margin = DEFAULT_CONFIG.lateral_reserve_margin
    before = shared_lateral_episode(tmp_path_factory, "random", SEED, NO_MARGIN, "no-margin")
    assert 0.0 <= _first_reserve(before) < margin
    slipped = [
        v.reason
        for v in before.visits
        if v.state == State.DELIVER.value and v.next == State.COARSE_REACH.value
    ]
    assert slipped and slipped[0].startswith("slipped at the lift"), slipped

    result = lateral_episode(tmp_path, "random", SEED)
    assert _first_reserve(result) >= margin
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["regrasps"] == 0 and cycle["lift_retries"] == 0
    assert cycle["squeeze_reserve"] >= margin
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
