"""A lateral squeeze that holds the block's weight (issue 23; ``TaskConfig.lateral_holding_forces``,
``controllers.grasp.holding``): on random scene 85 (two blocks) the lateral hand presses from
different heights on faces that do not oppose one another. The least-squares balance of the
planned contacts (``controllers.hand.grip.balanced_shares``) leaves a net push that the table
carries until the lift, and the block slips out of the hand as it rises; the normal forces chosen
with the weight and the friction cones in the balance lift it and deliver it with the first grasp.
Judged physically (fsm.judge, the wrist sensor at the lift)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.fsm.lateral import BALANCED_SQUEEZE, lateral_episode

SEED = 85


@pytest.mark.e2e
def test_a_squeeze_that_holds_the_weight_lifts_the_block_the_balanced_one_let_slip(
    tmp_path: Path,
) -> None:
    """Balanced shares (and the search blind to the reserve): the first grasp slips at the lift
    (a lift retry), and so does the second ("block slipped during lift"). The defaults (holding
    forces, the reserve first): the first grasp lifts the block with the hand (no lift retry,
    no regrasp), with a positive friction reserve by the model, and the block is set down
    within 20 mm of the place point, upright."""
    slipped = lateral_episode(tmp_path / "balanced", "random", SEED, BALANCED_SQUEEZE)
    assert not slipped.success
    assert slipped.failure == "block slipped during lift", slipped.failure
    (before,) = slipped.cycles
    assert before["lift_retries"] == 1

    result = lateral_episode(tmp_path / "holding", "random", SEED)
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral"
    assert cycle["lift_retries"] == 0 and cycle["regrasps"] == 0
    assert cycle["squeeze_reserve"] > 0.0
    assert cycle["lift_height"] > 0.08  # the block rose with the hand (10 cm lift)
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, j
    assert not j["finger_contact"]
