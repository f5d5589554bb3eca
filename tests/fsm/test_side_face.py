"""A block's side face, seen in perspective near the image's edge, is a region the vision cannot
model on its own (fsm.perception.side_face): it is that block, not an obstacle of its own, in
the robot's belief and in the place point's check. Random scene 61 has one, beside the
trapezoid; a real block's region is never taken for another block's face."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.planning.belief_world import BeliefWorld
from fsm.perception import UNLABELLED, other_footprints, perceive, seen_blocks, side_face
from hand_sim.scene import load_scene
from hand_sim.world import World
from vision import VisionError


@pytest.fixture(scope="module")
def view():
    world = World.build(load_scene("random", seed=61, blocks=3))
    world.step(500)
    belief = BeliefWorld.over(world)
    return world, belief, perceive(belief)


def _refused(selection) -> list[int]:
    out = []
    for i in range(len(selection.blocks)):
        try:
            selection.model(i)
        except VisionError:
            out.append(i)
    return out


def test_the_side_face_is_its_block_and_no_obstacle(view) -> None:
    world, belief, sel = view
    (face,) = _refused(sel)
    # judged on the truth: the region's points (from the depth image) are on the trapezoid's
    # side, within its 3 cm radius of its centre and below its top
    obs = sel.observation
    points = obs.geometry.backproject(obs.depth)[sel.blocks[face].top_mask]
    centre, _ = world.block_pose("trapezoid_2")
    assert np.linalg.norm(points[:, :2] - centre[:2], axis=1).max() < 0.032
    assert points[:, 2].max() < world.scene.table.height + 0.2 + 0.002
    index = sel.names.index("hexagon_0")
    model = sel.model(index)
    blocks = seen_blocks(belief, sel, "hexagon_0", model)
    assert sorted(b.name for b in blocks) == sorted(b.name for b in world.scene.blocks)
    assert not any(b.name.startswith(UNLABELLED) for b in blocks)
    footprints, unmodelled = other_footprints(belief, sel, index, model)
    assert len(footprints) == 2 and unmodelled == []


def test_a_real_block_is_not_another_blocks_face(view) -> None:
    _, _, sel = view
    models = {i: sel.model(i) for i in range(len(sel.blocks)) if i not in _refused(sel)}
    for i in models:
        prisms = [(m.world_vertices, float(m.centroid[2])) for j, m in models.items() if j != i]
        assert not side_face(sel, i, prisms)
        assert side_face(sel, i, [(models[i].world_vertices, float(models[i].centroid[2]))])
