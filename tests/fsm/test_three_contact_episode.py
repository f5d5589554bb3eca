"""A lateral episode on three contacts (issue 23): where no palm pose beside the block has a
four-contact grasp that passes Eq. 13, the thumb and two fingers take one, the third finger held
clear, and the block is delivered, judged physically."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from fsm.config import DEFAULT_CONFIG
from tests.fsm.lateral import lateral_episode

#: Random scene 19 with the bench's block count for it (two blocks; the target a rectangle,
#: whose sampled four-contact grasps score S_G 0.50 at every palm pose: the thumb against three
#: fingers on parallel faces).
SEED = 19


@pytest.mark.e2e
def test_a_block_no_four_contact_grasp_passes_is_delivered_on_three(tmp_path: Path) -> None:
    """Without three-contact grasps, by the paper's gate (``lateral_gate_rule`` "paper"), the
    lateral hand has no pre-shape for random scene 19's rectangle (its four-contact grasps
    score 0.50 > 0.4) and the episode fails; with them
    (the default) the pre-shape is the thumb, middle and ring fingers', the first finger held
    clear, and the block is lifted, carried and set down at the place point: the summary names
    the three fingers, their three contacts and an S_G within Eq. 13's 0.4."""
    off = replace(DEFAULT_CONFIG, lateral_three_contacts=False, lateral_gate_rule="paper")
    four = lateral_episode(tmp_path / "four", "random", SEED, off)
    assert not four.success
    assert "no pre-shape" in four.visits[1].reason, four.visits[1].reason

    result = lateral_episode(tmp_path / "three", "random", SEED)
    assert "three sampled contacts" in result.visits[1].reason, result.visits[1].reason
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert len(cycle["contact_fingers"]) == 3 and "th" in cycle["contact_fingers"]
    assert len(cycle["contacts"]) == 3 and len(cycle["contact_theta"]) == 3
    assert cycle["s_g"] <= 0.4
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    assert max(j["other_blocks_moved_m"].values()) < 0.01
