"""Coarse Reach pitches on where no grasp at its pitch can set the block down (issue 23), on
random scene 59: at the level lateral goal the representative hand of
``controllers.preshape.set_down_check.goal_sets_down`` has a set-down, but every grasp the
palm-pose search would take there has none (the forearm passes within a millimetre of a neighbour at
the place point). The search passes over ``lateral_grasp_set_down_checks`` of them (a strict gate:
a further pitch is left), and Coarse Reach is entered again for the axis pitched 15 deg down,
where a lateral goal with a path exists. The bands of S_G are searched in their order alone
(``lateral_reserve_before_bands`` off, as before that rule): with it, 59's first grasp is
another, of a later band (the hand rolled 90 deg), which has a set-down. The verdicts are the
delivery planner's own; the episode is stopped as Coarse Reach is entered the second time (the
pitched search is other tests' business), and the pitched plan is planned here from there."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fsm import handlers
from fsm.config import DEFAULT_CONFIG
from fsm.lateral_preshape import pitched_at_least
from fsm.states import Failure, State, TaskFailedError
from tests.fsm.lateral import lateral_episode

SEED = 59


@pytest.mark.e2e
def test_no_grasp_at_a_pitch_that_sets_the_block_down_sends_coarse_reach_to_the_next(
    tmp_path: Path, monkeypatch
) -> None:
    coarse_reach = handlers.HANDLERS[State.COARSE_REACH]
    floors: list[float] = []
    pitched = []

    def stop_on_the_second_visit(ep):
        if ep.set_down_floor is None:
            return coarse_reach(ep)
        floors.append(ep.set_down_floor)
        pitched.append(pitched_at_least(ep, ep.coarse, ep.set_down_floor))
        raise TaskFailedError(Failure.NO_COARSE_PATH, "stopped by the test at Coarse Reach")

    monkeypatch.setitem(handlers.HANDLERS, State.COARSE_REACH, stop_on_the_second_visit)
    config = replace(DEFAULT_CONFIG, lateral_reserve_before_bands=False)
    result = lateral_episode(tmp_path, "random", SEED, config)
    reach = [v for v in result.visits if v.state == State.COARSE_REACH.value]
    assert [v.next for v in reach] == [State.COARSE_REACH.value, "Failed"], reach
    checks = DEFAULT_CONFIG.lateral_grasp_set_down_checks
    assert f"{checks} grasps passed over: none could set the block down" in reach[0].reason
    assert "pitched 15 deg down next" in reach[0].reason
    assert floors == [pytest.approx(np.deg2rad(15.0))]
    (plan,) = pitched
    assert plan is not None and plan.found and plan.approach == "lateral"
    assert plan.goal.pitch == pytest.approx(np.deg2rad(15.0), abs=np.deg2rad(1.0))
    assert result.failure_detail.endswith("stopped by the test at Coarse Reach")
