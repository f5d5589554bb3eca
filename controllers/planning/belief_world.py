"""The world as the robot believes it: the nominal robot in a model of its own, the blocks the
overhead camera saw, and what the robot's sensors read (section 5.2-5.3; docs/robustness.md).

The simulated world (:class:`hand_sim.world.World`) is the truth: the physics steps it, the
renderer draws it, the judge reads it. The robot's software -- every controller, the vision and
the task cycle's states -- works on a :class:`BeliefWorld` instead, which has the World's
interface and answers every question from the robot's belief:

- **its model** is compiled from the unperturbed scene's robot and table (link lengths, joint
  offsets, the arm's base and the camera's pose as calibrated) with, for blocks, the prisms the
  overhead camera saw (:meth:`BeliefWorld.see`: each block's polygon extruded to its seen height,
  an unmodelled one as the hull of its pixels); before the first look it holds no block;
- **its state** is what the sensors read: the joint angles from the encoders
  (:attr:`hand_sim.world.World.sensors`: true angle + offset + noise), the joint velocities and
  accelerations (the encoders differentiated), the tendon tensions, the wrist's force, torque and
  acceleration, the servo hand's pads; the fingertips, the palm and the contact forces estimated
  from the tensions follow from them by the nominal kinematics;
- **a held block** moves with the palm as it was when the hand closed on it
  (:meth:`BeliefWorld.hold`): the robot does not see a block in its hand;
- **its commands** go to the simulated robot's servos (joint targets as the encoders are to read
  them) and :meth:`BeliefWorld.step` steps the simulation;
- **the overhead image** (:meth:`BeliefWorld.look`) is rendered by the true camera and read
  through the sensor's noise, but interpreted with the nominal camera model, which the robot
  checks against the table in the same view (:mod:`vision.calibration`) and corrects when it
  has drifted. Unperturbed, the image and its geometry are bit for bit those of the simulated
  camera.

The simulated world is held privately and reached only through its sensors and servos; nothing
here reads a simulated block. The state is read from the sensors lazily, once after each step,
when something asks for it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import mujoco
import numpy as np
from dm_control import mjcf
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.polygon import Polygon, centroid_of
from hand_sim import robot
from hand_sim.assembly import CAMERA_NAME, build_mjcf
from hand_sim.camera import camera_pose, focal_length, intrinsics
from hand_sim.errors import HandSimError, SimulationError
from hand_sim.perturb import PerturbSpec
from hand_sim.scene_spec import BlockSpec
from hand_sim.tendon_drive import joint_torques
from hand_sim.world import World
from vision import DEFAULT_HEIGHT, DEFAULT_WIDTH, CameraGeometry, Observation, overhead_camera
from vision.calibration import Calibration, calibrate

#: Colour of the seen blocks in the belief's model (it is never rendered for perception).
SEEN_RGBA = (0.6, 0.6, 0.6, 1.0)


class BeliefWorld(World):
    """The robot's view of the simulated world ``sim`` (module docstring), with the World's
    interface. Build with :meth:`over`; tell it what the camera saw with :meth:`see`."""

    def __init__(self, sim: World, blocks: Sequence[BlockSpec] = ()) -> None:
        if not sim.with_robot:
            raise HandSimError("a belief needs a simulated world with the robot in it")
        self._sim = sim
        self._held: tuple[str, NDArray[np.float64], NDArray[np.float64]] | None = None
        #: where the robot last knew each named block (world xy): the task's layout at first,
        #: then where the camera saw it or the hand put it; the names the next view's blocks get
        self.labels: dict[str, NDArray[np.float64]] = {
            b.name: np.asarray(b.position, dtype=float) for b in sim.scene.blocks
        }
        #: the camera's last check against the table (:meth:`look`), or None
        self.last_check: Calibration | None = None
        self._build(tuple(blocks))

    @classmethod
    def over(cls, sim: World) -> BeliefWorld:
        """The robot's belief before it has looked: the nominal robot and table, no block."""
        return cls(sim)

    def _build(self, blocks: tuple[BlockSpec, ...]) -> None:
        """Compile the nominal robot, table and camera with ``blocks`` (World's own setup)."""
        sim = self._sim
        scene = dataclasses.replace(sim.scene, blocks=blocks, perturb=PerturbSpec())
        root, _ = build_mjcf(scene, with_robot=True, hand=sim.hand)
        try:
            physics = mjcf.Physics.from_mjcf_model(root)
        except Exception as e:  # compile errors come from MuJoCo as ValueError
            raise SimulationError(f"the robot's belief does not compile: {e}") from e
        self._dirty = False  # World's setup reads the data before the sensors are read
        World.__init__(self, scene, root, physics, True, sim.hand, None)
        # the joints' sliding history is sensed (the encoders, differentiated): the estimate
        # of the contact forces shares the simulated hand's
        self.friction_memory = sim.friction_memory
        self._palm = self.model.body(robot.hand_name(robot.PALM_BODY)).id
        self._camera = self.model.camera(CAMERA_NAME).id
        self._dirty = True

    # --- what the robot saw ----------------------------------------------------------------
    def see(self, blocks: Sequence[BlockSpec]) -> None:
        """Believe the table holds ``blocks`` (the camera's view of it; names as labelled), each
        standing on the table. A block held is let go of first (the robot looks with its arm
        parked)."""
        self._held = None
        self._build(tuple(blocks))
        for b in blocks:
            if b.name in self.labels:
                self.labels[b.name] = np.asarray(b.position, dtype=float)

    def put(self, name: str, xy: ArrayLike) -> None:
        """Remember that block ``name`` now stands at ``xy`` (the hand set it down there)."""
        self.labels[name] = np.asarray(xy, dtype=float).reshape(2).copy()

    def look(
        self, width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT, *, check: bool = True
    ) -> Observation:
        """The overhead camera's view now: the simulated camera's images as its sensor delivers
        them (:meth:`hand_sim.sensing.Sensors.image`), with the camera's geometry as calibrated
        (the nominal model's) or, with ``check``, as the table in this very view shows it when
        that differs (:func:`vision.calibration.calibrate`; :attr:`last_check` keeps the
        result)."""
        with overhead_camera(self._sim, width, height) as cam:
            rgb, depth = cam.rgb(), cam.depth()
        rgb, depth = self._sim.sensors.image(rgb, depth)
        obs = Observation(
            np.ascontiguousarray(rgb, dtype=np.uint8),
            np.ascontiguousarray(depth, dtype=np.float32),
            self.camera_geometry(width, height),
        )
        if not check:
            return obs
        table = self.scene.table
        self.last_check = calibrate(obs, table.position_xy, table.size_xy, table.height)
        if not self.last_check.corrected:
            return obs
        return Observation(obs.rgb, obs.depth, self.last_check.geometry)

    def camera_geometry(self, width: int, height: int) -> CameraGeometry:
        """The overhead camera as calibrated (the nominal model's), for a ``width`` x ``height``
        image; the arithmetic is the simulated camera's (:mod:`hand_sim.camera`)."""
        K = intrinsics(focal_length(self.model, self._camera, height), width, height)
        return CameraGeometry(K, camera_pose(self.data, self._camera), width, height)

    # --- a held block ----------------------------------------------------------------------
    def hold(self, name: str) -> None:
        """From now on block ``name`` moves with the palm, as it is relative to it now."""
        d = self.data
        body = self.block_body_id(name)
        R = d.xmat[self._palm].reshape(3, 3)
        p_rel = R.T @ (d.xpos[body] - d.xpos[self._palm])
        R_rel = R.T @ d.xmat[body].reshape(3, 3)
        self._held = (name, p_rel, R_rel)

    def let_go(self) -> None:
        """The hand no longer holds a block; it stays where the belief last had it."""
        self._held = None

    @property
    def held(self) -> str | None:
        """The block the belief moves with the palm, or None."""
        return None if self._held is None else self._held[0]

    # --- state from the sensors ------------------------------------------------------------
    @property
    def data(self) -> mujoco.MjData:
        """The belief's state, read from the sensors once after each step."""
        if self._dirty:
            self._dirty = False
            self._read_sensors()
        return self._data

    @data.setter
    def data(self, value: mujoco.MjData) -> None:
        self._data = value

    def _read_sensors(self) -> None:
        sim, m, d, idx = self._sim, self.model, self._data, self._idx
        d.qpos[idx.arm_qpos] = sim.sensors.arm_angles()
        d.qpos[idx.hand_qpos] = sim.sensors.hand_angles()
        d.qvel[:] = 0.0
        d.qvel[idx.arm_dof] = sim.arm_qvel()
        d.qvel[idx.hand_dof] = sim.hand_qvel()
        if self._held is not None:
            name, p_rel, R_rel = self._held
            mujoco.mj_kinematics(m, d)
            R = d.xmat[self._palm].reshape(3, 3)
            adr = self._block_qpos[name]
            d.qpos[adr : adr + 3] = d.xpos[self._palm] + R @ p_rel
            quat = np.empty(4)
            mujoco.mju_mat2Quat(quat, (R @ R_rel).ravel())
            d.qpos[adr + 3 : adr + 7] = quat
        mujoco.mj_fwdPosition(m, d)
        mujoco.mj_fwdVelocity(m, d)
        d.qacc[:] = 0.0
        d.qacc[idx.hand_dof] = sim.hand_qacc()
        if self.tendon_drive is not None:
            layout = self.tendon_drive.layout
            tensions = sim.sensors.tensions()
            d.sensordata[layout.flex_sensor_adr] = tensions[:, 0]
            d.sensordata[layout.ext_sensor_adr] = tensions[:, 1]
            d.sensordata[layout.angle_sensor_adr] = d.qpos[layout.qpos_adr]
        d.time = sim.time

    def wrist_readings(self) -> NDArray[np.float64]:
        return self._sim.sensors.wrist()

    def pad_forces(self) -> NDArray[np.float64]:
        """(4,) the servo hand's pads' forces against anything not the robot (its sensors)."""
        return self._sim.pad_forces()

    def touch_sensors(self) -> NDArray[np.float64]:
        """(4,) the fingertip touch pads' readings (the simulated hand's sensors)."""
        return self._sim.touch_sensors()

    def hand_joint_torques(self) -> NDArray[np.float64]:
        """(16,) joint torques (N m): the tendon hand's from its sensed tensions, the servo
        hand's as its servos report them."""
        if self.tendon_drive is None:
            return self._sim.hand_joint_torques()
        t = self.hand_tensions()
        return joint_torques(t[:, 0], t[:, 1], self.tendon_drive.layout.radius)

    # --- commands and time go to the simulated robot -----------------------------------------
    def step(self, n: int = 1) -> None:
        """Step the simulation ``n`` physics steps (its servos tracking the targets)."""
        self._sim.step(n)
        self._dirty = True

    def check(self) -> None:
        self._sim.check()

    def reset(self) -> None:
        raise HandSimError("the robot's belief is not reset: build a new one over the world")

    @property
    def time(self) -> float:
        """Simulated time (s): the robot's clock."""
        return self._sim.time

    @property  # type: ignore[override]
    def on_step(self) -> Callable[[World], None] | None:
        """The simulated world's step hook (an episode's clock and recorder)."""
        return self._sim.on_step

    @on_step.setter
    def on_step(self, hook: Callable[[World], None] | None) -> None:
        self._sim.on_step = hook

    def set_arm_targets(self, q5: ArrayLike) -> None:
        self._sim.set_arm_targets(q5)

    def set_hand_targets(self, q16: ArrayLike) -> None:
        self._sim.set_hand_targets(q16)

    def arm_targets(self) -> NDArray[np.float64]:
        return self._sim.arm_targets()

    def hand_targets(self) -> NDArray[np.float64]:
        return self._sim.hand_targets()


def modelled_block(
    name: str, polygon: Polygon, centroid_xy: ArrayLike, yaw: float, height: float
) -> BlockSpec:
    """A block the camera modelled: ``polygon`` in its object frame (centroid at the origin)
    turned by ``yaw`` about its centroid at world ``centroid_xy``, ``height`` m tall."""
    xy = np.asarray(centroid_xy, dtype=float)
    position = (float(xy[0]), float(xy[1]))
    return BlockSpec(name, polygon, position, float(yaw), float(height), SEEN_RGBA)


def outline_block(name: str, outline_xy: ArrayLike, height: float) -> BlockSpec:
    """A block the camera saw but could not model: its outline ``outline_xy`` (k, 2), world,
    convex (the hull of its top face's pixels), extruded to ``height`` m."""
    xy = np.asarray(outline_xy, dtype=float)
    c = centroid_of(xy)
    polygon = Polygon.from_vertices(xy - c, name=name)
    return BlockSpec(name, polygon, (float(c[0]), float(c[1])), 0.0, float(height), SEEN_RGBA)
