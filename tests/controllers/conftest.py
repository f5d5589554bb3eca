"""Fixtures of the controller tests: clutter3 with the arm driven to its coarse-reach goal."""

from __future__ import annotations

import pytest

from controllers.arm_path import execute_path
from controllers.reach import ReachTarget, plan_coarse_reach
from hand_sim.scene import load_scene
from hand_sim.world import World


def hover_over_target(scene: str = "clutter3") -> tuple[World, ReachTarget]:
    """Build ``scene`` and drive the arm (in simulation) along the coarse-reach path above the
    target block; fails the test if no path is found."""
    world = World.build(load_scene(scene))
    target = ReachTarget.from_world(world, world.scene.target)
    plan = plan_coarse_reach(world, target)
    assert plan.found, plan.reason
    execute_path(world, plan.path.path, hand_q=plan.hand_q)
    return world, target


@pytest.fixture(scope="module")
def hovering() -> tuple[World, ReachTarget]:
    """clutter3 with the arm above the target block, and the target; one per test module (the
    tests of a module may move the arm and hand, so modules do not share it)."""
    return hover_over_target()
