"""The episode recorder of the task cycle (section 5.2, Figure 14): everything a person needs to
replay a pick-and-place episode in the rerun viewer and see what happened and why.

An :class:`EpisodeRecorder` writes one ``.rrd`` (via :class:`hand_sim.recorder.Recorder`) and
sends a blueprint, so the viewer opens on the 3D scene, the cameras, the plots and the event log.
The machine hooks :meth:`EpisodeRecorder.tick` into ``World.on_step``; every tick logs what is
due at the given rates of *simulated* time:

- ``world/bodies/...``: static geometry of every visible geom and each moving body's pose
  (``body_rate_hz``, buffered and sent as columns);
- ``world/cameras/overhead``: the overhead camera's pose and pinhole (static), its RGB images at
  ``world/cameras/overhead/rgb`` (``image_rate_hz``, JPEG); they project into the 3D view;
- ``scalars/arm/<joint>/{q,target}``, ``scalars/hand/<finger>/j<i>/{q,target}`` (rad),
  ``scalars/actuator_force/...`` (N m), ``scalars/touch/<finger>`` (N),
  ``scalars/wrist/{force,torque}/{x,y,z}`` (N, N m, world axes) at ``scalar_rate_hz``, buffered;
- ``world/contacts/{points,forces}``: the contacts between the robot and the target block
  (``mj_contactForce`` via :func:`hand_sim.contacts.robot_contacts`) as points and arrows whose
  tip is the contact point and whose length is :data:`FORCE_ARROW_SCALE` metres per newton,
  with ``scalars/contact_force/<finger|palm|arm>`` (normal force on the block, N), at
  ``contact_rate_hz``.

The machine's own records: ``events`` (a TextLog entry per transition, reachability loop and the
verdict), the Select/Model image with its pinhole at ``world/cameras/<name>`` and the extracted
polygon over it (2D) and in 3D (``world/perceived/<name>``, also projected onto the overhead
image), and each Wrench Closure step (``scalars/synthesis/...`` and the virtual contacts
``world/synthesis/contacts``).

Timelines: ``sim_time`` (duration, s) and ``step`` (physics step index) for everything;
``synthesis_step`` (sequence) as well for the Wrench Closure records, which take no simulated
time. The body poses are logged on ``synthesis_step`` once per Wrench Closure run so that the 3D
view shows the scene when that timeline is selected.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

import mujoco
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from numpy.typing import ArrayLike, NDArray

from hand_sim import robot
from hand_sim.camera import OverheadCamera
from hand_sim.contacts import robot_contacts
from hand_sim.errors import HandSimError
from hand_sim.recorder import (
    CAMERAS_PATH,
    EVENTS_PATH,
    SCALARS_PATH,
    Recorder,
    sim_step,
)
from hand_sim.world import CAMERA_NAME, World

#: Length (m) of a contact force arrow per newton: the 6 N grip force of
#: :data:`controllers.grip.GRIP_FORCE` draws a 3 cm arrow beside a ~5 cm block.
FORCE_ARROW_SCALE = 0.005
#: Radius (m) of the drawn contact points (real and virtual), force arrows and polygon lines.
CONTACT_RADIUS = 0.003
VIRTUAL_CONTACT_RADIUS = 0.005
ARROW_RADIUS = 0.0015
POLYGON_RADIUS = 0.002
#: Radius of the polygon drawn over camera images, in UI points (constant on screen: a
#: 1920x1440 image shrunk into a small view would make a radius in pixels vanish).
OVERLAY_RADIUS = rr.components.Radius.ui_points(1.5)
#: Distance (m) from a camera at which the 3D view draws its image: the overhead camera hangs
#: ~1.2 m above the table, so at 0.25 m its image floats well above the robot's reach.
IMAGE_PLANE_DISTANCE = 0.25
#: The Select/Model camera usually is the overhead one at a higher resolution: its image is drawn
#: nearer the camera, so that the two do not fight in the 3D view.
VISION_PLANE_DISTANCE = 0.15
#: Timeline of the Wrench Closure steps (virtual: no simulated time passes).
SYNTHESIS_TIMELINE = "synthesis_step"
#: Where the machine's records go (entity paths).
CONTACTS_PATH = "world/contacts"
PERCEIVED_PATH = "world/perceived"
SYNTHESIS_CONTACTS = "world/synthesis/contacts"
#: Colour (rgb) per robot part touching the target, and of the perceived polygon and the virtual
#: contacts.
PART_COLOURS: dict[str, tuple[int, int, int]] = {
    "ff": (230, 60, 60),
    "mf": (60, 180, 75),
    "rf": (60, 110, 230),
    "th": (245, 150, 30),
    "palm": (150, 150, 150),
    "arm": (160, 80, 200),
}
POLYGON_COLOUR = (255, 230, 0)
VIRTUAL_CONTACT_COLOUR = (255, 0, 255)
#: Where the 3D view looks at and from, relative to the table centre at its top (m): at the
#: space between the arm (which stands at x = -0.6) and the blocks, from in front of the table
#: and to the right of the arm, raised.
LOOK_OFFSET = (-0.12, 0.0, 0.18)
EYE_OFFSET = (0.7, -1.05, 0.75)
#: Rates are compared on a grid of simulated time with this slack (s), so that a tick at
#: t = 0.2 s counts as t = 0.2 s whatever the rounding of MuJoCo's time accumulator.
_TIME_SLACK = 1e-6


@dataclass
class RecordingStats:
    """What the recorder did and what it cost (wall time spent inside :meth:`tick`)."""

    ticks: int = 0
    body_frames: int = 0
    scalar_rows: int = 0
    images: int = 0
    contact_frames: int = 0
    tick_seconds: float = 0.0

    @property
    def seconds_per_tick(self) -> float:
        return self.tick_seconds / self.ticks if self.ticks else 0.0


class _Rate:
    """Due once per period of simulated time: at the first tick at or after each multiple of
    1/hz (hz = 0: never). Simulated time going backwards (a world reset) starts it afresh."""

    def __init__(self, what: str, hz: float) -> None:
        if not (math.isfinite(hz) and hz >= 0.0):
            raise HandSimError(f"{what} must be a finite rate >= 0 Hz (0 = never), got {hz!r}")
        self.hz = float(hz)
        self._slot = -1
        self._time = -math.inf

    def due(self, t: float) -> bool:
        if self.hz == 0.0:
            return False
        if t < self._time:
            self._slot = -1
        self._time = t
        slot = math.floor(t * self.hz + _TIME_SLACK)
        if slot <= self._slot:
            return False
        self._slot = slot
        return True


def _rgb(colour: tuple[int, int, int], alpha: int = 255) -> list[int]:
    return [*colour, alpha]


def _closed(points: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.vstack([points, points[:1]])


def _points(what: str, value: ArrayLike, dim: int, min_rows: int = 0) -> NDArray[np.float64]:
    a = np.asarray(value, dtype=float)
    if a.ndim != 2 or a.shape[1] != dim or len(a) < min_rows or not np.all(np.isfinite(a)):
        raise HandSimError(
            f"{what} must be a finite ({'k' if min_rows == 0 else f'k>={min_rows}'}, {dim}) "
            f"array, got shape {a.shape}"
        )
    return a


def _plain_camera(world: World, width: int, height: int) -> OverheadCamera:
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


class EpisodeRecorder:
    """Records one task-cycle episode of ``world`` to ``path`` (``.rrd``); see the module
    docstring for what is logged where. Use as a context manager (or call :meth:`close`): the
    file is complete after close, also when the episode raises (the exception is logged as an
    ERROR event first)."""

    def __init__(
        self,
        path: Path,
        world: World,
        *,
        overhead_width: int = 640,
        overhead_height: int = 480,
        image_rate_hz: float = 5.0,
        body_rate_hz: float = 50.0,
        scalar_rate_hz: float = 50.0,
        contact_rate_hz: float = 10.0,
        jpeg_quality: int | None = None,
    ) -> None:
        if not world.with_robot:
            raise HandSimError("an episode recording needs a world with the arm and hand")
        self._rates = {
            "body": _Rate("body_rate_hz", body_rate_hz),
            "scalar": _Rate("scalar_rate_hz", scalar_rate_hz),
            "image": _Rate("image_rate_hz", image_rate_hz),
            "contact": _Rate("contact_rate_hz", contact_rate_hz),
        }
        self.world = world
        self.path = Path(path)
        self.stats = RecordingStats()
        self._target: int | None = None
        self._contacts_shown = False
        self._last_logged: float | None = None
        self._latest: tuple[int, float] | None = None  # (step, sim_time) of the latest tick
        self._synthesis_offset = 0
        self._synthesis_last: int | None = None
        self._synthesis_time: float | None = None
        self._polygons: dict[str, rr.LineStrips3D] = {}
        self._actuators = self._actuator_ids(world)
        self._camera = _plain_camera(world, overhead_width, overhead_height)
        self._rec: Recorder | None = None
        try:
            kwargs = {} if jpeg_quality is None else {"jpeg_quality": jpeg_quality}
            self._rec = Recorder(self.path, world, **kwargs)
            self._setup(world)
            self.tick(world)
        except BaseException:
            self._camera.close()
            if self._rec is not None:
                self._rec.close()
            raise

    # --- setup -----------------------------------------------------------------------------
    @property
    def recorder(self) -> Recorder:
        """The underlying :class:`Recorder` (raises once closed)."""
        if self._rec is None:
            raise HandSimError(f"the episode recorder of {self.path} is closed")
        return self._rec

    @staticmethod
    def _actuator_ids(world: World) -> NDArray[np.int64]:
        names = (*robot.ARM_ACTUATORS, *robot.HAND_ACTUATORS)
        ids = [
            mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_ACTUATOR, robot.qualified(n))
            for n in names
        ]
        return np.array(ids, dtype=np.int64)

    def _setup(self, world: World) -> None:
        rec = self.recorder
        cam = self._camera
        rec.log_camera(
            CAMERA_NAME,
            cam.intrinsics,
            cam.pose,
            (cam.width, cam.height),
            image_plane_distance=IMAGE_PLANE_DISTANCE,
        )
        self._series = self._series_names()
        self._contact_series = [f"contact_force/{p}" for p in PART_COLOURS]
        self._style_series()
        rr.send_blueprint(self.blueprint(world), recording=rec.stream)

    @staticmethod
    def _series_names() -> list[str]:
        """Names (under ``scalars/``) of the series logged at the scalar rate, in the order of
        :meth:`_scalar_row`."""
        arm = robot.ARM_JOINTS
        hand = [f"{f}/j{i}" for f in robot.FINGERS for i in range(robot.JOINTS_PER_FINGER)]
        return [
            *(f"arm/{j}/q" for j in arm),
            *(f"arm/{j}/target" for j in arm),
            *(f"hand/{j}/q" for j in hand),
            *(f"hand/{j}/target" for j in hand),
            *(f"actuator_force/arm/{j}" for j in arm),
            *(f"actuator_force/hand/{j}" for j in hand),
            *(f"touch/{f}" for f in robot.FINGERS),
            *(f"wrist/force/{a}" for a in "xyz"),
            *(f"wrist/torque/{a}" for a in "xyz"),
        ]

    def _style_series(self) -> None:
        """Static names and colours of the plotted series: a joint's position and its servo
        target share a colour (the target thinner and paler), fingers keep their colours."""
        stream = self.recorder.stream
        palette = [(230, 60, 60), (60, 180, 75), (60, 110, 230), (245, 150, 30), (160, 80, 200)]

        def style(name: str, colour: tuple[int, int, int], label: str, target: bool) -> None:
            stream.log(
                f"{SCALARS_PATH}/{name}",
                rr.SeriesLines(
                    colors=[_rgb(colour, 120 if target else 255)],
                    widths=[1.0 if target else 2.0],
                    names=[label],
                ),
                static=True,
            )

        for i, j in enumerate(robot.ARM_JOINTS):
            for kind in ("q", "target"):
                style(f"arm/{j}/{kind}", palette[i], f"{j} {kind}", kind == "target")
            style(f"actuator_force/arm/{j}", palette[i], j, False)
        for f in robot.FINGERS:
            for i in range(robot.JOINTS_PER_FINGER):
                shade = tuple(int(c * (1.0 - 0.18 * i)) for c in PART_COLOURS[f])
                for kind in ("q", "target"):
                    style(f"hand/{f}/j{i}/{kind}", shade, f"{f}j{i} {kind}", kind == "target")
                style(f"actuator_force/hand/{f}/j{i}", shade, f"{f}a{i}", False)
            style(f"touch/{f}", PART_COLOURS[f], f"touch {f}", False)
        for part, colour in PART_COLOURS.items():
            style(f"contact_force/{part}", colour, f"{part} on target", False)
        for i, a in enumerate("xyz"):
            style(f"wrist/force/{a}", palette[i], f"F{a}", False)
            style(f"wrist/torque/{a}", palette[i], f"T{a}", True)
        for name, colour, label in (
            ("synthesis/eps_fc", (230, 60, 60), "eps_FC"),
            ("synthesis/eps_mc", (60, 110, 230), "eps_MC"),
            ("synthesis/predicted_failure", (245, 150, 30), "predicted failure (noise)"),
            ("synthesis/s_g", (60, 180, 75), "S_G"),
            ("wrench_closure/reachable", (60, 180, 75), "contacts reachable"),
            ("wrench_closure/loop", (160, 80, 200), "posture loop"),
        ):
            style(name, colour, label, False)

    def blueprint(self, world: World) -> rrb.Blueprint:
        """The viewer layout: the 3D scene (left), the cameras, plots in tabs and the event log
        (right); the time panel on ``sim_time``."""
        table = world.scene.table
        centre = np.array([*table.position_xy, table.height])
        scene = rrb.Spatial3DView(
            origin="world",
            name="scene",
            eye_controls=rrb.EyeControls3D(
                position=centre + np.array(EYE_OFFSET),
                look_target=centre + np.array(LOOK_OFFSET),
                eye_up=[0, 0, 1],
            ),
        )
        cameras = rrb.Tabs(
            rrb.Spatial2DView(origin=f"{CAMERAS_PATH}/{CAMERA_NAME}", name="overhead camera"),
            rrb.Spatial2DView(origin=f"{CAMERAS_PATH}/vision", name="Select/Model image"),
        )
        s = SCALARS_PATH
        plots = rrb.Tabs(
            rrb.TimeSeriesView(
                name="touch & contact forces",
                contents=[f"+ {s}/touch/**", f"+ {s}/contact_force/**"],
            ),
            rrb.TimeSeriesView(origin=f"{s}/arm", name="arm joints"),
            rrb.TimeSeriesView(origin=f"{s}/hand", name="hand joints"),
            rrb.TimeSeriesView(origin=f"{s}/wrist", name="wrist F/T"),
            rrb.TimeSeriesView(origin=f"{s}/actuator_force", name="actuator forces"),
            rrb.TimeSeriesView(
                name="wrench closure (synthesis_step)",
                contents=[f"+ {s}/synthesis/**", f"+ {s}/wrench_closure/**"],
            ),
        )
        log = rrb.TextLogView(origin=EVENTS_PATH, name="events")
        return rrb.Blueprint(
            rrb.Horizontal(
                scene,
                rrb.Vertical(cameras, plots, log, row_shares=[4, 3, 2]),
                column_shares=[3, 2],
            ),
            rrb.TimePanel(timeline="sim_time"),
            collapse_panels=True,
        )

    # --- every simulation step -------------------------------------------------------------
    def tick(self, world: World) -> None:
        """Log what is due at the world's current simulated time (``World.on_step`` hook)."""
        started = time.perf_counter()
        rec = self.recorder
        if world.model is not self.world.model:
            raise HandSimError("EpisodeRecorder.tick got a different world than it records")
        t = world.time
        if self._latest is None or t > self._latest[1]:
            self._latest = (sim_step(world), t)
        due = {k: r.due(t) for k, r in self._rates.items()}
        if any(due.values()):
            self._log_frame(world, due)
            self._last_logged = t
        else:
            rec.set_time(sim_step(world), t)
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
            rec.log_scalars(self._series, self._scalar_row(world))
            st.scalar_rows += 1
        if due["image"]:
            rec.log_camera_image(CAMERA_NAME, self._camera.rgb())
            st.images += 1
        if due["contact"]:
            self._log_contacts(world)
            st.contact_frames += 1

    def _scalar_row(self, world: World) -> NDArray[np.float64]:
        force, torque = world.wrist_wrench()
        return np.concatenate(
            [
                world.arm_qpos(),
                world.arm_targets(),
                world.hand_qpos(),
                world.hand_targets(),
                world.data.actuator_force[self._actuators],
                world.touch(),
                force,
                torque,
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
        colours = [_rgb(PART_COLOURS[c.finger]) for c in contacts]
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
        self.recorder.log_scalars(self._contact_series, list(totals.values()))
        self._contacts_shown = True

    def _clear_contacts(self) -> None:
        stream = self.recorder.stream
        empty = np.zeros((0, 3))
        stream.log(f"{CONTACTS_PATH}/points", rr.Points3D(empty))
        stream.log(f"{CONTACTS_PATH}/forces", rr.Arrows3D(vectors=empty, origins=empty))
        self._contacts_shown = False

    def set_target(self, block_name: str | None) -> None:
        """The block whose contacts with the robot are drawn (None: none)."""
        self._target = None if block_name is None else self.world.block_body_id(block_name)
        self._now()
        if self._contacts_shown:
            self._clear_contacts()
        self._rates["contact"] = _Rate("contact_rate_hz", self._rates["contact"].hz)

    # --- the machine's records -------------------------------------------------------------
    def _now(self) -> None:
        """Put what is logged next at the world's current simulated time, or at the latest time
        already logged if the world's time went back (MuJoCo resets the state, time included,
        when it detects an instability): the machine's last records stay at the end."""
        t = self.world.time
        if self._latest is not None and t < self._latest[1]:
            self.recorder.set_time(*self._latest)
        else:
            self.recorder.set_time(sim_step(self.world), t)

    def _event(self, text: str, level: str) -> None:
        self._now()
        self.recorder.log_event(text, level)

    def log_transition(
        self, from_state: str, to_state: str, reason: str, *, level: str = "INFO"
    ) -> None:
        """A state transition of the machine, with its reason, in the event log."""
        self._event(f"{from_state} -> {to_state}: {reason}", level)

    def log_vision(
        self,
        rgb: NDArray[np.uint8],
        K: ArrayLike,
        pose: ArrayLike,
        polygon_world: ArrayLike,
        pixel_contour: ArrayLike,
        z_top: float,
        *,
        name: str = "vision",
    ) -> None:
        """The Select/Model image with its pinhole at ``world/cameras/<name>`` (``K`` 3x3 pixels,
        ``pose`` 4x4 camera-to-world in OpenCV axes), the extracted contour drawn over it
        (``pixel_contour`` (k, 2) pixels) and the perceived polygon in 3D (``polygon_world``
        (k, 2) world xy at height ``z_top``), also projected onto the overhead image. A new
        Select/Model clears the previous cycle's virtual contacts."""
        img = np.asarray(rgb)
        K_ = np.asarray(K, dtype=float)
        T = np.asarray(pose, dtype=float)
        if (
            K_.shape != (3, 3)
            or T.shape != (4, 4)
            or not np.all(np.isfinite(np.r_[K_.ravel(), T.ravel()]))
        ):
            raise HandSimError(
                f"log_vision needs K (3, 3) and pose (4, 4), finite; got {K_.shape} and {T.shape}"
            )
        poly = _points("polygon_world", polygon_world, 2, min_rows=3)
        contour = _points("pixel_contour", pixel_contour, 2, min_rows=3)
        if not math.isfinite(z_top):
            raise HandSimError(f"z_top must be finite, got {z_top!r}")
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise HandSimError(
                f"the image of {name!r} must be an (H, W, 3) uint8 array, "
                f"got {img.shape} {img.dtype}"
            )
        self._now()
        rec = self.recorder
        stream = rec.stream
        rec.log_camera(
            name,
            K_,
            T,
            (img.shape[1], img.shape[0]),
            image_plane_distance=VISION_PLANE_DISTANCE,
        )
        rec.log_camera_image(name, img)
        stream.log(
            f"{CAMERAS_PATH}/{name}/polygon",
            rr.LineStrips2D(
                [_closed(contour)],
                colors=[POLYGON_COLOUR],
                radii=OVERLAY_RADIUS,
                labels=["perceived polygon"],
                show_labels=False,
            ),
        )
        xyz = np.column_stack([poly, np.full(len(poly), float(z_top))])
        strip = rr.LineStrips3D(
            [_closed(xyz)],
            colors=[POLYGON_COLOUR],
            radii=POLYGON_RADIUS,
            labels=[f"{name} polygon"],
            show_labels=False,
        )
        self._polygons[name] = strip
        stream.log(f"{PERCEIVED_PATH}/{name}", strip)
        overhead_px = self._camera.world_to_pixel(xyz)
        stream.log(
            f"{CAMERAS_PATH}/{CAMERA_NAME}/polygon",
            rr.LineStrips2D([_closed(overhead_px)], colors=[POLYGON_COLOUR], radii=OVERLAY_RADIUS),
        )
        stream.log(SYNTHESIS_CONTACTS, rr.Points3D(np.zeros((0, 3))))

    def log_synthesis(
        self,
        step: int,
        eps_fc: float,
        eps_mc: float,
        predicted_failure: bool | None,
        contacts_world: ArrayLike,
        s_g: float | None = None,
    ) -> None:
        """One Wrench Closure controller step (sections 3.6, 5.2): eps_FC (Eq. 5), eps_MC
        (Eq. 10), the F/S predictor's output (1 = failure predicted, the PI controller injects
        noise; omitted when None, as for kb and ql), S_G (Eq. 13) if given, and the virtual
        contacts (n, 3) world points. Logged at the current simulated time and on the
        ``synthesis_step`` timeline, which counts the controller's steps over the whole episode:
        a run whose ``step`` restarts continues the timeline after the previous run."""
        pts = _points("contacts_world", contacts_world, 3)
        values = {"eps_fc": eps_fc, "eps_mc": eps_mc}
        if predicted_failure is not None:
            values["predicted_failure"] = float(bool(predicted_failure))
        if s_g is not None:
            values["s_g"] = s_g
        if not all(math.isfinite(float(v)) for v in values.values()):
            raise HandSimError(f"log_synthesis got a non-finite value: {values}")
        k = self._synthesis_offset + int(step)
        if self._synthesis_last is not None and k <= self._synthesis_last:
            self._synthesis_offset = self._synthesis_last + 1 - int(step)
            k = self._synthesis_last + 1
        self._now()
        rec = self.recorder
        stream = rec.stream
        stream.set_time(SYNTHESIS_TIMELINE, sequence=k)
        try:
            if self._synthesis_time != self.world.time:  # a new Wrench Closure run
                self._log_scene_now()
                self._synthesis_time = self.world.time
            for key, value in values.items():
                stream.log(f"{SCALARS_PATH}/synthesis/{key}", rr.Scalars(float(value)))
            stream.log(
                SYNTHESIS_CONTACTS,
                rr.Points3D(
                    pts,
                    radii=VIRTUAL_CONTACT_RADIUS,
                    colors=[VIRTUAL_CONTACT_COLOUR],
                    labels=[f"c{i}" for i in range(len(pts))],
                    show_labels=False,
                ),
            )
        finally:
            stream.disable_timeline(SYNTHESIS_TIMELINE)
        self._synthesis_last = k

    def _log_scene_now(self) -> None:
        """The moving bodies' poses and the perceived polygons at the stream's current times
        (including ``synthesis_step``), so the 3D view has a scene on that timeline."""
        self.recorder.log_poses_now(self.world)
        for name, strip in self._polygons.items():
            self.recorder.stream.log(f"{PERCEIVED_PATH}/{name}", strip)

    def log_reachability(self, loop: int, reachable: bool, reason: str) -> None:
        """The Wrench Closure <-> Posture Control loop (section 5.2): whether the hand can reach
        the proposed contacts, as an event (WARN when not) and as scalars."""
        word = "reachable" if reachable else "unreachable"
        self._event(
            f"Wrench Closure loop {loop}: contacts {word}: {reason}",
            "INFO" if reachable else "WARN",
        )
        stream = self.recorder.stream
        stream.log(f"{SCALARS_PATH}/wrench_closure/reachable", rr.Scalars(float(bool(reachable))))
        stream.log(f"{SCALARS_PATH}/wrench_closure/loop", rr.Scalars(float(loop)))

    def log_verdict(self, success: bool, text: str) -> None:
        """The episode's final verdict: INFO when it succeeded, ERROR when it failed."""
        self._event(f"{'SUCCESS' if success else 'FAILED'}: {text}", "INFO" if success else "ERROR")

    # --- lifetime --------------------------------------------------------------------------
    def close(self, *, final_frame: bool = True) -> None:
        """Log the final state (unless ``final_frame`` is False, or simulated time has not moved
        since the last frame, or the state is not finite), flush everything to the file and
        close it. Idempotent. Leaving the ``with`` block on an exception skips the final frame:
        after a :class:`~hand_sim.errors.SimulationError` MuJoCo may have reset the state."""
        if self._rec is None:
            return
        try:
            d = self.world.data
            moved = self._last_logged is None or self.world.time > self._last_logged
            finite = bool(np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel)))
            if final_frame and moved and finite:
                self._log_frame(self.world, dict.fromkeys(self._rates, True))
        finally:
            try:
                self._camera.close()
            finally:
                rec, self._rec = self._rec, None
                rec.close()

    def __enter__(self) -> EpisodeRecorder:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        try:
            if exc is not None and self._rec is not None:
                name = exc_type.__name__ if exc_type else "error"
                self._now()
                self._rec.log_event(f"episode raised {name}: {exc}", "ERROR")
        finally:
            self.close(final_frame=exc is None)
