"""Tests of hand_sim.recorder: what is logged can be read back from the .rrd, geometry and poses
agree with the simulation, and the file is complete even when the episode raises."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from hand_sim.errors import HandSimError
from hand_sim.recorder import Recorder, entity_name, read_recording
from hand_sim.robot import hand_name
from hand_sim.scene import load_scene
from hand_sim.world import World


def last_row(path: Path, entity: str, column: str) -> object:
    """The last row of ``column`` logged at ``entity``."""
    rows = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if chunk.entity_path == entity:
            batch = chunk.to_record_batch()
            if column in batch.schema.names:
                rows.extend(batch.column(column).to_pylist())
    assert rows, (entity, column)
    return rows[-1]


def last_value(path: Path, entity: str, column: str) -> np.ndarray:
    return np.array(last_row(path, entity, column), dtype=float)


def rotate(q_xyzw: np.ndarray, v: np.ndarray) -> np.ndarray:
    x, y, z, w = q_xyzw
    u = np.array([x, y, z])
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


@pytest.fixture(scope="module")
def world() -> World:
    return World.build(load_scene("clutter3"))


def test_logged_entities_read_back(tmp_path: Path, world: World) -> None:
    path = tmp_path / "ep.rrd"
    n_frames = 5
    with Recorder(path, world) as rec:
        for k in range(n_frames):
            world.step(20)
            rec.log_world(world)
            rec.log_scalar("k", k)
        rec.log_image("overhead", np.zeros((48, 64, 3), np.uint8))
        rec.log_depth("overhead", np.ones((48, 64), np.float32))
        rec.log_event("finished", "INFO")
    got = read_recording(path)
    for block in world.scene.blocks:
        body = f"/world/bodies/{block.name}"
        assert got[body]["Transform3D:translation"] == n_frames
        assert got[f"{body}/geoms/{block.name}_geom"]["Mesh3D:vertex_positions"] == 1
        np.testing.assert_allclose(
            last_value(path, body, "Transform3D:translation")[0],
            world.block_pose(block.name)[0],
            atol=1e-6,
        )
    palm = f"/world/bodies/{entity_name(hand_name('palm'))}"
    assert got[palm]["Transform3D:translation"] == n_frames
    assert any(k.startswith(palm + "/geoms/") for k in got)
    assert got["/world/bodies/table"]["Transform3D:translation"] == 1  # welded to the world: static
    assert got["/scalars/k"]["Scalars:scalars"] == n_frames
    assert got["/images/overhead"]["EncodedImage:blob"] == 1
    assert got["/depth/overhead"]["DepthImage:buffer"] == 1
    assert got["/events"]["TextLog:text"] == 1


def test_logged_block_mesh_is_the_prism_of_its_footprint(tmp_path: Path, world: World) -> None:
    path = tmp_path / "mesh.rrd"
    with Recorder(path, world):
        pass
    block = world.scene.blocks[0]
    geom = f"/world/bodies/{block.name}/geoms/{block.name}_geom"
    verts = last_value(path, geom, "Mesh3D:vertex_positions")
    t = last_value(path, geom, "Transform3D:translation")[0]
    q = last_value(path, geom, "Transform3D:quaternion")[0]
    body_frame = np.array([rotate(q, v) for v in verts]) + t
    expected = block.polygon.vertices
    for z in (-0.5 * block.height, 0.5 * block.height):
        face = body_frame[np.abs(body_frame[:, 2] - z) < 1e-6][:, :2]
        assert len(face) == len(expected)
        d = np.linalg.norm(face[:, None, :] - expected[None, :, :], axis=-1)
        assert d.min(axis=1).max() < 1e-6


def test_file_is_closed_and_readable_when_the_episode_raises(tmp_path: Path, world: World) -> None:
    path = tmp_path / "crash.rrd"
    with pytest.raises(RuntimeError, match="boom"), Recorder(path, world) as rec:
        rec.log_world(world)
        raise RuntimeError("boom")
    with pytest.raises(HandSimError, match="closed"):
        rec.log_scalar("x", 1.0)
    got = read_recording(path)
    assert got["/events"]["TextLog:text"] == 1
    assert "RuntimeError: boom" in str(last_row(path, "/events", "TextLog:text"))
    assert "ERROR" in str(last_row(path, "/events", "TextLog:level"))
    assert got[f"/world/bodies/{world.scene.blocks[0].name}"]["Transform3D:translation"] == 1


def test_path_holds_only_a_complete_recording_also_after_ctrl_c(
    tmp_path: Path, world: World
) -> None:
    path = tmp_path / "ep.rrd"
    with pytest.raises(KeyboardInterrupt), Recorder(path, world) as rec:
        rec.log_world(world)
        assert not path.exists()  # written under a temporary name until closed
        assert len(list(tmp_path.iterdir())) == 1
        raise KeyboardInterrupt
    assert [p.name for p in tmp_path.iterdir()] == ["ep.rrd"]
    assert "KeyboardInterrupt" in str(last_row(path, "/events", "TextLog:text"))
    assert read_recording(path)[f"/world/bodies/{world.scene.blocks[0].name}"]


def test_bad_input_is_refused(tmp_path: Path) -> None:
    with pytest.raises(HandSimError, match=r"must end in \.rrd"):
        Recorder(tmp_path / "x.txt")
    with Recorder(tmp_path / "x.rrd") as rec:
        with pytest.raises(HandSimError, match=r"\(H, W, 3\) uint8"):
            rec.log_image("cam", np.zeros((4, 4), np.uint8))
        with pytest.raises(HandSimError, match="unknown event level 'LOUD'"):
            rec.log_event("x", "LOUD")


def test_camera_pose_and_pinhole_read_back(tmp_path: Path) -> None:
    path = tmp_path / "cam.rrd"
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])  # looking straight down, image x along world x
    pose[:3, 3] = [0.1, -0.2, 1.9]
    K = np.array([[500.0, 0.0, 319.5], [0.0, 500.0, 239.5], [0.0, 0.0, 1.0]])
    with Recorder(path) as rec:
        rec.log_camera("overhead", K, pose, (640, 480))
    entity = "/world/cameras/overhead"
    np.testing.assert_allclose(last_value(path, entity, "Transform3D:translation")[0], pose[:3, 3])
    q = last_value(path, entity, "Transform3D:quaternion")[0]
    for axis in np.eye(3):  # the logged rotation maps camera axes as the pose does
        np.testing.assert_allclose(rotate(q, axis), pose[:3, :3] @ axis, atol=1e-6)
    logged_K = last_value(path, entity, "Pinhole:image_from_camera")[0].reshape(3, 3)
    np.testing.assert_allclose(logged_K.T, K)  # rerun stores the matrix column-major
