"""A pitched lateral palm keeps its face clear of the block (issue 23): the palm face's depth
along the approach axis (:func:`controllers.preshape.palm_candidates.palm_plate_depth`, a linear
programme) against a brute-force count over points of the prism, and the pitched palm poses
of :func:`~controllers.preshape.palm_candidates.lateral_poses` against MuJoCo's own distance between
the palm's collision box and the block."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from controllers.grasp.polygon import Polygon
from controllers.preshape.palm_candidates import (
    DEFAULT_PALM_POSE,
    PoseSetting,
    lateral_poses,
    palm_half_face,
    palm_plate_depth,
)
from controllers.reach.coarse import ReachTarget, lateral_frame
from hand_sim import robot

#: The palm's collision box, half its face (m): models/hand.xml's palm_collision.
HALF_FACE = (0.05, 0.05)


def _brute_depth(
    target: ReachTarget, origin: np.ndarray, frame: np.ndarray, height: float
) -> float:
    """The least axis coordinate of points on a fine grid of the prism (footprint x [top -
    height, top]) that lie in the palm face's shadow (independent of the linear programme)."""
    foot = target.footprint()
    lo, hi = foot.min(axis=0), foot.max(axis=0)
    xs, ys = np.meshgrid(np.linspace(lo[0], hi[0], 121), np.linspace(lo[1], hi[1], 121))
    flat = np.column_stack([xs.ravel(), ys.ravel()])
    inside = _inside(flat, foot)
    zs = np.linspace(target.top_z - height, target.top_z, 81)
    pts = np.array([[x, y, z] for x, y in flat[inside] for z in zs])
    rel = pts - origin
    a, b = HALF_FACE
    shadow = (np.abs(rel @ frame[:, 0]) <= a) & (np.abs(rel @ frame[:, 1]) <= b)
    return float((rel[shadow] @ frame[:, 2]).min()) if shadow.any() else float("inf")


def _inside(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Whether each of ``points`` lies inside the convex, counter-clockwise ``poly``."""
    edges = np.roll(poly, -1, axis=0) - poly
    rel = points[:, None, :] - poly[None, :, :]
    cross = edges[None, :, 0] * rel[:, :, 1] - edges[None, :, 1] * rel[:, :, 0]
    return (cross >= -1e-12).all(axis=1)


@pytest.mark.parametrize("tilt_deg", [0.0, 15.0, 30.0, 45.0])
@pytest.mark.parametrize("roll_deg", [0.0, 10.0, 90.0])
@pytest.mark.parametrize("shift", [0.0, 0.024])
def test_plate_depth_matches_a_brute_force_count(
    tilt_deg: float, roll_deg: float, shift: float
) -> None:
    """For a 20 cm irregular pentagon standing 0.45 m from the base, the linear programme's
    depth equals the least axis coordinate over a 121 x 121 x 81 grid of the prism's points in
    the face's shadow, within the grid's spacing (a grid point lies at most one step inside
    the exact minimum)."""
    polygon = Polygon.from_vertices(
        np.array([[0.03, -0.01], [0.02, 0.03], [-0.02, 0.035], [-0.035, 0.0], [-0.01, -0.03]])
    )
    target = ReachTarget(polygon, (0.45, 0.08), 0.4, 0.20)
    radial = np.array([0.98, 0.2, 0.0]) / np.hypot(0.98, 0.2)
    frame = lateral_frame(radial, np.deg2rad(tilt_deg), np.deg2rad(roll_deg))
    origin = np.array([0.45, 0.08, 0.10]) + shift * np.cross([0.0, 0.0, 1.0], radial)
    exact = palm_plate_depth(target, origin, frame, HALF_FACE)
    brute = _brute_depth(target, origin, frame, height=0.20)
    step = 0.075 / 120 + 0.20 / 80
    assert brute - step <= exact <= brute + 1e-9


def test_a_level_palm_meets_the_near_side_and_a_pitched_one_its_top_edge() -> None:
    """A square facing the palm square-on: the level palm's depth is half the side (its near
    face); pitched 45 deg, the palm's upper edge meets the block's near top edge before its
    centre line does, so the depth is further out than the centre line's exit through the
    near face (half the side / cos 45 deg)."""
    polygon = Polygon.from_vertices(
        np.array([[0.025, -0.025], [0.025, 0.025], [-0.025, 0.025], [-0.025, -0.025]])
    )
    target = ReachTarget(polygon, (0.45, 0.0), 0.0, 0.20)
    origin = np.array([0.45, 0.0, 0.10])
    radial = np.array([1.0, 0.0, 0.0])
    level = palm_plate_depth(target, origin, lateral_frame(radial, 0.0), HALF_FACE)
    assert level == pytest.approx(-0.025, abs=1e-9)
    pitched = palm_plate_depth(target, origin, lateral_frame(radial, np.deg2rad(45.0)), HALF_FACE)
    assert pitched < -0.025 / np.cos(np.deg2rad(45.0)) - 0.01
    # beyond the block's top the shadow misses it
    above = origin + np.array([0.0, 0.0, 0.3])
    assert palm_plate_depth(target, above, lateral_frame(radial, 0.0), HALF_FACE) == float("inf")


@pytest.mark.parametrize("tilt_deg", [30.0, 45.0])
def test_pitched_palm_poses_keep_the_palm_clear_of_the_block(square, tilt_deg: float) -> None:
    """Every sampled-search palm pose beside single_square under a goal pitched 30 or 45 deg
    keeps the palm's collision box clear of the block by MuJoCo's own distance: at least the
    smallest gap (1.5 cm, along the axis) times the cosine of the pitch, less 1 mm (the arm's
    IK tolerance). The poses exist (the arm reaches them). With the gap counted from the palm's
    centre line instead, the palm sank 2.0 (30 deg) and 3.8 cm (45 deg) into the block."""
    world, target, _, _ = square
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    radial = np.array([*(np.asarray(target.position_xy) - base), 0.0])
    radial /= np.linalg.norm(radial)
    setting = PoseSetting(world, world.model, target, lateral_frame(radial, np.deg2rad(tilt_deg)))
    poses = lateral_poses(setting, sampled=True)
    assert len(poses) >= 10
    m = world.model
    data = mujoco.MjData(m)
    palm = m.geom(robot.hand_name("palm_collision")).id
    block = m.geom(f"{world.scene.target}_geom").id
    gap = min(DEFAULT_PALM_POSE.lateral_sampled_gaps)
    assert palm_half_face(m) == HALF_FACE  # the box the poses keep clear is the model's
    fromto = np.zeros(6)
    for pose in poses:
        data.qpos[:] = pose.qpos
        mujoco.mj_kinematics(m, data)
        distance = mujoco.mj_geomDistance(m, data, palm, block, 0.1, fromto)
        # the gap is along the axis; the nearest points lie across the tilted face
        assert distance >= gap * np.cos(np.deg2rad(tilt_deg)) - 0.001, pose.label
