"""A set-down aimed off the place point, within the judge's tolerance, to keep the descent's
clearance (issue 23; ``controllers.deliver.set_down_aim``): on random scene 40 (three blocks) the
only set-down the lateral palm holding the rectangle can take lowers the ring finger's proximal link
within 2 mm of the irregular pentagon beside the place point, inside the 3 mm every hand link
keeps on the way down, and the episode failed with no set-down posture. Aimed a few millimetres
away from the pentagon, along the normal between the two, the block is set down, judged
physically (fsm.judge) against the place point asked for, and the pentagon is not moved."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from controllers.deliver.set_down_aim import MAX_AIM_OFFSET
from tests.fsm.lateral import lateral_episode

SEED = 40


@pytest.mark.e2e
def test_a_set_down_aimed_off_the_place_point_keeps_the_clearance_and_delivers(
    tmp_path: Path,
) -> None:
    """The set-down is aimed off the point by at most MAX_AIM_OFFSET (every other one failed:
    aimed set-downs are tried only then), the block lands within 20 mm of the point asked for,
    upright, and no neighbour moves."""
    result = lateral_episode(tmp_path, "random", SEED)
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral"
    aimed = re.search(r"aimed ([0-9.]+) mm off the place point", cycle["set_down"])
    assert aimed is not None, cycle["set_down"]
    assert 0.0 < float(aimed.group(1)) <= MAX_AIM_OFFSET * 1000.0
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]
    assert max(j["other_blocks_moved_m"].values()) < 0.002, j["other_blocks_moved_m"]
