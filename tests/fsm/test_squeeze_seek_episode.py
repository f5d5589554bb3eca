"""A lateral squeeze whose light finger loses its face closes it again (issue 23;
``TaskConfig.lateral_squeeze_seek``, ``controllers.hand.grip.squeeze(seek=True)``): on
single_irregular_triangle at seed 0 the balanced squeeze asks the middle finger for a few tenths
of a newton; without seeking, the force loop leaves it short of the face and the squeeze fails;
with it the squeeze settles and the block is delivered, judged physically."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from fsm.states import State
from tests.fsm.lateral import BALANCED_SQUEEZE, lateral_episode

SCENE = "single_irregular_triangle"


def _grasp_object(result) -> str:
    return next(v.reason for v in result.visits if v.state == State.GRASP_OBJECT.value)


@pytest.mark.e2e
def test_a_light_finger_that_loses_its_face_closes_again_and_the_block_is_delivered(
    tmp_path: Path,
) -> None:
    """Without seeking (and no regrasp, so the episode ends there) the first squeeze does not
    reach the grip force, the middle finger well short of its share (0.0-0.2 N of 0.33 N); with
    it (the default) the same grasp's squeeze settles with every pad pressing, and the block is
    lifted, carried and set down at the place point. Both with the balanced squeeze
    (``BALANCED_SQUEEZE``: its shares asked the middle finger for 0.33 N)."""
    off = replace(BALANCED_SQUEEZE, lateral_squeeze_seek=False, max_regrasps=0)
    short = lateral_episode(tmp_path / "off", SCENE, 0, off)
    assert not short.success
    assert "squeeze did not reach the grip force" in _grasp_object(short)
    (cycle,) = short.cycles  # the middle finger well short of its share
    assert cycle["grip_forces"][1] < 0.75 * cycle["grip_target"][1], cycle

    result = lateral_episode(tmp_path / "seek", SCENE, 0, BALANCED_SQUEEZE)
    assert "all four pads touch" in _grasp_object(result), _grasp_object(result)
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert min(cycle["grip_forces"]) > 0.1, cycle["grip_forces"]
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
