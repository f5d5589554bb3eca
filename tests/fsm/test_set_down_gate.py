"""The palm-pose search's set-down gate (``fsm.handlers.set_down_pitch.set_down_gate``): a pose
whose grasp cannot set the block down at the place point is passed over like one whose approach
collides, until ``checks`` poses have been passed over for it. On random scene 182 a level
lateral hand has no set-down and a hand pitched 30 deg down has one
(tests/controllers/test_set_down_check.py); the verdicts here are the delivery planner's own,
not stand-ins."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.delivery import plan_delivery
from fsm.config import TaskConfig
from fsm.handlers.set_down_pitch import set_down_gate
from hand_sim.world import World
from tests.controllers.test_set_down_check import _grasp_pose, scene182  # noqa: F401


@pytest.fixture(scope="module")
def poses(scene182) -> tuple[World, np.ndarray, np.ndarray]:  # noqa: F811
    world, target = scene182
    return world, _grasp_pose(world, target, 0.0), _grasp_pose(world, target, 30.0)


def test_the_gate_passes_over_a_grasp_with_no_set_down_until_its_checks_are_spent(poses) -> None:
    world, level, pitched = poses
    asked: list[np.ndarray] = []

    def sets_down(qpos: np.ndarray) -> bool:
        asked.append(qpos)
        name, place = world.scene.target, np.asarray(world.scene.place)
        # as the gate asks it: from the lifted block, the lift itself unchecked
        plan = plan_delivery(world, name, place, qpos=qpos, with_transit=False, check_lift=False)
        return plan.found

    plan = object()  # what the approach planner returns for an approached pose
    approached = {id(level): plan, id(pitched): plan}
    gated = set_down_gate(lambda q, _c: approached.get(id(q)), sets_down, checks=2)
    contacts = None
    # a pose whose approach collides is passed over without asking
    assert gated(level.copy(), contacts) is None and asked == []
    assert gated(level, contacts) is None  # asked: no set-down, passed over (1 of 2)
    assert gated(pitched, contacts) is plan  # asked: it sets down, taken
    assert gated(level, contacts) is None  # asked again, passed over (2 of 2)
    assert len(asked) == 3
    # both refusals spent: a pose is taken unasked, even one with no set-down
    assert gated(level, contacts) is plan
    assert len(asked) == 3


def test_a_gate_with_checks_to_spare_keeps_asking() -> None:
    level = np.zeros(3)
    calls = 0

    def never(_qpos: np.ndarray) -> bool:
        nonlocal calls
        calls += 1
        return False

    gated = set_down_gate(lambda _q, _c: "plan", never, checks=3)
    assert [gated(level, None) for _ in range(4)] == [None, None, None, "plan"]
    assert calls == 3


@pytest.mark.parametrize("checks", [-1, 1.5, True, "4"])
def test_set_down_checks_that_are_not_a_count_are_refused(checks) -> None:
    with pytest.raises(ValueError, match="lateral_grasp_set_down_checks must be a whole number"):
        TaskConfig(lateral_grasp_set_down_checks=checks)
