"""A pitched lateral palm keeps its face clear of the block (issue 23;
``controllers.preshape.palm_candidates.palm_plate_depth``): on random scene 47 (two blocks) the arm
reaches a lateral goal only with the approach axis pitched 45 deg down; with the palm poses'
gap counted from the palm's centre line every pose put the palm's upper edge inside the
block, no approach cleared and the episode failed without a pre-shape. Judged physically."""

from __future__ import annotations

from pathlib import Path

import pytest

from fsm.states import State
from tests.fsm.lateral import lateral_episode


@pytest.mark.e2e
def test_a_pitched_lateral_goal_takes_a_sampled_preshape_and_delivers(tmp_path: Path) -> None:
    """The goal is pitched 45 deg; Coarse Reach takes a sampled pre-shape (not "no pre-shape");
    the block is lifted clear of the table, carried and set down within 20 mm of the place
    point, upright, no finger on it."""
    result = lateral_episode(tmp_path, "random", 47)
    coarse = next(v.reason for v in result.visits if v.state == State.COARSE_REACH.value)
    assert "axis pitched 45 deg down" in coarse, coarse
    assert "sampled pre-shape" in coarse, coarse
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["approach_pitch_deg"] == pytest.approx(45.0, abs=1.0)
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
