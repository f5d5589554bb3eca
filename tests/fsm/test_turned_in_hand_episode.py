"""A lateral grasp whose block turns in the hand at the lift (issue 23), on random scene 189:
its first grasp of the irregular hexagon still holds the block's weight at the top of the lift
(the wrist weighs it, the pads feel it), but the block has pivoted about the pinch by about 8
deg, and the pressing fingertips, which keep pressing as it turns, moved 4 mm in the palm's
frame. (By the search before the reserve margin, ``NO_MARGIN``, in both episodes: with the
margin the first grasp is another, and holds without turning.)

- With the check off (``TaskConfig.lateral_tip_motion_limit`` 0) the block is carried tilted,
  set down on an edge and falls over: not placed.
- With the default 2 mm, the hand senses the fingertips' motion, lowers the palm back to where it
  grasped the block, lets go, looks again and grasps it from another palm pose; that grasp's
  fingertips stay put and the block is delivered.

Judged physically (fsm.judge: the block within 20 mm of the place point, upright, no finger on
it); the block's tilt in the hand is the simulation's, recorded for judging only."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from fsm.config import TaskConfig
from fsm.states import State
from tests.fsm.lateral import NO_MARGIN, lateral_episode

SEED = 189


@pytest.mark.parametrize("limit", [-0.001, 0.02, float("nan")])
def test_fingertip_motion_limits_outside_0_to_2_cm_are_refused(limit: float) -> None:
    with pytest.raises(ValueError, match="lateral_tip_motion_limit must lie in"):
        TaskConfig(lateral_tip_motion_limit=limit)


@pytest.mark.e2e
@pytest.mark.skip(
    reason="the scenario of this seed no longer arises since the robot plans around the blocks "
    "it saw (docs/robustness.md); a seed that shows it is to be found again"
)
def test_a_block_that_turns_in_the_hand_is_set_back_down_and_grasped_again(
    tmp_path: Path,
) -> None:
    off = lateral_episode(
        tmp_path / "off", "random", SEED, replace(NO_MARGIN, lateral_tip_motion_limit=0.0)
    )
    assert not off.success
    assert off.failure == "block not placed as asked", off.failure
    (cycle,) = off.cycles
    assert cycle["lift_tilt_deg"] > 5.0, cycle["lift_tilt_deg"]  # the simulation's, judging only
    assert max(cycle["lift_tip_motion_mm"]) > 2.0, cycle["lift_tip_motion_mm"]  # sensed
    assert cycle["judgement"]["tilt_deg"] >= 10.0, cycle["judgement"]

    result = lateral_episode(tmp_path / "default", "random", SEED, NO_MARGIN)
    retried = [
        v.reason
        for v in result.visits
        if v.state == State.DELIVER.value and v.next == State.COARSE_REACH.value
    ]
    assert len(retried) == 1 and "turned or slid in the hand" in retried[0], retried
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["lift_retries"] == 1
    assert max(cycle["lift_tip_motion_mm"]) < 2.0, cycle["lift_tip_motion_mm"]
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]
