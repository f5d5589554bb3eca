"""What a lateral grasp that loses its block at the lift leads to, on random scene 69
(two blocks), whose first lateral grasp of the irregular pentagon, by the search before the
reserve margin (``NO_MARGIN``; with the margin the first grasp keeps more, and holds,
``tests/fsm/test_reserve_margin_episode.py``), keeps 0.32 N of friction in reserve by the 3-D
model and lets the block slip out as the arm lifts it:

- the regrasp after the slip takes only palm poses whose grasp keeps more reserve than the one
  that slipped (``TaskConfig.lateral_retry_by_reserve``, the default). Without it the next pose
  is the next in order, whose grasp (0.31 N) slips too, and the episode fails.

Judged physically (fsm.judge: the block within 20 mm of the place point, upright, no finger on
it)."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest

from fsm.machine import EpisodeResult
from fsm.states import State
from tests.fsm.lateral import NO_MARGIN, lateral_episode, shared_lateral_episode

SEED = 69
#: the regrasp after a slip blind to the reserve: the next palm pose in order (both from the
#: search before the reserve margin, whose first grasp slips)
BLIND = replace(NO_MARGIN, lateral_retry_by_reserve=False)


def _slips(result: EpisodeResult) -> list[str]:
    """The transition log's Deliver -> Coarse Reach reasons (a grasp let go after its lift)."""
    return [
        v.reason
        for v in result.visits
        if v.state == State.DELIVER.value and v.next == State.COARSE_REACH.value
    ]


def _reserves(result: EpisodeResult) -> list[float]:
    """The friction reserve (N) of each grasp Grasp Object squeezed and handed to Deliver."""
    return [
        float(m.group(1))
        for v in result.visits
        if v.state == State.GRASP_OBJECT.value and v.next == State.DELIVER.value
        for m in [re.search(r"friction reserve (-?[0-9.]+) N", v.reason)]
        if m is not None
    ]


def _delivered(result: EpisodeResult) -> None:
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["lift_retries"] == 1
    assert cycle["lift_height"] > 0.08  # the last grasp's block rose with the hand
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]


@pytest.mark.e2e
@pytest.mark.skip(
    reason="the scenario of this seed no longer arises since the robot plans around the blocks "
    "it saw (docs/robustness.md); a seed that shows it is to be found again"
)
def test_a_lift_failure_is_regrasped_with_more_reserve(tmp_path: Path, tmp_path_factory) -> None:
    """Blind to the reserve: both grasps slip ("block slipped during lift"). The default: the
    second grasp keeps more reserve than the first, says so in the log, and delivers the block."""
    blind = lateral_episode(tmp_path / "blind", "random", SEED, BLIND)
    assert not blind.success
    assert blind.failure == "block slipped during lift", blind.failure

    result = shared_lateral_episode(tmp_path_factory, "random", SEED, NO_MARGIN, "no-margin")
    (slip,) = _slips(result)
    assert slip.startswith("slipped at the lift"), slip
    reach = [v.reason for v in result.visits if v.state == State.COARSE_REACH.value]
    assert "of the one that slipped" in reach[-1], reach[-1]
    first, last = _reserves(result)
    assert last > first, (first, last)
    _delivered(result)
