"""A drawn :class:`~hand_sim.perturb.Perturbation` applied to the simulated world's model: the
camera's and the arm base's poses, the links' lengths, the blocks' masses and frictions, the
pads' frictions and the tendon actuators' lag (in the MJCF, before it is compiled, so that every
derived quantity follows), and the joint loops' gains (in the compiled model and the tendon
drive). Only the simulated world is changed: the robot's belief is built from the unperturbed
scene (section 5.3: "calibration drifts, and kinematic model imprecision").

Frictions: MuJoCo takes the larger coefficient of a contact's two geoms unless one geom has a
higher ``priority``. The pads already outrank the blocks; with ``object`` the table's top gets a
priority below the blocks' (-1), so that a block's drawn friction is the friction between it and
the table, and a pad's the friction between it and a block (two blocks still take the larger).
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
from dm_control import mjcf

from hand_sim import robot
from hand_sim.perturb import LINKS, Perturbation
from hand_sim.tendon_drive import PDGains, TendonDrive

#: Names of the elements changed, as the assembled world names them.
CAMERA = "overhead"
ARM_FRAME = robot.ARM_MODEL
TABLE_TOP = "table/table_top"


def quat_of_rotvec(v: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of the rotation vector ``v`` (rad)."""
    quat = np.empty(4)
    mujoco.mju_axisAngle2Quat(
        quat, np.asarray(v, float) / max(np.linalg.norm(v), 1e-300), float(np.linalg.norm(v))
    )
    return quat


def turned(quat: np.ndarray, rotvec: np.ndarray) -> np.ndarray:
    """``quat`` (w, x, y, z) turned by ``rotvec`` about world axes: q_delta * quat."""
    out = np.empty(4)
    mujoco.mju_mulQuat(out, quat_of_rotvec(rotvec), np.asarray(quat, float))
    return out


def _element(root: mjcf.RootElement, kind: str, name: str) -> mjcf.Element:
    element = root.find(kind, name)
    if element is None:
        raise ValueError(f"the world's MJCF has no {kind} {name!r}")
    return element


def apply_to_mjcf(
    root: mjcf.RootElement,
    p: Perturbation,
    *,
    with_robot: bool,
    hand: str,
    blocks: tuple[str, ...],
) -> None:
    """Change ``root`` (the assembled world of :func:`hand_sim.assembly.build_mjcf`) as ``p``
    asks: everything but the gains (:func:`apply_gains`)."""
    s = p.spec
    if s.scale("camera"):
        camera = _element(root, "camera", CAMERA)
        camera.pos = np.asarray(camera.pos, float) + p.camera_shift
        camera.quat = turned(np.asarray(camera.quat, float), p.camera_turn)
    if s.scale("arm_base") and with_robot:
        frame = _element(root, "attachment_frame", ARM_FRAME)
        frame.pos = np.asarray(frame.pos, float) + p.arm_base_shift
    if s.scale("kinematics") and with_robot:
        for (model, body, axis), delta in zip(LINKS, p.link_deltas, strict=True):
            prefix = robot.HAND_PREFIX if model == "hand" else robot.ARM_PREFIX
            element = _element(root, "body", prefix + body)
            pos = np.asarray(element.pos, float).copy()
            pos[axis] += float(delta) * (1.0 if pos[axis] >= 0.0 else -1.0)
            element.pos = pos
    if s.scale("object"):
        from hand_sim.blocks import GEOM_SUFFIX

        _element(root, "geom", TABLE_TOP).priority = -1
        for name in blocks:
            geom = _element(root, "geom", name + GEOM_SUFFIX)
            geom.density = float(geom.density) * p.mass_factor(name)
            friction = np.asarray(geom.friction, float).copy()
            friction[0] *= p.friction_factor(name)
            geom.friction = friction
        if with_robot:
            for finger, factor in zip(robot.FINGERS, p.pad_friction_factors, strict=True):
                pad = _element(root, "geom", robot.hand_name(f"{finger}_pad"))
                friction = np.asarray(
                    pad.friction if pad.friction is not None else pad.dclass.geom.friction, float
                ).copy()
                friction[0] *= float(factor)
                pad.friction = friction
    if s.scale("actuation") and with_robot and hand == "tendon":
        for i, joint in enumerate(robot.HAND_JOINTS):
            finger, index = joint[:2], joint[3:]
            for k, side in enumerate(("flex", "ext")):
                act = _element(root, "actuator", robot.hand_name(f"{finger}a{index}_{side}"))
                lag = act.dynprm if act.dynprm is not None else act.dclass.general.dynprm
                lag = np.asarray(lag, float).copy()
                lag[0] *= float(p.lag_factors[2 * i + k])
                act.dynprm = lag


def apply_gains(
    model: mujoco.MjModel, drive: TendonDrive | None, p: Perturbation, hand_ctrl: np.ndarray
) -> TendonDrive | None:
    """The joint loops' gains times ``p``'s factors: the tendon drive's stiffness and damping
    (returned, a new drive), or the servo hand's position servos (changed in ``model``)."""
    if not p.spec.scale("actuation"):
        return drive
    if drive is not None:
        gains = PDGains(
            kp=drive.gains.kp * p.kp_factors,
            kd=drive.gains.kd * p.kd_factors,
            torque_limit=drive.gains.torque_limit,
        )
        return dataclasses.replace(drive, gains=gains)
    model.actuator_gainprm[hand_ctrl, 0] *= p.kp_factors
    model.actuator_biasprm[hand_ctrl, 1] *= p.kp_factors
    model.actuator_biasprm[hand_ctrl, 2] *= p.kd_factors
    return None
