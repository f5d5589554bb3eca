"""Perturbations of the simulated world (hand_sim.perturb): each moves what it names by at most
its magnitude times SCALE, judged on the simulated model and data against the nominal world
built from the same scene (an independent computation: body and camera poses, masses,
frictions, gains, readings), the same seed draws the same perturbation, and an unperturbed world
is the nominal one exactly."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from hand_sim import perturb, robot
from hand_sim.errors import SceneError
from hand_sim.perturb import (
    KINDS,
    PerturbError,
    PerturbSpec,
    draw,
    for_episode,
)
from hand_sim.scene import load_scene, parse_scene
from hand_sim.world import World

SEEDS = (0, 1, 2, 3, 4, 5)
SCALES = (0.5, 1.0, 2.0)


@pytest.fixture(scope="module")
def scene():
    return load_scene("clutter3")


@pytest.fixture(scope="module")
def nominal(scene) -> World:
    return World.build(scene)


def _perturbed(scene, text: str, seed: int, with_robot: bool = True) -> World:
    p = draw(PerturbSpec.parse(text), seed, scene.block_names)
    return World.build(scene, perturbation=p, with_robot=with_robot)


def _angle(R1: np.ndarray, R2: np.ndarray) -> float:
    c = (np.trace(R1.T @ R2) - 1.0) / 2.0
    return math.acos(min(1.0, max(-1.0, c)))


# --- names and scales -----------------------------------------------------------------------
def test_parse_names_scales_and_woes() -> None:
    assert PerturbSpec.parse("camera").scales == (("camera", 1.0),)
    assert PerturbSpec.parse("object=2, camera=0.5").scales == (("camera", 0.5), ("object", 2.0))
    woes = PerturbSpec.parse("woes=0.5")
    assert [k for k, _ in woes.scales] == list(KINDS) and {s for _, s in woes.scales} == {0.5}
    # a kind named beside woes keeps its own scale, before or after it
    for text in ("woes,camera=2", "camera=2,woes"):
        spec = PerturbSpec.parse(text)
        assert spec.scale("camera") == 2.0 and spec.scale("object") == 1.0
    assert PerturbSpec.parse("none").scales == () and not PerturbSpec.parse("none").active
    assert not PerturbSpec.parse("camera=0").active
    assert PerturbSpec.parse("camera=1,object=2").text() == "camera=1,object=2"


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("lens", "unknown perturbation 'lens'; valid: camera, arm_base"),
        ("camera=x", "camera: scale must be a number from 0 to 4"),
        ("camera=-1", "camera: scale must be a number from 0 to 4"),
        ("camera=5", "camera: scale must be a number from 0 to 4"),
        ("camera=nan", "camera: scale must be a number from 0 to 4"),
        ("camera,camera=2", "camera is named twice"),
        ("camera,,object", "empty name"),
    ],
)
def test_parse_refuses_with_the_valid_names(text: str, fragment: str) -> None:
    with pytest.raises(PerturbError, match=None) as e:
        PerturbSpec.parse(text)
    assert fragment in str(e.value)


def test_scene_file_perturb_table(tmp_path) -> None:
    body = 'target = "a"\nplace = [0.0, -0.2]\n[[blocks]]\nname = "a"\nshape = "square"\n'
    body += "position = [0.0, 0.0]\n"
    scene = parse_scene({**_toml(body), "perturb": {"camera": 1, "woes": 0.5}}, "x.toml", "x")
    assert scene.perturb.scale("camera") == 1.0 and scene.perturb.scale("object") == 0.5
    assert parse_scene(_toml(body), "x.toml", "x").perturb.scales == ()
    with pytest.raises(SceneError, match=r"x.toml: perturb.lens: unknown key; valid keys"):
        parse_scene({**_toml(body), "perturb": {"lens": 1}}, "x.toml", "x")
    with pytest.raises(SceneError, match=r"perturb.camera: 9 is out of range \[0, 4\]"):
        parse_scene({**_toml(body), "perturb": {"camera": 9}}, "x.toml", "x")


def _toml(text: str) -> dict:
    import tomllib

    return tomllib.loads(text)


# --- seeds ----------------------------------------------------------------------------------
def test_same_seed_same_draw_and_kinds_drawn_apart(scene) -> None:
    a = draw(PerturbSpec.parse("woes"), 7, scene.block_names)
    b = draw(PerturbSpec.parse("woes"), 7, scene.block_names)
    assert a.to_json() == b.to_json()
    c = draw(PerturbSpec.parse("woes"), 8, scene.block_names)
    assert not np.allclose(a.camera_shift, c.camera_shift)
    # a kind's draw does not depend on which others are on, and scale multiplies it
    alone = draw(PerturbSpec.parse("camera"), 7, scene.block_names)
    double = draw(PerturbSpec.parse("camera=2"), 7, scene.block_names)
    np.testing.assert_array_equal(alone.camera_shift, a.camera_shift)
    np.testing.assert_allclose(double.camera_turn, 2.0 * alone.camera_turn, rtol=1e-12)
    assert np.all(alone.arm_offsets == 0.0) and alone.mass_factors == {}


def test_nothing_perturbed_is_the_nominal_world(scene, nominal) -> None:
    assert for_episode(PerturbSpec.parse("none"), 3, scene.block_names) is None
    assert for_episode(PerturbSpec.parse("woes=0"), 3, scene.block_names) is None
    world = World.build(scene)
    world.step(50)
    s = world.sensors
    assert s.exact
    np.testing.assert_array_equal(s.arm_angles(), world.arm_qpos())
    np.testing.assert_array_equal(s.hand_angles(), world.hand_qpos())
    np.testing.assert_array_equal(s.tensions(), world.hand_tensions())
    q = world.arm_qpos() + 0.01
    world.set_arm_targets(q)
    np.testing.assert_array_equal(world.arm_targets(), q)
    np.testing.assert_array_equal(world.data.ctrl[world._idx.arm_ctrl], q)  # the servo's own


# --- each perturbation, bounded ---------------------------------------------------------------
@pytest.mark.parametrize("scale", SCALES)
def test_camera_moves_by_at_most_its_magnitude(scene, scale: float) -> None:
    base = World.build(scene, with_robot=False)
    c = base.model.camera("overhead").id
    shifts, turns = [], []
    for seed in SEEDS:
        w = _perturbed(scene, f"camera={scale}", seed, with_robot=False)
        shifts.append(np.linalg.norm(w.data.cam_xpos[c] - base.data.cam_xpos[c]))
        R0, R1 = (x.data.cam_xmat[c].reshape(3, 3) for x in (base, w))
        turns.append(_angle(R0, R1))
    assert max(shifts) <= perturb.CAMERA_SHIFT * scale + 1e-12
    assert max(turns) <= perturb.CAMERA_TURN * scale + 1e-9
    assert max(shifts) > 0.3 * perturb.CAMERA_SHIFT * scale  # it does move
    assert max(turns) > 0.3 * perturb.CAMERA_TURN * scale


@pytest.mark.parametrize("scale", (1.0, 2.0))
def test_arm_base_moves_by_at_most_its_magnitude(scene, nominal, scale: float) -> None:
    body = nominal.model.body(robot.arm_name("arm_base")).id
    shifts = []
    for seed in SEEDS[:4]:
        w = _perturbed(scene, f"arm_base={scale}", seed)
        shifts.append(np.linalg.norm(w.data.xpos[body] - nominal.data.xpos[body]))
        # nothing else of the world moves: the camera, the table, the blocks
        for b in scene.block_names:
            np.testing.assert_array_equal(w.block_pose(b)[0], nominal.block_pose(b)[0])
    assert max(shifts) <= perturb.ARM_BASE_SHIFT * scale + 1e-12
    assert max(shifts) > 0.3 * perturb.ARM_BASE_SHIFT * scale


@pytest.mark.parametrize("scale", (1.0, 2.0))
def test_kinematics_links_and_encoders(scene, nominal, scale: float) -> None:
    for seed in SEEDS[:3]:
        w = _perturbed(scene, f"kinematics={scale}", seed)
        deltas = []
        for model_name, body, _axis in perturb.LINKS:
            name = (robot.hand_name if model_name == "hand" else robot.arm_name)(body)
            b = w.model.body(name).id
            deltas.append(
                np.linalg.norm(w.model.body_pos[b]) - np.linalg.norm(nominal.model.body_pos[b])
            )
        assert max(np.abs(deltas)) <= perturb.LINK_LENGTH * scale + 1e-12
        assert max(np.abs(deltas)) > 0.3 * perturb.LINK_LENGTH * scale
        arm = w.sensors.arm_angles() - w.arm_qpos()
        hand = w.sensors.hand_angles() - w.hand_qpos()
        assert np.abs(arm).max() <= perturb.ARM_ENCODER_OFFSET * scale + 1e-12
        assert np.abs(hand).max() <= perturb.HAND_ENCODER_OFFSET * scale + 1e-12
        assert np.abs(arm).max() > 0.2 * perturb.ARM_ENCODER_OFFSET * scale


def test_a_servo_closes_its_loop_on_its_encoder(scene) -> None:
    w = _perturbed(scene, "kinematics", 3)
    target = w.sensors.arm_angles() + np.array([0.05, -0.03, 0.04, 0.02, 0.1])
    w.set_arm_targets(target)
    np.testing.assert_allclose(w.arm_targets(), target, atol=1e-15)
    w.step(1000)
    np.testing.assert_allclose(w.sensors.arm_angles(), target, atol=3e-3)
    offsets = w.sensors.arm_offsets
    np.testing.assert_allclose(w.arm_qpos(), target - offsets, atol=3e-3)


@pytest.mark.parametrize("scale", (1.0, 2.0))
def test_object_masses_and_frictions(scene, nominal, scale: float) -> None:
    lo_m, hi_m = (f**scale for f in perturb.MASS_FACTOR)
    lo_f, hi_f = (f**scale for f in perturb.FRICTION_FACTOR)
    m0 = nominal.model
    ratios = []
    for seed in SEEDS[:3]:
        w = _perturbed(scene, f"object={scale}", seed)
        m = w.model
        for b in scene.block_names:
            body, geom = m.body(b).id, m.geom(b + "_geom").id
            ratio = m.body_mass[body] / m0.body_mass[body]
            ratios.append(ratio)
            assert lo_m - 1e-9 <= ratio <= hi_m + 1e-9
            np.testing.assert_allclose(m.body_inertia[body] / m0.body_inertia[body], ratio)
            f = m.geom_friction[geom, 0] / m0.geom_friction[geom, 0]
            assert lo_f - 1e-9 <= f <= hi_f + 1e-9
            assert w.block_weight(b) / nominal.block_weight(b) == pytest.approx(ratio)
        for finger in robot.FINGERS:
            g = m.geom(robot.hand_name(f"{finger}_pad")).id
            f = m.geom_friction[g, 0] / m0.geom_friction[g, 0]
            assert lo_f - 1e-9 <= f <= hi_f + 1e-9
            assert m.geom_priority[g] > m.geom_priority[m.geom(b + "_geom").id]
        # the table's top gives way to a block's own friction
        assert m.geom_priority[m.geom("table/table_top").id] < m.geom_priority[geom]
    assert max(ratios) / min(ratios) > 1.2


def test_sensing_noise_has_its_standard_deviation(scene) -> None:
    w = _perturbed(scene, "sensing=2", 0)
    w.step(20)
    true_t, true_q = w.hand_tensions(), w.arm_qpos()
    n = 3000
    t = np.array([w.sensors.tensions() for _ in range(n)])
    q = np.array([w.sensors.arm_angles() for _ in range(n)])
    rel, floor = perturb.TENSION_NOISE
    z = (t - true_t) / (2.0 * (rel * np.abs(true_t) + floor))
    assert abs(z.mean()) < 0.01 and z.std() == pytest.approx(1.0, abs=0.02)
    zq = (q - true_q) / (2.0 * perturb.ANGLE_NOISE)
    assert abs(zq.mean()) < 0.02 and zq.std() == pytest.approx(1.0, abs=0.03)
    # the image: a flat grey and a flat depth come back with the noise's deviation, blurred
    rgb = np.full((200, 300, 3), 120, np.uint8)
    depth = np.full((200, 300), 1.1, np.float32)
    depth[:, :20] = 5.0  # the floor far below: noisy alike
    noisy, d = w.sensors.image(rgb, depth)
    assert noisy.dtype == np.uint8 and d.dtype == np.float32
    dev = noisy.astype(float) - 120.0
    assert dev.std() == pytest.approx(2.0 * perturb.PIXEL_NOISE, rel=0.05)
    assert (d[:, 20:] - 1.1).std() == pytest.approx(2.0 * perturb.DEPTH_NOISE, rel=0.05)
    assert (d[:, :20] - 5.0).std() == pytest.approx(2.0 * perturb.DEPTH_NOISE, rel=0.1)
    edge = np.zeros((40, 40, 3), np.uint8)
    edge[:, 20:] = 200
    quiet = World.build(
        scene,
        with_robot=False,
        perturbation=draw(PerturbSpec.parse("sensing=4"), 0, scene.block_names),
    )
    blurred, _ = quiet.sensors.image(edge, np.ones((40, 40), np.float32))
    row = blurred[20, :, 0].astype(float)
    assert 30 < row[18] < 170 or 30 < row[21] < 170  # the edge is spread over pixels


@pytest.mark.parametrize("scale", (1.0, 2.0))
def test_actuation_gains_and_lag(scene, nominal, scale: float) -> None:
    lo, hi = 1.0 - perturb.ACTUATION_FACTOR * scale, 1.0 + perturb.ACTUATION_FACTOR * scale
    w = _perturbed(scene, f"actuation={scale}", 2)
    g0, g1 = nominal.tendon_drive.gains, w.tendon_drive.gains
    for ratio in (g1.kp / g0.kp, g1.kd / g0.kd):
        assert lo - 1e-12 <= ratio.min() and ratio.max() <= hi + 1e-12
        assert np.ptp(ratio) > 0.2 * perturb.ACTUATION_FACTOR * scale
    acts = nominal.tendon_drive.layout.actuators
    lag = w.model.actuator_dynprm[acts, 0] / nominal.model.actuator_dynprm[acts, 0]
    assert lo - 1e-12 <= lag.min() and lag.max() <= hi + 1e-12
    # the perturbed drive is the one that steps the hand
    w.step(5)
    assert w.tendon_drive is not nominal.tendon_drive


def test_servo_hand_gains(scene) -> None:
    p = draw(PerturbSpec.parse("actuation"), 1, scene.block_names)
    w0 = World.build(scene, hand="servo")
    w1 = World.build(scene, hand="servo", perturbation=p)
    idx = w0._idx.hand_ctrl
    ratio = w1.model.actuator_gainprm[idx, 0] / w0.model.actuator_gainprm[idx, 0]
    np.testing.assert_allclose(ratio, p.kp_factors)
    np.testing.assert_allclose(
        w1.model.actuator_biasprm[idx, 2] / w0.model.actuator_biasprm[idx, 2], p.kd_factors
    )


def test_summary_record(scene) -> None:
    p = draw(PerturbSpec.parse("woes"), 11, scene.block_names)
    rec = p.to_json()
    assert rec["asked"] == ",".join(f"{k}=1" for k in KINDS) and rec["seed"] == 11
    assert set(rec) >= {*KINDS, "asked", "scales", "seed"}
    assert rec["camera"]["shift_mm"] <= 10.0 and rec["camera"]["turn_deg"] <= 1.0
    assert set(rec["object"]["mass_factors"]) == set(scene.block_names)


def test_model_state_layout_is_unchanged(scene, nominal) -> None:
    w = _perturbed(scene, "woes=2", 5)
    assert (w.model.nq, w.model.nv, w.model.nu, w.model.nbody) == (
        nominal.model.nq,
        nominal.model.nv,
        nominal.model.nu,
        nominal.model.nbody,
    )
    mujoco.mj_forward(w.model, w.data)
    w.step(200)  # stable
