"""``python -m vision --scene clutter3 --seed 3 --name pentagon --overlay x.png`` models the
pentagon where ``python -m fsm.run --scene clutter3 --seed 3`` puts it, and writes the overlay."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from hand_sim.scene_seed import episode_scene
from vision.__main__ import main as vision_cli


def centroid(out: str) -> np.ndarray:
    m = re.search(r"centroid \(([-+\d.]+), ([-+\d.]+),", out)
    assert m is not None, out
    return np.array([float(m[1]), float(m[2])])


def test_seed_models_the_block_in_the_jittered_layout(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    overlay = tmp_path / "x.png"
    argv = ["--scene", "clutter3", "--seed", "3", "--name", "pentagon", "--width", "640"]
    assert vision_cli([*argv, "--height", "480", "--overlay", str(overlay)]) == 0
    out = capsys.readouterr().out
    assert "block pentagon: 5 edges" in out
    img = cv2.imread(str(overlay))
    assert img is not None and img.shape == (480, 640, 3)
    seeded = episode_scene("clutter3", 3).block("pentagon").position
    as_written = episode_scene("clutter3", 0).block("pentagon").position
    assert np.linalg.norm(np.subtract(seeded, as_written)) > 1e-3  # the seed moved it
    assert np.linalg.norm(centroid(out) - seeded) < 2e-3  # the model is where the seed put it
