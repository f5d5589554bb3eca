"""Shared set-up of the reach and posture tests: clutter3 with the arm at its coarse-reach goal."""

from __future__ import annotations

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
