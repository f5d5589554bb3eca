"""The overhead camera's check of its calibration against the table (vision.calibration): a
camera moved off its calibration by the ``camera`` perturbation is found where it truly is
(compared with the simulated camera's pose, which the estimate never reads), with and without
sensor noise; a camera that has not moved keeps its calibration bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.planning.belief_world import BeliefWorld
from hand_sim.camera import camera_pose
from hand_sim.perturb import PerturbSpec, draw
from hand_sim.scene import load_scene
from hand_sim.world import World
from vision.calibration import SHIFT_TOLERANCE, TURN_TOLERANCE, calibrate


def _view(text: str | None, seed: int):
    scene = load_scene("clutter3")
    p = None if text is None else draw(PerturbSpec.parse(text), seed, scene.block_names)
    world = World.build(scene, perturbation=p)
    return world, BeliefWorld.over(world).look(check=False)


def _angle(R1: np.ndarray, R2: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(R1.T @ R2) - 1.0) / 2.0, -1.0, 1.0)))


@pytest.mark.parametrize(
    ("text", "seed"), [("camera", 0), ("camera=2", 3), ("camera,sensing=2", 5)]
)
def test_a_drifted_camera_is_found_where_it_is(text: str, seed: int) -> None:
    world, obs = _view(text, seed)
    t = world.scene.table
    cal = calibrate(obs, t.position_xy, t.size_xy, t.height)
    true = camera_pose(world.data, world.model.camera("overhead").id)
    assert cal.corrected
    assert np.linalg.norm(cal.geometry.cam_to_world[:3, 3] - true[:3, 3]) < 2e-4
    assert _angle(cal.geometry.cam_to_world[:3, :3], true[:3, :3]) < np.radians(0.01)
    # and the image's table points land on the table with it: 2 cm off without it
    assert cal.outline_rms < 1e-3


def test_a_camera_that_has_not_moved_keeps_its_calibration() -> None:
    world, obs = _view(None, 0)
    t = world.scene.table
    cal = calibrate(obs, t.position_xy, t.size_xy, t.height)
    assert not cal.corrected and cal.geometry is obs.geometry
    assert cal.shift < 0.2 * SHIFT_TOLERANCE and cal.turn < 0.2 * TURN_TOLERANCE
    # the robot's look is then the simulated camera's, bit for bit
    again = BeliefWorld.over(world).look()
    np.testing.assert_array_equal(again.geometry.cam_to_world, obs.geometry.cam_to_world)
