"""Episode recording to rerun (``.rrd``): the 3D scene over simulated time, camera images, named
scalar series and text events, so that a pick-and-place cycle (section 5.2) can be replayed.

Layout of the recording:
- ``world/bodies/<body>``: the body's world pose (Transform3D) at every logged step; bodies welded
  to the world are logged once, as static. Poses are buffered and sent as columns.
- ``world/bodies/<body>/geoms/<geom>``: the geom's pose in its body and its shape (Boxes3D,
  Capsules3D, Cylinders3D, Ellipsoids3D or Mesh3D), static.
- ``world/cameras/<name>``: a camera's pose and pinhole model (a frustum in 3D), its colour
  images at ``world/cameras/<name>/rgb`` (JPEG; they project into the 3D view).
- ``images/<name>``: JPEG-compressed colour images; ``depth/<name>``: depth images (m).
- ``scalars/<name>``: scalar series (one at a time, or rows of several buffered and sent as
  columns: :meth:`Recorder.log_scalars`); ``events``: text log.
Timelines: ``step`` (sequence) and ``sim_time`` (duration, s). Dots replace the slashes of
dm_control names in entity paths (``arm/hand/palm`` -> ``arm.hand.palm``).
"""

from __future__ import annotations

import os
import uuid
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
import rerun as rr
from numpy.typing import ArrayLike, NDArray
from rerun.chunk import RrdReader

from graspsim_base.files import temporary_name
from hand_sim.errors import HandSimError
from hand_sim.lifetime import ClosesOnExit

if TYPE_CHECKING:
    from hand_sim.world import World

APPLICATION_ID = "graspsim"
BODIES_PATH = "world/bodies"
CAMERAS_PATH = "world/cameras"
IMAGES_PATH, DEPTH_PATH, SCALARS_PATH, EVENTS_PATH = "images", "depth", "scalars", "events"
#: Geom groups shown (MuJoCo's viewer shows 0-2 by default; collision geoms sit in group 3).
VISIBLE_GROUPS = (0, 1, 2)
#: JPEG quality of logged camera images.
JPEG_QUALITY = 85
#: Half-size (m) drawn for infinite planes.
PLANE_HALF_SIZE = 2.0
#: Body poses are buffered and sent as columns every this many frames (and on close): one
#: column per body is ~50x cheaper than one log call per body per frame.
POSE_BUFFER_FRAMES = 250
#: Seconds to wait for the file sink when closing.
FLUSH_TIMEOUT_S = 30.0
EVENT_LEVELS = ("TRACE", "DEBUG", "INFO", "WARN", "ERROR", "CRITICAL")
#: Entity (under a camera's path) of the camera's colour images.
CAMERA_IMAGE = "rgb"
#: MuJoCo's default geom colour: a geom with a material and this rgba shows the material's colour.
_DEFAULT_RGBA = np.array([0.5, 0.5, 0.5, 1.0], dtype=np.float32)


def entity_name(name: str) -> str:
    """A MuJoCo name as one rerun entity-path part."""
    return name.strip("/").replace("/", ".") or "unnamed"


def sim_step(world: World) -> int:
    """The index of the world's current physics step (the ``step`` timeline)."""
    return round(world.data.time / world.model.opt.timestep)


def _xyzw(wxyz: ArrayLike) -> list[float]:
    q = np.asarray(wxyz, dtype=float)
    return [float(q[1]), float(q[2]), float(q[3]), float(q[0])]


def _matrix_to_xyzw(R: NDArray[np.float64]) -> list[float]:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).ravel())
    return _xyzw(q)


def _geom_rgba(model: mujoco.MjModel, g: int) -> NDArray[np.uint8]:
    rgba = model.geom_rgba[g]
    mat = model.geom_matid[g]
    if mat >= 0 and np.allclose(rgba, _DEFAULT_RGBA):
        rgba = model.mat_rgba[mat]
    return (np.clip(rgba, 0.0, 1.0) * 255).astype(np.uint8)


def geom_archetype(model: mujoco.MjModel, g: int) -> Any | None:
    """The rerun archetype drawing geom ``g`` in its own frame (None for unsupported types)."""
    t, size, colour = model.geom_type[g], model.geom_size[g], [_geom_rgba(model, g)]
    G = mujoco.mjtGeom
    if t == G.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size], colors=colour, fill_mode="solid")
    if t == G.mjGEOM_PLANE:
        half = [s if s > 0 else PLANE_HALF_SIZE for s in size[:2]]
        return rr.Boxes3D(half_sizes=[[half[0], half[1], 1e-4]], colors=colour, fill_mode="solid")
    if t == G.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=colour, fill_mode="solid")
    if t == G.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size], colors=colour, fill_mode="solid")
    if t == G.mjGEOM_CAPSULE:  # MuJoCo: centred on z; rerun: from the origin along +z
        return rr.Capsules3D(
            lengths=[2 * size[1]],
            radii=[size[0]],
            translations=[[0.0, 0.0, -size[1]]],
            colors=colour,
        )
    if t == G.mjGEOM_CYLINDER:
        return rr.Cylinders3D(
            lengths=[2 * size[1]], radii=[size[0]], colors=colour, fill_mode="solid"
        )
    if t == G.mjGEOM_MESH:
        m = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
        f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
        return rr.Mesh3D(
            vertex_positions=model.mesh_vert[v0 : v0 + nv],
            triangle_indices=model.mesh_face[f0 : f0 + nf],
            albedo_factor=colour[0],
        )
    return None


class Recorder(ClosesOnExit):
    """Writes one episode to ``path`` (``.rrd``). Use as a context manager: the file is flushed
    and closed on exit, also when the body raises or is interrupted by Ctrl-C (the exception is
    logged as an ERROR event and then propagates).

    The episode is written to a hidden temporary file beside ``path``, renamed to ``path`` when
    the recorder closes: ``path`` only ever holds a complete, readable recording.

    ``live``: a rerun sink the same stream goes to as well, as it is logged (``rr.GrpcSink`` to
    a running viewer, ``rr.GrpcServerSink`` serving one); the file is written the same either
    way, and a viewer that goes away does not cost the file (:attr:`live_error` says why the
    stream stopped)."""

    def __init__(
        self,
        path: str | Path,
        world: World | None = None,
        *,
        jpeg_quality: int = JPEG_QUALITY,
        live: Any | None = None,
    ) -> None:
        self.path = Path(path)
        if self.path.suffix != ".rrd":
            raise HandSimError(f"recording path {self.path} must end in .rrd")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.jpeg_quality = jpeg_quality
        self._partial = temporary_name(self.path)
        self._rec: rr.RecordingStream | None = rr.RecordingStream(
            APPLICATION_ID, recording_id=str(uuid.uuid4())
        )
        # simulated time is the recording's time: no wall-clock ``log_time`` timeline (it would
        # make two runs of the same episode differ)
        self._rec.set_log_time_enabled(False)
        self._live = live
        #: why the live stream stopped (its sink's error at close), or "" (none, or no error)
        self.live_error = ""
        if live is None:
            self._rec.save(str(self._partial))
        else:
            self._rec.set_sinks(rr.FileSink(str(self._partial)), live)
        self._rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._geometry_for: int | None = None
        self._now: tuple[int, float] | None = None  # (step, sim_time) of the last set_time
        self._series: dict[tuple[str, ...], _ScalarRows] = {}
        self._moving: list[tuple[int, str]] = []  # (body id, entity path) of non-welded bodies
        self._steps: list[int] = []
        self._times: list[float] = []
        self._pos: list[NDArray[np.float64]] = []
        self._quat: list[NDArray[np.float64]] = []
        if world is not None:
            self.log_geometry(world)

    @property
    def stream(self) -> rr.RecordingStream:
        if self._rec is None:
            raise HandSimError(f"the recorder of {self.path} is closed")
        return self._rec

    # --- time ------------------------------------------------------------------------------
    def set_time(self, step: int, sim_time: float) -> None:
        """Set both timelines for what is logged next."""
        self._now = (int(step), float(sim_time))
        self.stream.set_time("step", sequence=int(step))
        self.stream.set_time("sim_time", duration=float(sim_time))

    # --- the 3D scene ----------------------------------------------------------------------
    def log_geometry(self, world: World) -> None:
        """Log every body's visible geoms (static) and the poses of bodies welded to the world."""
        m, d = world.model, world.data
        rec = self.stream
        for g in range(m.ngeom):
            if m.geom_group[g] not in VISIBLE_GROUPS or m.geom_rgba[g, 3] == 0.0:
                continue
            arch = geom_archetype(m, g)
            if arch is None:
                continue
            b = m.geom_bodyid[g]
            path = f"{self._body_path(m, b)}/geoms/{entity_name(m.geom(g).name or f'geom{g}')}"
            rec.log(
                path,
                rr.Transform3D(translation=m.geom_pos[g], quaternion=_xyzw(m.geom_quat[g])),
                static=True,
            )
            rec.log(path, arch, static=True)
        self._flush_poses()
        for b in range(1, m.nbody):
            if m.body_weldid[b] == 0:
                rec.log(self._body_path(m, b), self._pose(d, b), static=True)
        self._moving = [
            (b, self._body_path(m, b)) for b in range(1, m.nbody) if m.body_weldid[b] != 0
        ]
        self._geometry_for = id(m)

    @staticmethod
    def _body_path(model: mujoco.MjModel, b: int) -> str:
        return f"{BODIES_PATH}/{entity_name(model.body(b).name or f'body{b}')}" if b else "world"

    @staticmethod
    def _pose(data: mujoco.MjData, b: int) -> rr.Transform3D:
        return rr.Transform3D(translation=data.xpos[b], quaternion=_xyzw(data.xquat[b]))

    def log_world(self, world: World) -> None:
        """Log the pose of every moving body at the world's current step and simulated time
        (buffered: written every :data:`POSE_BUFFER_FRAMES` frames and on close)."""
        if self._geometry_for != id(world.model):
            self.log_geometry(world)
        d = world.data
        step = sim_step(world)
        self.set_time(step, d.time)
        ids = [b for b, _ in self._moving]
        self._steps.append(step)
        self._times.append(float(d.time))
        self._pos.append(d.xpos[ids].copy())
        self._quat.append(d.xquat[ids][:, [1, 2, 3, 0]].copy())
        if len(self._steps) >= POSE_BUFFER_FRAMES:
            self._flush_poses()

    def log_poses_now(self, world: World) -> None:
        """Log the pose of every moving body now, unbuffered, at the stream's current times
        (which may include a timeline of the caller's, such as a controller's step counter)."""
        if self._geometry_for != id(world.model):
            self.log_geometry(world)
        d = world.data
        for b, path in self._moving:
            self.stream.log(path, self._pose(d, b))

    def _flush_poses(self) -> None:
        """Send the buffered body poses, one column chunk per body."""
        if not self._steps:
            return
        rec = self.stream
        indexes = [
            rr.TimeColumn("step", sequence=np.array(self._steps)),
            rr.TimeColumn("sim_time", duration=np.array(self._times)),
        ]
        pos, quat = np.stack(self._pos), np.stack(self._quat)
        for i, (_, path) in enumerate(self._moving):
            columns = rr.Transform3D.columns(translation=pos[:, i], quaternion=quat[:, i])
            rec.send_columns(path, indexes=indexes, columns=columns)
        self._steps, self._times, self._pos, self._quat = [], [], [], []

    def log_camera(
        self,
        name: str,
        intrinsics: NDArray[np.float64],
        pose: NDArray[np.float64],
        size: tuple[int, int],
        *,
        static: bool = True,
        image_plane_distance: float | None = None,
    ) -> None:
        """Log a pinhole camera as ``world/cameras/<name>``, drawn as a frustum in 3D:
        ``intrinsics`` K (3x3), ``pose`` camera-to-world 4x4 in OpenCV axes (x right, y down,
        z forward), ``size`` (width, height) in pixels. Static (for the whole recording) unless
        ``static=False`` (then at the current time). ``image_plane_distance`` (m) is where the
        3D view draws the camera's images (rerun's default when None)."""
        path = f"{CAMERAS_PATH}/{name}"
        q = _matrix_to_xyzw(pose[:3, :3])
        self.stream.log(path, rr.Transform3D(translation=pose[:3, 3], quaternion=q), static=static)
        self.stream.log(
            path,
            rr.Pinhole(
                image_from_camera=intrinsics,
                resolution=list(size),
                camera_xyz=rr.ViewCoordinates.RDF,
                image_plane_distance=image_plane_distance,
            ),
            static=static,
        )

    def log_camera_image(self, name: str, rgb: NDArray[np.uint8]) -> None:
        """Log an (H, W, 3) uint8 colour image of camera ``name`` (see :meth:`log_camera`) as
        ``world/cameras/<name>/rgb``, JPEG-compressed: the 2D view of the camera shows it and
        the 3D view projects it through the camera's pinhole."""
        self.stream.log(f"{CAMERAS_PATH}/{name}/{CAMERA_IMAGE}", self._jpeg(name, rgb))

    # --- images, scalars, events -----------------------------------------------------------
    def log_image(self, entity: str, rgb: NDArray[np.uint8]) -> None:
        """Log an (H, W, 3) uint8 colour image as ``images/<entity>``, JPEG-compressed."""
        self.stream.log(f"{IMAGES_PATH}/{entity}", self._jpeg(entity, rgb))

    def _jpeg(self, what: str, rgb: NDArray[np.uint8]) -> rr.EncodedImage:
        img = np.asarray(rgb)
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise HandSimError(
                f"the image of {what!r} must be an (H, W, 3) uint8 array, "
                f"got {img.shape} {img.dtype}"
            )
        return rr.Image(img).compress(jpeg_quality=self.jpeg_quality)

    def log_depth(self, entity: str, depth: NDArray[np.float32]) -> None:
        """Log an (H, W) depth image in metres as ``depth/<entity>``."""
        self.stream.log(
            f"{DEPTH_PATH}/{entity}", rr.DepthImage(np.asarray(depth, dtype=np.float32), meter=1.0)
        )

    def log_scalar(self, name: str, value: float) -> None:
        """Append ``value`` to the series ``scalars/<name>``."""
        self.stream.log(f"{SCALARS_PATH}/{name}", rr.Scalars(float(value)))

    def log_scalars(self, names: Sequence[str], values: ArrayLike) -> None:
        """Append one row to the series ``scalars/<name>`` of each of ``names``, at the time of
        the last :meth:`set_time`/:meth:`log_world` (buffered per tuple of names: sent as one
        column per series every :data:`POSE_BUFFER_FRAMES` rows and on close, which costs a
        few microseconds per row instead of one log call per value)."""
        if self._now is None:
            raise HandSimError("log_scalars needs a time: call set_time or log_world first")
        key = tuple(names)
        row = np.asarray(values, dtype=float).reshape(-1)
        if row.shape != (len(key),):
            raise HandSimError(f"log_scalars got {row.size} values for {len(key)} series")
        rows = self._series.get(key)
        if rows is None:
            rows = self._series[key] = _ScalarRows(key)
        rows.append(*self._now, row)
        if len(rows) >= POSE_BUFFER_FRAMES:
            rows.send(self.stream)

    def log_event(self, text: str, level: str = "INFO") -> None:
        """Log a text event (level one of TRACE, DEBUG, INFO, WARN, ERROR, CRITICAL)."""
        if level not in EVENT_LEVELS:
            raise HandSimError(f"unknown event level {level!r}; valid: {', '.join(EVENT_LEVELS)}")
        self.stream.log(EVENTS_PATH, rr.TextLog(text, level=level))

    # --- lifetime --------------------------------------------------------------------------
    def close(self) -> None:
        """Flush everything to the file, close it and give it its name ``path`` (idempotent)."""
        if self._rec is not None:
            try:
                self._flush_poses()
                for rows in self._series.values():
                    rows.send(self._rec)
            finally:
                rec, self._rec = self._rec, None
                try:
                    try:
                        rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
                    except RuntimeError as e:  # only a live sink fails so (a viewer gone)
                        if self._live is None:
                            raise
                        self.live_error = str(e)
                    rec.disconnect()
                finally:
                    if self._partial.exists():
                        os.replace(self._partial, self.path)

    def _exit(self, exc_type: type[BaseException] | None, exc: BaseException | None) -> None:
        """Leaving the ``with`` block on an exception logs it as an ERROR event, then closes."""
        try:
            if exc is not None and self._rec is not None:
                self.log_event(
                    f"episode raised {exc_type.__name__ if exc_type else 'error'}: {exc}", "ERROR"
                )
        finally:
            self.close()


class _ScalarRows:
    """Buffered rows of a fixed tuple of scalar series that share their times."""

    def __init__(self, names: tuple[str, ...]) -> None:
        self.paths = [f"{SCALARS_PATH}/{n}" for n in names]
        self.steps: list[int] = []
        self.times: list[float] = []
        self.rows: list[NDArray[np.float64]] = []

    def __len__(self) -> int:
        return len(self.steps)

    def append(self, step: int, sim_time: float, row: NDArray[np.float64]) -> None:
        self.steps.append(step)
        self.times.append(sim_time)
        self.rows.append(row)

    def send(self, rec: rr.RecordingStream) -> None:
        """One column per series, then empty the buffer."""
        if not self.steps:
            return
        indexes = [
            rr.TimeColumn("step", sequence=np.array(self.steps)),
            rr.TimeColumn("sim_time", duration=np.array(self.times)),
        ]
        values = np.stack(self.rows)
        for i, path in enumerate(self.paths):
            rec.send_columns(
                path, indexes=indexes, columns=rr.Scalars.columns(scalars=values[:, i])
            )
        self.steps, self.times, self.rows = [], [], []


def read_recording(path: str | Path) -> dict[str, dict[str, int]]:
    """Read an ``.rrd`` back: entity path -> {component column: number of rows logged}."""
    out: dict[str, dict[str, int]] = defaultdict(dict)
    for chunk in RrdReader(str(path)).stream().to_chunks():
        batch = chunk.to_record_batch()
        for col in batch.schema.names:
            if ":" in col:
                cols = out[chunk.entity_path]
                cols[col] = cols.get(col, 0) + batch.num_rows
    return dict(out)
