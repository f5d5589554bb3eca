"""controllers.hand.tendon_control: the tension allocation keeps every tension in [T0, T_max] and
gives the requested torque (clipped at r (T_max - T0)); the torque estimate from the tensions is
its inverse; the gains are models/hand.xml's servos' and the tendon hand can deliver their
torques; the closed loop tracks joint targets on the hand alone; a step smaller than the
stiction band does not move the joint."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from controllers.hand.tendon_control import (
    PRETENSION,
    SERVO_KP,
    SERVO_TORQUE_LIMIT,
    PDGains,
    TendonHandController,
    TendonLayout,
    allocate_tensions,
    joint_torques,
    torque_limit,
)
from hand_sim import robot

MODELS = Path(__file__).resolve().parents[2] / "models"
HAND = MODELS / "utah_mit_hand" / "utah_mit_hand.xml"
SCENE = MODELS / "utah_mit_hand" / "scene.xml"
#: Tracking tolerance (rad) of the closed loop with gravity: joint friction / kp (0.05 / 3.6 =
#: 0.014 at the DIP, the stiction band: the loop stops anywhere inside it) and a margin.
TRACKING_TOLERANCE = 0.02


def _model(path: Path = SCENE) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(path))


def test_allocation_keeps_tensions_in_range_and_gives_the_torque() -> None:
    rng = np.random.default_rng(0)
    radius = rng.uniform(0.005, 0.012, 200)
    t_max = rng.uniform(100.0, 900.0, 200)
    limit = torque_limit(radius, t_max)
    torque = rng.uniform(-1.5, 1.5, 200) * limit  # a third beyond the limit
    cmd = allocate_tensions(torque, radius, t_max)
    assert np.all(cmd.flex >= PRETENSION) and np.all(cmd.ext >= PRETENSION)
    assert np.all(cmd.flex <= t_max + 1e-9) and np.all(cmd.ext <= t_max + 1e-9)
    # Only one tendon of a pair pulls above the pretension, the one the torque's sign picks.
    assert np.all(np.minimum(cmd.flex, cmd.ext) == PRETENSION)
    assert np.all((cmd.flex > PRETENSION) == (torque > 0))
    delivered = joint_torques(cmd.flex, cmd.ext, radius)
    np.testing.assert_allclose(delivered, np.clip(torque, -limit, limit))
    np.testing.assert_allclose(delivered, cmd.torque)
    np.testing.assert_array_equal(cmd.saturated, np.abs(torque) > limit)


def test_allocation_refuses_impossible_parameters() -> None:
    with pytest.raises(ValueError):
        allocate_tensions([1.0], [0.0], [800.0])
    with pytest.raises(ValueError):
        allocate_tensions([1.0], [0.008], [5.0], pretension=10.0)


def test_layout_reads_the_model() -> None:
    layout = TendonLayout.from_model(_model(HAND))
    np.testing.assert_allclose(layout.radius, 0.008)
    np.testing.assert_allclose(layout.max_tension, 800.0)
    assert len(set(layout.actuators)) == 32


def test_layout_refuses_a_tendon_that_pushes() -> None:
    xml = HAND.read_text().replace('gear="-1"', 'gear="1"')
    model = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(ValueError, match="pull"):
        TendonLayout.from_model(model)


def test_gains_are_the_servo_hands_and_the_tendons_can_deliver_them() -> None:
    """SERVO_KP / SERVO_TORQUE_LIMIT are models/hand.xml's servo gains and force ranges, and
    r (T_max - T0) covers every one of those force ranges."""
    servo = _model(MODELS / "hand.xml")
    model = _model(HAND)
    layout = TendonLayout.from_model(model)
    gains = PDGains.servo_equivalent(model, layout)
    for k, name in enumerate(robot.HAND_ACTUATORS):
        act = servo.actuator(name)
        assert act.gainprm[0] == pytest.approx(SERVO_KP[k % 4])
        assert act.forcerange[1] == pytest.approx(SERVO_TORQUE_LIMIT[k % 4])
    assert np.all(torque_limit(layout.radius, layout.max_tension) >= gains.torque_limit)
    assert np.all(gains.kd > 0.0)


def test_the_loop_tracks_random_targets() -> None:
    """Seeded random targets inside the joint ranges (with gravity, palm up): after 0.6 s every
    joint is within TRACKING_TOLERANCE of its target, and every commanded tension stayed within
    [T0, T_max]."""
    model = _model()
    data = mujoco.MjData(model)
    ctrl = TendonHandController.for_model(model)
    ranges = np.array([model.joint(j).range for j in robot.HAND_JOINTS])
    rng = np.random.default_rng(3)
    for _ in range(3):
        lo, hi = ranges[:, 0] + 0.1, ranges[:, 1] - 0.1
        target = rng.uniform(lo, hi)
        log = ctrl.run(data, target, 0.6).arrays()
        error = np.abs(ctrl.layout.angles(data) - target)
        assert error.max() < TRACKING_TOLERANCE, robot.HAND_JOINTS[int(error.argmax())]
        assert log["commanded"].min() >= PRETENSION
        assert log["commanded"].max() <= 800.0
    assert not any(w.number for w in data.warning)


def test_the_loop_estimates_its_own_torques_from_the_tension_sensors() -> None:
    """Once the tensions have settled, r (T_flex - T_ext) of the sensed tensions is the torque
    the loop asked for (within 1 %)."""
    model = _model()
    model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    ctrl = TendonHandController.for_model(model)
    target = np.tile([0.3, 0.8, 0.6, 0.5], 4)
    cmd = allocate_tensions(np.linspace(-2.0, 2.0, 16), ctrl.layout.radius, ctrl.layout.max_tension)
    ctrl.apply(data, cmd)
    mujoco.mj_step(model, data, nstep=40)  # the hand moves; the tensions settle in 80 ms
    estimate = joint_torques(*ctrl.layout.tensions(data), ctrl.layout.radius)
    np.testing.assert_allclose(estimate, cmd.torque, rtol=0.01, atol=1e-6)
    ctrl.run(data, target, 0.5)
    assert np.abs(ctrl.layout.angles(data) - target).max() < TRACKING_TOLERANCE


def test_a_step_inside_the_stiction_band_does_not_move_the_joint() -> None:
    """Without gravity, at rest on target: a step of the MCP target whose PD torque (kp x step)
    is below the joint friction leaves the joint where it is (the loop sticks), a step twice
    the friction moves it to within friction / kp of the target."""
    model = _model()
    model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    ctrl = TendonHandController.for_model(model)
    k = robot.HAND_JOINTS.index("mfj1")
    friction = model.dof_frictionloss[ctrl.layout.dof_adr[k]]
    kp = ctrl.gains.kp[k]
    target = np.tile([0.0, 0.6, 0.5, 0.4], 4)
    ctrl.run(data, target, 0.5)
    start = ctrl.layout.angles(data)[k]
    small = target.copy()
    small[k] = start + 0.7 * friction / kp
    ctrl.run(data, small, 0.3)
    assert abs(ctrl.layout.angles(data)[k] - start) < 0.1 * friction / kp
    large = target.copy()
    large[k] = start + 2.0 * friction / kp
    ctrl.run(data, large, 0.3)
    moved = ctrl.layout.angles(data)[k] - start
    assert moved > 0.9 * friction / kp
    assert abs(ctrl.layout.angles(data)[k] - large[k]) <= 1.05 * friction / kp
