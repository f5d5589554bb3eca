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
from hand_sim.contact_estimate import (
    DETECTION_THRESHOLD,
    ContactEstimate,
    ContactEstimator,
    FrictionMemory,
)
from hand_sim.errors import HandSimError, SimulationError
from hand_sim.indices import RobotIndices, element_id
from hand_sim.scene_spec import Scene
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

#: What :meth:`World.touch` reads: the fingertip touch pads (the servo hand), or the contact
#: forces estimated from the tendon tensions (the tendon hand, :mod:`hand_sim.contact_estimate`).
TOUCH_PADS, TOUCH_TENDONS = "touch pads", "tendon-tension estimate"

#: MuJoCo warnings that mean the simulation can no longer be trusted.
FATAL_WARNINGS: tuple[mujoco.mjtWarning, ...] = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
    mujoco.mjtWarning.mjWARN_CONTACTFULL,
    mujoco.mjtWarning.mjWARN_CNSTRFULL,
)


class World:
    """The compiled scene: MuJoCo model/data (``.model``, ``.data``) behind a dm_control
    ``mjcf.Physics`` (``.physics``), with accessors that speak the robot's joint order.

    Build with :meth:`build`; step with :meth:`step`, which refuses to continue after NaN or a
    MuJoCo instability warning. ``hand`` is the kind of hand on the arm (:data:`HAND_KINDS`): the
    servo hand's joint targets are its position servos' controls; the tendon hand's are held in
    registers of the same names and :meth:`step` closes its joint loop
    (:class:`~hand_sim.tendon_drive.TendonDrive`) before every physics step.
    """

    def __init__(
        self,
        scene: Scene,
        mjcf_root: mjcf.RootElement,
        physics: mjcf.Physics,
        with_robot: bool,
        hand: str = DEFAULT_HAND,
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
        self._block_bodies, self._block_qpos = self._resolve_blocks()
        self._warnings = self._warning_counts()
        #: Called with the world after every :meth:`step` call (a controller steps once per
        #: control period): an episode's recorder and clock hook in here.
        self.on_step: Callable[[World], None] | None = None
        #: Reusable state of the controllers' kinematic queries, by model
        #: (:mod:`controllers.posture.kinematic_scratch`); nothing of the simulation.
        self.scratch: dict[object, object] = {}

    # --- construction ----------------------------------------------------------------------
    @classmethod
    def build(
        cls,
        scene: Scene,
        *,
        with_robot: bool = True,
        models_dir: Path = MODELS_DIR,
        hand: str = DEFAULT_HAND,
    ) -> World:
        """Assemble the MJCF of ``scene``: table, arm (at :data:`ARM_BASE_POSITION`, ``home``
        posture) carrying the ``hand`` (one of :data:`HAND_KINDS`: "servo", models/hand.xml;
        "tendon", models/utah_mit_hand/), a free prism per block and the overhead camera.

        ``with_robot=False`` leaves the arm and hand out (a lighter world for vision and tests).
        """
        if hand not in HAND_KINDS:
            raise HandSimError(f"unknown hand {hand!r}; valid: {', '.join(HAND_KINDS)}")
        root, home = build_mjcf(scene, with_robot=with_robot, models_dir=models_dir, hand=hand)
        try:
            physics = mjcf.Physics.from_mjcf_model(root)
        except Exception as e:  # compile errors come from MuJoCo as ValueError
            raise SimulationError(
                f"the world model for scene {scene.name!r} does not compile: {e}"
            ) from e
        world = cls(scene, root, physics, with_robot, hand)
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
        if self.with_robot:
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
        """Position-servo targets (rad) of the arm's joints, in :data:`robot.ARM_JOINTS` order."""
        self.data.ctrl[self._idx.arm_ctrl] = self._targets(q5, len(robot.ARM_JOINTS), "arm")

    def set_hand_targets(self, q16: ArrayLike) -> None:
        """Position-servo targets (rad) of the hand's joints, in :data:`robot.HAND_JOINTS` order
        (the tendon hand's joint loop tracks them, clipped to the joint ranges)."""
        self.data.ctrl[self._idx.hand_ctrl] = self._targets(q16, len(robot.HAND_JOINTS), "hand")

    def arm_targets(self) -> NDArray[np.float64]:
        self._require_robot()
        return self.data.ctrl[self._idx.arm_ctrl].copy()

    def hand_targets(self) -> NDArray[np.float64]:
        self._require_robot()
        return self.data.ctrl[self._idx.hand_ctrl].copy()

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

    @property
    def touch_source(self) -> str:
        """What :meth:`touch` reads: :data:`TOUCH_PADS` or :data:`TOUCH_TENDONS`."""
        return TOUCH_TENDONS if self.contact_estimator is not None else TOUCH_PADS

    @property
    def touch_floor(self) -> float:
        """Force (N) at or below which :meth:`touch` means "no contact" (a lost grip): 0 for the
        touch pads; the estimate's error floor for the tendon hand
        (:data:`hand_sim.contact_estimate.DETECTION_THRESHOLD`)."""
        return DETECTION_THRESHOLD if self.contact_estimator is not None else 0.0

    def touch_felt(self, threshold: float, forces: ArrayLike | None = None) -> NDArray[np.bool_]:
        """(4,) whether a guard may take each finger for touching now: with touch pads, its pad
        force (``forces``, default :meth:`touch_sensors`) above ``threshold``; for the tendon
        hand, the least pad force its tensions allow, every stuck joint's friction anywhere in
        [-F, F] (:attr:`~hand_sim.contact_estimate.ContactEstimate.least`), above ``threshold``
        and :data:`~hand_sim.contact_estimate.DETECTION_THRESHOLD`: a finger that friction alone
        could hold where it is is not taken for a touching one, and a finger pressing harder than
        its friction could explain is, however unsure the estimate's friction."""
        if self.contact_estimator is None:
            self._require_robot()
            pads = self.touch_sensors() if forces is None else np.asarray(forces, dtype=float)
            return pads > threshold
        least = self.contact_estimator.estimate(
            self.model, self.data, self.friction_memory.direction, least=True
        ).least
        return np.asarray(least) > max(threshold, DETECTION_THRESHOLD)

    def touch(self, normals: ArrayLike | None = None) -> NDArray[np.float64]:
        """(4,) fingertip normal forces (N), order ff, mf, rf, th, as the hand senses them: the
        servo hand's touch pads (:meth:`touch_sensors`); the tendon hand, which like the real
        Utah/MIT hand has no fingertip sensors, the estimate from its tendon tensions and joint
        angles (:meth:`contact_estimate`). :attr:`touch_source` says which. ``normals`` (4, 3):
        the contacts' outward face normals (world axes), when the caller knows them (a planned
        grip): the tendon hand then reports each estimated force's component into its face
        (the pads measure the normal force anyway)."""
        if self.contact_estimator is not None:
            return self.contact_estimate(normals).normal
        return self.touch_sensors()

    def touch_sensors(self) -> NDArray[np.float64]:
        """(4,) fingertip touch sensor readings (N), order ff, mf, rf, th: the normal force on the
        palmar side and tip of each distal pad (contacts on the back of a fingertip, or on other
        finger links, are not felt; :func:`hand_sim.contacts.hand_contacts` lists those). Both
        hands have them; for the tendon hand they are the ground truth its estimate is judged
        against, not something its guards read."""
        self._require_robot()
        return self.data.sensordata[self._idx.touch_adr].copy()

    def contact_estimate(self, normals: ArrayLike | None = None) -> ContactEstimate:
        """The tendon hand's fingertip forces estimated from its 32 tension sensors and joint
        angles (:class:`~hand_sim.contact_estimate.ContactEstimator`; ``normals``: the contacts'
        outward face normals, as in :meth:`touch`); raises for the servo hand."""
        self._require_robot()
        if self.contact_estimator is None:
            raise HandSimError(f"the {self.hand} hand has no tendons to estimate forces from")
        faces = None if normals is None else np.asarray(normals, dtype=float).reshape(4, 3)
        return self.contact_estimator.estimate(
            self.model, self.data, self.friction_memory.direction, normals=faces
        )

    def wrist_wrench(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The wrist force/torque sensor between the arm's flange and the hand: force (3,) in N
        and torque (3,) in N m that the flange exerts on the hand, in world axes. With the hand
        at rest it carries the hand's weight plus whatever the hand holds."""
        self._require_robot()
        i, j = self._idx.wrist_force_adr, self._idx.wrist_torque_adr
        R = self.data.site_xmat[self._idx.mount_site].reshape(3, 3)
        d = self.data.sensordata
        return R @ d[i : i + 3], R @ d[j : j + 3]

    def wrist_acceleration(self) -> NDArray[np.float64]:
        """The wrist accelerometer (m/s^2, world axes): the hand's acceleration minus gravity, so
        (0, 0, 9.81) at rest."""
        self._require_robot()
        i = self._idx.wrist_accel_adr
        R = self.data.site_xmat[self._idx.mount_site].reshape(3, 3)
        return R @ self.data.sensordata[i : i + 3]

    def hand_tensions(self) -> NDArray[np.float64]:
        """(16, 2) tendon tensions (N) of the tendon hand's joints (:data:`robot.HAND_JOINTS`
        order; flexor, extensor), read by its tension sensors; raises for the servo hand."""
        self._require_robot()
        if self.tendon_drive is None:
            raise HandSimError(f"the {self.hand} hand has no tendons")
        return np.column_stack(self.tendon_drive.layout.tensions(self.data))

    def hand_joint_torques(self) -> NDArray[np.float64]:
        """(16,) torques (N m) the hand's actuators apply to its joints (the servos, or the
        tendon pairs), :data:`robot.HAND_JOINTS` order."""
        self._require_robot()
        return self.data.qfrc_actuator[self._idx.hand_dof].copy()
