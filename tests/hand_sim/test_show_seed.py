"""``--seed`` with a scene file means the same layout in every command: ``python -m vision`` and
``python -m hand_sim.show`` build, for ``--scene clutter3 --seed 3``, the world
``python -m fsm.run --scene clutter3 --seed 3`` runs its episode in (every block's pose jittered
from the seed; seed 0 is the file as written), and show's overhead image is that world's."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fsm.layout import episode_scene
from fsm.run import options_from_args
from hand_sim import clitools, show
from hand_sim.camera import OverheadCamera
from hand_sim.scene import Scene
from hand_sim.world import World
from vision.__main__ import parse_args as vision_args

SCENE, SEED = "clutter3", 3


def fsm_run_scene(tmp_path: Path, seed: int) -> Scene:
    """The scene ``python -m fsm.run --scene clutter3 --seed N`` runs (fsm.machine's path)."""
    options = options_from_args(["--scene", SCENE, "--seed", str(seed), "--out", str(tmp_path)])
    return episode_scene(options.scene, options.seed, options.blocks)


def block_poses(scene: Scene) -> dict[str, np.ndarray]:
    world = World.build(scene)
    return {b.name: np.concatenate(world.block_pose(b.name)) for b in scene.blocks}


def test_vision_and_show_build_the_world_fsm_run_builds(tmp_path: Path) -> None:
    fsm_poses = block_poses(fsm_run_scene(tmp_path / "run", SEED))
    flags = ["--scene", SCENE, "--seed", str(SEED)]
    for args in (
        vision_args([*flags, "--name", "pentagon"]),
        show.parse_args([*flags, "--out", str(tmp_path / "show")]),
    ):
        poses = block_poses(clitools.scene_from_arguments(args))
        assert poses.keys() == fsm_poses.keys()
        for name, pose in poses.items():
            np.testing.assert_array_equal(pose, fsm_poses[name])
    as_written = block_poses(fsm_run_scene(tmp_path / "run0", 0))
    for name, pose in fsm_poses.items():  # the seed moved every block
        assert np.linalg.norm(pose[:2] - as_written[name][:2]) > 1e-4
    args = vision_args(["--scene", SCENE, "--name", "pentagon"])  # no --seed: the file as written
    for name, pose in block_poses(clitools.scene_from_arguments(args)).items():
        np.testing.assert_array_equal(pose, as_written[name])


def test_show_photographs_the_jittered_layout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """show's overhead.png for seed 3 is the image of fsm.run's seed-3 world after the same
    settling (the arm's moves, which come after the picture, are left out to keep this short)."""
    monkeypatch.setattr(show, "ARM_WAYPOINTS", ())
    w, h = 160, 120
    out = tmp_path / "demo"
    argv = ["--scene", SCENE, "--seed", str(SEED), "--out", str(out)]
    assert show.main([*argv, "--width", str(w), "--height", str(h)]) == 0
    assert "overhead.png" in capsys.readouterr().out
    png = cv2.imread(str(out / "overhead.png"))
    world = World.build(fsm_run_scene(tmp_path / "run", SEED))
    steps = round(show.SETTLE_S / world.model.opt.timestep) // show.LOG_EVERY
    for _ in range(steps):
        world.step(show.LOG_EVERY)
    with OverheadCamera(world, w, h) as cam:
        expected = cv2.cvtColor(cam.rgb(), cv2.COLOR_RGB2BGR)
    np.testing.assert_array_equal(png, expected)


def test_blocks_stay_refused_for_a_scene_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "o"
    assert show.main(["--scene", SCENE, "--seed", "3", "--blocks", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--blocks: applies to --scene random only" in err[0]
    assert not out.exists()
