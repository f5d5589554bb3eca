"""Physics telemetry of a :class:`~hand_sim.world.World` with the robot, written to a
:class:`~hand_sim.recorder.Recorder` at rates of *simulated* time (:mod:`hand_sim.schedule`).

:meth:`WorldTelemetry.tick` (hook it into ``World.on_step``) logs what is due:

- ``world/bodies/...``: each moving body's pose (``body_hz``, buffered and sent as columns; the
  static geometry is logged by the :class:`~hand_sim.recorder.Recorder` itself);
- ``world/cameras/overhead``: the overhead camera's pose and pinhole (static, logged once), its
  RGB images at ``world/cameras/overhead/rgb`` (``image_hz``, JPEG);
- ``scalars/arm/<joint>/{q,target}``, ``scalars/hand/<finger>/j<i>/{q,target}`` (rad),
  ``scalars/actuator_force/...`` (N m), ``scalars/touch/<finger>`` (N),
  ``scalars/wrist/{force,torque}/{x,y,z}`` (N, N m, world axes) at ``scalar_hz``, buffered
  (:func:`series_names`); with the tendon hand also its 32 tendon tensions
  ``scalars/tendon/<finger>/j<i>_<flex|ext>`` (N, the tension sensors) and the fingertip forces
  estimated from them, ``scalars/contact_estimate/<finger>`` (N, what its guards read, beside the
  touch pads' ground truth ``touch/<finger>``), and its ``actuator_force/hand/...`` are the
  joint torques the tendon pairs apply (N m);
- ``world/contacts/{points,forces}``: the contacts between the robot and a target block
  (:meth:`WorldTelemetry.set_contact_target`; ``mj_contactForce`` via
  :func:`hand_sim.contacts.robot_contacts`) as points and arrows whose tip is the contact point
  and whose length is :data:`FORCE_ARROW_SCALE` metres per newton, with
  ``scalars/contact_force/<finger|palm|arm>`` (normal force on the block, N), at ``contact_hz``.

Everything is on the ``sim_time`` (duration, s) and ``step`` (physics step index) timelines.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np
import rerun as rr
from numpy.typing import NDArray

from hand_sim import robot
from hand_sim.camera import OverheadCamera
from hand_sim.contacts import robot_contacts
from hand_sim.errors import HandSimError
from hand_sim.recorder import SCALARS_PATH, Recorder, sim_step
from hand_sim.schedule import RateSchedule
from hand_sim.world import CAMERA_NAME, World

#: Length (m) of a contact force arrow per newton: the 6 N grip force of
#: :data:`controllers.hand.grip.GRIP_FORCE` draws a 3 cm arrow beside a ~5 cm block.
FORCE_ARROW_SCALE = 0.005
#: Radius (m) of the drawn contact points and force arrows.
CONTACT_RADIUS = 0.003
ARROW_RADIUS = 0.0015
#: Distance (m) from a camera at which the 3D view draws its image: the overhead camera hangs
#: ~1.2 m above the table, so at 0.25 m its image floats well above the robot's reach.
IMAGE_PLANE_DISTANCE = 0.25
#: Where the contacts are drawn (entity path).
CONTACTS_PATH = "world/contacts"
#: Colour (rgb) per robot part touching the target.
PART_COLOURS: dict[str, tuple[int, int, int]] = {
    "ff": (230, 60, 60),
    "mf": (60, 180, 75),
    "rf": (60, 110, 230),
    "th": (245, 150, 30),
    "palm": (150, 150, 150),
    "arm": (160, 80, 200),
}
#: Colours of the arm's joints (base to wrist) and of the x, y, z axes in the plots.
SERIES_PALETTE: tuple[tuple[int, int, int], ...] = (
    (230, 60, 60),
    (60, 180, 75),
    (60, 110, 230),
    (245, 150, 30),
    (160, 80, 200),
)
#: Where the tendon hand's tensions are logged (under ``scalars/``), and the sides of a pair.
TENDON_PATH = "tendon"
#: Where the tendon hand's estimated fingertip forces are logged (under ``scalars/``), beside
#: the touch pads' ``touch/<finger>``.
ESTIMATE_PATH = "contact_estimate"
TENDON_SIDES: tuple[str, ...] = ("flex", "ext")
#: Names (under ``scalars/``) of the contact force series, :data:`PART_COLOURS` order.
CONTACT_SERIES: tuple[str, ...] = tuple(f"contact_force/{p}" for p in PART_COLOURS)


@dataclass
class RecordingStats:
    """What the telemetry logged and what it cost (wall time spent inside
    :meth:`WorldTelemetry.tick`)."""

    ticks: int = 0
    body_frames: int = 0
    scalar_rows: int = 0
    images: int = 0
    contact_frames: int = 0
    tick_seconds: float = 0.0

    @property
    def seconds_per_tick(self) -> float:
        return self.tick_seconds / self.ticks if self.ticks else 0.0


#: Default rate (Hz of simulated time) of the overhead camera's recorded images: a 640x480
#: render and its JPEG cost 5-9 ms each (docs/recording.md), the largest part of what recording
#: adds to an episode; the 3D view moves at ``body_hz`` whatever this rate.
IMAGE_HZ = 2.0


@dataclass(frozen=True)
class TelemetryRates:
    """Rates (Hz of simulated time; 0: never) of each kind of record. Checked when made: a
    negative or non-finite rate raises :class:`HandSimError` naming it (``image_rate_hz``...)."""

    body_hz: float = 50.0
    scalar_hz: float = 50.0
    image_hz: float = IMAGE_HZ
    contact_hz: float = 10.0

    def __post_init__(self) -> None:
        self.schedule()

    def schedule(self) -> RateSchedule:
        """A fresh schedule of the rates named ``body``, ``scalar``, ``image``, ``contact``."""
        rates = {
            "body": self.body_hz,
            "scalar": self.scalar_hz,
            "image": self.image_hz,
            "contact": self.contact_hz,
        }
        return RateSchedule(rates, "{name}_rate_hz")


def rgba(colour: tuple[int, int, int], alpha: int = 255) -> list[int]:
    """``colour`` with an alpha, as rerun takes it."""
    return [*colour, alpha]


def tendon_series_names() -> list[str]:
    """Names (under ``scalars/``) of the tendon hand's 32 tension series, joint by joint
    (:data:`robot.HAND_JOINTS` order), flexor then extensor."""
    return [
        f"{TENDON_PATH}/{f}/j{i}_{side}"
        for f in robot.FINGERS
        for i in range(robot.JOINTS_PER_FINGER)
        for side in TENDON_SIDES
    ]


def series_names(hand: str = "servo") -> list[str]:
    """Names (under ``scalars/``) of the series logged at the scalar rate with the ``hand``
    (``World.hand``), in the order of a row of :meth:`WorldTelemetry.scalar_row`."""
    arm = robot.ARM_JOINTS
    joints = [f"{f}/j{i}" for f in robot.FINGERS for i in range(robot.JOINTS_PER_FINGER)]
    return [
        *(f"arm/{j}/q" for j in arm),
        *(f"arm/{j}/target" for j in arm),
        *(f"hand/{j}/q" for j in joints),
        *(f"hand/{j}/target" for j in joints),
        *(f"actuator_force/arm/{j}" for j in arm),
        *(f"actuator_force/hand/{j}" for j in joints),
        *(f"touch/{f}" for f in robot.FINGERS),
        *(f"wrist/force/{a}" for a in "xyz"),
        *(f"wrist/torque/{a}" for a in "xyz"),
        *(tendon_series_names() if hand == "tendon" else []),
        *(f"{ESTIMATE_PATH}/{f}" for f in (robot.FINGERS if hand == "tendon" else ())),
    ]


def style_series(
    stream: rr.RecordingStream,
    name: str,
    colour: tuple[int, int, int],
    label: str,
    *,
    target: bool = False,
) -> None:
    """Static name and colour of the plotted series ``scalars/<name>``; a servo target is drawn
    thinner and paler than the position it is the target of."""
    stream.log(
        f"{SCALARS_PATH}/{name}",
        rr.SeriesLines(
            colors=[rgba(colour, 120 if target else 255)],
            widths=[1.0 if target else 2.0],
            names=[label],
        ),
        static=True,
    )


def style_telemetry_series(stream: rr.RecordingStream, hand: str = "servo") -> None:
    """Styles of every telemetry series: a joint's position and its servo target share a colour
    (the target thinner and paler), fingers keep their colours; the tendon hand's tensions take
    their joint's colour, the extensor drawn thinner and paler."""
    palette = SERIES_PALETTE
    for i, j in enumerate(robot.ARM_JOINTS):
        for kind in ("q", "target"):
            label = f"{j} {kind}"
            style_series(stream, f"arm/{j}/{kind}", palette[i], label, target=kind == "target")
        style_series(stream, f"actuator_force/arm/{j}", palette[i], j)
    for f in robot.FINGERS:
        for i in range(robot.JOINTS_PER_FINGER):
            shade = tuple(int(c * (1.0 - 0.18 * i)) for c in PART_COLOURS[f])
            for kind in ("q", "target"):
                label = f"{f}j{i} {kind}"
                style_series(stream, f"hand/{f}/j{i}/{kind}", shade, label, target=kind == "target")
            style_series(stream, f"actuator_force/hand/{f}/j{i}", shade, f"{f}a{i}")
            if hand == "tendon":
                for side in TENDON_SIDES:
                    name = f"{TENDON_PATH}/{f}/j{i}_{side}"
                    style_series(stream, name, shade, f"{f}j{i} {side}", target=side == "ext")
        style_series(stream, f"touch/{f}", PART_COLOURS[f], f"touch {f}")
        if hand == "tendon":
            style_series(
                stream, f"{ESTIMATE_PATH}/{f}", PART_COLOURS[f], f"estimate {f}", target=True
            )
    for part, colour in PART_COLOURS.items():
        style_series(stream, f"contact_force/{part}", colour, f"{part} on target")
    for i, a in enumerate("xyz"):
        style_series(stream, f"wrist/force/{a}", palette[i], f"F{a}")
        style_series(stream, f"wrist/torque/{a}", palette[i], f"T{a}", target=True)


def plain_camera(world: World, width: int, height: int) -> OverheadCamera:
    """An overhead camera without multisampling, whatever the vision's camera has set on the
    model (MuJoCo reads ``offsamples`` when a renderer is made): 13 ms per 640x480 frame on our
    loaded 2-core machine, 36-43 ms with the vision's 4x MSAA."""
    quality = world.model.vis.quality
    saved = int(quality.offsamples)
    quality.offsamples = 0
    try:
        return OverheadCamera(world, width, height)
    finally:
        quality.offsamples = saved


def actuator_ids(world: World) -> NDArray[np.int64]:
    """Ids of the arm's then the hand's actuators (:data:`robot.ARM_ACTUATORS`,
    :data:`robot.HAND_ACTUATORS` order)."""
    names = (*robot.ARM_ACTUATORS, *robot.HAND_ACTUATORS)
    ids = [
        mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_ACTUATOR, robot.qualified(n))
        for n in names
    ]
    return np.array(ids, dtype=np.int64)


class WorldTelemetry:
    """Logs ``world``'s physics to ``recorder`` at ``rates`` (see the module docstring); its
    overhead camera renders ``overhead_width`` x ``overhead_height`` images. Making it logs the
    camera's pinhole and the series' styles (static); :meth:`close` releases the camera (the
    recorder stays open: it is the caller's)."""

    def __init__(
        self,
        recorder: Recorder,
        world: World,
        rates: TelemetryRates,
        *,
        overhead_width: int = 640,
        overhead_height: int = 480,
    ) -> None:
        if not world.with_robot:
            raise HandSimError("robot telemetry needs a world with the arm and hand")
        self.recorder = recorder
        self.world = world
        self.stats = RecordingStats()
        self.series = series_names(world.hand)
        self._schedule = rates.schedule()
        self._target: int | None = None
        self._contacts_shown = False
        self._last_logged: float | None = None
        self._latest: tuple[int, float] | None = None  # (step, sim_time) of the latest tick
        self._actuators = actuator_ids(world)
        self.camera = plain_camera(world, overhead_width, overhead_height)
        try:
            cam = self.camera
            recorder.log_camera(
                CAMERA_NAME,
                cam.intrinsics,
                cam.pose,
                (cam.width, cam.height),
                image_plane_distance=IMAGE_PLANE_DISTANCE,
            )
            style_telemetry_series(recorder.stream, world.hand)
        except BaseException:
            self.camera.close()
            raise

    # --- every simulation step -------------------------------------------------------------
    def tick(self, world: World) -> None:
        """Log what is due at the world's current simulated time (``World.on_step`` hook)."""
        started = time.perf_counter()
        if world.model is not self.world.model:
            raise HandSimError("the telemetry got a different world than it records")
        t = world.time
        if self._latest is None or t > self._latest[1]:
            self._latest = (sim_step(world), t)
        due = self._schedule.due(t)
        if any(due.values()):
            self._log_frame(world, due)
            self._last_logged = t
        else:
            self.recorder.set_time(sim_step(world), t)
        self.stats.ticks += 1
        self.stats.tick_seconds += time.perf_counter() - started

    def _log_frame(self, world: World, due: dict[str, bool]) -> None:
        rec = self.recorder
        st = self.stats
        if due["body"]:
            rec.log_world(world)
            st.body_frames += 1
        else:
            rec.set_time(sim_step(world), world.time)
        if due["scalar"]:
            rec.log_scalars(self.series, self.scalar_row(world))
            st.scalar_rows += 1
        if due["image"]:
            rec.log_camera_image(CAMERA_NAME, self.camera.rgb())
            st.images += 1
        if due["contact"]:
            self._log_contacts(world)
            st.contact_frames += 1

    def scalar_row(self, world: World) -> NDArray[np.float64]:
        """The values of :func:`series_names` now."""
        force, torque = world.wrist_wrench()
        actuator_force = world.data.actuator_force[self._actuators]
        tendon: list[NDArray[np.float64]] = []
        if world.tendon_drive is not None:
            actuator_force[len(robot.ARM_ACTUATORS) :] = world.hand_joint_torques()
            tendon = [world.hand_tensions().ravel(), world.contact_estimate().normal]
        return np.concatenate(
            [
                world.arm_qpos(),
                world.arm_targets(),
                world.hand_qpos(),
                world.hand_targets(),
                actuator_force,
                world.touch_sensors(),
                force,
                torque,
                *tendon,
            ]
        )

    def _log_contacts(self, world: World) -> None:
        """Contact points and force arrows between the robot and the target block."""
        stream = self.recorder.stream
        if self._target is None:
            if self._contacts_shown:
                self._clear_contacts()
            return
        contacts = robot_contacts(world, self._target)
        pos = np.array([c.position for c in contacts]).reshape(-1, 3)
        vec = FORCE_ARROW_SCALE * np.array([c.force for c in contacts]).reshape(-1, 3)
        colours = [rgba(PART_COLOURS[c.finger]) for c in contacts]
        labels = [f"{c.finger} {c.link}: {c.normal_force:.2f} N" for c in contacts]
        stream.log(
            f"{CONTACTS_PATH}/points",
            rr.Points3D(
                pos, radii=CONTACT_RADIUS, colors=colours, labels=labels, show_labels=False
            ),
        )
        stream.log(
            f"{CONTACTS_PATH}/forces",
            rr.Arrows3D(
                origins=pos - vec,
                vectors=vec,
                radii=ARROW_RADIUS,
                colors=colours,
                labels=labels,
                show_labels=False,
            ),
        )
        totals = dict.fromkeys(PART_COLOURS, 0.0)
        for c in contacts:
            totals[c.finger] += c.normal_force
        self.recorder.log_scalars(CONTACT_SERIES, list(totals.values()))
        self._contacts_shown = True

    def _clear_contacts(self) -> None:
        stream = self.recorder.stream
        empty = np.zeros((0, 3))
        stream.log(f"{CONTACTS_PATH}/points", rr.Points3D(empty))
        stream.log(f"{CONTACTS_PATH}/forces", rr.Arrows3D(vectors=empty, origins=empty))
        self._contacts_shown = False

    def set_contact_target(self, block_name: str | None) -> None:
        """The block whose contacts with the robot are drawn (None: none); the drawing of the
        previous one is cleared at once and the contact rate starts afresh."""
        self._target = None if block_name is None else self.world.block_body_id(block_name)
        self.set_time_now()
        if self._contacts_shown:
            self._clear_contacts()
        self._schedule.restart("contact")

    # --- time and lifetime -----------------------------------------------------------------
    def set_time_now(self) -> None:
        """Put what is logged next at the world's current simulated time, or at the latest time
        already ticked if the world's time went back (MuJoCo resets the state, time included,
        when it detects an instability): records made after a reset stay at the end."""
        t = self.world.time
        if self._latest is not None and t < self._latest[1]:
            self.recorder.set_time(*self._latest)
        else:
            self.recorder.set_time(sim_step(self.world), t)

    def log_final_frame(self) -> None:
        """Log everything now, unless simulated time has not moved since the last frame or the
        state is not finite (after a :class:`~hand_sim.errors.SimulationError` MuJoCo may have
        reset it)."""
        d = self.world.data
        moved = self._last_logged is None or self.world.time > self._last_logged
        finite = bool(np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel)))
        if moved and finite:
            self._log_frame(self.world, dict.fromkeys(self._schedule.names, True))

    def close(self) -> None:
        """Release the overhead camera's renderer."""
        self.camera.close()
