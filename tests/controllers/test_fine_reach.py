"""Tests of fine reach (controllers.reach.fine): harmonic fingertip fields and the closed loop
in simulation, from the coarse-reach posture above clutter3's target."""

from __future__ import annotations

import numpy as np

from controllers.planning.harmonic import ascend
from controllers.reach.coarse import ReachTarget
from controllers.reach.fine import (
    GRASP_DEPTH,
    OBSTACLE_MARGIN,
    TOUCH_STANDOFF,
    contact_targets,
    fine_reach,
    fingertip_fields,
    project_to_surface,
)
from hand_sim.scene import load_scene
from hand_sim.world import World


def outline_distance(target: ReachTarget, xy: np.ndarray) -> np.ndarray:
    """Distance of points to the footprint outline, by dense sampling of the outline."""
    verts = target.footprint()
    samples = np.vstack(
        [
            a + (b - a) * t
            for a, b in zip(verts, np.roll(verts, -1, 0), strict=True)
            for t in np.linspace(0, 1, 2001)[:, None]
        ]
    )
    return np.linalg.norm(xy[:, None] - samples[None], axis=2).min(axis=1)


def test_projection_is_the_nearest_outline_point():
    world = World.build(load_scene("clutter3"), with_robot=False)
    target = ReachTarget.from_world(world, world.scene.target)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.1, 0.1, (50, 2)), rng.uniform(0.7, 1.0, 50)])
    st = project_to_surface(target, pts, table_z=world.scene.table.height)
    assert np.all(outline_distance(target, st.points[:, :2]) < 1e-4)
    reach = np.linalg.norm(pts[:, :2] - st.points[:, :2], axis=1)
    assert np.all(reach <= outline_distance(target, pts[:, :2]) + 1e-4)
    z = np.clip(pts[:, 2], world.scene.table.height + 0.02, target.top_z - GRASP_DEPTH)
    np.testing.assert_allclose(st.points[:, 2], z)
    ct = contact_targets(target, st.theta)  # theta round-trips to the same surface points
    np.testing.assert_allclose(ct.points[:, :2], st.points[:, :2], atol=1e-9)


def test_fingertip_fields_lead_around_the_block_to_the_targets(hovering):
    world, target = hovering
    tips = world.fingertip_positions()
    st = project_to_surface(target, tips, table_z=world.scene.table.height)
    fields = fingertip_fields(world, target, st, include=tips)
    for tip, ff in zip(world.fingertip_positions(), fields, strict=True):
        path = ascend(ff.field, ff.spec.to_grid(tip))
        assert path.found, path.reason
        pts = ff.spec.to_config(path.points)
        assert np.linalg.norm(pts[-1] - ff.target) < 0.02
        # no point of the path is inside the block (grown by less than the obstacle margin)
        verts = target.footprint()
        ang = target.polygon.normal_angle + target.yaw
        normals = np.stack([np.cos(ang), np.sin(ang)], axis=1)
        signed = np.einsum("nkd,kd->nk", pts[:, None, :2] - verts[None], normals).max(axis=1)
        inside = (signed < OBSTACLE_MARGIN / 2) & (pts[:, 2] < target.top_z)
        assert not inside.any()


def test_fine_reach_ends_with_every_fingertip_within_5mm(hovering):
    world, _ = hovering
    result = fine_reach(world, world.scene.target)
    assert result.reached
    assert result.tip_error.max() < 0.005
    tips = world.fingertip_positions()
    np.testing.assert_allclose(
        np.linalg.norm(
            tips - (result.targets.points + TOUCH_STANDOFF * result.targets.normals), axis=1
        ),
        result.tip_error,
    )
    assert result.max_penetration < 0.002
    assert result.other_contacts == ()
    # the target block was touched, not shoved
    pos, _ = world.block_pose(world.scene.target)
    assert np.linalg.norm(pos[:2] - np.asarray(world.scene.target_block.position)) < 0.005
