"""Two renderers in one thread: closing one leaves the other's images as they were
(``mujoco.Renderer.close`` frees its GL objects in whatever context is current; the interactive
page's live view renders beside the recording's camera, which closes at each cycle's end)."""

from __future__ import annotations

import numpy as np

from hand_sim.camera import OverheadCamera
from hand_sim.scene import load_scene
from hand_sim.world import World


def test_closing_a_camera_does_not_spoil_another_cameras_images() -> None:
    world = World.build(load_scene("clutter3"), with_robot=False)
    kept = OverheadCamera(world, 160, 120)
    try:
        before = kept.rgb()
        closed = OverheadCamera(world, 200, 150)
        closed.rgb()
        assert np.array_equal(kept.rgb(), before)  # ``kept``'s context is the current one now
        closed.close()
        assert np.array_equal(kept.rgb(), before)
    finally:
        kept.close()
