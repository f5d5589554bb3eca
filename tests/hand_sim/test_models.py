"""The MJCF models in models/: they load and step cleanly, every servo reaches its target, the
fingertip touch sensors work, and a balanced grasp found by benchmarks.hand_reachability holds a
0.3 kg block when the hand lifts it."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from benchmarks import hand_reachability as reach
from benchmarks.lift_rig import LIFT, LIFT_STEPS, LIFT_TIME, SERVO_HAND, SQUEEZE, lift_rig

MODELS = Path(__file__).resolve().parents[2] / "models"
MODEL_FILES = ("hand.xml", "hand_scene.xml", "arm.xml", "table.xml")
FINGERS = ("ff", "mf", "rf", "th")
HAND_ACTUATORS = tuple(f"{f}a{i}" for f in FINGERS for i in range(4))
ARM_JOINTS = ("waist", "shoulder", "elbow", "wrist_pitch", "wrist_roll")

#: Servo tolerances (rad) after settling: fingers under their own weight, arm carrying the hand
#: and a 0.35 kg payload.
HAND_TOLERANCE = 0.03
ARM_TOLERANCE = 0.01
PAYLOAD_MASS = 0.35


def _load(name: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_path(str(MODELS / name))
    return model, mujoco.MjData(model)


def _step_clean(model: mujoco.MjModel, data: mujoco.MjData, seconds: float) -> None:
    """Step ``seconds`` of sim time; fail on NaN or on any MuJoCo warning."""
    mujoco.mj_step(model, data, nstep=round(seconds / model.opt.timestep))
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    raised = {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(data.warning) if w.number}
    assert not raised, f"MuJoCo warnings: {raised}"


def _arm_with_hand(payload: float = PAYLOAD_MASS) -> mujoco.MjModel:
    """arm.xml with hand.xml attached at the flange (names prefixed ``hand/``) and a payload
    sphere held 5 cm in front of the palm."""
    arm = mujoco.MjSpec.from_file(str(MODELS / "arm.xml"))
    hand = mujoco.MjSpec.from_file(str(MODELS / "hand.xml"))
    arm.attach(hand, site=arm.site("attachment_site"), prefix="hand/")
    if payload > 0.0:
        palm = arm.body("hand/palm")
        body = palm.add_body(name="payload", pos=[0.0, 0.0, 0.075])
        body.add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[0.02, 0, 0],
            mass=payload,
            contype=0,
            conaffinity=0,
        )
    return arm.compile()


@pytest.mark.parametrize("name", MODEL_FILES)
def test_model_loads_and_steps_one_second(name: str) -> None:
    model, data = _load(name)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    _step_clean(model, data, 1.0)


def test_hand_has_the_named_elements() -> None:
    model, _ = _load("hand.xml")
    assert (model.nq, model.nu) == (16, 16)
    for f in FINGERS:
        for part in ("proximal", "middle", "distal"):
            model.body(f"{f}_{part}")
        model.site(f"{f}_tip")
        assert model.sensor(f"{f}_touch").type == mujoco.mjtSensor.mjSENS_TOUCH
        for i in range(4):
            # Every servo acts on the joint of the same finger and index.
            assert model.actuator(f"{f}a{i}").trnid[0] == model.joint(f"{f}j{i}").id
    model.body("palm")
    model.site("mount")


@pytest.mark.parametrize("actuator", HAND_ACTUATORS)
def test_hand_servo_reaches_target(actuator: str) -> None:
    model, data = _load("hand_scene.xml")
    act = model.actuator(actuator)
    joint = model.joint(act.trnid[0])
    lo, hi = act.ctrlrange
    if actuator.endswith("0"):
        # Abduct with the finger raised (MCP flexed): extended fingers would hit their neighbours.
        data.ctrl[model.actuator(actuator[:2] + "a1").id] = 1.4
    for target in (lo + 0.25 * (hi - lo), lo + 0.75 * (hi - lo)):
        data.ctrl[act.id] = target
        _step_clean(model, data, 1.0)
        assert abs(data.qpos[joint.qposadr[0]] - target) < HAND_TOLERANCE


def test_hand_stays_stable_under_random_and_extreme_targets() -> None:
    """Random servo targets (fingers colliding with each other) and every joint at either end of
    its range: no warning, no NaN, and the hand comes to rest."""
    model, data = _load("hand_scene.xml")
    rng = np.random.default_rng(0)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    for _ in range(10):
        data.ctrl[:] = rng.uniform(lo, hi)
        _step_clean(model, data, 0.5)
    for end in (lo, hi):
        data.ctrl[:] = end
        _step_clean(model, data, 1.0)
    assert np.abs(data.qvel).max() < 0.01


def test_arm_home_keyframe_exists() -> None:
    model, data = _load("arm.xml")
    key = model.key("home")
    mujoco.mj_resetDataKeyframe(model, data, key.id)
    np.testing.assert_allclose(key.ctrl, key.qpos[:5])
    model.site("attachment_site")


#: Arm postures: parked, and reaching far over the table with the tool pointing down.
ARM_POSTURES = {
    "home": np.array([0.0, -0.9, -1.6, -0.64, 0.0]),
    "far_top": np.array([0.3, 1.0, 1.2, np.pi - 2.2, 0.5]),
}


@pytest.mark.parametrize("posture", sorted(ARM_POSTURES))
@pytest.mark.parametrize("joint", ARM_JOINTS)
def test_arm_servo_reaches_target_with_hand_and_payload(posture: str, joint: str) -> None:
    model = _arm_with_hand()
    data = mujoco.MjData(model)
    q0 = ARM_POSTURES[posture]
    data.qpos[:5] = q0
    data.ctrl[:5] = q0
    target = q0.copy()
    target[ARM_JOINTS.index(joint)] += 0.3
    data.ctrl[:5] = target
    _step_clean(model, data, 2.0)
    np.testing.assert_allclose(data.qpos[:5], target, atol=ARM_TOLERANCE)


def _hand_between_plates() -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The hand (palm up) with fixed plates 4 cm above the fingers and the thumb."""
    spec = mujoco.MjSpec.from_file(str(MODELS / "hand_scene.xml"))
    for name, y in (("finger_plate", 0.13), ("thumb_plate", -0.12)):
        spec.worldbody.add_geom(
            name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.08, 0.03, 0.005], pos=[0.0, y, 0.055]
        )
    model = spec.compile()
    return model, mujoco.MjData(model)


def test_touch_sensors_zero_in_free_space_and_positive_against_a_box() -> None:
    model, data = _hand_between_plates()
    touch = [model.sensor(f"{f}_touch").id for f in FINGERS]
    _step_clean(model, data, 0.3)
    np.testing.assert_array_equal(data.sensordata[touch], 0.0)
    for f in FINGERS:  # flex the MCPs: every fingertip pad presses on a plate
        data.ctrl[model.actuator(f"{f}a1").id] = 0.9
    _step_clean(model, data, 1.0)
    assert np.all(data.sensordata[touch] > 0.1), data.sensordata[touch]


def test_touch_sensor_ignores_contacts_away_from_the_tip() -> None:
    """A plate touching only the proximal links leaves the tip sensors at zero."""
    spec = mujoco.MjSpec.from_file(str(MODELS / "hand_scene.xml"))
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.08, 0.01, 0.005], pos=[0.0, 0.075, 0.028]
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    for f in ("ff", "mf", "rf"):
        data.ctrl[model.actuator(f"{f}a1").id] = 0.6
    _step_clean(model, data, 1.0)
    assert data.ncon > 0
    for f in FINGERS:
        assert data.sensor(f"{f}_touch").data[0] == 0.0


# --- a balanced grasp holds a block ----------------------------------------------------------


def _grasp_world(found: reach.GraspFound, poly_name: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """benchmarks.lift_rig with hand.xml; hand servos at the found configuration + SQUEEZE."""
    model, data = lift_rig(found, SERVO_HAND, poly_name)
    target = found.qpos.copy()
    for f in range(4):
        target[4 * f + 1 : 4 * f + 4] += SQUEEZE
    data.ctrl[[model.actuator(f"hand/{a}").id for a in HAND_ACTUATORS]] = target
    mujoco.mj_forward(model, data)
    return model, data


@pytest.mark.parametrize("kind", ["top", "lateral"])
def test_balanced_grasp_lifts_a_wood_block(kind: str) -> None:
    """The reachability search finds a balanced (S_G < 0.2) grasp of the 4 cm square prism;
    closing the fingers 0.15 rad past it and lifting 8 cm carries a 0.3 kg block (< 3 mm slip)."""
    hs = reach.sample_hand(3000, np.random.default_rng(0))
    best, found = reach.evaluate("square", kind, hs, np.array([0.0]))
    assert found is not None and best[0] < 0.2
    model, data = _grasp_world(found, "square")
    z0 = data.body("block").xpos[2]
    _step_clean(model, data, 0.5)
    touch = np.array([data.sensor(f"hand/{f}_touch").data[0] for f in FINGERS])
    assert np.count_nonzero(touch > 0.1) >= 3, touch
    lift = model.actuator("lift").id
    for k in range(1, LIFT_STEPS + 1):  # a smooth lift, as an arm trajectory would be
        data.ctrl[lift] = LIFT * k / LIFT_STEPS
        _step_clean(model, data, LIFT_TIME / LIFT_STEPS)
    _step_clean(model, data, 1.0)
    hand_rise = data.qpos[model.joint("lift").qposadr[0]]
    block_rise = data.body("block").xpos[2] - z0
    assert hand_rise == pytest.approx(LIFT, abs=0.005)
    assert abs(block_rise - hand_rise) < 0.003
