"""The robot's belief (controllers.planning.belief_world): its model is the nominal robot with the
blocks the camera saw, its state what the sensors read. Moving the truth where no sensor sees it
(the arm's base, a neighbour block after the camera looked, a block's mass) changes no plan;
unperturbed, what the robot reads is the simulation's own state and image, bit for bit."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from controllers.planning.belief import planning_model
from controllers.planning.belief_world import BeliefWorld, modelled_block, outline_block
from controllers.planning.cspace import CollisionChecker
from controllers.reach.coarse import PRESHAPE, ReachTarget, plan_coarse_reach
from hand_sim import robot
from hand_sim.perturb import PerturbSpec, draw
from hand_sim.scene import load_scene
from hand_sim.world import World
from vision import Observation, overhead_camera

SCENE = "clutter3"


def _seen(scene) -> list:
    """What the camera would report: each block's footprint and height (a stand-in for the
    vision, so that both beliefs below see the same)."""
    return [modelled_block(b.name, b.polygon, b.position, b.yaw, b.height) for b in scene.blocks]


def _world(text: str | None = None, seed: int = 2) -> World:
    scene = load_scene(SCENE)
    p = None if text is None else draw(PerturbSpec.parse(text), seed, scene.block_names)
    return World.build(scene, perturbation=p)


def _belief(truth: World) -> BeliefWorld:
    belief = BeliefWorld.over(truth)
    belief.see(_seen(truth.scene))
    return belief


def _planning(belief: BeliefWorld, name: str = "pentagon"):
    target = ReachTarget.from_world(belief, name)
    model = planning_model(
        belief, name, target.polygon, target.yaw, target.position_xy, target.top_z
    )
    return target, model


def _scan(world: World, model=None) -> np.ndarray:
    """Collision status of a fixed set of arm postures over the table."""
    rng = np.random.default_rng(0)
    q = np.column_stack(
        [
            rng.uniform(-0.6, 0.6, 400),
            rng.uniform(0.2, 1.4, 400),
            rng.uniform(0.5, 2.0, 400),
            rng.uniform(0.0, 1.5, 400),
            rng.uniform(-1.0, 1.0, 400),
        ]
    )
    return CollisionChecker(world, hand_q=PRESHAPE, model=model).scan(q).collides


def test_unperturbed_the_robot_reads_the_simulation_bit_for_bit() -> None:
    truth = _world()
    belief = BeliefWorld.over(truth)
    truth.set_hand_targets(truth.hand_qpos() + 0.1)
    belief.step(100)
    mujoco.mj_forward(truth.model, truth.data)  # the simulation's derived state, now
    np.testing.assert_array_equal(belief.arm_qpos(), truth.arm_qpos())
    np.testing.assert_array_equal(belief.hand_qpos(), truth.hand_qpos())
    np.testing.assert_array_equal(belief.fingertip_positions(), truth.fingertip_positions())
    np.testing.assert_array_equal(belief.hand_tensions(), truth.hand_tensions())
    for a, b in zip(belief.wrist_wrench(), truth.wrist_wrench(), strict=True):
        np.testing.assert_array_equal(a, b)
    assert belief.time == truth.time
    seen = belief.look()
    with overhead_camera(truth) as cam:
        true = Observation.capture(cam)
    np.testing.assert_array_equal(seen.rgb, true.rgb)
    np.testing.assert_array_equal(seen.depth, true.depth)
    np.testing.assert_array_equal(seen.geometry.K, true.geometry.K)
    np.testing.assert_array_equal(seen.geometry.cam_to_world, true.geometry.cam_to_world)


def test_the_camera_is_read_with_its_calibration_not_its_true_pose() -> None:
    nominal, moved = _world(), _world("camera")
    belief = BeliefWorld.over(moved)
    seen = belief.look(640, 480, check=False)
    with overhead_camera(nominal, 640, 480) as cam:
        calibrated = Observation.capture(cam)
    np.testing.assert_array_equal(seen.geometry.cam_to_world, calibrated.geometry.cam_to_world)
    assert not np.array_equal(seen.rgb, calibrated.rgb)  # the true camera took the picture
    # checked against the table in the same view, the pose moves towards the true one
    checked = belief.look(640, 480)
    with overhead_camera(moved, 640, 480) as cam:
        true = Observation.capture(cam).geometry.cam_to_world
    before = np.linalg.norm(calibrated.geometry.cam_to_world[:3, 3] - true[:3, 3])
    after = np.linalg.norm(checked.geometry.cam_to_world[:3, 3] - true[:3, 3])
    assert belief.last_check is not None and belief.last_check.corrected and after < before


def test_encoders_and_nominal_kinematics() -> None:
    truth = _world("kinematics", seed=4)
    belief = BeliefWorld.over(truth)
    offsets = truth.sensors.arm_offsets
    np.testing.assert_allclose(belief.arm_qpos() - truth.arm_qpos(), offsets, atol=1e-15)
    # the fingertips follow from the encoders by the nominal model, not the true one
    nominal = _world()
    nominal.data.qpos[robot.arm_qpos_addresses(nominal.model)] = belief.arm_qpos()
    nominal.data.qpos[robot.hand_qpos_addresses(nominal.model)] = belief.hand_qpos()
    mujoco.mj_kinematics(nominal.model, nominal.data)
    np.testing.assert_allclose(belief.fingertip_positions(), nominal.fingertip_positions())
    assert np.abs(belief.fingertip_positions() - truth.fingertip_positions()).max() > 1e-3
    # a commanded angle is what the encoder reads once the servo settles
    target = belief.arm_qpos() + 0.03
    belief.set_arm_targets(target)
    belief.step(800)
    np.testing.assert_allclose(belief.arm_qpos(), target, atol=3e-3)


@pytest.mark.parametrize(
    "change",
    ["arm_base moved 5 mm", "a neighbour moved after the camera looked", "block masses"],
)
def test_moving_the_truth_where_no_sensor_sees_it_changes_no_plan(change: str) -> None:
    """Collision checks and the coarse reach's path are the same whatever the unsensed truth;
    the same checks on the simulated world itself do change (the test has teeth)."""
    base = _world()
    if change == "arm_base moved 5 mm":
        moved = World.build(
            base.scene,
            perturbation=draw(PerturbSpec.parse("arm_base"), 3, base.scene.block_names),
        )
        moved_shift = np.linalg.norm(moved.sensors.perturbation.arm_base_shift)
        assert moved_shift > 1e-3
    elif change == "block masses":
        moved = _world("object=2")
    else:
        moved = _world()
    a, b = _belief(base), _belief(moved)
    if change == "a neighbour moved after the camera looked":
        pos, quat = moved.block_pose("rectangle")
        moved.set_block_pose("rectangle", pos + np.array([-0.04, -0.05, 0.0]), quat)
        assert not np.array_equal(_scan(moved), _scan(base))  # the truth did change
    target_a, model_a = _planning(a)
    target_b, model_b = _planning(b)
    np.testing.assert_array_equal(_scan(a, model_a), _scan(b, model_b))
    plan_a = plan_coarse_reach(a, target_a, approaches=("top",), model=model_a)
    plan_b = plan_coarse_reach(b, target_b, approaches=("top",), model=model_b)
    assert plan_a.found and plan_b.found
    np.testing.assert_array_equal(plan_a.path.path, plan_b.path.path)


def test_the_planning_obstacles_are_the_seen_blocks_not_the_simulated_bodies() -> None:
    truth = _world()
    belief = BeliefWorld.over(truth)
    assert belief.model.nbody < truth.model.nbody  # before it looks, no block
    blob = outline_block("blob", [[0.15, 0.15], [0.2, 0.15], [0.2, 0.2], [0.15, 0.2]], 0.12)
    seen = [*_seen(truth.scene)[:1], blob]
    belief.see(seen)
    names = {belief.model.body(i).name for i in range(belief.model.nbody)}
    assert "pentagon" in names and "blob" in names and "rectangle" not in names
    pos, _ = belief.block_pose("blob")
    np.testing.assert_allclose(pos, [0.175, 0.175, truth.scene.table.height + 0.06], atol=1e-9)


def test_a_held_block_moves_with_the_palm() -> None:
    truth = _world()
    belief = _belief(truth)
    before = belief.block_pose("pentagon")[0]
    belief.hold("pentagon")
    assert belief.held == "pentagon"
    belief.set_arm_targets(belief.arm_qpos() + np.array([0.2, 0.0, 0.0, 0.0, 0.0]))
    belief.step(600)
    after = belief.block_pose("pentagon")[0]
    palm = belief.model.body(robot.hand_name(robot.PALM_BODY)).id
    assert np.linalg.norm(after - before) > 0.05
    # its distance to the palm is what it was when the hand took it
    belief.let_go()
    belief.step(200)
    np.testing.assert_array_equal(belief.block_pose("pentagon")[0], after)
    assert np.isfinite(belief.data.xpos[palm]).all()
