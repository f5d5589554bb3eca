"""A grasp's set-down checked before the grasp is taken: ``plan_delivery`` from a palm pose the
arm is not in yet (``qpos``), without the transit. On random scene 182 a neighbour stands
20-25 cm inward of the place point, on the radial line: a level lateral hand's forearm passes
through it at the set-down, a hand pitched 30 deg down passes above it."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from controllers.deliver.plan import SET_DOWN_HOVER, plan_delivery
from controllers.errors import ReachError
from controllers.planning.cspace import CollisionChecker
from controllers.preshape.palm_candidates import (
    DEFAULT_PALM_POSE,
    PoseSetting,
    lateral_poses,
    robot_base_xy,
)
from controllers.reach.coarse import (
    PRESHAPE,
    ReachTarget,
    goal_poses,
    lateral_fallback_poses,
    solve_goal,
)
from fsm.layout import episode_scene
from hand_sim import robot
from hand_sim.world import World
from tests.controllers.test_reach import carried_contacts

SEED, BLOCKS = 182, 2


@pytest.fixture(scope="module")
def scene182() -> tuple[World, ReachTarget]:
    world = World.build(episode_scene("random", SEED, BLOCKS))
    return world, ReachTarget.from_world(world, world.scene.target)


def _grasp_pose(world: World, target: ReachTarget, tilt_deg: float) -> np.ndarray:
    """The qpos of the nearest sampled lateral palm pose (smallest gap, not rolled or shifted)
    at the first lateral coarse goal pitched ``tilt_deg`` down (level: the nominal goal), its
    IK started from the goal's posture; the hand in the pinch pre-shape."""
    base = robot_base_xy(world)
    goals = (
        goal_poses(target, base)["lateral"]
        if tilt_deg == 0.0
        else lateral_fallback_poses(target, base, np.deg2rad(tilt_deg))
    )
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    goal = next(
        g
        for pose in goals
        if (g := solve_goal(checker, "lateral", [pose], world.arm_qpos())) is not None
    )
    params = replace(
        DEFAULT_PALM_POSE,
        lateral_sampled_gaps=DEFAULT_PALM_POSE.lateral_sampled_gaps[:1],
        lateral_rolls=(0.0,),
        lateral_sampled_shifts=(0.0,),
    )
    where = PoseSetting(world, world.model, target, goal.palm_rotation, goal.q)
    (pose,) = lateral_poses(where, params, sampled=True)
    return pose.qpos


def test_a_level_hand_has_no_set_down_where_a_pitched_one_has(scene182) -> None:
    world, target = scene182
    before = world.data.qpos.copy()
    name, place = world.scene.target, np.asarray(world.scene.place)
    level = plan_delivery(
        world, name, place, qpos=_grasp_pose(world, target, 0.0), with_transit=False
    )
    assert not level.found
    assert "no collision-free posture above the place point" in level.reason
    start = _grasp_pose(world, target, 30.0)
    pitched = plan_delivery(world, name, place, qpos=start, with_transit=False)
    assert pitched.found, pitched.reason
    assert pitched.transit is None
    # the world was read, not moved
    np.testing.assert_array_equal(world.data.qpos, before)
    # the block ends hovering over the place point
    np.testing.assert_allclose(pitched.block_goal[:2], place, atol=2e-3)
    height = world.scene.block(name).height
    assert (
        abs(pitched.block_goal[2] - (world.scene.table.height + 0.5 * height + SET_DOWN_HOVER))
        < 2e-3
    )
    # independently: the way down, the block carried rigidly from the grasp pose, touches nothing
    held = World.build(world.scene)
    held.data.qpos[:] = start
    mujoco.mj_forward(held.model, held.data)
    assert carried_contacts(held, name, pitched.path[-2:], 0.0) == []


def test_a_checker_copies_the_configuration_it_is_given(scene182) -> None:
    world, target = scene182
    start = _grasp_pose(world, target, 30.0)
    checker = CollisionChecker(world, qpos=start, carried=world.scene.target)
    block, _ = checker.carried_pose(start[robot.arm_qpos_addresses(world.model)])
    np.testing.assert_allclose(
        block, world.data.xpos[world.block_body_id(world.scene.target)], atol=1e-9
    )
    with pytest.raises(ReachError, match="qpos"):
        CollisionChecker(world, qpos=np.full(3, 0.0))
    with pytest.raises(ReachError, match="qpos"):
        CollisionChecker(world, qpos=np.full(world.model.nq, np.nan))
