"""Fixtures of the controller tests: clutter3 with the arm driven to its coarse-reach goal;
single_square with the arm at its lateral goal, the palm poses beside it and the finger samples."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.bench_lateral_search import square_at_lateral_goal
from controllers.hand.finger_geometry import PerceivedPrism
from controllers.hand.finger_samples import FingerSamples
from controllers.reach.arm_path import execute_path
from controllers.reach.coarse import ReachTarget, plan_coarse_reach
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


@pytest.fixture(scope="module")
def square() -> tuple[World, ReachTarget, PerceivedPrism, list]:
    """single_square with the arm at its lateral coarse goal, and the sampled search's palm
    poses beside the block (as the lateral search's benchmark sets them up)."""
    return square_at_lateral_goal()


@pytest.fixture(scope="module")
def samples() -> FingerSamples:
    """The sampled finger postures of the lateral search (the default seed and count)."""
    return FingerSamples.draw()


def grasps_beside(square, samples, search, squeeze: float) -> list:
    """(pose, grasp) at every palm pose beside single_square (``square``) where ``search``
    (:func:`controllers.preshape.lateral_grasp.sampled_lateral_grasp` or its three-contact kin)
    finds a grasp, the fingertips ``squeeze`` inside the faces."""
    world, target, prism, poses = square
    pose_xy = (np.asarray(target.position_xy), target.yaw)
    found = [
        (pose, search(world.model, pose.qpos, samples, prism, target.polygon, pose_xy, squeeze))
        for pose in poses
    ]
    return [(pose, grasp) for pose, grasp in found if grasp is not None]
