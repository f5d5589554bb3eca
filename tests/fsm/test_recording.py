"""Tests of fsm.recording: the episode recording holds what issue 9 asks for (entities, the two
timelines, the Wrench Closure timeline, a blueprint), logs at the given rates of simulated time,
is complete when the episode raises, and draws contact force arrows when a finger presses the
block."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from controllers.deliver.carry import move_palm
from controllers.hand.grip import move_hand
from controllers.planning.cspace import CollisionChecker
from controllers.reach.arm_path import execute_path
from controllers.reach.coarse import PRESHAPE, ReachTarget, goal_poses, solve_goal
from fsm.recorder_protocol import SynthesisRecord, VisionView
from fsm.recording import FORCE_ARROW_SCALE, EpisodeRecorder
from hand_sim import robot
from hand_sim.camera import OverheadCamera
from hand_sim.contacts import robot_contacts
from hand_sim.errors import HandSimError, SceneError, SimulationError
from hand_sim.recorder import read_recording
from hand_sim.scene import load_scene
from hand_sim.telemetry import IMAGE_HZ, series_names
from hand_sim.world import World

CONTROL_STEPS = 10  # one 20 ms control period of 2 ms physics steps


def rows(path: Path, entity: str, column: str) -> list[tuple[dict[str, Any], Any]]:
    """(timeline values, value) of every row of ``column`` at ``entity``, in time order of
    ``step`` (static rows last), rows at the same time in the order they were logged (rerun's
    row ids are big-endian time stamps); timelines as numbers (durations in seconds)."""
    out = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        if column not in batch.schema.names:
            continue
        times: dict[str, list[Any]] = {}
        for name in ("sim_time", "step", "synthesis_step"):
            if name in batch.schema.names:
                col = batch.column(name)
                if pa.types.is_duration(col.type):
                    times[name] = [v / 1e9 for v in col.cast(pa.int64()).to_pylist()]
                else:
                    times[name] = col.to_pylist()
        ids = batch.column("rerun.controls.RowId").to_pylist()
        for i, value in enumerate(batch.column(column).to_pylist()):
            out.append(({k: v[i] for k, v in times.items()}, value, ids[i]))
    out.sort(key=lambda r: (r[0].get("step", np.inf), r[0].get("synthesis_step", 0), r[2]))
    return [(t, v) for t, v, _ in out]


def timelines(path: Path) -> set[str]:
    names: set[str] = set()
    for chunk in RrdReader(str(path)).stream().to_chunks():
        names |= {n for n in chunk.to_record_batch().schema.names if ":" not in n}
    return names - {"rerun.controls.RowId"}


def run_for(world: World, seconds: float, steps_per_tick: int = CONTROL_STEPS) -> None:
    for _ in range(round(seconds / (world.model.opt.timestep * steps_per_tick))):
        world.step(steps_per_tick)


@pytest.fixture(scope="module")
def built_world() -> World:
    """clutter3, built once for the module (building is the costly part)."""
    return World.build(load_scene("clutter3"))


@pytest.fixture
def world(built_world: World) -> World:
    """The module's clutter3 world as :meth:`World.build` left it: every test starts from the
    same state, time 0 and no step hook."""
    built_world.reset()
    built_world.on_step = None
    return built_world


def test_episode_entities_timelines_and_layout(tmp_path: Path, world: World) -> None:
    path = tmp_path / "episode.rrd"
    target = world.scene.target
    block = world.scene.block(target)
    z_top = world.scene.table.height + block.height
    polygon = block.footprint()
    with OverheadCamera(world, 320, 240) as cam:
        vision_rgb, K, pose = cam.rgb(), cam.intrinsics, cam.pose
        contour = cam.world_to_pixel(np.column_stack([polygon, np.full(len(polygon), z_top)]))
    contacts = np.column_stack([polygon[:4], np.full(4, z_top - 0.05)])
    with EpisodeRecorder(path, world) as rec:
        world.on_step = rec.tick
        rec.log_transition("Start", "Select/Model", f"pick {target}")
        run_for(world, 0.3)
        rec.log_vision(VisionView(vision_rgb, K, pose, polygon, contour, z_top))
        t_synthesis = world.time
        for k in range(1, 6):  # a kb run: no predictor
            rec.log_synthesis(SynthesisRecord(k, 0.5 / k, 0.2 / k, None, contacts))
        rec.log_reachability(1, False, "ff cannot reach c2")
        run_for(world, 0.1)
        for k in range(1, 4):  # a pi run after Posture Control: the step count restarts
            rec.log_synthesis(
                SynthesisRecord(
                    k, 0.1, 0.05, k == 2, contacts + 0.001 * k, s_g=0.3 if k == 3 else None
                )
            )
        rec.log_reachability(2, True, "all four contacts reachable")
        rec.log_verdict(True, "delivered")
        t_end = world.time
    got = read_recording(path)
    n_frames = rec.stats.body_frames
    assert n_frames == round(0.4 / 0.02) + 1  # 50 Hz of 0.4 s, and the first frame at t = 0

    # the 3-D scene: static geometry, moving bodies on both timelines
    for b in world.scene.blocks:
        assert got[f"/world/bodies/{b.name}/geoms/{b.name}_geom"]["Mesh3D:vertex_positions"] == 1
        poses = rows(path, f"/world/bodies/{b.name}", "Transform3D:translation")
        on_sim = [r for r in poses if "synthesis_step" not in r[0]]
        assert len(on_sim) == n_frames
        assert all("step" in t and "sim_time" in t for t, _ in poses)
        np.testing.assert_allclose(on_sim[-1][1][0], world.block_pose(b.name)[0], atol=1e-9)
        # once per Wrench Closure run on the synthesis timeline, so the 3D view has a scene there
        assert [t["synthesis_step"] for t, _ in poses if "synthesis_step" in t] == [1, 6]

    # the overhead camera: a pinhole with its images under it
    assert got["/world/cameras/overhead"]["Pinhole:image_from_camera"] == 1
    # at IMAGE_HZ (2 Hz): the frames at multiples of its period in [0, 0.4] s
    assert got["/world/cameras/overhead/rgb"]["EncodedImage:blob"] == _frames_due(0.4, IMAGE_HZ)

    # every scalar series, one row per frame
    for name in series_names():
        assert got[f"/scalars/{name}"]["Scalars:scalars"] == n_frames, name
    touch = rows(path, "/scalars/touch/th", "Scalars:scalars")
    assert touch[-1][0]["sim_time"] == pytest.approx(t_end)

    # vision: image, pinhole, polygon over the image, in 3D and over the overhead image
    assert got["/world/cameras/vision"]["Pinhole:image_from_camera"] == 1
    assert got["/world/cameras/vision/rgb"]["EncodedImage:blob"] == 1
    strip2d = np.array(rows(path, "/world/cameras/vision/polygon", "LineStrips2D:strips")[0][1][0])
    np.testing.assert_allclose(strip2d, np.vstack([contour, contour[:1]]))
    strip3d = np.array(rows(path, "/world/perceived/vision", "LineStrips3D:strips")[0][1][0])
    np.testing.assert_allclose(strip3d[:-1, :2], polygon)
    np.testing.assert_allclose(strip3d[:, 2], z_top)
    np.testing.assert_allclose(strip3d[-1], strip3d[0])
    over = np.array(rows(path, "/world/cameras/overhead/polygon", "LineStrips2D:strips")[0][1][0])
    # the overhead image is 640x480, the vision one 320x240; integer pixels at pixel centres
    np.testing.assert_allclose(over[:-1], 2.0 * (contour + 0.5) - 0.5, atol=1e-3)

    # Wrench Closure: its own timeline, continued across runs, at the sim time of each run
    eps = rows(path, "/scalars/synthesis/eps_fc", "Scalars:scalars")
    assert [t["synthesis_step"] for t, _ in eps] == [1, 2, 3, 4, 5, 6, 7, 8]
    assert eps[0][0]["sim_time"] == pytest.approx(t_synthesis)
    assert eps[-1][0]["sim_time"] == pytest.approx(t_synthesis + 0.1)
    np.testing.assert_allclose([v[0] for _, v in eps[:5]], [0.5 / k for k in range(1, 6)])
    failure = rows(path, "/scalars/synthesis/predicted_failure", "Scalars:scalars")
    assert [(t["synthesis_step"], v[0]) for t, v in failure if t] == [(6, 0.0), (7, 1.0), (8, 0.0)]
    assert [v[0] for t, v in rows(path, "/scalars/synthesis/s_g", "Scalars:scalars") if t] == [0.3]
    virtual = rows(path, "/world/synthesis/contacts", "Points3D:positions")
    np.testing.assert_allclose(virtual[-1][1], contacts + 0.003)
    reachable = rows(path, "/scalars/wrench_closure/reachable", "Scalars:scalars")
    assert [v[0] for t, v in reachable if t] == [0.0, 1.0]

    # the event log: transitions, reachability loops and the verdict, at their sim times
    events = rows(path, "/events", "TextLog:text")
    levels = [v[0] for _, v in rows(path, "/events", "TextLog:level")]
    assert [v[0] for _, v in events] == [
        f"Start -> Select/Model: pick {target}",
        "Wrench Closure loop 1: contacts unreachable: ff cannot reach c2",
        "Wrench Closure loop 2: contacts reachable: all four contacts reachable",
        "SUCCESS: delivered",
    ]
    assert levels == ["INFO", "WARN", "INFO", "INFO"]
    assert events[1][0]["sim_time"] == pytest.approx(t_synthesis)

    # simulated time only: no wall-clock timeline, so two runs give the same recording
    assert timelines(path) == {"sim_time", "step", "synthesis_step"}

    # the viewer opens on the 3D scene, the overhead camera, plots and the event log
    reader = RrdReader(str(path))
    (blueprint,) = reader.blueprints()
    views = set()
    for chunk in reader.stream(store=blueprint).to_chunks():
        batch = chunk.to_record_batch()
        if "ViewBlueprint:class_identifier" in batch.schema.names:
            kind = batch.column("ViewBlueprint:class_identifier").to_pylist()[0][0]
            origin = batch.column("ViewBlueprint:space_origin").to_pylist()[0][0]
            views.add((kind, origin.strip("/")))
    assert {
        ("3D", "world"),
        ("2D", "world/cameras/overhead"),
        ("TimeSeries", "scalars/arm"),
        ("TextLog", "events"),
    } <= views


@pytest.mark.parametrize("steps_per_tick", [1, CONTROL_STEPS])
def test_rates_are_of_simulated_time(tmp_path: Path, world: World, steps_per_tick: int) -> None:
    path = tmp_path / "rates.rrd"
    rates = {"image_rate_hz": 5.0, "body_rate_hz": 50.0, "scalar_rate_hz": 25.0}
    with EpisodeRecorder(path, world, contact_rate_hz=10.0, **rates) as rec:
        rec.set_target(world.scene.target)
        world.on_step = rec.tick
        run_for(world, 1.0, steps_per_tick)
    got = read_recording(path)
    # 1 s at each rate, plus the frame at t = 0; the same whether ticked every 2 or 20 ms
    assert got["/world/cameras/overhead/rgb"]["EncodedImage:blob"] == 6
    assert got[f"/world/bodies/{world.scene.target}"]["Transform3D:translation"] == 51
    assert got["/scalars/arm/elbow/q"]["Scalars:scalars"] == 26
    assert len(rows(path, "/world/contacts/points", "Points3D:positions")) == 11
    image_times = [
        t["sim_time"] for t, _ in rows(path, "/world/cameras/overhead/rgb", "EncodedImage:blob")
    ]
    np.testing.assert_allclose(image_times, np.arange(6) * 0.2, atol=1e-9)
    # logged values are the state at their time: the last elbow angle is the world's now
    elbow = robot.ARM_JOINTS.index("elbow")
    assert rows(path, "/scalars/arm/elbow/q", "Scalars:scalars")[-1][1][0] == pytest.approx(
        world.arm_qpos()[elbow]
    )


def _frames_due(seconds: float, rate_hz: float) -> int:
    """Frames a rate logs over ``seconds`` from t = 0: one at each multiple of its period."""
    return math.floor(seconds * rate_hz + 1e-9) + 1


def test_a_rate_of_zero_logs_nothing(tmp_path: Path, world: World) -> None:
    path = tmp_path / "off.rrd"
    with EpisodeRecorder(path, world, image_rate_hz=0.0, scalar_rate_hz=0.0) as rec:
        world.on_step = rec.tick
        run_for(world, 0.2)
    got = read_recording(path)
    assert "/world/cameras/overhead/rgb" not in got
    assert not any(k.startswith("/scalars/arm") and "Scalars:scalars" in v for k, v in got.items())
    assert got[f"/world/bodies/{world.scene.target}"]["Transform3D:translation"] == 11


def test_file_is_complete_when_the_episode_raises(tmp_path: Path, world: World) -> None:
    path = tmp_path / "crash.rrd"
    with pytest.raises(RuntimeError, match="boom"), EpisodeRecorder(path, world) as rec:
        world.on_step = rec.tick
        run_for(world, 0.6)
        world.step(3)  # simulated time moves past the last frame: no final frame on a crash
        raise RuntimeError("boom")
    got = read_recording(path)
    n = round(0.6 / 0.02) + 1  # all still in the column buffers when the exception came
    assert got[f"/world/bodies/{world.scene.target}"]["Transform3D:translation"] == n
    assert got["/scalars/touch/ff"]["Scalars:scalars"] == n
    assert got["/world/cameras/overhead/rgb"]["EncodedImage:blob"] == _frames_due(0.6, IMAGE_HZ)
    (event,) = rows(path, "/events", "TextLog:text")
    assert event[1] == ["episode raised RuntimeError: boom"]
    assert event[0]["sim_time"] == pytest.approx(world.time)
    assert rows(path, "/events", "TextLog:level")[0][1] == ["ERROR"]
    with pytest.raises(HandSimError, match="closed"):
        rec.tick(world)
    rec.close()  # idempotent


def test_records_after_mujoco_resets_an_unstable_state_stay_at_the_end(
    tmp_path: Path, world: World
) -> None:
    path = tmp_path / "unstable.rrd"
    rec = EpisodeRecorder(path, world)
    world.on_step = rec.tick
    run_for(world, 0.2)
    t_last = world.time
    adr = world.model.jnt_qposadr[world.model.body_jntadr[world.block_body_id("pentagon")]]
    world.data.qpos[adr] = np.nan
    with pytest.raises(SimulationError, match="BADQPOS"):
        world.step(1)
    assert world.time < 0.01  # MuJoCo reset the state, time included
    rec.log_transition("Grasp Object", "Failed", "simulation unstable", level="ERROR")
    rec.log_verdict(False, "simulation unstable")
    rec.close()
    events = rows(path, "/events", "TextLog:text")
    assert [t["sim_time"] for t, _ in events] == [pytest.approx(t_last)] * 2
    # no final frame of the reset state: the last pose is the one before the blow-up
    poses = rows(path, "/world/bodies/pentagon", "Transform3D:translation")
    assert poses[-1][0]["sim_time"] == pytest.approx(t_last)


def test_contact_arrows_when_a_finger_presses_the_block(tmp_path: Path) -> None:
    """Top approach over the block, fingers curled, palm lowered until the hand touches the block
    and pressed 1 mm further: the arrows are the robot's contact forces on the block, tip at the
    contact point, FORCE_ARROW_SCALE m per N, and the hand pushes the block down."""
    world = World.build(load_scene("single_rectangle"))
    name = world.scene.target
    body = world.block_body_id(name)
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    base = world.data.xpos[
        mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_BODY, robot.arm_name("arm_base"))
    ][:2]
    poses = goal_poses(ReachTarget.from_world(world, name), base)["top"]
    goal = solve_goal(checker, "top", poses, world.arm_qpos())
    assert goal is not None
    execute_path(world, np.array([world.arm_qpos(), goal.q]), hand_q=PRESHAPE)
    path = tmp_path / "press.rrd"
    with EpisodeRecorder(path, world, image_rate_hz=0.0, contact_rate_hz=50.0) as rec:
        rec.set_target(name)
        world.on_step = rec.tick
        lo, hi = world.hand_ctrlrange().T
        curled = np.array(PRESHAPE)
        for j in (1, 2, 3):
            curled[j::4] = (lo + 0.9 * (hi - lo))[j::4]
        move_hand(world, curled, 0.5)
        touching = move_palm(
            world, checker, (0.0, 0.0, -0.2), 2.0, stop=lambda w: bool(robot_contacts(w, body))
        )
        assert not touching  # stopped early: the hand reached the block
        move_palm(world, checker, (0.0, 0.0, -0.001), 0.2)
        expected, t_pressed = robot_contacts(world, body), world.time
        world.step(CONTROL_STEPS)
        rec.set_target(None)  # clears the drawing at once
        t_cleared = world.time
        world.step(CONTROL_STEPS)
    assert expected

    def at(entity: str, column: str, t: float) -> list[Any]:
        return [v for time, v in rows(path, entity, column) if time["sim_time"] == pytest.approx(t)]

    points = rows(path, "/world/contacts/points", "Points3D:positions")
    assert points[0][1] == []  # the hand above the block at the start: nothing drawn
    assert [] in at("/world/contacts/points", "Points3D:positions", t_cleared)
    assert points[-1][0]["sim_time"] == pytest.approx(t_cleared)  # nothing drawn after that
    pos = np.array([c.position for c in expected])
    force = np.array([c.force for c in expected])
    (o,) = at("/world/contacts/forces", "Arrows3D:origins", t_pressed)
    (v,) = at("/world/contacts/forces", "Arrows3D:vectors", t_pressed)
    (p,) = at("/world/contacts/points", "Points3D:positions", t_pressed)
    o, v = np.array(o), np.array(v)
    np.testing.assert_allclose(v, FORCE_ARROW_SCALE * force, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(o + v, pos, atol=1e-6)
    np.testing.assert_allclose(np.array(p), pos, atol=1e-6)
    assert v[:, 2].sum() < 0.0  # pressing from above pushes the block down
    for finger in {c.finger for c in expected}:
        total = sum(c.normal_force for c in expected if c.finger == finger)
        (series,) = at(f"/scalars/contact_force/{finger}", "Scalars:scalars", t_pressed)
        assert series[0] == pytest.approx(total)
        assert total > 0.0


def test_bad_input_is_refused(tmp_path: Path, world: World) -> None:
    path = tmp_path / "bad.rrd"
    with pytest.raises(HandSimError, match="image_rate_hz must be a finite rate"):
        EpisodeRecorder(path, world, image_rate_hz=-1.0)
    assert not path.exists()  # nothing half-written
    with pytest.raises(HandSimError, match="needs a world with the arm and hand"):
        EpisodeRecorder(path, World.build(load_scene("clutter3"), with_robot=False))
    with EpisodeRecorder(path, world, image_rate_hz=0.0) as rec:
        rgb = np.zeros((48, 64, 3), np.uint8)
        square = np.array([[0.0, 0.0], [0.05, 0.0], [0.05, 0.05], [0.0, 0.05]])
        with pytest.raises(HandSimError, match=r"K \(3, 3\) and pose \(4, 4\)"):
            rec.log_vision(VisionView(rgb, np.eye(4), np.eye(4), square, square, 0.95))
        with pytest.raises(HandSimError, match="polygon_world must be a finite"):
            rec.log_vision(VisionView(rgb, np.eye(3), np.eye(4), square[:2], square, 0.95))
        with pytest.raises(HandSimError, match=r"\(H, W, 3\) uint8"):
            rec.log_vision(VisionView(rgb[..., 0], np.eye(3), np.eye(4), square, square, 0.95))
        with pytest.raises(HandSimError, match="contacts_world must be a finite"):
            rec.log_synthesis(SynthesisRecord(1, 0.1, 0.1, None, square))
        with pytest.raises(HandSimError, match="non-finite"):
            rec.log_synthesis(SynthesisRecord(1, float("nan"), 0.1, None, np.zeros((4, 3))))
        with pytest.raises(HandSimError, match="unknown event level 'LOUD'"):
            rec.log_transition("A", "B", "why", level="LOUD")
        with pytest.raises(SceneError, match="nope"):
            rec.set_target("nope")
    got = read_recording(path)
    assert "/world/cameras/vision" not in got
    assert "/world/synthesis/contacts" not in got
    assert "/events" not in got
