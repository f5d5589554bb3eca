"""A set-down past the waist's end stop (issue 23; controllers.deliver.plan.set_down_ik): on random
scene 11 (three blocks) the lateral grasp holds the trapezoid with the arm's waist near its
2.9 rad limit, and the place point lies further round. The transit's start turned with the
waist was the only IK seed of the set-down, and the joint clipped it: "no set-down posture at
the place point asked for". Seeded also from the coarse reach's elbow-up postures, the arm
reaches the place point; the block is judged physically (fsm.judge) where it stands."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.fsm.lateral import lateral_episode

SEED = 11


@pytest.mark.e2e
def test_a_place_point_past_the_waist_end_stop_is_reached_and_the_block_set_down(
    tmp_path: Path,
) -> None:
    """The lateral episode delivers the block to within 20 mm of the place point asked for,
    upright, the hand off it (the first grasp, of a negative friction reserve, may slip at the
    lift and be taken again: the set-down is what is tested here)."""
    result = lateral_episode(tmp_path, "random", SEED)
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral"
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]
