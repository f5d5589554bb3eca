"""A lateral palm from the block's far side (``controllers.reach.coarse.plan_coarse_reach``): on
random scene 1 (3 blocks) a neighbour stands on the radial line between the arm's base and the
target, so no lateral goal on the base's side has a collision-free posture (checked here with the
same IK goals); the plan ends beyond the block with the palm facing back towards the base, the arm
follows it touching nothing, and the palm poses beside the block (Posture Control's and the
pre-shape's) stay on that side."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.planning.cspace import CollisionChecker
from controllers.preshape.palm_candidates import (
    DEFAULT_PALM_POSE,
    PoseSetting,
    approach_origin,
    lateral_poses,
    robot_base_xy,
)
from controllers.reach.arm_path import execute_path
from controllers.reach.coarse import (
    LATERAL_TILTS,
    PRESHAPE,
    CoarseReachPlan,
    ReachTarget,
    goal_poses,
    lateral_fallback_poses,
    lateral_frame,
    plan_coarse_reach,
    solve_goal,
)
from fsm.layout import episode_scene
from hand_sim import robot
from hand_sim.world import World

SEED, BLOCKS = 1, 3


def _scene() -> tuple[World, ReachTarget]:
    world = World.build(episode_scene("random", SEED, BLOCKS))
    return world, ReachTarget.from_world(world, world.scene.target)


@pytest.fixture(scope="module")
def far_plan() -> tuple[World, ReachTarget, CoarseReachPlan]:
    world, target = _scene()
    return world, target, plan_coarse_reach(world, target, approaches=("lateral",))


def _radial(world: World, target: ReachTarget) -> tuple[np.ndarray, np.ndarray, float]:
    base = np.asarray(robot_base_xy(world))
    centre = np.asarray(target.position_xy)
    return (
        base,
        (centre - base) / np.linalg.norm(centre - base),
        float(np.linalg.norm(centre - base)),
    )


def test_no_goal_on_the_base_side_leaves_one_beyond_the_block_facing_the_base(far_plan) -> None:
    world, target, plan = far_plan
    base, radial, distance = _radial(world, target)
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    near = goal_poses(target, base)["lateral"] + lateral_fallback_poses(target, base)
    assert solve_goal(checker, "lateral", near, world.arm_qpos()) is None
    assert plan.found and plan.approach == "lateral" and plan.goal is not None
    assert not CollisionChecker(world, hand_q=PRESHAPE).collides(plan.goal.q)
    palm, rotation = checker.palm_pose(plan.goal.q)
    # beyond the block: further from the base than the block's farthest point
    assert (palm[:2] - base) @ radial > distance + target.radius
    facing = rotation[:2, 2] / np.linalg.norm(rotation[:2, 2])
    assert facing @ radial < -np.cos(np.deg2rad(5.0))
    assert min(abs(plan.goal.pitch - t) for t in LATERAL_TILTS) < np.deg2rad(2.0)


def test_the_arm_follows_the_far_side_path_touching_nothing() -> None:
    world, target = _scene()
    plan = plan_coarse_reach(world, target, approaches=("lateral",))
    assert plan.found
    run = execute_path(world, plan.path.path, hand_q=plan.hand_q)
    assert run.contacts == ()
    # the simulated arm's joints where the plan ends
    np.testing.assert_allclose(world.arm_qpos(), plan.goal.q, atol=0.02)


def test_the_approach_comes_from_the_base_or_its_mirror_through_the_block(far_plan) -> None:
    world, target, plan = far_plan
    base, radial, _ = _radial(world, target)
    centre = np.asarray(target.position_xy)
    near = lateral_frame(np.array([*radial, 0.0]), 0.0)
    np.testing.assert_allclose(approach_origin(base, target, near), base)
    np.testing.assert_allclose(
        approach_origin(base, target, plan.goal.palm_rotation), 2 * centre - base
    )
    top = np.diag([1.0, -1.0, -1.0])  # palm down: no horizontal approach, the base's
    np.testing.assert_allclose(approach_origin(base, target, top), base)


def test_palm_poses_of_a_far_side_goal_stay_beyond_the_block_facing_the_base(far_plan) -> None:
    world, target, plan = far_plan
    base, radial, distance = _radial(world, target)
    where = PoseSetting(world, world.model, target, plan.goal.palm_rotation, plan.goal.q)
    poses = lateral_poses(where, DEFAULT_PALM_POSE, sampled=True)
    assert poses
    checker = CollisionChecker(world)
    arm = robot.arm_qpos_addresses(world.model)
    for pose in poses:
        palm, rotation = checker.palm_pose(pose.qpos[arm])
        assert (palm[:2] - base) @ radial > distance, pose.label
        facing = rotation[:2, 2] / np.linalg.norm(rotation[:2, 2])
        assert facing @ radial < -np.cos(np.deg2rad(10.0)), pose.label
