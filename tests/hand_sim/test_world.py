"""Tests of hand_sim.world (with the real models): scenes stand still, servos reach their targets,
touch sensors read contact forces, and instability is reported instead of silently reset."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from controllers.grasp import paper_object
from hand_sim import robot
from hand_sim.errors import HandSimError, SceneError, SimulationError
from hand_sim.scene import load_scene, scene_names
from hand_sim.world import MODELS_DIR, TIMESTEP, World

#: Acceptance: no block moves more than 1 mm on its own in 2 s.
MAX_DRIFT_M = 1e-3
SETTLE_STEPS = round(2.0 / TIMESTEP)
#: Servo tracking tolerances (rad): the arm is gravity-compensated and stiff; the finger servos
#: are soft (kp 1.2-3 N m/rad) and sag a few mrad under the fingers' weight.
ARM_TOL, HAND_TOL = 0.005, 0.02

SCENES = [(n, None) for n in scene_names() if n != "random"] + [("random", s) for s in (0, 1)]


def quat_angle(q1: np.ndarray, q2: np.ndarray) -> float:
    return 2.0 * math.acos(min(1.0, abs(float(np.dot(q1, q2)))))


@pytest.mark.parametrize(("name", "seed"), SCENES)
def test_scene_stands_still_for_two_seconds(name: str, seed: int | None) -> None:
    scene = load_scene(name, seed=seed, blocks=5 if seed is not None else None)
    world = World.build(scene)
    start = {b.name: world.block_pose(b.name) for b in scene.blocks}
    for b in scene.blocks:  # built where the scene file says, resting on the table
        pos, quat = start[b.name]
        np.testing.assert_allclose(
            pos, [*b.position, scene.table.height + 0.5 * b.height], atol=1e-9
        )
        assert quat_angle(quat, np.array([math.cos(b.yaw / 2), 0, 0, math.sin(b.yaw / 2)])) < 1e-6
    world.step(SETTLE_STEPS)  # raises SimulationError on NaN / instability
    assert world.time == pytest.approx(2.0)
    for b in scene.blocks:
        pos, quat = world.block_pose(b.name)
        assert np.linalg.norm(pos - start[b.name][0]) < MAX_DRIFT_M, b.name
        assert quat_angle(quat, start[b.name][1]) < math.radians(0.5), b.name
    assert np.all(np.isfinite(world.data.qpos))


@pytest.fixture(scope="module")
def world() -> World:
    return World.build(load_scene("single_square"))


def test_arm_starts_at_home_keyframe_with_hand_on_its_flange(world: World) -> None:
    world.reset()
    standalone = mujoco.MjModel.from_xml_path(str(MODELS_DIR / "arm.xml"))
    np.testing.assert_allclose(world.arm_qpos(), standalone.key("home").qpos, atol=1e-12)
    np.testing.assert_allclose(world.arm_targets(), world.arm_qpos())
    m, d = world.model, world.data
    site = m.site(robot.qualified(robot.ATTACHMENT_SITE)).id
    palm = m.body(robot.hand_name(robot.PALM_BODY)).id
    np.testing.assert_allclose(d.xpos[palm], d.site_xpos[site], atol=1e-9)
    np.testing.assert_allclose(d.xmat[palm], d.site_xmat[site], atol=1e-9)
    assert world.fingertip_positions().shape == (4, 3)
    assert m.opt.timestep == TIMESTEP


def test_each_arm_servo_reaches_its_target(world: World) -> None:
    world.reset()
    lo, hi = world.arm_ctrlrange().T
    target = world.arm_targets() + np.array([0.4, 0.3, 0.3, -0.3, 0.8])
    assert np.all((target > lo) & (target < hi))
    world.set_arm_targets(target)
    world.step(round(2.0 / TIMESTEP))
    error = np.abs(world.arm_qpos() - target)
    assert np.all(error < ARM_TOL), error
    assert np.all(np.abs(world.arm_qvel()) < 1e-2)  # settled, not swinging through


def test_each_hand_servo_reaches_its_target(world: World) -> None:
    world.reset()
    lo, hi = world.hand_ctrlrange().T
    target = lo + 0.6 * (hi - lo)
    target[0::4] = [-0.3, 0.0, 0.3, 0.4]  # spread the fingers apart, swing the thumb
    world.set_hand_targets(target)
    world.step(round(2.0 / TIMESTEP))
    error = np.abs(world.hand_qpos() - target)
    assert np.all(error < HAND_TOL), dict(zip(robot.HAND_JOINTS, error.round(4), strict=True))
    # each joint actually moved to its own target (not merely stayed near zero)
    assert np.all(np.abs(world.hand_qpos()) > 0.5 * np.abs(target) - HAND_TOL)


@pytest.mark.parametrize("finger", range(len(robot.FINGERS)))
def test_touch_is_zero_in_free_space_and_measures_a_block_pressing_on_a_fingertip(
    finger: int,
) -> None:
    """The servo hand's fingertip touch pads (the tendon hand has none: its touch is estimated
    from the tensions, tests/hand_sim/test_contact_estimate.py)."""
    world = World.build(load_scene("single_square"), hand="servo")
    world.set_arm_targets(np.zeros(5))  # every link straight up, tool axis up
    hand = np.zeros(16)
    for f in range(len(robot.FINGERS)):  # the others curled out of the way
        hand[4 * f + 1 : 4 * f + 4] = [1.5, 1.5, 1.2]
    hand[4 * finger + 1 : 4 * finger + 4] = [math.pi / 2, 0.0, 0.0]  # this one points straight up
    world.set_hand_targets(hand)
    world.step(round(3.0 / TIMESTEP))
    np.testing.assert_array_equal(world.touch(), np.zeros(4))

    block = world.scene.blocks[0]
    tip = world.fingertip_positions()[finger]
    world.set_block_pose(block.name, [tip[0], tip[1], tip[2] + 0.5 * block.height + 0.005])
    world.step(round(0.1 / TIMESTEP))
    touch = world.touch()
    m, d = world.model, world.data
    pad = m.geom(robot.hand_name(f"{robot.FINGERS[finger]}_pad")).id
    normal = 0.0
    for i in range(d.ncon):
        if pad in (d.contact[i].geom1, d.contact[i].geom2):
            f = np.zeros(6)
            mujoco.mj_contactForce(m, d, i, f)
            normal += f[0]
    weight = m.body_subtreemass[world.block_body_id(block.name)] * -m.opt.gravity[2]
    assert touch[finger] == pytest.approx(normal, rel=1e-6)
    assert touch[finger] == pytest.approx(weight, rel=0.2)  # the block rests on that fingertip
    np.testing.assert_array_equal(np.delete(touch, finger), np.zeros(3))


def test_nan_state_raises_simulation_error() -> None:
    world = World.build(load_scene("single_triangle"))
    world.data.qvel[0] = np.nan
    with pytest.raises(SimulationError, match=r"BADQVEL|non-finite"):
        world.step(1)


def test_bad_targets_and_names_are_refused(world: World) -> None:
    with pytest.raises(HandSimError, match="5 finite joint angles"):
        world.set_arm_targets(np.zeros(4))
    with pytest.raises(HandSimError, match="16 finite joint angles"):
        world.set_hand_targets([np.nan] * 16)
    with pytest.raises(SceneError, match="no block 'nope'; valid: square"):
        world.block_pose("nope")
    with pytest.raises(HandSimError, match="unknown robot element 'pinky'"):
        robot.qualified("pinky")


def test_world_without_robot_has_no_arm() -> None:
    world = World.build(load_scene("clutter3"), with_robot=False)
    assert world.model.nu == 0
    with pytest.raises(HandSimError, match="with_robot=False"):
        world.arm_qpos()


@pytest.mark.parametrize(
    ("table", "field"),
    [("height = 0.80", "table.height"), ("size = [1.4, 0.9]", "table.size")],
)
def test_scene_table_must_match_the_table_model(tmp_path, table: str, field: str) -> None:
    """One table: a scene may not draw a larger or higher table than the one blocks stand on."""
    path = tmp_path / "big_table.toml"
    path.write_text(
        f'target = "a"\nplace = [0.0, -0.2]\n[table]\n{table}\n'
        '[[blocks]]\nname = "a"\nshape = "square"\nposition = [0.0, 0.0]\n'
    )
    with pytest.raises(SceneError, match=rf"{field}: .* differs from the table model"):
        load_scene(path)


def test_a_block_at_the_scene_table_edge_stands_on_the_physical_table(tmp_path) -> None:
    """The scene's table is the collision table: a block allowed at its edge does not fall."""
    from hand_sim.scene_spec import DEFAULT_TABLE_SIZE, TABLE_EDGE_MARGIN

    half = float(np.abs(paper_object("square").vertices[:, 0]).max())
    edge = 0.5 * DEFAULT_TABLE_SIZE[0] - TABLE_EDGE_MARGIN - half - 1e-4
    path = tmp_path / "edge.toml"
    path.write_text(
        'target = "a"\nplace = [0.0, -0.2]\n'
        f'[[blocks]]\nname = "a"\nshape = "square"\nposition = [{edge}, 0.0]\n'
    )
    world = World.build(load_scene(path), with_robot=False)
    world.step(round(1.0 / TIMESTEP))
    pos, _ = world.block_pose("a")
    assert pos[2] == pytest.approx(world.scene.table.height + 0.1, abs=1e-3)


@pytest.mark.parametrize("side", [+1.0, -1.0])
def test_touch_feels_the_pad_not_the_back_of_the_fingertip(side: float) -> None:
    """A block face pressed 1 mm into the palmar side of a fingertip is felt by its touch sensor;
    pressed into the back of the fingertip, the sensor reads 0 while the contact list
    (hand_sim.contacts) still sees the force on the distal link. The servo hand's touch pads
    (the tendon hand's estimate: tests/hand_sim/test_contact_estimate.py)."""
    from hand_sim.contacts import robot_contacts

    world = World.build(load_scene("single_square"), hand="servo")
    world.set_arm_targets(np.zeros(5))
    hand = np.zeros(16)
    for f in range(len(robot.FINGERS)):
        hand[4 * f + 1 : 4 * f + 4] = [1.5, 1.5, 1.2]
    hand[1:4] = [math.pi / 2, 0.0, 0.0]  # the first finger points straight up
    world.set_hand_targets(hand)
    world.step(round(3.0 / TIMESTEP))
    m, d = world.model, world.data
    distal = m.body(robot.hand_name("ff_distal")).id
    R = d.xmat[distal].reshape(3, 3)
    palmar = R[:, 2]  # horizontal: the finger points up
    pad_centre = d.xpos[distal] + 0.00875 * R[:, 1]
    block = world.scene.blocks[0]
    half = float(np.abs(block.polygon.vertices[:, 0]).max())  # the square's half width
    centre = pad_centre + side * palmar * (0.0085 + half - 0.001)
    centre[2] += 0.5 * block.height - 0.02  # the block's lowest 2 cm face the pad, above the palm
    yaw = math.atan2(palmar[1], palmar[0])
    world.set_block_pose(block.name, centre, [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
    contacts = robot_contacts(world, world.block_body_id(block.name))
    on_ff_distal = [c for c in contacts if c.finger == "ff" and c.link == "distal"]
    assert on_ff_distal and max(c.normal_force for c in on_ff_distal) > 0.01
    if side > 0:
        assert world.touch()[0] == pytest.approx(sum(c.normal_force for c in on_ff_distal))
    else:
        assert world.touch()[0] == 0.0


def test_wrist_sensor_weighs_the_hand_and_what_it_holds() -> None:
    world = World.build(load_scene("single_square"))
    world.step(round(1.0 / TIMESTEP))
    force, _ = world.wrist_wrench()
    m = world.model
    hand = [b for b in range(m.nbody) if m.body(b).name.startswith(robot.HAND_PREFIX)]
    hand_weight = float(m.body_mass[hand].sum()) * -m.opt.gravity[2]
    np.testing.assert_allclose(force, [0.0, 0.0, hand_weight], atol=0.01 * hand_weight)
