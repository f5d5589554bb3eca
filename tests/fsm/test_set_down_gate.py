"""The palm-pose search's set-down gate (``controllers.preshape.set_down_check.SetDownGate``):
a pose whose grasp cannot set the block down at the place point is passed over like one whose
approach collides, until ``checks`` poses have been passed over for it; then taken unasked, or, by a
strict gate (a further pitch left), passed over unasked. On random scene 182 a level
lateral hand has no set-down and a hand pitched 30 deg down has one
(tests/controllers/test_set_down_check.py); the verdicts here are the delivery planner's own,
not stand-ins."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from controllers.deliver.plan import plan_delivery
from controllers.preshape.set_down_check import SetDownGate, next_tilt, set_down_gate
from fsm.config import TaskConfig
from hand_sim.world import World
from tests.controllers.test_set_down_check import _grasp_pose, scene182  # noqa: F401


@pytest.fixture(scope="module")
def poses(scene182) -> tuple[World, np.ndarray, np.ndarray]:  # noqa: F811
    world, target = scene182
    return world, _grasp_pose(world, target, 0.0), _grasp_pose(world, target, 30.0)


def _asking(world: World, asked: list[np.ndarray]) -> Callable[[np.ndarray], bool]:
    """The gate's question as it asks it (from the lifted block, the lift itself unchecked),
    each posture asked kept in ``asked``."""

    def sets_down(qpos: np.ndarray) -> bool:
        asked.append(qpos)
        name, place = world.scene.target, np.asarray(world.scene.place)
        plan = plan_delivery(world, name, place, qpos=qpos, with_transit=False, check_lift=False)
        return plan.found

    return sets_down


def test_the_gate_passes_over_a_grasp_with_no_set_down_until_its_checks_are_spent(poses) -> None:
    world, level, pitched = poses
    asked: list[np.ndarray] = []
    sets_down = _asking(world, asked)
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


def test_a_strict_gate_once_spent_passes_over_every_pose_unasked(poses) -> None:
    world, level, pitched = poses
    asked: list[np.ndarray] = []
    planned: list[np.ndarray] = []
    sets_down = _asking(world, asked)

    def approach(qpos: np.ndarray, _contacts: object) -> str:
        planned.append(qpos)
        return "plan"

    gate = SetDownGate(2, strict=True)
    gated = gate.wrap(approach, sets_down)
    assert gated(level, None) is None and not gate.spent  # no set-down: 1 of 2
    assert gated(pitched, None) == "plan"  # a set-down: taken, nothing spent
    assert gated(level, None) is None and gate.spent and gate.refused == 2
    # spent: even the pitched grasp, which sets down, is passed over, neither asked nor planned
    assert gated(pitched, None) is None
    assert len(asked) == 3 and len(planned) == 3


def test_the_next_pitch_is_the_next_of_the_lateral_tilts_further_down() -> None:
    # controllers.reach.coarse.LATERAL_TILTS: 15, 30 and 45 deg down
    assert np.degrees(next_tilt(0.0)) == pytest.approx(15.0)
    assert np.degrees(next_tilt(-1e-9)) == pytest.approx(15.0)  # a level goal's pitch
    assert np.degrees(next_tilt(np.radians(15.0))) == pytest.approx(30.0)
    assert np.degrees(next_tilt(np.radians(20.0))) == pytest.approx(30.0)
    assert next_tilt(np.radians(45.0)) is None


@pytest.mark.parametrize("checks", [-1, 1.5, True, "4"])
def test_set_down_checks_that_are_not_a_count_are_refused(checks) -> None:
    with pytest.raises(ValueError, match="lateral_grasp_set_down_checks must be a whole number"):
        TaskConfig(lateral_grasp_set_down_checks=checks)
