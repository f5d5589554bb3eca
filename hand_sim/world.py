"""The simulated world: the compiled scene of :mod:`hand_sim.assembly` stepped with MuJoCo
(section 5, Figure 13).

:meth:`World.build` turns a :class:`~hand_sim.scene.Scene` into one MuJoCo model; the accessors
hide dm_control's name prefixes and index arithmetic so that controllers read and command the
robot by joint order (:mod:`hand_sim.robot`), and :meth:`World.step` refuses to continue after
NaN or a MuJoCo instability warning.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
from dm_control import mjcf
from numpy.typing import ArrayLike, NDArray

from hand_sim import robot
from hand_sim.assembly import (
    CAMERA_NAME,
    DEFAULT_HAND,
    HAND_KINDS,
    MODELS_DIR,
    TABLE_HEIGHT_TOLERANCE,
    TABLE_MODEL,
    TABLE_XML,
    TIMESTEP,
    build_mjcf,
    geom_top,
)
from hand_sim.blocks import JOINT_SUFFIX
from hand_sim.contact_estimate import ContactEstimator, FrictionMemory
from hand_sim.errors import HandSimError, SimulationError
from hand_sim.hand_senses import TOUCH_PADS, TOUCH_TENDONS, HandSenses
from hand_sim.indices import RobotIndices, element_id
from hand_sim.perturb import Perturbation
from hand_sim.scene_spec import Scene
from hand_sim.sensing import Sensors
from hand_sim.tendon_drive import TendonDrive

__all__ = [
    "CAMERA_NAME",
    "DEFAULT_HAND",
    "HAND_KINDS",
    "MODELS_DIR",
    "TIMESTEP",
    "TOUCH_PADS",
    "TOUCH_TENDONS",
    "World",
]

#: MuJoCo warnings that mean the simulation can no longer be trusted.
FATAL_WARNINGS: tuple[mujoco.mjtWarning, ...] = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_CONTACTFULL,
    mujoco.mjtWarning.mjWARN_CNSTRFULL,
)


class World(HandSenses):
    """The compiled scene: MuJoCo model/data (``.model``, ``.data``) behind a dm_control
    ``mjcf.Physics`` (``.physics``), with accessors that speak the robot's joint order.

    Build with :meth:`build`; step with :meth:`step`, which refuses to continue after NaN or a
    MuJoCo instability warning. ``hand`` is the kind of hand on the arm (:data:`HAND_KINDS`): the
    servo hand's joint targets are its position servos' controls; the tendon hand's are held in
    registers of the same names and :meth:`step` closes its joint loop
    (:class:`~hand_sim.tendon_drive.TendonDrive`) before every physics step.

    ``perturbation`` (:mod:`hand_sim.perturb`) is how this world differs from the nominal one
    the robot believes in: it is built into the model, and :attr:`sensors` reads the world as
    the robot's sensors do (offsets, noise). A joint target is what the joint's encoder is to
    read (:meth:`set_arm_targets`); the accessors ``arm_qpos``, ``hand_qpos``... are the
    simulation's true state, for the physics, the recording and the judge.
    """

    def __init__(
        self,
        scene: Scene,
        mjcf_root: mjcf.RootElement,
        physics: mjcf.Physics,
        with_robot: bool,
        hand: str = DEFAULT_HAND,
        perturbation: Perturbation | None = None,
    ) -> None:
        self.scene = scene
        self.mjcf_root = mjcf_root
        self.physics = physics
        self.model: mujoco.MjModel = physics.model.ptr
        self.data: mujoco.MjData = physics.data.ptr
        self.with_robot = with_robot
        self.hand = hand
        self._idx = RobotIndices.of(self.model) if with_robot else RobotIndices.empty()
        #: The tendon hand's joint loop (None for the servo hand or without the robot).
        self.tendon_drive: TendonDrive | None = None
        #: The tendon hand's contact-force estimate from its tensions (None otherwise).
        self.contact_estimator: ContactEstimator | None = None
        #: The tendon hand's joints' last sliding directions (their friction's sign), updated
        #: every :meth:`step` call.
        self.friction_memory = FrictionMemory()
        if with_robot and hand == "tendon":
            self.tendon_drive = TendonDrive.for_model(self.model, robot.HAND_PREFIX)
            self.contact_estimator = ContactEstimator.for_model(self.model, robot.HAND_PREFIX)
        #: how this world differs from the nominal one (None: it is the nominal world)
        self.perturbation = perturbation
        if perturbation is not None and with_robot:
            from hand_sim.perturb_model import apply_gains

            self.tendon_drive = apply_gains(
                self.model, self.tendon_drive, perturbation, self._idx.hand_ctrl
            )
        #: the robot's sensors' readings of this world (offsets and noise of ``perturbation``)
        self.sensors = Sensors(self, perturbation)
        self._block_bodies, self._block_qpos = self._resolve_blocks()
        self._warnings = self._warning_counts()
        #: Reusable state of the controllers' kinematic queries, by model
        #: (:mod:`controllers.posture.kinematic_scratch`); nothing of the simulation.
        self.scratch: dict[object, object] = {}

    #: Called with the world after every :meth:`step` call (a controller steps once per
    #: control period): an episode's recorder and clock hook in here.
    on_step: Callable[[World], None] | None = None

    # --- construction ----------------------------------------------------------------------
    @classmethod
    def build(
        cls,
        scene: Scene,
        *,
        with_robot: bool = True,
        models_dir: Path = MODELS_DIR,
        hand: str = DEFAULT_HAND,
        perturbation: Perturbation | None = None,
    ) -> World:
        """Assemble the MJCF of ``scene``: table, arm (at :data:`ARM_BASE_POSITION`, ``home``
        posture) carrying the ``hand`` (one of :data:`HAND_KINDS`: "servo", models/hand.xml;
        "tendon", models/utah_mit_hand/), a free prism per block and the overhead camera.

        ``with_robot=False`` leaves the arm and hand out (a lighter world for vision and tests).
        ``perturbation``: the world differs from the nominal one by it (:mod:`hand_sim.perturb`).
        """
        if hand not in HAND_KINDS:
            raise HandSimError(f"unknown hand {hand!r}; valid: {', '.join(HAND_KINDS)}")
        root, home = build_mjcf(
            scene,
            with_robot=with_robot,
            models_dir=models_dir,
            hand=hand,
            perturbation=perturbation,
        )
        try:
            physics = mjcf.Physics.from_mjcf_model(root)
        except Exception as e:  # compile errors come from MuJoCo as ValueError
            raise SimulationError(
                f"the world model for scene {scene.name!r} does not compile: {e}"
            ) from e
        world = cls(scene, root, physics, with_robot, hand, perturbation)
        world._check_table()
        world._go_home(home)
        return world

    def _resolve_blocks(self) -> tuple[dict[str, int], dict[str, int]]:
        """Body ids and free-joint qpos addresses of the scene's blocks, by block name."""
        m = self.model
        obj = mujoco.mjtObj
        bodies = {b.name: element_id(m, obj.mjOBJ_BODY, b.name) for b in self.scene.blocks}
        qpos = {
            b.name: int(m.jnt_qposadr[element_id(m, obj.mjOBJ_JOINT, b.name + JOINT_SUFFIX)])
            for b in self.scene.blocks
        }
        return bodies, qpos

    def _check_table(self) -> None:
        """The table model's top must be where the scene says (blocks are placed on it)."""
        m, d = self.model, self.data
        mujoco.mj_forward(m, d)
        prefix = TABLE_MODEL + "/"
        top = -np.inf
        for g in range(m.ngeom):
            body_name = m.body(m.geom_bodyid[g]).name
            colliding = m.geom_contype[g] or m.geom_conaffinity[g]
            if body_name.startswith(prefix) and colliding:
                top = max(top, geom_top(m, d, g))
        if not np.isfinite(top) or abs(top - self.scene.table.height) > TABLE_HEIGHT_TOLERANCE:
            raise SimulationError(
                f"scene {self.scene.name!r} puts the table top at z = {self.scene.table.height} m "
                f"but models/{TABLE_XML} has its top at z = {top:.4f} m"
            )

    def _go_home(self, home: dict[str, float]) -> None:
        """Arm at the ``home`` keyframe, hand at its reference posture, every servo holding it
        (the tendon hand's tendons at their pretension)."""
        d = self.data
        for name, value in home.items():
            j = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_JOINT, robot.arm_name(name))
            if j >= 0:
                d.qpos[self.model.jnt_qposadr[j]] = value
        if self.with_robot:  # every servo holds the joint where it is
            d.ctrl[self._idx.arm_ctrl] = d.qpos[self._idx.arm_qpos]
            d.ctrl[self._idx.hand_ctrl] = d.qpos[self._idx.hand_qpos]
        if self.tendon_drive is not None:
            self.tendon_drive.rest(self.model, d)
        mujoco.mj_forward(self.model, d)
        self._initial = (d.qpos.copy(), d.qvel.copy(), d.ctrl.copy(), d.act.copy())

    # --- stepping --------------------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of :data:`TIMESTEP`; raise :class:`SimulationError` on NaN or on
        a MuJoCo instability warning (MuJoCo would otherwise silently reset the state)."""
        if n < 0:
            raise HandSimError(f"step count must be >= 0, got {n}")
        if self.tendon_drive is None:
            mujoco.mj_step(self.model, self.data, nstep=n)
        else:
            lo, hi = self.model.actuator_ctrlrange[self._idx.hand_ctrl].T
            target = np.clip(self.data.ctrl[self._idx.hand_ctrl], lo, hi)
            self.tendon_drive.step(self.model, self.data, target, n)
            self.friction_memory.update(self.data.qvel[self.tendon_drive.layout.dof_adr])
        self.check()
        if self.on_step is not None:
            self.on_step(self)

    def check(self) -> None:
        """Raise :class:`SimulationError` if the state holds NaN/inf or MuJoCo raised a warning."""
        counts = self._warning_counts()
        for w, before, now in zip(FATAL_WARNINGS, self._warnings, counts, strict=True):
            if now > before:
                self._warnings = counts
                raise SimulationError(
                    f"MuJoCo warning {w.name} at t = {self.data.time:.3f} s "
                    f"(scene {self.scene.name!r}): "
                    "the simulation is unstable and its state is not trustworthy"
                )
        d = self.data
        for field in ("qpos", "qvel", "qacc"):
            values = getattr(d, field)
            if not np.all(np.isfinite(values)):
                bad = int(np.flatnonzero(~np.isfinite(values))[0])
                raise SimulationError(
                    f"non-finite {field}[{bad}] at t = {d.time:.3f} s (scene {self.scene.name!r})"
                )

    def _warning_counts(self) -> tuple[int, ...]:
        return tuple(int(self.data.warning[w].number) for w in FATAL_WARNINGS)

    def reset(self) -> None:
        """Back to the state right after :meth:`build` (time 0, blocks placed, arm at home)."""
        mujoco.mj_resetData(self.model, self.data)
        qpos, qvel, ctrl, act = self._initial
        self.data.qpos[:], self.data.qvel[:], self.data.ctrl[:] = qpos, qvel, ctrl
        self.data.act[:] = act
        self.friction_memory.reset()
        mujoco.mj_forward(self.model, self.data)
        self._warnings = self._warning_counts()

    @property
    def time(self) -> float:
        """Simulated time (s)."""
        return float(self.data.time)

    # --- blocks ----------------------------------------------------------------------------
    def block_pose(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World position (3,) of block ``name``'s centroid (mid-height) and its quaternion (4,)
        (w, x, y, z)."""
        if name not in self._block_bodies:
            self.scene.block(name)  # raises SceneError listing the blocks
        b = self._block_bodies[name]
        return self.data.xpos[b].copy(), self.data.xquat[b].copy()

    def set_block_pose(
        self, name: str, position: ArrayLike, quat: ArrayLike = (1.0, 0.0, 0.0, 0.0)
    ) -> None:
        """Teleport block ``name`` (centroid at ``position`` (3,), orientation ``quat``
        (w, x, y, z)), at rest; recomputes the derived quantities (positions, contacts, sensors)."""
        if name not in self._block_qpos:
            self.scene.block(name)
        p, q = np.asarray(position, dtype=float), np.asarray(quat, dtype=float)
        if (
            p.shape != (3,)
            or q.shape != (4,)
            or not (np.all(np.isfinite(p)) and np.all(np.isfinite(q)))
        ):
            raise HandSimError(
                "block pose needs a finite position (3,) and quaternion (4,), "
                f"got {position!r}, {quat!r}"
            )
        norm = float(np.linalg.norm(q))
        if norm == 0.0:
            raise HandSimError("block quaternion must not be zero")
        adr = self._block_qpos[name]
        self.data.qpos[adr : adr + 3] = p
        self.data.qpos[adr + 3 : adr + 7] = q / norm
        dof = self.model.jnt_dofadr[self.model.body_jntadr[self._block_bodies[name]]]
        self.data.qvel[dof : dof + 6] = 0.0
        mujoco.mj_forward(self.model, self.data)

    def block_body_id(self, name: str) -> int:
        """MuJoCo body id of block ``name``."""
        if name not in self._block_bodies:
            self.scene.block(name)
        return self._block_bodies[name]

    def block_weight(self, name: str) -> float:
        """Weight m*g (N) of block ``name``: its mass times the model's gravity's magnitude."""
        mass = self.model.body_subtreemass[self.block_body_id(name)]
        return float(mass * np.linalg.norm(self.model.opt.gravity))

    # --- robot -----------------------------------------------------------------------------
    def _require_robot(self) -> None:
        if not self.with_robot:
            raise HandSimError("this world was built with with_robot=False: it has no arm or hand")

    def _targets(self, q: ArrayLike, n: int, what: str) -> NDArray[np.float64]:
        self._require_robot()
        a = np.asarray(q, dtype=float)
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            raise HandSimError(f"{what} targets must be {n} finite joint angles (rad), got {q!r}")
        return a

    def set_arm_targets(self, q5: ArrayLike) -> None:
        """Position-servo targets (rad) of the arm's joints, in :data:`robot.ARM_JOINTS` order:
        the angles the joints' encoders are to read (a servo closes its loop on its encoder, so
        with an encoder offset the joint stops that far from the target)."""
        q = self._targets(q5, len(robot.ARM_JOINTS), "arm")
        if self.perturbation is not None:
            q = q - self.sensors.arm_offsets
        self.data.ctrl[self._idx.arm_ctrl] = q

    def set_hand_targets(self, q16: ArrayLike) -> None:
        """Position-servo targets (rad) of the hand's joints, in :data:`robot.HAND_JOINTS` order,
        as the joints' angle sensors are to read them (the tendon hand's joint loop tracks them,
        clipped to the joint ranges)."""
        q = self._targets(q16, len(robot.HAND_JOINTS), "hand")
        if self.perturbation is not None:
            q = q - self.sensors.hand_offsets
        self.data.ctrl[self._idx.hand_ctrl] = q

    def arm_targets(self) -> NDArray[np.float64]:
        """The arm's servo targets (rad), as set by :meth:`set_arm_targets`."""
        self._require_robot()
        q = self.data.ctrl[self._idx.arm_ctrl].copy()
        return q if self.perturbation is None else q + self.sensors.arm_offsets

    def hand_targets(self) -> NDArray[np.float64]:
        """The hand's joint targets (rad), as set by :meth:`set_hand_targets`."""
        self._require_robot()
        q = self.data.ctrl[self._idx.hand_ctrl].copy()
        return q if self.perturbation is None else q + self.sensors.hand_offsets

    def arm_qpos(self) -> NDArray[np.float64]:
        """Arm joint angles (rad), :data:`robot.ARM_JOINTS` order."""
        self._require_robot()
        return self.data.qpos[self._idx.arm_qpos].copy()

    def hand_qpos(self) -> NDArray[np.float64]:
        """Hand joint angles (rad), :data:`robot.HAND_JOINTS` order."""
        self._require_robot()
        return self.data.qpos[self._idx.hand_qpos].copy()

    def arm_qvel(self) -> NDArray[np.float64]:
        """Arm joint velocities (rad/s), :data:`robot.ARM_JOINTS` order."""
        self._require_robot()
        return self.data.qvel[self._idx.arm_dof].copy()

    def hand_qvel(self) -> NDArray[np.float64]:
        """Hand joint velocities (rad/s), :data:`robot.HAND_JOINTS` order."""
        self._require_robot()
        return self.data.qvel[self._idx.hand_dof].copy()

    def hand_qacc(self) -> NDArray[np.float64]:
        """Hand joint accelerations (rad/s^2), :data:`robot.HAND_JOINTS` order."""
        self._require_robot()
        return self.data.qacc[self._idx.hand_dof].copy()

    def arm_ctrlrange(self) -> NDArray[np.float64]:
        """(5, 2) control range of the arm's servos (rad)."""
        self._require_robot()
        return self.model.actuator_ctrlrange[self._idx.arm_ctrl].copy()

    def hand_ctrlrange(self) -> NDArray[np.float64]:
        """(16, 2) control range of the hand's servos (rad): the joint ranges (the servo hand's
        actuators and the tendon hand's target registers inherit them)."""
        self._require_robot()
        return self.model.actuator_ctrlrange[self._idx.hand_ctrl].copy()

    def fingertip_positions(self) -> NDArray[np.float64]:
        """(4, 3) world positions of the fingertip sites, order ff, mf, rf, th."""
        self._require_robot()
        return self.data.site_xpos[self._idx.tip_sites].copy()
