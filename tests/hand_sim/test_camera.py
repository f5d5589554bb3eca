"""Tests of hand_sim.camera: the overhead image shows each block where its scene file puts it,
and pixel <-> world conversions agree with what is rendered."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from hand_sim.camera import OverheadCamera
from hand_sim.errors import HandSimError
from hand_sim.scene import load_scene
from hand_sim.world import World

REPO = Path(__file__).resolve().parents[2]
#: A block's top face found in the image must be this close (m) to its scene position.
POSITION_TOL = 0.003
#: Pixels within this depth (m) of a block's top plane belong to its top face.
TOP_FACE_DEPTH_TOL = 0.002


@pytest.fixture(scope="module", params=[("clutter3", None), ("clutter5", None), ("random", 7)])
def rig(request: pytest.FixtureRequest):
    name, seed = request.param
    world = World.build(load_scene(name, seed=seed, blocks=6 if seed is not None else None))
    world.step(100)
    cam = OverheadCamera(world)
    yield world, cam
    cam.close()


def test_image_shows_each_block_at_its_scene_position_and_colour(rig) -> None:
    world, cam = rig
    rgb, depth, seg = cam.rgb(), cam.depth(), cam.segmentation()
    assert rgb.shape == (480, 640, 3) and rgb.dtype == np.uint8
    assert depth.shape == (480, 640) and depth.dtype == np.float32
    camera_z = cam.pose[2, 3]
    geom_body = np.append(world.model.geom_bodyid, -1)[seg]
    colours = np.array([b.rgba[:3] for b in world.scene.blocks])
    for i, block in enumerate(world.scene.blocks):
        z_top = world.scene.table.height + block.height
        top = (geom_body == world.block_body_id(block.name)) & (
            np.abs(depth - (camera_z - z_top)) < TOP_FACE_DEPTH_TOL
        )
        # the top face's visible area matches the footprint's area at that distance
        expected_px = block.polygon.area * (cam.intrinsics[0, 0] / (camera_z - z_top)) ** 2
        assert top.sum() == pytest.approx(expected_px, rel=0.1), block.name
        v, u = np.nonzero(top)
        found = cam.pixel_to_world(np.array([u.mean(), v.mean()]), z_top)
        assert np.linalg.norm(found[:2] - np.array(block.position)) < POSITION_TOL, block.name
        # the pixels are the block's colour: nearest of the scene's colours (by hue direction)
        mean = rgb[top].mean(axis=0) / 255.0
        cos = colours @ mean / (np.linalg.norm(colours, axis=1) * np.linalg.norm(mean))
        assert int(np.argmax(cos)) == i, block.name


def test_the_skipped_skybox_pass_leaves_every_pixel_as_it_was(rig) -> None:
    """The camera skips MuJoCo's skybox pass (a cheaper frame): the table fills the view, so
    every pixel is some geom's and the images with the pass are the same to the bit."""
    _, cam = rig
    assert (cam.segmentation() >= 0).all()
    rgb, depth = cam.rgb(), cam.depth()
    flags = cam._renderer.scene.flags
    flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = True
    try:
        np.testing.assert_array_equal(cam.rgb(), rgb)
        np.testing.assert_array_equal(cam.depth(), depth)
    finally:
        flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False


def test_table_edges_appear_where_the_intrinsics_project_them(rig) -> None:
    world, cam = rig
    depth = cam.depth()
    t = world.scene.table
    tx, ty = t.position_xy
    u_edge = cam.world_to_pixel([tx + 0.5 * t.size_xy[0], ty, t.height])[0]
    v_edge = cam.world_to_pixel([tx, ty - 0.5 * t.size_xy[1], t.height])[1]
    v_mid = round(float(cam.world_to_pixel([tx, ty, t.height])[1]))
    u_mid = round(float(cam.world_to_pixel([tx, ty, t.height])[0]))
    table_depth = cam.pose[2, 3] - t.height
    row_on_table = np.abs(depth[v_mid, :] - table_depth) < 1e-3
    col_on_table = np.abs(depth[:, u_mid] - table_depth) < 1e-3
    last_u = np.flatnonzero(row_on_table).max()  # rightmost table pixel on the centre row
    last_v = np.flatnonzero(col_on_table).max()  # lowest table pixel (-y side) on the centre column
    assert abs(last_u - u_edge) <= 1.0
    assert abs(last_v - v_edge) <= 1.0


def test_depth_deprojects_onto_the_table_and_into_the_blocks(rig) -> None:
    world, cam = rig
    points = cam.depth_to_points(cam.depth())
    seg = cam.segmentation()
    m = world.model
    names = np.array([m.geom(g).name for g in range(m.ngeom)] + [""])
    table = np.char.find(names[seg].astype(str), "table") >= 0
    assert table.mean() > 0.5
    np.testing.assert_allclose(points[table][:, 2], world.scene.table.height, atol=1e-3)
    geom_body = np.append(m.geom_bodyid, -1)[seg]
    for block in world.scene.blocks:
        pts = points[geom_body == world.block_body_id(block.name)]
        assert len(pts) > 100
        # every pixel of the block (top face and the sides seen in perspective) lies in its prism
        fp = block.footprint()
        edges = np.roll(fp, -1, axis=0) - fp
        normals = (
            np.column_stack([edges[:, 1], -edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]
        )
        outside = (pts[:, :2] @ normals.T - np.einsum("ij,ij->i", normals, fp)).max(axis=1)
        assert outside.max() < 0.002, block.name
        z = pts[:, 2] - world.scene.table.height
        assert z.min() > -1e-3 and z.max() < block.height + 1e-3


def test_pixel_world_round_trip() -> None:
    world = World.build(load_scene("single_square"), with_robot=False)
    with OverheadCamera(world, 320, 240) as cam:
        rng = np.random.default_rng(3)
        pts = np.column_stack([rng.uniform(-0.4, 0.4, (50, 2)), rng.uniform(0.75, 1.0, 50)])
        uv = cam.world_to_pixel(pts)
        np.testing.assert_allclose(cam.pixel_to_world(uv, pts[:, 2]), pts, atol=1e-9)
        K = cam.intrinsics
        fovy = np.radians(world.model.cam_fovy[cam.camera_id])
        assert K[1, 1] == pytest.approx(120.0 / np.tan(fovy / 2))
        # straight down: the image centre sees the point below the camera
        below = cam.pixel_to_world(np.array([159.5, 119.5]), 0.75)
        np.testing.assert_allclose(below[:2], cam.pose[:2, 3], atol=1e-9)
        # +x in the world is to the right in the image, +y is up
        right, up = cam.world_to_pixel([[0.1, 0, 0.75], [0, 0.1, 0.75]])
        assert right[0] > 159.5 and up[1] < 119.5


def test_bad_sizes_and_closed_camera_are_refused() -> None:
    world = World.build(load_scene("single_square"), with_robot=False)
    with pytest.raises(HandSimError, match="image size 5000x480"):
        OverheadCamera(world, 5000, 480)
    cam = OverheadCamera(world, 64, 48)
    cam.close()
    with pytest.raises(HandSimError, match="closed"):
        cam.rgb()


def test_renders_headless_even_when_mujoco_was_imported_first(tmp_path: Path) -> None:
    """MuJoCo picks its GL backend on first import; importing it before hand_sim (as isort orders
    imports) must not leave the camera on GLFW, which has no display here."""
    code = (
        "import mujoco\n"
        "from hand_sim.camera import OverheadCamera\n"
        "from hand_sim.scene import load_scene\n"
        "from hand_sim.world import World\n"
        "w = World.build(load_scene('single_square'), with_robot=False)\n"
        "with OverheadCamera(w, 64, 48) as c:\n"
        "    print(c.rgb().shape)\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    run = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "(48, 64, 3)" in run.stdout
