"""A lateral episode under the gate counted from the thumb's opposition (issue 23;
``TaskConfig.lateral_gate_rule``): where every grasp the lateral hand can take beside the block
scores above Eq. 13's 0.4, the paper's rule leaves it no pre-shape and the episode fails; the
default rule takes the best of them and the block is delivered, judged physically."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from controllers.grasp.score import SUCCESS_THRESHOLD, opposition_floor
from fsm.config import DEFAULT_CONFIG
from tests.fsm.lateral import lateral_episode

#: Random scene 20 with the bench's block count for it (two blocks; the target a trapezoid,
#: whose best lateral grasps, of four contacts or three, score above 0.4 at every palm pose).
SEED = 20


@pytest.mark.e2e
def test_a_block_whose_lateral_grasps_all_score_above_the_paper_gate_is_delivered(
    tmp_path: Path,
) -> None:
    """By the rule "paper" random scene 20's trapezoid has no lateral pre-shape and the episode
    fails, named; by the default rule the pre-shape's sampled grasp scores above 0.4 and within
    the gate counted from the thumb's opposition, the grasp the hand closes scores so too, and
    the block is lifted, carried and set down at the place point."""
    paper_rule = replace(DEFAULT_CONFIG, lateral_gate_rule="paper")
    paper = lateral_episode(tmp_path / "paper", "random", SEED, paper_rule)
    assert not paper.success and paper.failure is not None
    assert "no pre-shape" in paper.visits[1].reason, paper.visits[1].reason

    result = lateral_episode(tmp_path / "opposition", "random", SEED)
    coarse = result.visits[1].reason
    assert "sampled pre-shape" in coarse, coarse
    taken = float(coarse.split("S_G ")[1].split()[0])
    assert SUCCESS_THRESHOLD < taken <= SUCCESS_THRESHOLD + opposition_floor(4)
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    n = len(cycle["contact_fingers"])
    assert SUCCESS_THRESHOLD < cycle["s_g"] <= DEFAULT_CONFIG.lateral_gate_for(n)
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    assert max(j["other_blocks_moved_m"].values()) < 0.01
