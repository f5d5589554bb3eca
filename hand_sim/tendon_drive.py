"""The actuator layer of the tendon-driven Utah/MIT hand of section 5 (models/utah_mit_hand):
desired joint angles -> joint torques (a PD loop) -> 32 non-negative tendon tensions, and back from
measured tensions to joint torques. This is the simulated robot's own joint servo, so it lives in
``hand_sim`` beside :class:`~hand_sim.world.World`, which runs it at every physics step when the
world is built with ``hand="tendon"``; :mod:`controllers.hand.tendon_control` re-exports it and adds
the standalone loop the model's tests use.

The law is the one the Utah/MIT hand's joint controllers used in outline (Jacobsen et al., "Design
of the Utah/M.I.T. Dextrous Hand", ICRA 1986): a joint-space loop computes the torque each joint
needs from its angle error; the torque is then split over the joint's antagonistic pair of tendons,
which can only pull. For a pair over a pulley of radius r, the joint torque is

    tau = r (T_flex - T_ext),

so the torque's sign picks the tendon that pulls, and both tendons keep a minimum pretension T0 so
that neither goes slack (a slack tendon can leave its pulley and takes time to take up again):

    T_flex = T0 + max(tau, 0) / r,    T_ext = T0 + max(-tau, 0) / r.

A tension cannot exceed the actuator's maximum T_max, so the torque a joint can get is limited to
r (T_max - T0) in either direction: a larger request is clipped to that limit (the command reports
the torque actually delivered). The inverse, used with the 32 wrist tension sensors, estimates each
joint's torque from its pair's measured tensions with the same formula.

The pulley radius and the maximum tension are read from the model (the tendons' coefficients and
the actuators' force range), not repeated here; models/utah_mit_hand/README.md gives their values
and sources. Everything is numpy on a compiled MuJoCo model and its data; there is no global state.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from hand_sim import robot

#: Minimum tension (N) both tendons of a pair keep (README: why 10 N).
PRETENSION = 10.0
#: Period (s) of the joint PD loop: 500 Hz, one update per 2 ms physics step.
CONTROL_PERIOD = 0.002
#: PD stiffness (N m/rad) per joint of a finger (j0 abduction, j1 MCP, j2 PIP, j3 DIP): the gains
#: of models/hand.xml's position servos, so the task cycle's squeeze depths give the same forces.
SERVO_KP = (6.0, 9.0, 6.0, 3.6)
#: Torque limit (N m) per joint of a finger: the force ranges of models/hand.xml's servos.
SERVO_TORQUE_LIMIT = (5.0, 6.0, 4.0, 2.4)
#: Damping ratio of the PD loop (models/hand.xml's servos use dampratio 1).
DAMPING_RATIO = 1.0


def _fixed_tendon_coef(model: mujoco.MjModel, tendon: int, joint: int) -> float:
    """Coefficient of ``joint`` in the fixed tendon ``tendon`` (ValueError if it is not a fixed
    tendon of that one joint)."""
    adr, num = model.tendon_adr[tendon], model.tendon_num[tendon]
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, tendon)
    if num != 1 or model.wrap_type[adr] != mujoco.mjtWrap.mjWRAP_JOINT:
        raise ValueError(f"tendon {name} is not a fixed tendon on one joint")
    if model.wrap_objid[adr] != joint:
        raise ValueError(f"tendon {name} does not act on its joint")
    return float(model.wrap_prm[adr])


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise ValueError(f"the model has no {kind.name[6:].lower()} named {name!r}")
    return i


@dataclass(frozen=True)
class TendonLayout:
    """Where the 16 joints' angles, tendons, actuators and tension sensors are in a compiled model,
    in :data:`hand_sim.robot.HAND_JOINTS` order, with each joint's pulley radius and maximum
    tension. Tendon arrays of 32 are ordered joint by joint, flexor then extensor."""

    joints: tuple[str, ...]
    qpos_adr: NDArray[np.int_]
    dof_adr: NDArray[np.int_]
    angle_sensor_adr: NDArray[np.int_]
    flex_actuator: NDArray[np.int_]
    ext_actuator: NDArray[np.int_]
    flex_sensor_adr: NDArray[np.int_]
    ext_sensor_adr: NDArray[np.int_]
    radius: NDArray[np.float64]
    max_tension: NDArray[np.float64]

    @classmethod
    def from_model(cls, model: mujoco.MjModel, prefix: str = "") -> TendonLayout:
        """Read the layout of models/utah_mit_hand/utah_mit_hand.xml's names (each preceded by
        ``prefix`` when the hand is attached to something). Checks the conventions the control law
        relies on: the flexor's coefficient is -r and the extensor's +r, both actuators pull
        (gear -1) with force range [0, T_max], and a pair shares r and T_max."""
        obj = mujoco.mjtObj
        cols: dict[str, list] = {k: [] for k in cls.__dataclass_fields__ if k != "joints"}
        for joint in robot.HAND_JOINTS:
            j = _id(model, obj.mjOBJ_JOINT, prefix + joint)
            finger, index = joint[:2], joint[3:]
            cols["qpos_adr"].append(model.jnt_qposadr[j])
            cols["dof_adr"].append(model.jnt_dofadr[j])
            sensor = _id(model, obj.mjOBJ_SENSOR, f"{prefix}{joint}_pos")
            cols["angle_sensor_adr"].append(model.sensor_adr[sensor])
            coefs, limits = [], []
            for side in ("flex", "ext"):
                tendon = _id(model, obj.mjOBJ_TENDON, f"{prefix}{joint}_{side}")
                act = _id(model, obj.mjOBJ_ACTUATOR, f"{prefix}{finger}a{index}_{side}")
                sensor = _id(model, obj.mjOBJ_SENSOR, f"{prefix}{joint}_{side}_tension")
                if model.actuator_trnid[act, 0] != tendon or model.actuator_gear[act, 0] != -1:
                    raise ValueError(f"actuator of {joint}_{side} does not pull its tendon")
                lo, hi = model.actuator_forcerange[act]
                if not model.actuator_forcelimited[act] or lo != 0.0 or hi <= 0.0:
                    raise ValueError(f"actuator of {joint}_{side} is not pull-only")
                coefs.append(_fixed_tendon_coef(model, tendon, j))
                limits.append(hi)
                cols[f"{side}_actuator"].append(act)
                cols[f"{side}_sensor_adr"].append(model.sensor_adr[sensor])
            flex, ext = coefs
            if not (flex < 0.0 < ext and np.isclose(-flex, ext)) or limits[0] != limits[1]:
                raise ValueError(f"the tendons of {joint} are not an antagonistic pair")
            cols["radius"].append(ext)
            cols["max_tension"].append(limits[0])
        arrays = {k: np.asarray(v) for k, v in cols.items()}
        return cls(joints=robot.HAND_JOINTS, **arrays)

    @property
    def actuators(self) -> NDArray[np.int_]:
        """The 32 actuator ids, joint by joint, flexor then extensor."""
        return np.column_stack((self.flex_actuator, self.ext_actuator)).ravel()

    def angles(self, data: mujoco.MjData) -> NDArray[np.float64]:
        """The 16 joint angles (rad) read by the joint-angle sensors (a copy)."""
        return data.sensordata[self.angle_sensor_adr]

    def tensions(self, data: mujoco.MjData) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Measured (flexor, extensor) tensions (N) of the 16 joints, from the tension sensors
        (copies)."""
        return data.sensordata[self.flex_sensor_adr], data.sensordata[self.ext_sensor_adr]


@dataclass(frozen=True)
class TensionCommand:
    """Tendon tensions (N) for the 16 joints and the joint torques (N m) they give."""

    flex: NDArray[np.float64]
    ext: NDArray[np.float64]
    torque: NDArray[np.float64]
    #: The torque that was asked for, before the tension limit clipped it.
    requested: NDArray[np.float64]

    @property
    def saturated(self) -> NDArray[np.bool_]:
        """Joints whose requested torque was clipped by the tension limit."""
        return ~np.isclose(self.torque, self.requested)

    def as_ctrl(self) -> NDArray[np.float64]:
        """The 32 tensions in :attr:`TendonLayout.actuators` order."""
        return np.column_stack((self.flex, self.ext)).ravel()


def torque_limit(
    radius: ArrayLike, max_tension: ArrayLike, pretension: float = PRETENSION
) -> NDArray[np.float64]:
    """Largest torque (N m) a pair can give either way: r (T_max - T0)."""
    return np.asarray(radius, float) * (np.asarray(max_tension, float) - pretension)


def _checked_limit(
    radius: ArrayLike, max_tension: ArrayLike, pretension: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The pulley radii and :func:`torque_limit`, refusing a non-positive radius, a negative
    pretension or one above the maximum tension."""
    r = np.asarray(radius, float)
    if np.any(r <= 0.0) or pretension < 0.0:
        raise ValueError("pulley radii must be positive and the pretension non-negative")
    limit = torque_limit(r, max_tension, pretension)
    if np.any(limit < 0.0):
        raise ValueError("the pretension exceeds the maximum tension")
    return r, limit


def allocate_tensions(
    torque: ArrayLike,
    radius: ArrayLike,
    max_tension: ArrayLike,
    pretension: float = PRETENSION,
) -> TensionCommand:
    """Tensions of each antagonistic pair for the joint torques ``torque``: the torque's sign
    picks the tendon that pulls, T = T0 + |tau| / r on it and T0 on the other. A torque beyond
    :func:`torque_limit` is clipped to it, so every tension stays in [T0, T_max]."""
    requested = np.asarray(torque, float)
    r, limit = _checked_limit(radius, max_tension, pretension)
    tau = np.clip(requested, -limit, limit)
    flex = pretension + np.maximum(tau, 0.0) / r
    ext = pretension + np.maximum(-tau, 0.0) / r
    return TensionCommand(flex=flex, ext=ext, torque=tau, requested=requested)


def joint_torques(flex: ArrayLike, ext: ArrayLike, radius: ArrayLike) -> NDArray[np.float64]:
    """Joint torques (N m) estimated from the pairs' tensions: tau = r (T_flex - T_ext)."""
    return np.asarray(radius, float) * (np.asarray(flex, float) - np.asarray(ext, float))


@dataclass(frozen=True)
class PDGains:
    """Per-joint PD gains and torque limits of the joint loop (16 each)."""

    kp: NDArray[np.float64]
    kd: NDArray[np.float64]
    torque_limit: NDArray[np.float64]

    @classmethod
    def servo_equivalent(
        cls, model: mujoco.MjModel, layout: TendonLayout, damping_ratio: float = DAMPING_RATIO
    ) -> PDGains:
        """The gains of models/hand.xml's position servos (:data:`SERVO_KP`,
        :data:`SERVO_TORQUE_LIMIT`), damped as MuJoCo's ``dampratio`` does it:
        kd = 2 zeta sqrt(kp M0), M0 the joint's inertia in the model's reference posture."""
        per_finger = len(robot.FINGERS)
        kp = np.tile(SERVO_KP, per_finger)
        inertia = model.dof_M0[layout.dof_adr]
        kd = 2.0 * damping_ratio * np.sqrt(kp * inertia)
        return cls(kp=kp, kd=kd, torque_limit=np.tile(SERVO_TORQUE_LIMIT, per_finger))


@dataclass(frozen=True)
class TendonDrive:
    """The joint PD loop and the tension allocation of one hand in a compiled model: what the
    hand's joint servos do at every physics step (:data:`CONTROL_PERIOD` = the 2 ms step; at
    50 Hz the loop does not settle, docs/models.md)."""

    layout: TendonLayout
    gains: PDGains
    pretension: float = PRETENSION

    @classmethod
    def for_model(cls, model: mujoco.MjModel, prefix: str = "") -> TendonDrive:
        """The drive of the hand named with ``prefix`` in ``model``, servo-equivalent gains."""
        layout = TendonLayout.from_model(model, prefix)
        return cls(layout, PDGains.servo_equivalent(model, layout))

    def torques(self, data: mujoco.MjData, target: ArrayLike) -> NDArray[np.float64]:
        """PD torques (N m) towards the 16 joint ``target`` angles, within the gains' limits:
        the error is read by the joint-angle sensors, the velocity is the simulator's (the real
        hand differentiated its angle sensors)."""
        error = np.asarray(target, float) - self.layout.angles(data)
        velocity = data.qvel[self.layout.dof_adr]
        tau = self.gains.kp * error - self.gains.kd * velocity
        return np.clip(tau, -self.gains.torque_limit, self.gains.torque_limit)

    def command(self, data: mujoco.MjData, target: ArrayLike) -> TensionCommand:
        """Tensions for the PD torques towards ``target`` (:func:`allocate_tensions`)."""
        return allocate_tensions(
            self.torques(data, target),
            self.layout.radius,
            self.layout.max_tension,
            self.pretension,
        )

    def apply(self, data: mujoco.MjData, command: TensionCommand) -> None:
        """Write the command's 32 tensions to the tendon actuators."""
        data.ctrl[self.layout.actuators] = command.as_ctrl()

    def rest(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Put every tendon at the pretension, commanded and actual (the actuators' first-order
        lag state): the hand at rest with no tendon slack (a slack tendon would take the first
        5 ms of a command to take up)."""
        acts = self.layout.actuators
        data.ctrl[acts] = self.pretension
        adr = model.actuator_actadr[acts]
        data.act[adr[adr >= 0]] = self.pretension

    @cached_property
    def _loop(self) -> _LoopConstants:
        return _LoopConstants.of(self)

    def step(
        self, model: mujoco.MjModel, data: mujoco.MjData, target: ArrayLike, n: int = 1
    ) -> None:
        """``n`` physics steps with the loop closed before each one: the tensions towards the
        joint ``target`` angles are computed from the state, written, and one step is taken.
        The same arithmetic as :meth:`command` then :meth:`apply`, bit for bit (the two clips
        merged into one, to the smaller bound; min and max are exact), with the constants and
        the index arrays computed once: the loop runs at every 2 ms physics step."""
        c = self._loop
        target = np.asarray(target, float)
        tensions = np.empty_like(c.radius2)
        flex, ext = tensions[:, 0], tensions[:, 1]
        for _ in range(n):
            tau = c.kp * (target - data.sensordata[c.angle_adr]) - c.kd * data.qvel[c.dof_adr]
            np.clip(tau, c.low, c.high, out=tau)
            np.maximum(tau, 0.0, out=flex)
            np.negative(tau, out=tau)
            np.maximum(tau, 0.0, out=ext)
            tensions /= c.radius2
            tensions += self.pretension
            data.ctrl[c.actuators] = tensions.ravel()
            mujoco.mj_step(model, data)


@dataclass(frozen=True)
class _LoopConstants:
    """What :meth:`TendonDrive.step` needs at every step, computed once: index arrays, gains,
    the torque bound (the smaller of the gains' limit and :func:`torque_limit`) and the radii as
    a (16, 2) column pair."""

    actuators: NDArray[np.int_]
    angle_adr: NDArray[np.int_]
    dof_adr: NDArray[np.int_]
    kp: NDArray[np.float64]
    kd: NDArray[np.float64]
    low: NDArray[np.float64]
    high: NDArray[np.float64]
    radius2: NDArray[np.float64]

    @classmethod
    def of(cls, drive: TendonDrive) -> _LoopConstants:
        layout, gains = drive.layout, drive.gains
        r, limit = _checked_limit(layout.radius, layout.max_tension, drive.pretension)
        bound = np.minimum(gains.torque_limit, limit)
        return cls(
            actuators=layout.actuators,
            angle_adr=layout.angle_sensor_adr,
            dof_adr=layout.dof_adr,
            kp=gains.kp,
            kd=gains.kd,
            low=-bound,
            high=bound,
            radius2=np.column_stack((r, r)),
        )
