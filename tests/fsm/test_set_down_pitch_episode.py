"""A lateral approach pitched for its set-down (issue 23), on random scene 63: the hexagon's
place point has a trapezoid 8-12 cm inward of it on the radial line and a pentagon beside it.
The arm reaches the hexagon itself with its axis pitched 15 deg down, and a hand holding it so
cannot set it down at the place point: its wrist and forearm, low along the radial line, meet
the trapezoid.

- With the check off (``TaskConfig.lateral_set_down_pitch`` False) the hand grasps the block
  at 15 deg, lifts it, and Deliver finds no set-down: "place point unreachable or occupied".
- With it (the default), Coarse Reach finds that before the grasp, takes the goal pitched 30 deg
  down, whose hand can set the block down, and the block is delivered.

Judged physically (fsm.judge: the block within 20 mm of the place point, upright, no finger on
it)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from fsm.config import DEFAULT_CONFIG
from fsm.states import State
from tests.fsm.lateral import lateral_episode

SEED = 63


@pytest.mark.e2e
def test_a_lateral_grasp_is_pitched_where_a_level_hand_could_not_set_its_block_down(
    tmp_path: Path,
) -> None:
    off = lateral_episode(
        tmp_path / "off", "random", SEED, replace(DEFAULT_CONFIG, lateral_set_down_pitch=False)
    )
    assert not off.success
    assert off.failure == "place point unreachable or occupied", off.failure
    (cycle,) = off.cycles
    assert cycle["approach_pitch_deg"] < 20.0, cycle["approach_pitch_deg"]

    result = lateral_episode(tmp_path / "default", "random", SEED)
    reach = next(v.reason for v in result.visits if v.state == State.COARSE_REACH.value)
    assert "could not set the block down at the place point" in reach, reach
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral"
    assert cycle["approach_pitch_deg"] > 25.0, cycle["approach_pitch_deg"]
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]
