"""A lateral grasp from the block's far side (issue 23), on random scene 1: a neighbour stands
on the radial line between the arm's base and the triangle, where a lateral palm on the base's
side would have to be, so Coarse Reach has no goal there (before the far side, the episode
failed with "no coarse path: no collision-free goal posture for lateral"). The palm goes
beyond the block, pitched down and facing back towards the base; the grasp holds, and the
block is delivered, judged physically (fsm.judge: within 20 mm of the place point, upright,
no finger on it)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fsm.states import State
from tests.fsm.lateral import lateral_episode

SEED = 1


@pytest.mark.e2e
def test_a_block_with_a_neighbour_on_the_base_side_is_grasped_from_its_far_side(
    tmp_path: Path,
) -> None:
    result = lateral_episode(tmp_path, "random", SEED)
    reach = next(v.reason for v in result.visits if v.state == State.COARSE_REACH.value)
    assert "from the block's far side" in reach, reach
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral" and cycle["approach_far_side"]
    assert cycle["approach_pitch_deg"] > 10.0, cycle["approach_pitch_deg"]
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]
