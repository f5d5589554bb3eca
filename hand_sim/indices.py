"""Addresses of the robot's joints, actuators, sites and sensors in a compiled world model: one
resolution of :mod:`hand_sim.robot`'s names, shared by :class:`hand_sim.world.World` and the
controllers (posture control, the grip, the planners)."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from hand_sim import robot
from hand_sim.errors import SimulationError


def element_id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    """Id of the element ``name`` of type ``kind``; raises :class:`SimulationError` if the model
    has none."""
    i = mujoco.mj_name2id(model, kind, name)
    if i < 0:
        raise SimulationError(f"the world model has no {kind.name[6:].lower()} {name!r}")
    return i


def _ids(model: mujoco.MjModel, kind: mujoco.mjtObj, names: tuple[str, ...]) -> NDArray[np.int64]:
    return np.array([element_id(model, kind, robot.qualified(n)) for n in names], dtype=np.int64)


@dataclass(frozen=True)
class RobotIndices:
    """Addresses of the robot's elements in a world model; arm arrays in
    :data:`robot.ARM_JOINTS` order, hand arrays in :data:`robot.HAND_JOINTS` order (finger by
    finger, ff, mf, rf, th). A world without the robot has empty arrays and -1 addresses
    (:meth:`empty`)."""

    arm_joints: NDArray[np.int64]  #: (5,) joint ids
    arm_qpos: NDArray[np.int64]  #: (5,) qpos addresses
    arm_dof: NDArray[np.int64]  #: (5,) dof addresses
    arm_ctrl: NDArray[np.int64]  #: (5,) actuator ids
    hand_joints: NDArray[np.int64]  #: (16,) joint ids
    hand_qpos: NDArray[np.int64]  #: (16,) qpos addresses
    hand_dof: NDArray[np.int64]  #: (16,) dof addresses
    hand_ctrl: NDArray[np.int64]  #: (16,) actuator ids
    tip_sites: NDArray[np.int64]  #: (4,) fingertip site ids, order ff, mf, rf, th
    touch_adr: NDArray[np.int64]  #: (4,) sensordata addresses of the touch sensors
    wrist_force_adr: int
    wrist_torque_adr: int
    wrist_accel_adr: int
    mount_site: int

    @classmethod
    def of(cls, model: mujoco.MjModel) -> RobotIndices:
        """Resolve the robot's names in ``model`` (a world model with the arm and hand); raises
        :class:`SimulationError` naming a missing element."""
        obj = mujoco.mjtObj
        arm_j = _ids(model, obj.mjOBJ_JOINT, robot.ARM_JOINTS)
        hand_j = _ids(model, obj.mjOBJ_JOINT, robot.HAND_JOINTS)
        arm_a = _ids(model, obj.mjOBJ_ACTUATOR, robot.ARM_ACTUATORS)
        hand_a = _ids(model, obj.mjOBJ_ACTUATOR, robot.HAND_ACTUATORS)
        tips = _ids(model, obj.mjOBJ_SITE, robot.FINGERTIP_SITES)
        touch = model.sensor_adr[_ids(model, obj.mjOBJ_SENSOR, robot.TOUCH_SENSORS)]
        wrist = model.sensor_adr[_ids(model, obj.mjOBJ_SENSOR, robot.WRIST_SENSORS)]
        mount = element_id(model, obj.mjOBJ_SITE, robot.qualified(robot.MOUNT_SITE))
        return cls(
            arm_joints=arm_j,
            arm_qpos=model.jnt_qposadr[arm_j],
            arm_dof=model.jnt_dofadr[arm_j],
            arm_ctrl=arm_a,
            hand_joints=hand_j,
            hand_qpos=model.jnt_qposadr[hand_j],
            hand_dof=model.jnt_dofadr[hand_j],
            hand_ctrl=hand_a,
            tip_sites=tips,
            touch_adr=np.asarray(touch, dtype=np.int64),
            wrist_force_adr=int(wrist[0]),
            wrist_torque_adr=int(wrist[1]),
            wrist_accel_adr=int(wrist[2]),
            mount_site=mount,
        )

    @classmethod
    def empty(cls) -> RobotIndices:
        """The indices of a world built without the robot: nothing to address."""
        none = np.zeros(0, dtype=np.int64)
        return cls(none, none, none, none, none, none, none, none, none, none, -1, -1, -1, -1)

    @property
    def finger_qpos(self) -> NDArray[np.int64]:
        """(4, 4) qpos addresses of the hand's joints, one row per finger."""
        return self.hand_qpos.reshape(len(robot.FINGERS), -1)

    @property
    def finger_dofs(self) -> NDArray[np.int64]:
        """(4, 4) dof addresses of the hand's joints, one row per finger."""
        return self.hand_dof.reshape(len(robot.FINGERS), -1)

    @property
    def arm_dofs(self) -> NDArray[np.int64]:
        """(5,) dof addresses of the arm's joints (the name posture control uses)."""
        return self.arm_dof
