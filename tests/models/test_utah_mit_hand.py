"""models/utah_mit_hand: the tendon-driven Utah/MIT hand (issue 24). Its names and kinematics are
those of models/hand.xml; each of its 32 tendons turns its joint the right way and only pulls; the
tension sensors read the tendons' forces; a joint holds a load up to r T_max and gives way above;
joint friction makes it stick until the torque exceeds the friction; the closed-loop hand steps a
grasp motion cleanly; it attaches to the arm as hand_sim attaches hand.xml; and the servo hand's
balanced grasp, held by the tendons, lifts a block."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest
from dm_control import mjcf

from benchmarks import hand_reachability as reach
from benchmarks.lift_rig import LIFT, LIFT_STEPS, LIFT_TIME, SQUEEZE, TENDON_HAND, lift_rig
from controllers.hand.tendon_control import TendonHandController, TendonLayout
from hand_sim import robot

MODELS = Path(__file__).resolve().parents[2] / "models"
HAND = TENDON_HAND
SCENE = MODELS / "utah_mit_hand" / "scene.xml"
SIDES = ("flex", "ext")
#: The model's stated parameters (README.md): pulley radius (m), maximum tension (N), joint
#: friction (N m).
RADIUS, T_MAX, FRICTION = 0.008, 800.0, 0.05


def _load(path: Path = HAND, gravity: bool = False) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_path(str(path))
    if not gravity:
        model.opt.gravity[:] = 0.0
    return model, mujoco.MjData(model)


def _warnings(data: mujoco.MjData) -> dict[str, int]:
    return {mujoco.mjtWarning(i).name: w.number for i, w in enumerate(data.warning) if w.number}


def _mid_range(model: mujoco.MjModel, data: mujoco.MjData, layout: TendonLayout) -> None:
    """Every hand joint at the middle of its range, at rest."""
    for k, name in enumerate(layout.joints):
        data.qpos[layout.qpos_adr[k]] = model.joint(name).range.mean()
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)


def _names(model: mujoco.MjModel, kind: mujoco.mjtObj, count: int) -> set[str]:
    return {n for i in range(count) if (n := mujoco.mj_id2name(model, kind, i))}


def test_names_and_kinematics_are_those_of_hand_xml() -> None:
    tendon, _ = _load()
    servo, _ = _load(MODELS / "hand.xml")
    obj = mujoco.mjtObj
    for kind, count in (
        (obj.mjOBJ_BODY, "nbody"),
        (obj.mjOBJ_JOINT, "njnt"),
        (obj.mjOBJ_SITE, "nsite"),
        (obj.mjOBJ_GEOM, "ngeom"),
    ):
        assert _names(servo, kind, getattr(servo, count)) <= _names(
            tendon, kind, getattr(tendon, count)
        ), kind
    for name in robot.HAND_JOINTS:
        np.testing.assert_array_equal(tendon.joint(name).range, servo.joint(name).range)
        np.testing.assert_array_equal(tendon.joint(name).axis, servo.joint(name).axis)
    for f in robot.FINGERS:
        for link in ("proximal", "middle", "distal"):
            a, b = tendon.body(f"{f}_{link}"), servo.body(f"{f}_{link}")
            np.testing.assert_allclose(a.pos, b.pos)
            np.testing.assert_allclose(a.quat, b.quat)  # ff and rf keep hand.xml's splay
            np.testing.assert_allclose(a.mass, b.mass)
    assert tendon.ntendon == tendon.nu == 32
    assert tendon.nsensor == 16 + 32 + servo.nsensor


def test_every_tendon_turns_its_joint_the_right_way_alone() -> None:
    model, data = _load()
    layout = TendonLayout.from_model(model)
    pull = 50.0  # N: 0.4 N m, eight times the joint friction
    for k, joint in enumerate(layout.joints):
        for side, sign in zip(SIDES, (1.0, -1.0), strict=True):
            mujoco.mj_resetData(model, data)
            _mid_range(model, data, layout)
            q0 = layout.angles(data)
            data.ctrl[:] = 0.0
            data.ctrl[getattr(layout, f"{side}_actuator")[k]] = pull
            mujoco.mj_step(model, data, nstep=25)
            moved = layout.angles(data) - q0
            assert sign * moved[k] > 0.02, f"{joint}_{side} moved its joint by {moved[k]:+.4f}"
            others = np.delete(moved, k)
            assert np.abs(others).max() < 0.5 * abs(moved[k]), f"{joint}_{side} moved others"


def test_tendon_forces_are_never_negative() -> None:
    """Random commands, half of them negative or above T_max: every actuator force stays in
    [0, T_max] at every step, with gravity, joints going to their limits."""
    model, data = _load(SCENE, gravity=True)
    rng = np.random.default_rng(24)
    lowest, highest = np.inf, -np.inf
    for _ in range(100):
        data.ctrl[:] = rng.uniform(-T_MAX, 2 * T_MAX, model.nu) * rng.integers(0, 2, model.nu)
        for _ in range(5):
            mujoco.mj_step(model, data)
            lowest = min(lowest, data.actuator_force.min())
            highest = max(highest, data.actuator_force.max())
    assert lowest >= 0.0
    assert highest <= T_MAX
    assert highest > 0.5 * T_MAX  # the commands did reach the actuators
    assert np.all(np.isfinite(data.qpos))


def test_tension_sensors_read_the_tendon_forces() -> None:
    """Held random tensions: each sensor reads its commanded tension (after the actuator's lag)
    within 1 %, and the joint torque MuJoCo applies is r (T_flex - T_ext) of the sensed tensions
    within 1 %."""
    model, data = _load()
    layout = TendonLayout.from_model(model)
    rng = np.random.default_rng(7)
    _mid_range(model, data, layout)
    for _ in range(3):
        tension = rng.uniform(5.0, 60.0, model.nu)
        data.ctrl[layout.actuators] = tension
        mujoco.mj_step(model, data, nstep=40)  # 80 ms: 16 actuator time constants
        flex, ext = layout.tensions(data)
        sensed = np.column_stack((flex, ext)).ravel()
        np.testing.assert_allclose(sensed, tension, rtol=0.01)
        np.testing.assert_allclose(sensed, data.actuator_force[layout.actuators], rtol=0.01)
        torque = data.qfrc_actuator[layout.dof_adr]
        np.testing.assert_allclose(torque, RADIUS * (flex - ext), rtol=0.01, atol=1e-9)


@pytest.mark.parametrize("side", SIDES)
def test_a_joint_holds_up_to_r_tmax_and_gives_way_above(side: str) -> None:
    """One tendon at T_max against an external torque on its joint (qfrc_applied): at 0.9 r T_max
    the joint does not give way, at 1.1 r T_max it is driven back to its limit."""
    model, data = _load()
    layout = TendonLayout.from_model(model)
    sign = 1.0 if side == "flex" else -1.0
    limit = RADIUS * T_MAX  # 6.4 N m
    for k, joint in enumerate(layout.joints):
        for factor, holds in ((0.9, True), (1.1, False)):
            mujoco.mj_resetData(model, data)
            _mid_range(model, data, layout)
            q0 = layout.angles(data)[k]
            data.ctrl[getattr(layout, f"{side}_actuator")[k]] = T_MAX
            data.act[:] = data.ctrl  # the tension is already up when the load comes on
            data.qfrc_applied[layout.dof_adr[k]] = -sign * factor * limit
            mujoco.mj_step(model, data, nstep=100)
            q = layout.angles(data)[k]
            if holds:
                assert sign * (q - q0) > 0.0, f"{joint}_{side} gave way at {factor} r Tmax"
            else:
                lo, hi = model.joint(joint).range
                # MuJoCo's joint limits are soft: 6.4 N m pushes a joint a little past them.
                assert q == pytest.approx(lo if sign > 0 else hi, abs=0.05), joint
    assert not _warnings(data)


def test_stiction_holds_the_joint_until_the_torque_exceeds_the_friction() -> None:
    """A slow ramp of one flexor's tension (the extensor at 10 N): the joint does not move while
    the net torque r (T_flex - T_ext) is below the joint friction, and moves once it is above."""
    model, data = _load()
    layout = TendonLayout.from_model(model)
    for k in range(4):  # ff's four joints; the others are the same joints
        mujoco.mj_resetData(model, data)
        _mid_range(model, data, layout)
        q0 = layout.angles(data)[k]
        torque, angle = [], []
        for step in range(400):  # 0.8 s, torque 0 -> 0.1 N m (twice the friction)
            t = 10.0 + 12.5 * step / 400
            data.ctrl[layout.flex_actuator[k]] = t
            data.ctrl[layout.ext_actuator[k]] = 10.0
            mujoco.mj_step(model, data)
            flex, ext = layout.tensions(data)
            torque.append(RADIUS * (flex[k] - ext[k]))
            angle.append(layout.angles(data)[k] - q0)
        torque, angle = np.asarray(torque), np.asarray(angle)
        below, above = torque < 0.9 * FRICTION, torque > 1.2 * FRICTION
        assert np.abs(angle[below]).max() < 1e-3, "the joint crept below the friction"
        assert angle[-1] > 0.01, "the joint did not break away"
        moving = np.flatnonzero(angle > 2e-3)[0]
        assert 0.9 * FRICTION < torque[moving] < 1.2 * FRICTION
        assert above[-1]


def test_pd_grasp_motion_steps_cleanly() -> None:
    """2 s of a closed-loop close-and-open motion (with gravity): no MuJoCo warning, no NaN, the
    tensions within [0, T_max]."""
    model, data = _load(SCENE, gravity=True)
    ctrl = TendonHandController.for_model(model)
    open_q = np.zeros(16)
    closed = np.tile([0.0, 1.3, 1.2, 0.9], 4)

    def target(t: float) -> np.ndarray:
        s = 0.5 - 0.5 * np.cos(np.pi * min(t, 2.0))  # 0 -> 1 -> 0 over 2 s
        return open_q + s * (closed - open_q)

    log = ctrl.run(data, target, 2.0).arrays()
    assert not _warnings(data)
    assert np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    assert log["measured"].min() >= 0.0 and log["measured"].max() <= T_MAX
    mid = np.argmin(np.abs(log["time"] - 1.0))
    np.testing.assert_allclose(log["angles"][mid], closed, atol=0.05)


def test_it_attaches_to_the_arm_as_hand_sim_attaches_hand_xml() -> None:
    """dm_control parses the model (its schema knows every element used) and attaches it at the
    arm's flange the way hand_sim.assembly does; the controller finds its 16 joints, 32 tendons
    and sensors under hand_sim's prefix, with the model's parameters intact."""
    arm = mjcf.from_path(str(MODELS / "arm.xml"))
    arm.model = robot.ARM_MODEL
    for key in list(arm.keyframe.all_children()):
        key.remove()
    hand = mjcf.from_path(str(HAND))
    hand.model = robot.HAND_MODEL
    arm.find("site", robot.ATTACHMENT_SITE).attach(hand)
    root = mjcf.RootElement(model="tendon_hand_on_arm")
    root.attach(arm)
    model = mjcf.Physics.from_mjcf_model(root).model.ptr
    layout = TendonLayout.from_model(model, prefix=robot.HAND_PREFIX)
    np.testing.assert_allclose(layout.radius, RADIUS)
    np.testing.assert_allclose(layout.max_tension, T_MAX)
    np.testing.assert_allclose(model.dof_frictionloss[layout.dof_adr], FRICTION)
    assert model.nu == 32 + len(robot.ARM_ACTUATORS)


# --- the servo hand's balanced grasp, held by the tendons -------------------------------------


@pytest.mark.parametrize("kind", ["top", "lateral"])
def test_the_balanced_grasp_lifts_a_wood_block_on_tendons(kind: str) -> None:
    """The grasp tests/hand_sim/test_models.py lifts with hand.xml's servos (the reachability
    search's balanced grasp of the square, S_G < 0.2, closed 0.15 rad past contact), here held by
    the tendon loop: at least three pads press, the tensions stay within [T0, T_max], and an 8 cm
    lift carries the 0.3 kg block with it (< 3 mm slip)."""
    hs = reach.sample_hand(3000, np.random.default_rng(0), HAND)
    best, found = reach.evaluate("square", kind, hs, np.array([0.0]))
    assert found is not None and best[0] < 0.2
    model, data = lift_rig(found, HAND)
    ctrl = TendonHandController.for_model(model, prefix="hand/")
    target = found.qpos.copy()
    for f in range(len(robot.FINGERS)):
        target[4 * f + 1 : 4 * f + 4] += SQUEEZE
    z0 = data.body("block").xpos[2]
    log = ctrl.run(data, target, 0.5)
    touch = np.array([data.sensor(f"hand/{f}_touch").data[0] for f in robot.FINGERS])
    assert np.count_nonzero(touch > 0.1) >= 3, touch
    lift = model.actuator("lift").id
    for k in range(1, LIFT_STEPS + 1):  # a smooth lift, as an arm trajectory would be
        data.ctrl[lift] = LIFT * k / LIFT_STEPS
        ctrl.run(data, target, LIFT_TIME / LIFT_STEPS, log)
    ctrl.run(data, target, 1.0, log)
    assert not _warnings(data)
    hand_rise = data.qpos[model.joint("lift").qposadr[0]]
    block_rise = data.body("block").xpos[2] - z0
    assert hand_rise == pytest.approx(LIFT, abs=0.005)
    assert abs(block_rise - hand_rise) < 0.003
    commanded = np.asarray(log.commanded)
    assert commanded.min() >= ctrl.pretension and commanded.max() <= T_MAX
