"""How far a held block would turn under the physical test's loads if the fingers were the
springs their position servos make them: the grasp's stiffness (Cutkosky and Kao, "Computing and
controlling the compliance of a robotic hand", IEEE T-RA 5(2), 1989), a prediction of the test's
own criterion that no rigid-contact measure (S_G, Eq. 13) can make.

At the end of the squeeze each finger i touches the block at p_i (its force-weighted mean contact
point). Its joints are position servos of gain k_j (N m/rad); a servo at its force limit gives no
more torque, so its stiffness against a further load is taken as zero (:data:`SATURATED_STIFFNESS`,
a soft spring standing for it). The finger's stiffness at p_i is K_i = (J_i K_q^-1 J_i^T)^-1, J_i
the (3, 4) Jacobian of the contact point over the finger's joints; a block displacement (dx, dth)
about its centre of mass c moves p_i by dx + dth x (p_i - c), so the grasp's stiffness on the block
is K_G = sum_i A_i^T K_i A_i with A_i = [I, -[p_i - c]x]. A load w (6,) about c displaces the block
by K_G^-1 w; its rotation is the predicted turn. The loads are those of the test, from the
squeezed state: the weight when the table goes (hang) and the weight plus a push of m*g along
+-x, +-y, +-z.

The model is linear and keeps every contact stuck: it sees the fingers yielding and the block
pivoting about a line of contacts (K_G singular), not slip, separation, the pads' own softness or
torsional friction. It is measured in the palm's frame, as the test is: the arm does not enter.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from hand_sim import robot
from hand_sim.contacts import robot_contacts
from hand_sim.indices import RobotIndices
from hand_sim.world import World

#: Stiffness (N m/rad) standing for a servo at its force limit (it yields to any further load).
SATURATED_STIFFNESS = 1e-3
#: Relative force margin (of the limit) within which a servo counts as saturated.
SATURATION_MARGIN = 0.01
#: Compliance (m/N) added to each finger's so that a direction the finger cannot move in is
#: very stiff, not infinitely stiff (1e6 N/m).
RIGID_COMPLIANCE = 1e-6
#: Rotation (rad) reported for a load the grasp's stiffness cannot resist (K_G singular).
UNRESISTED_TURN = np.pi


@dataclass(frozen=True)
class GraspCompliance:
    """The predicted turn (rad) of the block per test stage, the worst and its stage, and how
    many of the hand's 16 servos are at their force limit."""

    turn: dict[str, float]
    worst_turn: float
    worst_stage: str
    saturated: int


def skew(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """[r]x: skew(r) @ v == cross(r, v)."""
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def joint_stiffness(world: World) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """(16,) stiffness (N m/rad) of the hand's joints as their position servos hold them now,
    :data:`robot.HAND_JOINTS` order, and which servos are at their force limit."""
    m, d = world.model, world.data
    act = RobotIndices.of(m).hand_ctrl
    gear = m.actuator_gear[act, 0]
    k = m.actuator_gainprm[act, 0] * gear**2
    lo, hi = m.actuator_forcerange[act].T
    f = d.actuator_force[act]
    limited = m.actuator_forcelimited[act].astype(bool)
    span = np.maximum(np.abs(lo), np.abs(hi))
    sat = limited & ((f <= lo + SATURATION_MARGIN * span) | (f >= hi - SATURATION_MARGIN * span))
    return np.where(sat, SATURATED_STIFFNESS, k), sat


def grasp_stiffness(
    points: NDArray[np.float64], finger_stiffness: list[NDArray[np.float64]], com: NDArray
) -> NDArray[np.float64]:
    """(6, 6) K_G = sum_i A_i^T K_i A_i of contacts ``points`` (n, 3) with (3, 3) stiffnesses,
    about ``com`` (the block displacement's order: translation, rotation)."""
    K = np.zeros((6, 6))
    for p, Ki in zip(points, finger_stiffness, strict=True):
        A = np.hstack([np.eye(3), -skew(np.asarray(p) - com)])
        K += A.T @ Ki @ A
    return K


def predicted_turn(K: NDArray[np.float64], force: NDArray[np.float64]) -> float:
    """Rotation (rad) of a block of grasp stiffness ``K`` under ``force`` (3,) at its centre of
    mass; :data:`UNRESISTED_TURN` when K cannot resist it."""
    w = np.concatenate([force, np.zeros(3)])
    dx = np.linalg.lstsq(K, w, rcond=1e-12)[0]  # a free direction the load does not push: 0
    if not np.all(np.isfinite(dx)) or np.linalg.norm(K @ dx - w) > 1e-6 * np.linalg.norm(w):
        return UNRESISTED_TURN
    return float(min(np.linalg.norm(dx[3:]), UNRESISTED_TURN))


def grasp_compliance(
    world: World, block: str, weight: float, pushes: tuple[tuple[str, tuple[float, ...]], ...]
) -> GraspCompliance | None:
    """The module docstring's prediction for ``block`` as the hand holds it now; ``weight``
    m*g (N); ``pushes`` the test's (label, unit direction) of an m*g push. None when some finger
    does not touch the block."""
    m, d = world.model, world.data
    body = world.block_body_id(block)
    com = d.xpos[body].copy()
    dofs = RobotIndices.of(m).finger_dofs
    k, sat = joint_stiffness(world)
    k = k.reshape(len(robot.FINGERS), -1)
    contacts = [c for c in robot_contacts(world, body) if c.normal_force > 0]
    points, stiff = [], []
    jacp = np.zeros((3, m.nv))
    for i, f in enumerate(robot.FINGERS):
        cs = [c for c in contacts if c.finger == f]
        if not cs:
            return None
        w = np.array([c.normal_force for c in cs])
        p = (w[:, None] * np.array([c.position for c in cs])).sum(0) / w.sum()
        link = cs[int(np.argmax(w))].link
        link_body = m.body(robot.hand_name(f"{f}_{link}")).id
        mujoco.mj_jac(m, d, jacp, None, p, link_body)
        J = jacp[:, dofs[i]]
        C = J @ np.diag(1.0 / k[i]) @ J.T + RIGID_COMPLIANCE * np.eye(3)
        points.append(p)
        stiff.append(np.linalg.inv(C))
    K = grasp_stiffness(np.array(points), stiff, com)
    down = np.array([0.0, 0.0, -weight])
    turn = {"hang": predicted_turn(K, down)}
    for label, direction in pushes:
        turn[label] = predicted_turn(K, down + weight * np.asarray(direction, dtype=float))
    stage = max(turn, key=lambda s: turn[s])
    return GraspCompliance(
        turn={s: round(t, 6) for s, t in turn.items()},
        worst_turn=turn[stage],
        worst_stage=stage,
        saturated=int(sat.sum()),
    )
