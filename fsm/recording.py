"""The episode recorder of the task cycle (section 5.2, Figure 14): everything a person needs to
replay a pick-and-place episode in the rerun viewer and see what happened and why.

An :class:`EpisodeRecorder` writes one ``.rrd`` (via :class:`hand_sim.recorder.Recorder`) and
sends a blueprint, so the viewer opens on the 3D scene, the cameras, the plots and the event log.
The physics is logged by :class:`hand_sim.telemetry.WorldTelemetry` at its rates of *simulated*
time (body poses, the overhead camera's images, joint, actuator, touch and wrist scalars, the
contacts with the target block: see :mod:`hand_sim.telemetry`); the machine hooks
:meth:`EpisodeRecorder.tick` into ``World.on_step``.

The machine's own records: ``events`` (a TextLog entry per transition, reachability loop and the
verdict), the Select/Model image with its pinhole at ``world/cameras/<name>`` and the extracted
polygon over it (2D) and in 3D (``world/perceived/<name>``, also projected onto the overhead
image), the place point asked for and the one used (``world/place/asked``, ``world/place/used``),
and each Wrench Closure step (``scalars/synthesis/...`` and the virtual contacts
``world/synthesis/contacts``).

Timelines: ``sim_time`` (duration, s) and ``step`` (physics step index) for everything;
``synthesis_step`` (sequence) as well for the Wrench Closure records, which take no simulated
time. The body poses are logged on ``synthesis_step`` once per Wrench Closure run so that the 3D
view shows the scene when that timeline is selected.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from numpy.typing import ArrayLike, NDArray

from fsm.recorder_protocol import SynthesisRecord, TablePoint, VisionView
from hand_sim.errors import HandSimError
from hand_sim.lifetime import ClosesOnExit
from hand_sim.recorder import (
    CAMERAS_PATH,
    EVENTS_PATH,
    SCALARS_PATH,
    Recorder,
)
from hand_sim.telemetry import (
    ESTIMATE_PATH,
    FORCE_ARROW_SCALE,
    IMAGE_HZ,
    PART_COLOURS,
    TENDON_PATH,
    RecordingStats,
    TelemetryRates,
    WorldTelemetry,
    style_series,
)
from hand_sim.world import CAMERA_NAME, World

__all__ = ["FORCE_ARROW_SCALE", "PART_COLOURS", "EpisodeRecorder", "RecordingStats"]

#: Radius (m) of the drawn virtual contacts and perceived polygon lines.
VIRTUAL_CONTACT_RADIUS = 0.005
POLYGON_RADIUS = 0.002
#: Radius of the polygon drawn over camera images, in UI points (constant on screen: a
#: 1920x1440 image shrunk into a small view would make a radius in pixels vanish).
OVERLAY_RADIUS = rr.components.Radius.ui_points(1.5)
#: The Select/Model camera usually is the overhead one at a higher resolution: its image is drawn
#: nearer the camera than the overhead one's (:data:`hand_sim.telemetry.IMAGE_PLANE_DISTANCE`),
#: so that the two do not fight in the 3D view.
VISION_PLANE_DISTANCE = 0.15
#: Timeline of the Wrench Closure steps (virtual: no simulated time passes).
SYNTHESIS_TIMELINE = "synthesis_step"
#: Where the machine's records go (entity paths).
PERCEIVED_PATH = "world/perceived"
PLACE_PATH = "world/place"
SYNTHESIS_CONTACTS = "world/synthesis/contacts"
#: Colour (rgb) of the perceived polygon and of the virtual contacts.
POLYGON_COLOUR = (255, 230, 0)
VIRTUAL_CONTACT_COLOUR = (255, 0, 255)
#: Colours (rgb) and radius (m) of the place point asked for and of the one used.
PLACE_ASKED_COLOUR = (255, 255, 255)
PLACE_USED_COLOUR = (0, 200, 0)
PLACE_RADIUS = 0.008
#: Styles (series under ``scalars/``, rgb colour, label) of the Wrench Closure series.
SYNTHESIS_SERIES: tuple[tuple[str, tuple[int, int, int], str], ...] = (
    ("synthesis/eps_fc", (230, 60, 60), "eps_FC"),
    ("synthesis/eps_mc", (60, 110, 230), "eps_MC"),
    ("synthesis/predicted_failure", (245, 150, 30), "predicted failure (noise)"),
    ("synthesis/s_g", (60, 180, 75), "S_G"),
    ("wrench_closure/reachable", (60, 180, 75), "contacts reachable"),
    ("wrench_closure/loop", (160, 80, 200), "posture loop"),
)
#: Where the 3D view looks at and from, relative to the table centre at its top (m): at the
#: space between the arm (which stands at x = -0.6) and the blocks, from in front of the table
#: and to the right of the arm, raised.
LOOK_OFFSET = (-0.12, 0.0, 0.18)
EYE_OFFSET = (0.7, -1.05, 0.75)


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


class EpisodeRecorder(ClosesOnExit):
    """Records one task-cycle episode of ``world`` to ``path`` (``.rrd``); see the module
    docstring for what is logged where. Use as a context manager (or call :meth:`close`): the
    file is complete after close, also when the episode raises (the exception is logged as an
    ERROR event first). A :class:`fsm.recorder_protocol.TaskRecorder`. ``live``: a rerun sink the
    recording streams to as well while the episode runs (:class:`hand_sim.recorder.Recorder`;
    ``fsm.run --live``); the file is the same."""

    def __init__(
        self,
        path: Path,
        world: World,
        *,
        overhead_width: int = 640,
        overhead_height: int = 480,
        image_rate_hz: float = IMAGE_HZ,
        body_rate_hz: float = 50.0,
        scalar_rate_hz: float = 50.0,
        contact_rate_hz: float = 10.0,
        jpeg_quality: int | None = None,
        live: Any | None = None,
    ) -> None:
        if not world.with_robot:
            raise HandSimError("an episode recording needs a world with the arm and hand")
        rates = TelemetryRates(
            body_hz=body_rate_hz,
            scalar_hz=scalar_rate_hz,
            image_hz=image_rate_hz,
            contact_hz=contact_rate_hz,
        )
        self.world = world
        self.path = Path(path)
        self._synthesis_offset = 0
        self._synthesis_last: int | None = None
        self._synthesis_time: float | None = None
        self._polygons: dict[str, rr.LineStrips3D] = {}
        kwargs = {} if jpeg_quality is None else {"jpeg_quality": jpeg_quality}
        self._rec: Recorder | None = Recorder(self.path, world, live=live, **kwargs)
        self._live_error = ""
        try:
            self.telemetry = WorldTelemetry(
                self._rec,
                world,
                rates,
                overhead_width=overhead_width,
                overhead_height=overhead_height,
            )
        except BaseException:
            self._rec.close()
            raise
        try:
            stream = self._rec.stream
            for name, colour, label in SYNTHESIS_SERIES:
                style_series(stream, name, colour, label)
            rr.send_blueprint(self.blueprint(world), recording=stream)
            self.tick(world)
        except BaseException:
            self.telemetry.close()
            self._rec.close()
            raise

    @property
    def recorder(self) -> Recorder:
        """The underlying :class:`Recorder` (raises once closed)."""
        if self._rec is None:
            raise HandSimError(f"the episode recorder of {self.path} is closed")
        return self._rec

    @property
    def stats(self) -> RecordingStats:
        """What the telemetry logged and what it cost."""
        return self.telemetry.stats

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
        tendon = (
            [
                rrb.TimeSeriesView(origin=f"{s}/{TENDON_PATH}", name="tendon tensions"),
                rrb.TimeSeriesView(
                    name="pads vs tendon estimate",
                    contents=[f"+ {s}/touch/**", f"+ {s}/{ESTIMATE_PATH}/**"],
                ),
            ]
            if world.hand == "tendon"
            else []
        )
        plots = rrb.Tabs(
            rrb.TimeSeriesView(
                name="touch & contact forces",
                contents=[
                    f"+ {s}/touch/**",
                    f"+ {s}/contact_force/**",
                    f"+ {s}/{ESTIMATE_PATH}/**",
                ],
            ),
            rrb.TimeSeriesView(origin=f"{s}/arm", name="arm joints"),
            rrb.TimeSeriesView(origin=f"{s}/hand", name="hand joints"),
            rrb.TimeSeriesView(origin=f"{s}/wrist", name="wrist F/T"),
            rrb.TimeSeriesView(origin=f"{s}/actuator_force", name="actuator forces"),
            rrb.TimeSeriesView(
                name="wrench closure (synthesis_step)",
                contents=[f"+ {s}/synthesis/**", f"+ {s}/wrench_closure/**"],
            ),
            *tendon,
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
        if self._rec is None:
            raise HandSimError(f"the episode recorder of {self.path} is closed")
        self.telemetry.tick(world)

    def set_target(self, block_name: str | None) -> None:
        """The block whose contacts with the robot are drawn (None: none)."""
        self.telemetry.set_contact_target(block_name)

    # --- the machine's records -------------------------------------------------------------
    def _event(self, text: str, level: str) -> None:
        self.telemetry.set_time_now()
        self.recorder.log_event(text, level)

    def log_transition(
        self, from_state: str, to_state: str, reason: str, *, level: str = "INFO"
    ) -> None:
        """A state transition of the machine, with its reason, in the event log."""
        self._event(f"{from_state} -> {to_state}: {reason}", level)

    def log_vision(self, view: VisionView) -> None:
        """The Select/Model image with its pinhole at ``world/cameras/<name>`` (``K`` 3x3 pixels,
        ``pose`` 4x4 camera-to-world in OpenCV axes), the extracted contour drawn over it
        (``pixel_contour`` (k, 2) pixels) and the perceived polygon in 3D (``polygon_world``
        (k, 2) world xy at height ``z_top``), also projected onto the overhead image. A new
        Select/Model clears the previous cycle's virtual contacts."""
        name, z_top = view.name, view.z_top
        img = np.asarray(view.rgb)
        K_ = np.asarray(view.K, dtype=float)
        T = np.asarray(view.pose, dtype=float)
        if (
            K_.shape != (3, 3)
            or T.shape != (4, 4)
            or not np.all(np.isfinite(np.r_[K_.ravel(), T.ravel()]))
        ):
            raise HandSimError(
                f"log_vision needs K (3, 3) and pose (4, 4), finite; got {K_.shape} and {T.shape}"
            )
        poly = _points("polygon_world", view.polygon_world, 2, min_rows=3)
        contour = _points("pixel_contour", view.pixel_contour, 2, min_rows=3)
        if not math.isfinite(z_top):
            raise HandSimError(f"z_top must be finite, got {z_top!r}")
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise HandSimError(
                f"the image of {name!r} must be an (H, W, 3) uint8 array, "
                f"got {img.shape} {img.dtype}"
            )
        self.telemetry.set_time_now()
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
        overhead_px = self.telemetry.camera.world_to_pixel(xyz)
        stream.log(
            f"{CAMERAS_PATH}/{CAMERA_NAME}/polygon",
            rr.LineStrips2D([_closed(overhead_px)], colors=[POLYGON_COLOUR], radii=OVERLAY_RADIUS),
        )
        stream.log(SYNTHESIS_CONTACTS, rr.Points3D(np.zeros((0, 3))))

    def log_synthesis(self, record: SynthesisRecord) -> None:
        """One Wrench Closure controller step (sections 3.6, 5.2): eps_FC (Eq. 5), eps_MC
        (Eq. 10), the F/S predictor's output (1 = failure predicted, the PI controller injects
        noise; omitted when None, as for kb and ql), S_G (Eq. 13) if given, and the virtual
        contacts (n, 3) world points. Logged at the current simulated time and on the
        ``synthesis_step`` timeline, which counts the controller's steps over the whole episode:
        a run whose ``step`` restarts continues the timeline after the previous run."""
        step, predicted_failure, s_g = record.step, record.predicted_failure, record.s_g
        pts = _points("contacts_world", record.contacts_world, 3)
        values = {"eps_fc": record.eps_fc, "eps_mc": record.eps_mc}
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
        self.telemetry.set_time_now()
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

    def log_place(self, asked: TablePoint | None, used: TablePoint | None, table_z: float) -> None:
        """The place point asked for (``world/place/asked``, white; cleared when the task cycle
        chose the point itself) and the one the block is taken to (``world/place/used``, green),
        on the table top at ``table_z``, labelled with their distance when they differ."""
        self.telemetry.set_time_now()
        stream = self.recorder.stream
        moved = None
        if asked is not None and used is not None:
            moved = 1000.0 * float(np.hypot(used[0] - asked[0], used[1] - asked[1]))
        same = moved is not None and moved <= 1e-6
        for key, point, colour in (
            ("asked", asked, PLACE_ASKED_COLOUR),
            ("used", used, PLACE_USED_COLOUR),
        ):
            if point is None:
                stream.log(f"{PLACE_PATH}/{key}", rr.Points3D(np.zeros((0, 3))))
                continue
            label = f"place point {key}"
            if key == "used" and moved is not None:
                # one label where the two points coincide (two would be drawn over each other)
                label = (
                    "place point asked and used"
                    if same
                    else (f"{label} ({moved:.0f} mm from the asked one)")
                )
            xyz = _points(f"place {key}", [[point[0], point[1], table_z]], 3, min_rows=1)
            labels = None if key == "asked" and same else [label]
            stream.log(
                f"{PLACE_PATH}/{key}",
                rr.Points3D(xyz, radii=PLACE_RADIUS, colors=[colour], labels=labels),
            )

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
            if final_frame:
                self.telemetry.log_final_frame()
        finally:
            try:
                self.telemetry.close()
            finally:
                rec, self._rec = self._rec, None
                rec.close()
                self._live_error = rec.live_error

    @property
    def live_error(self) -> str:
        """Why the live stream stopped before the recording closed ("" when it did not)."""
        return self._live_error

    def _exit(self, exc_type: type[BaseException] | None, exc: BaseException | None) -> None:
        """Leaving the ``with`` block on an exception logs it as an ERROR event and skips the
        final frame (:meth:`close`)."""
        try:
            if exc is not None and self._rec is not None:
                name = exc_type.__name__ if exc_type else "error"
                self.telemetry.set_time_now()
                self._rec.log_event(f"episode raised {name}: {exc}", "ERROR")
        finally:
            self.close(final_frame=exc is None)
