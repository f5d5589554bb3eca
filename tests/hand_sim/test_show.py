"""Tests of the demo ``python -m hand_sim.show``: it writes a readable .rrd holding the logged
entities and an overhead PNG, leaves the blocks standing, and refuses unknown scenes."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from rerun.chunk import RrdReader

from hand_sim.recorder import entity_name, read_recording
from hand_sim.robot import ARM_JOINTS, FINGERS, hand_name
from hand_sim.scene import load_scene
from hand_sim.show import ARM_WAYPOINTS, main


def scalar_series(path: Path, entity: str) -> np.ndarray:
    values: list[float] = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if chunk.entity_path == entity:
            values.extend(
                v[0] for v in chunk.to_record_batch().column("Scalars:scalars").to_pylist()
            )
    return np.array(values)


def test_demo_writes_a_readable_recording_and_overhead_png(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "demo"
    assert (
        main(["--scene", "clutter3", "--out", str(out), "--width", "160", "--height", "120"]) == 0
    )
    assert "episode.rrd" in capsys.readouterr().out
    png = cv2.imread(str(out / "overhead.png"))
    assert png is not None and png.shape == (120, 160, 3)
    assert png.std() > 10  # not a blank image

    rrd = out / "episode.rrd"
    got = read_recording(rrd)
    scene = load_scene("clutter3")
    frames = got[f"/world/bodies/{scene.blocks[0].name}"]["Transform3D:translation"]
    assert frames > 100
    for block in scene.blocks:
        assert got[f"/world/bodies/{block.name}"]["Transform3D:translation"] == frames
        assert f"/world/bodies/{block.name}/geoms/{block.name}_geom" in got
        # the arm moving around left every block where it was (no more than 1 mm)
        assert scalar_series(rrd, f"/scalars/blocks/{block.name}/shift_mm").max() < 1.0
    assert (
        got[f"/world/bodies/{entity_name(hand_name('palm'))}"]["Transform3D:translation"] == frames
    )
    assert got["/images/overhead"]["EncodedImage:blob"] == 2
    assert got["/world/cameras/overhead"]["Pinhole:image_from_camera"] == 1
    assert got["/depth/overhead"]["DepthImage:buffer"] == 1
    assert got["/events"]["TextLog:text"] == len(ARM_WAYPOINTS) + 2
    for joint in ARM_JOINTS:
        assert got[f"/scalars/arm/{joint}/qpos"]["Scalars:scalars"] == frames
    # the arm really went through its waypoints: the waist swung both ways
    waist = scalar_series(rrd, "/scalars/arm/waist/qpos")
    assert waist.max() > 0.2 and waist.min() < -0.2
    for finger in FINGERS:  # fingertips stayed above the table
        assert scalar_series(rrd, f"/scalars/fingertip_z/{finger}").min() > scene.table.height


def test_unknown_scene_is_one_line_on_stderr_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--scene", "clutter9", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err
    assert "unknown scene 'clutter9'" in err and "clutter3" in err and "single_square" in err
    assert not (tmp_path / "episode.rrd").exists()


def test_bad_random_request_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--scene", "random", "--seed", "1", "--blocks", "99", "--out", str(tmp_path)]) == 2
    assert "argument --blocks: must be an integer from 1 to 12" in capsys.readouterr().err


def test_overhead_png_is_in_the_frame_vision_picks_pixels_in() -> None:
    """A pixel read off the default overhead.png is the pixel ``python -m vision --pick-pixel``
    expects: same image size, same camera matrix and pose."""
    from hand_sim.camera import OverheadCamera
    from hand_sim.show import DEFAULT_HEIGHT, DEFAULT_WIDTH
    from hand_sim.world import World
    from vision import observation

    assert (DEFAULT_WIDTH, DEFAULT_HEIGHT) == (
        observation.DEFAULT_WIDTH,
        observation.DEFAULT_HEIGHT,
    )
    world = World.build(load_scene("clutter3"))
    with OverheadCamera(world, DEFAULT_WIDTH, DEFAULT_HEIGHT) as a:
        K, pose = a.intrinsics, a.pose
    with observation.overhead_camera(world) as b:
        np.testing.assert_array_equal(K, b.intrinsics)
        np.testing.assert_array_equal(pose, b.pose)
