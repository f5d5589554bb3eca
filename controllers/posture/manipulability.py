"""The hand's manipulability (section 5.2, Posture Control; Grupen & Souccar, ref. [16]).

Manipulability measure. Each finger's fingertip position Jacobian ``J_f`` (3 x 4, with respect
to that finger's own joints) has Yoshikawa manipulability ``w_f = sqrt(det(J_f J_f^T))``; the
hand's measure is ``M = sum_f log(w_f)`` (log of the product; ``-inf`` at a singular finger).
``w_f`` does not depend on the arm, but with the fingertips held the arm must move for the
fingers to change posture: the arm is "reconfigured to maximise the hand manipulability while
maintaining the current fingertip positions".

:class:`ManipulabilityTask` is a gradient-type mink task: its error is a constant desired
decrease of ``-2 M`` per step and its Jacobian the gradient of ``-2 M`` (finite differences over
the finger joints), so the QP trades it against the fingertip tasks; it needs ``solve_ik(...,
damping=...)``: without, the step explodes (docs/reach.md, "Posture control").
"""

from __future__ import annotations

import mink
import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.errors import PostureError
from hand_sim.indices import RobotIndices
from hand_sim.world import World

#: Manipulability task cost and desired decrease of -2M per IK step.
MANIPULABILITY_COST = 0.05
MANIPULABILITY_STEP = 0.5
#: Finite-difference step (rad) of the manipulability gradient.
FD_STEP = 1e-6


def finger_manipulability(
    model: mujoco.MjModel, data: mujoco.MjData, idx: RobotIndices
) -> NDArray[np.float64]:
    """``w_f = sqrt(det(J_f J_f^T))`` (m^3 rad^-3) of each finger; ``data`` must hold current
    kinematics and ``mj_comPos``."""
    jacp = np.zeros((3, model.nv))
    out = np.empty(len(idx.tip_sites))
    for f, site in enumerate(idx.tip_sites):
        mujoco.mj_jacSite(model, data, jacp, None, int(site))
        J = jacp[:, idx.finger_dofs[f]]
        out[f] = np.sqrt(max(np.linalg.det(J @ J.T), 0.0))
    return out


def log_manipulability(model: mujoco.MjModel, data: mujoco.MjData, idx: RobotIndices) -> float:
    """The hand's measure ``M = sum_f log(w_f)``."""
    with np.errstate(divide="ignore"):
        return float(np.log(finger_manipulability(model, data, idx)).sum())


class ManipulabilityTask(mink.Task):
    """A mink task whose error is a desired decrease ``step`` of ``-2 M`` and whose Jacobian is
    the gradient of ``-2 M = -sum_f log det(J_f J_f^T)`` over the finger joints."""

    k: int = 1

    def __init__(
        self,
        model: mujoco.MjModel,
        *,
        cost: float = MANIPULABILITY_COST,
        step: float = MANIPULABILITY_STEP,
        gain: float = 1.0,
    ) -> None:
        if cost < 0 or step <= 0:
            raise PostureError(f"need cost >= 0 and step > 0, got cost {cost} step {step}")
        super().__init__(cost=np.array([cost]), gain=gain, lm_damping=0.0)
        self.model = model
        self.idx = RobotIndices.of(model)
        self.step = float(step)
        self._data = mujoco.MjData(model)

    def objective(self, qpos: NDArray[np.float64]) -> float:
        """``-2 M`` at ``qpos``."""
        d = self._data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)
        return -2.0 * log_manipulability(self.model, d, self.idx)

    def compute_error(self, configuration: mink.Configuration) -> NDArray[np.float64]:
        """The desired decrease of ``-2 M`` this step."""
        return np.array([self.step])

    def compute_jacobian(self, configuration: mink.Configuration) -> NDArray[np.float64]:
        """Gradient (1, nv) of ``-2 M`` by central differences over the finger joints."""
        q = configuration.q.copy()
        grad = np.zeros((1, self.model.nv))
        for qa, da in zip(self.idx.hand_qpos, self.idx.hand_dof, strict=True):
            q[qa] += FD_STEP
            hi = self.objective(q)
            q[qa] -= 2 * FD_STEP
            lo = self.objective(q)
            q[qa] += FD_STEP
            grad[0, da] = (hi - lo) / (2 * FD_STEP)
        if not np.all(np.isfinite(grad)):
            grad[:] = 0.0  # at a singular finger; the fingertip tasks still act
        return grad


def world_log_manipulability(world: World) -> float:
    """``M`` of the hand in the world's current state."""
    model = world.model
    data = mujoco.MjData(model)
    data.qpos[:] = world.data.qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    return log_manipulability(model, data, RobotIndices.of(model))
