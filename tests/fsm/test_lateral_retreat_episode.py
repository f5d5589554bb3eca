"""A lateral hand leaving a block standing rises clear of its top before it backs off (issue 23;
``TaskConfig.lateral_retreat_rise``, ``controllers.deliver.carry.retreat(clear_top=...)``): on
random scene 80 (two blocks) the lateral grasp sets the triangle down upright at the place
point; backing off first drags it away with the released fingers and tips it, rising first
leaves it standing where it was set down. Judged physically (fsm.judge). Both with the
balanced squeeze (``BALANCED_SQUEEZE``), whose grasp this scene was traced with."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from tests.fsm.lateral import BALANCED_SQUEEZE, lateral_episode

SEED = 80


@pytest.mark.e2e
def test_a_lateral_hand_rises_clear_before_it_backs_off_and_the_block_stays_put(
    tmp_path: Path,
) -> None:
    """Backing off first: the block was set down and released, yet it ends more than 20 mm from
    the place point or tilted 10 deg or more ("not placed as asked"). Rising first (the
    default): the same grasp, carry and set-down, and the block stands within 20 mm of the
    place point, upright, no finger on it, its neighbour unmoved."""
    off = replace(BALANCED_SQUEEZE, lateral_retreat_rise=False)
    dragged = lateral_episode(tmp_path / "back", "random", SEED, off)
    assert not dragged.success
    assert dragged.failure == "block not placed as asked", dragged.failure
    (before,) = dragged.cycles
    j = before["judgement"]
    assert j["place_error_mm"] > 20.0 or j["tilt_deg"] >= 10.0, j

    result = lateral_episode(tmp_path / "rise", "random", SEED, BALANCED_SQUEEZE)
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral"
    assert cycle["s_g"] == pytest.approx(before["s_g"])  # the same grasp
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]
    assert max(j["other_blocks_moved_m"].values(), default=0.0) < 0.005, j
