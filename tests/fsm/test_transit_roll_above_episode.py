"""A held block's transit whose wrist roll cannot turn at the lift's top turns it higher up
(issue 23), on random scene 105: the square is grasped from its far side with the hand rolled
-90 deg, and at the top of the lift turning the roll to the set-down's would sweep the hand
or the block through a neighbour. Before, every set-down posture's transit failed there and the
episode ended "no set-down posture at the place point asked for ...: transit: turning the
wrist roll at the start collides". Now the palm rises straight up, the block in the hand,
until the roll turns clear (``controllers.reach.arm_path.roll_turned_above``); the block is carried,
set down and judged physically (fsm.judge: within 20 mm of the place point, upright, no
finger on it, no neighbour moved)."""

from __future__ import annotations

from pathlib import Path

import pytest

import controllers.deliver.plan as delivery
from tests.fsm.lateral import lateral_episode

SEED = 105


@pytest.mark.e2e
def test_a_transit_whose_roll_cannot_turn_at_the_lift_s_top_turns_it_above_and_delivers(
    tmp_path: Path, monkeypatch
) -> None:
    risen: list[float] = []
    roll_turned_above = delivery.roll_turned_above

    def recorded(checker, q_start, q_goal, **kwargs):
        path = roll_turned_above(checker, q_start, q_goal, **kwargs)
        if path is not None:
            # how far the palm rose before the roll turned (the path's first rows)
            z0 = checker.palm_pose(q_start)[0][2]
            risen.append(max(checker.palm_pose(q)[0][2] - z0 for q in path.path))
        return path

    monkeypatch.setattr(delivery, "roll_turned_above", recorded)
    result = lateral_episode(tmp_path, "random", SEED)
    assert result.success, f"{result.failure}: {result.failure_detail}"
    assert risen and risen[0] > 0.0, risen
    (cycle,) = result.cycles
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]
    assert max(j["other_blocks_moved_m"].values()) < 0.005, j["other_blocks_moved_m"]
