"""Tests of the tendon hand in the world (World.build(hand="tendon"), issue 24): it holds a
posture and tracks its joint targets with the PD -> tensions loop closed at every physics step,
every tension stays within [pretension, T_max], the recording logs the 32 tensions, and the
servo hand's world is the one it was (same actuators, World.step the plain mj_step)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from fsm.recording import EpisodeRecorder
from hand_sim import robot
from hand_sim.errors import HandSimError
from hand_sim.recorder import read_recording
from hand_sim.scene import load_scene
from hand_sim.telemetry import series_names, tendon_series_names
from hand_sim.tendon_drive import PRETENSION
from hand_sim.world import TIMESTEP, World

ONE_SECOND = round(1.0 / TIMESTEP)
#: Tracking tolerance (rad) after 1 s: the tendons' stiction (frictionloss 0.05 N m) over the
#: PD stiffness leaves up to 0.05 / 3.6 = 14 mrad at a DIP joint, plus the fingers' sag.
TRACK_TOL = 0.025
#: A still hand's joints drift less than this (rad) in 1 s.
HOLD_TOL = 0.005
#: The tension sensors read the actuators' force, which follows the command with a 5 ms lag:
#: within [T0, T_max] up to float rounding.
TENSION_EPS = 1e-6
#: A posture inside every joint range (per finger: abduction, MCP, PIP, DIP; rad).
POSTURE = np.tile([0.15, 0.6, 0.7, 0.4], len(robot.FINGERS))


@pytest.fixture(scope="module")
def built() -> World:
    return World.build(load_scene("clutter3"), hand="tendon")


@pytest.fixture
def world(built: World) -> World:
    built.reset()
    built.on_step = None
    return built


def _step_checking_tensions(world: World, steps: int) -> tuple[float, float]:
    """Step one physics step at a time; the lowest and highest tension seen."""
    t_max = float(world.tendon_drive.layout.max_tension.max())
    lo, hi = np.inf, -np.inf
    for _ in range(steps):
        world.step(1)
        tensions = world.hand_tensions()
        lo, hi = min(lo, float(tensions.min())), max(hi, float(tensions.max()))
    assert lo >= PRETENSION - TENSION_EPS and hi <= t_max + TENSION_EPS, (lo, hi)
    return lo, hi


def test_tendon_world_has_the_tendon_hand_and_target_registers(world: World) -> None:
    m = world.model
    assert world.hand == "tendon" and world.tendon_drive is not None
    assert len(world.tendon_drive.layout.actuators) == 32
    # the 16 joint targets sit in disabled registers with the servo hand's names and ranges
    idx = [m.actuator(robot.qualified(n)).id for n in robot.HAND_ACTUATORS]
    assert set(m.actuator_group[idx]) == {5} and m.opt.disableactuator == 1 << 5
    joints = [m.joint(robot.qualified(j)).id for j in robot.HAND_JOINTS]
    np.testing.assert_allclose(world.hand_ctrlrange(), m.jnt_range[joints], atol=1e-12)
    world.set_hand_targets(POSTURE)
    world.step(10)
    np.testing.assert_array_equal(world.data.actuator_force[idx], 0.0)
    np.testing.assert_array_equal(world.hand_targets(), POSTURE)


def test_tendon_hand_holds_its_posture_for_one_second(world: World) -> None:
    q0 = world.hand_qpos()
    _, hi = _step_checking_tensions(world, ONE_SECOND)  # SimulationError on NaN / warnings
    assert world.time == pytest.approx(1.0)
    assert hi < 2 * PRETENSION  # holding the fingers up takes little more than the pretension
    assert np.abs(world.hand_qpos() - q0).max() < HOLD_TOL
    assert np.all(np.isfinite(world.data.qpos))


def test_tendon_hand_tracks_its_targets(world: World) -> None:
    world.set_hand_targets(POSTURE)
    _, hi = _step_checking_tensions(world, ONE_SECOND)
    err = np.abs(world.hand_qpos() - POSTURE)
    assert err.max() < TRACK_TOL, err
    assert hi > 2 * PRETENSION  # the move did pull on the tendons
    # the joint torques are the pairs' tensions over their pulleys: tau = r (T_flex - T_ext)
    t = world.hand_tensions()
    tau = world.tendon_drive.layout.radius * (t[:, 0] - t[:, 1])
    np.testing.assert_allclose(world.hand_joint_torques(), tau, atol=1e-9)


def test_tendon_recording_logs_the_32_tensions(tmp_path: Path, world: World) -> None:
    path = tmp_path / "episode.rrd"
    with EpisodeRecorder(path, world) as rec:
        world.on_step = rec.tick
        world.set_hand_targets(POSTURE)
        for _ in range(20):
            world.step(10)
    got = read_recording(path)
    names = tendon_series_names()
    assert len(names) == 32 and names[:2] == ["tendon/ff/j0_flex", "tendon/ff/j0_ext"]
    assert set(names) <= set(series_names("tendon")) and not set(names) & set(series_names())
    for name in series_names("tendon"):
        assert got[f"/scalars/{name}"]["Scalars:scalars"] > 1, name


def test_servo_world_is_unchanged() -> None:
    """The servo hand's world (``hand="servo"``): the 5 arm and 16 hand position servos as
    before, no tendon loop, and World.step is MuJoCo's own stepping of the same model."""
    scene = load_scene("clutter3")
    world = World.build(scene, hand="servo")
    m = world.model
    assert world.hand == "servo" and world.tendon_drive is None and m.ntendon == 0
    names = [m.actuator(i).name for i in range(m.nu)]
    assert names == [robot.qualified(n) for n in (*robot.ARM_ACTUATORS, *robot.HAND_ACTUATORS)]
    assert m.opt.disableactuator == 0
    with pytest.raises(HandSimError, match="no tendons"):
        world.hand_tensions()
    twin = World.build(scene, hand="servo")
    targets = world.hand_targets() + 0.2
    world.set_hand_targets(targets)
    twin.set_hand_targets(targets)
    world.step(100)
    mujoco.mj_step(twin.model, twin.data, nstep=100)
    np.testing.assert_array_equal(world.data.qpos, twin.data.qpos)
    np.testing.assert_array_equal(world.data.qvel, twin.data.qvel)


def test_an_unknown_hand_is_refused() -> None:
    with pytest.raises(HandSimError, match="unknown hand 'banana'; valid: servo, tendon"):
        World.build(load_scene("clutter3"), hand="banana")


def test_the_drives_step_is_command_then_apply_bit_for_bit() -> None:
    """TendonDrive.step (constants computed once, the two clips merged) takes exactly the steps
    that computing each step's TensionCommand (the PD torque, its clip, allocate_tensions) and
    writing it would: the same qpos and tensions to the last bit, the fingers moving against
    the block and their torques clipped (targets far outside reach) on the way."""
    scene = load_scene("clutter3")
    fast, slow = World.build(scene, hand="tendon"), World.build(scene, hand="tendon")
    drive = fast.tendon_drive
    rng = np.random.default_rng(3)
    clipped = False
    for _ in range(12):
        target = rng.uniform(-2.0, 2.5, 16)  # beyond the ranges: the torques are clipped
        limit = drive.gains.torque_limit
        clipped |= bool(np.any(np.abs(drive.command(slow.data, target).torque) >= limit))
        drive.step(fast.model, fast.data, target, 15)
        for _ in range(15):
            drive.apply(slow.data, drive.command(slow.data, target))
            mujoco.mj_step(slow.model, slow.data)
        np.testing.assert_array_equal(fast.data.qpos, slow.data.qpos)
        np.testing.assert_array_equal(fast.data.ctrl, slow.data.ctrl)
        np.testing.assert_array_equal(fast.data.actuator_force, slow.data.actuator_force)
    assert clipped
    assert float(np.abs(fast.hand_qpos() - POSTURE).max()) > 0.1  # the hand moved
