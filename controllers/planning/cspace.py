"""The arm's configuration space as MuJoCo sees it: collision checks of arm/hand configurations
against the scene, forward kinematics of the palm, and a small arm IK (section 5.2, "Coarse
Reach": "all objects are mapped as obstacles on a four-dimensional c-space, as well as the table
and the robot itself").

A :class:`CollisionChecker` owns a private copy of the world's model and its own ``MjData``: the
world being simulated is never touched. In the copy, collision bits are rearranged so that only
pairs that matter for reaching are tested (arm-arm, arm-hand, arm/hand-environment; not the
hand's fixed internal pairs nor blocks against the table), which makes a check ~2x faster, and
the robot's geoms carry a margin so that contacts closer than ``clearance`` are reported.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.errors import ReachError
from hand_sim import robot
from hand_sim.errors import SimulationError
from hand_sim.indices import RobotIndices
from hand_sim.world import World

#: Collision bits of the planning model: arm links, hand links, everything else, the robot's
#: fixed base and its first moving link.
ARM_BIT, HAND_BIT, ENV_BIT, BASE_BIT, ROOT_BIT = 1, 2, 4, 8, 16
#: Site of the hand at the centre of the palm's grasping face (hand frame: +z = approach axis).
PALM_SITE = robot.hand_name("palm_center")
#: Default clearance (m) kept between the robot and every obstacle while planning.
DEFAULT_CLEARANCE = 0.01
#: Arm IK: iterations, damping (rad^2-ish), convergence tolerances (m, rad) and step limit (rad).
IK_ITERATIONS = 200
IK_DAMPING = 1e-4
IK_POSITION_TOLERANCE = 1e-4
IK_ANGLE_TOLERANCE = 1e-3
IK_MAX_STEP = 0.2
#: How much a rotation error weighs against a position error in the IK (m per rad).
IK_ROTATION_WEIGHT = 0.2


@dataclass(frozen=True)
class Contact:
    """One reported contact (or near contact, within the checker's clearance)."""

    geom1: str
    geom2: str
    distance: float  #: signed distance (m); negative = penetration


@dataclass(frozen=True, eq=False)
class Nearest:
    """The closest robot-environment pair at one posture
    (:meth:`CollisionChecker.nearest_obstacle`)."""

    robot_geom: str
    env_geom: str
    distance: float  #: signed distance (m); negative = penetration
    away: NDArray[np.float64]  #: (3,) unit normal moving the robot away from the obstacle


@dataclass(frozen=True, eq=False)
class Scan:
    """Collision status of many arm configurations."""

    collides: NDArray[np.bool_]  #: (N,)


@dataclass(frozen=True, eq=False)
class IKResult:
    """Result of :func:`CollisionChecker.solve_ik`; ``found`` when both tolerances are met."""

    found: bool
    q: NDArray[np.float64]  #: (5,) arm joints, within joint limits
    position_error: float  #: m
    angle_error: float  #: rad


def _body_kind(model: mujoco.MjModel, body: int) -> str:
    name = model.body(body).name
    if name.startswith(robot.HAND_PREFIX):
        return "hand"
    if name.startswith(robot.ARM_PREFIX):
        return "arm"
    return "env"


def rotation_error(R_target: NDArray[np.float64], R: NDArray[np.float64]) -> NDArray[np.float64]:
    """World-frame rotation vector taking ``R`` to ``R_target``."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, (R_target @ R.T).ravel())
    vel = np.empty(3)
    mujoco.mju_quat2Vel(vel, quat, 1.0)
    return vel


class CollisionChecker:
    """Collision checks and kinematics of arm configurations in a frozen copy of ``world``.

    The blocks stay where they are in ``world`` when the checker is made; the hand holds
    ``hand_q`` (default: its current joint angles). ``clearance`` (m) is the distance below
    which a robot-obstacle pair counts as a collision. ``carried`` names a block held in the
    hand: it then moves rigidly with the palm (its pose relative to the palm as in ``world``
    now) and counts as part of the hand (delivery: "navigate the hand/arm/object"). ``model`` is
    the model to copy instead of the world's (same state layout), e.g. a
    :func:`controllers.planning.belief.planning_model` holding the perceived target. ``qpos`` is
    the configuration to copy instead of the world's now (a posture the arm is not in yet, e.g.
    a grasp whose set-down is checked before it is taken).
    """

    def __init__(
        self,
        world: World,
        *,
        clearance: float = DEFAULT_CLEARANCE,
        hand_q: ArrayLike | None = None,
        carried: str | None = None,
        model: mujoco.MjModel | None = None,
        qpos: ArrayLike | None = None,
    ) -> None:
        if not world.with_robot:
            raise ReachError("the world was built with with_robot=False: nothing to plan for")
        if not 0.0 <= clearance < 0.2:
            raise ReachError(f"clearance must lie in [0, 0.2) m, got {clearance}")
        self.clearance = float(clearance)
        if model is not None and model.nq != world.model.nq:
            raise ReachError(
                f"a planning model needs the world's {world.model.nq} qpos, got {model.nq}"
            )
        self.model = copy.deepcopy(world.model if model is None else model)
        self.data = mujoco.MjData(self.model)
        state = world.data.qpos if qpos is None else np.asarray(qpos, dtype=float)
        if state.shape != world.data.qpos.shape or not np.all(np.isfinite(state)):
            raise ReachError(f"qpos must be {world.model.nq} finite numbers")
        self.data.qpos[:] = state
        try:
            idx = RobotIndices.of(self.model)
        except SimulationError as e:
            raise ReachError(str(e)) from e
        self._arm_qpos = idx.arm_qpos
        first = int(idx.arm_qpos[0])
        contiguous = np.array_equal(idx.arm_qpos, np.arange(first, first + len(idx.arm_qpos)))
        #: the arm's qpos as one slice when they are contiguous (a faster write than an index)
        self._arm_slice = slice(first, first + len(idx.arm_qpos)) if contiguous else None
        self._arm_dof = idx.arm_dof
        self._hand_qpos = idx.hand_qpos
        self.arm_limits = self.model.jnt_range[idx.arm_joints].copy()
        self.palm_site = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, PALM_SITE)
        if self.palm_site < 0:
            raise ReachError(f"the world model has no site {PALM_SITE!r}")
        self.kind = np.array(
            [_body_kind(self.model, int(b)) for b in self.model.geom_bodyid], dtype=object
        )
        self._carried: tuple[int, NDArray[np.float64], NDArray[np.float64]] | None = None
        if carried is not None:
            body = world.block_body_id(carried)  # raises SceneError listing the blocks
            mujoco.mj_kinematics(self.model, self.data)
            R_palm = self.data.site_xmat[self.palm_site].reshape(3, 3)
            p_rel = R_palm.T @ (self.data.xpos[body] - self.data.site_xpos[self.palm_site])
            R_rel = R_palm.T @ self.data.xmat[body].reshape(3, 3)
            adr = int(self.model.jnt_qposadr[self.model.body_jntadr[body]])
            self._carried = (adr, p_rel, R_rel)
            self.kind[self.model.geom_bodyid == body] = "carried"
        self._assign_collision_bits()
        if hand_q is not None:
            self.set_hand(hand_q)
        mujoco.mj_kinematics(self.model, self.data)

    def _assign_collision_bits(self) -> None:
        """Rewrite contype/conaffinity/margin of the planning copy so that MuJoCo itself generates
        only the contacts that matter, each within ``clearance``: arm-arm, arm-hand and
        robot-environment pairs; not hand-hand (the hand posture is fixed while reaching),
        environment-environment (blocks on the table), nor a robot link against the fixed base it
        rests on (MuJoCo's parent filter skips no pair whose parent is welded to the world)."""
        m = self.model
        weld = m.body_weldid[m.geom_bodyid]
        parent_weld = m.body_weldid[m.body_parentid[weld]]
        active = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
        robot_any = ARM_BIT | HAND_BIT | BASE_BIT | ROOT_BIT
        for g in np.flatnonzero(active):
            kind = self.kind[g]
            if kind == "env":
                ct, ca = ENV_BIT, ARM_BIT | HAND_BIT | ROOT_BIT
            elif kind == "carried":
                ct, ca = HAND_BIT, ARM_BIT | BASE_BIT | ROOT_BIT | ENV_BIT
            elif weld[g] == 0:  # fixed part of the robot (pedestal)
                ct, ca = BASE_BIT, ARM_BIT | HAND_BIT
            elif parent_weld[g] == 0:  # first moving link, resting on the base
                ct, ca = ROOT_BIT, ARM_BIT | HAND_BIT | ENV_BIT
            elif kind == "arm":
                ct, ca = ARM_BIT, robot_any | ENV_BIT
            else:
                ct, ca = HAND_BIT, ARM_BIT | BASE_BIT | ROOT_BIT | ENV_BIT
            m.geom_contype[g], m.geom_conaffinity[g] = ct, ca
            # MuJoCo adds the two geoms' margins: half each makes every pair's margin `clearance`
            m.geom_margin[g] = 0.5 * self.clearance
            m.geom_gap[g] = 0.0

    # --- state -----------------------------------------------------------------------------
    def set_hand(self, hand_q: ArrayLike) -> None:
        """Hold the hand at joint angles ``hand_q`` (16,), :data:`robot.HAND_JOINTS` order."""
        q = np.asarray(hand_q, dtype=float)
        if q.shape != (len(robot.HAND_JOINTS),) or not np.all(np.isfinite(q)):
            raise ReachError(f"hand posture must be 16 finite angles (rad), got {hand_q!r}")
        self.data.qpos[self._hand_qpos] = q

    def hand_q(self) -> NDArray[np.float64]:
        """The hand posture the checker holds."""
        return self.data.qpos[self._hand_qpos].copy()

    def _set_arm(self, q: ArrayLike) -> None:
        q = np.asarray(q, dtype=float)
        if q.shape != (len(robot.ARM_JOINTS),) or not np.all(np.isfinite(q)):
            raise ReachError(f"arm configuration must be 5 finite angles (rad), got {q!r}")
        self._place(q)

    def _place(self, q: NDArray[np.float64]) -> None:
        """Arm joints ``q`` and the kinematics of everything (the carried block follows)."""
        m, d = self.model, self.data
        d.qpos[self._arm_qpos] = q
        mujoco.mj_kinematics(m, d)
        if self._carried is not None:
            adr, p_rel, R_rel = self._carried
            R_palm = d.site_xmat[self.palm_site].reshape(3, 3)
            d.qpos[adr : adr + 3] = d.site_xpos[self.palm_site] + R_palm @ p_rel
            quat = np.empty(4)
            mujoco.mju_mat2Quat(quat, (R_palm @ R_rel).ravel())
            d.qpos[adr + 3 : adr + 7] = quat
            mujoco.mj_kinematics(m, d)

    def carried_pose(self, q_arm: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World position (3,) and quaternion (4,) of the carried block at ``q_arm``."""
        if self._carried is None:
            raise ReachError("this checker carries no block")
        self._set_arm(q_arm)
        adr = self._carried[0]
        return self.data.qpos[adr : adr + 3].copy(), self.data.qpos[adr + 3 : adr + 7].copy()

    # --- queries ---------------------------------------------------------------------------
    def contacts(self, q_arm: ArrayLike, *, clearance: float | None = None) -> list[Contact]:
        """Robot contacts (arm-arm, arm-hand, robot-environment) closer than ``clearance``
        (default: the checker's) at arm configuration ``q_arm`` (5,)."""
        self._set_arm(q_arm)
        mujoco.mj_collision(self.model, self.data)
        limit = self.clearance if clearance is None else clearance
        out = []
        for c in self.data.contact[: self.data.ncon]:
            if c.dist < limit:
                out.append(
                    Contact(
                        self.model.geom(c.geom1).name, self.model.geom(c.geom2).name, float(c.dist)
                    )
                )
        return out

    def nearest_obstacle(self, q_arm: ArrayLike) -> Nearest | None:
        """The closest robot-environment pair within the clearance at ``q_arm`` (5,), with the
        unit normal that moves the robot away from it; None when no pair is within the
        clearance, or when one is a pair of the robot's own links (moving the whole robot does
        not part those)."""
        self._set_arm(q_arm)
        mujoco.mj_collision(self.model, self.data)
        best: Nearest | None = None
        for c in self.data.contact[: self.data.ncon]:
            if c.dist >= self.clearance:
                continue
            env1, env2 = self.kind[c.geom1] == "env", self.kind[c.geom2] == "env"
            if env1 == env2:
                return None
            if best is None or c.dist < best.distance:
                # MuJoCo's contact normal points from geom1 to geom2
                away = np.array(c.frame[:3]) * (1.0 if env1 else -1.0)
                robot_geom, env_geom = (c.geom2, c.geom1) if env1 else (c.geom1, c.geom2)
                best = Nearest(
                    self.model.geom(robot_geom).name,
                    self.model.geom(env_geom).name,
                    float(c.dist),
                    away,
                )
        return best

    def collides(self, q_arm: ArrayLike) -> bool:
        """Whether the robot at ``q_arm`` (5,) is closer than the clearance to any obstacle."""
        self._set_arm(q_arm)
        mujoco.mj_collision(self.model, self.data)
        return self.data.ncon > 0

    def scan(self, configs: ArrayLike) -> Scan:
        """Collision status of every row of ``configs`` (N, 5). The loop holds only MuJoCo's
        calls (about 1 us of kinematics and 5 us of collision a posture): a grid of 14^4
        postures is scanned per planned path."""
        q = np.asarray(configs, dtype=float)
        if q.ndim != 2 or q.shape[1] != len(robot.ARM_JOINTS):
            raise ReachError(f"configs must have shape (N, 5), got {q.shape}")
        m, d = self.model, self.data
        kinematics, collision = mujoco.mj_kinematics, mujoco.mj_collision
        counts = np.zeros(len(q), dtype=np.int64)
        if self._carried is not None or self._arm_slice is None:
            for i in range(len(q)):
                self._place(q[i])
                collision(m, d)
                counts[i] = d.ncon
        else:
            qpos, arm = d.qpos, self._arm_slice
            for i, row in enumerate(q):
                qpos[arm] = row
                kinematics(m, d)
                collision(m, d)
                counts[i] = d.ncon
        return Scan(counts > 0)

    def palm_pose(self, q_arm: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World position (3,) and rotation matrix (3, 3) of the palm centre at ``q_arm``."""
        self._set_arm(q_arm)
        return (
            self.data.site_xpos[self.palm_site].copy(),
            self.data.site_xmat[self.palm_site].reshape(3, 3).copy(),
        )

    def solve_ik(
        self,
        position: ArrayLike,
        rotation: ArrayLike,
        q_seed: ArrayLike,
        *,
        iterations: int = IK_ITERATIONS,
    ) -> IKResult:
        """Arm joints putting the palm centre at ``position`` with orientation ``rotation`` (3x3),
        by damped least squares from ``q_seed`` within the joint limits."""
        p_goal = np.asarray(position, dtype=float)
        R_goal = np.asarray(rotation, dtype=float)
        q = np.clip(np.asarray(q_seed, dtype=float), *self.arm_limits.T)
        jacp = np.zeros((3, self.model.nv))
        jacr = np.zeros((3, self.model.nv))
        W = np.diag([1.0] * 3 + [IK_ROTATION_WEIGHT] * 3)
        pe = ae = np.inf
        for _ in range(iterations):
            p, R = self.palm_pose(q)
            ep = p_goal - p
            er = rotation_error(R_goal, R)
            pe, ae = float(np.linalg.norm(ep)), float(np.linalg.norm(er))
            if pe < IK_POSITION_TOLERANCE and ae < IK_ANGLE_TOLERANCE:
                break
            mujoco.mj_comPos(self.model, self.data)  # mj_jac needs cdof/subtree_com
            mujoco.mj_jacSite(self.model, self.data, jacp, jacr, self.palm_site)
            J = W @ np.vstack([jacp[:, self._arm_dof], jacr[:, self._arm_dof]])
            e = W @ np.concatenate([ep, er])
            dq = np.linalg.solve(J.T @ J + IK_DAMPING * np.eye(J.shape[1]), J.T @ e)
            scale = max(1.0, float(np.abs(dq).max()) / IK_MAX_STEP)
            q = np.clip(q + dq / scale, *self.arm_limits.T)
        found = pe < 10 * IK_POSITION_TOLERANCE and ae < 10 * IK_ANGLE_TOLERANCE
        return IKResult(bool(found), q, pe, ae)
