"""Lateral contacts from the hand's own reach (issue 23, controllers.lateral_grasp): the sampled
grasp at a palm pose beside the block is checked against independent computations (the prism's
signed distance, forward kinematics, S_G of the contacts on the unit-moment polygon, and the reach
test's own hand IK), and a whole lateral episode from it is judged physically."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from controllers.cspace import CollisionChecker
from controllers.finger_geometry import PerceivedPrism, fingertips_at
from controllers.finger_samples import FingerSamples
from controllers.grasp.objects import PAPER_OBJECTS, paper_object
from controllers.grasp.score import SUCCESS_THRESHOLD, grasp_score
from controllers.hand_reach import CONTACT_SEPARATION, TOP_MARGIN, check_reach
from controllers.lateral_grasp import LateralSampling, sampled_lateral_grasp
from controllers.palm_candidates import PoseSetting, face_arcs, lateral_poses
from controllers.reach import PRESHAPE, ReachTarget, goal_poses, solve_goal
from fsm.config import DEFAULT_CONFIG
from fsm.context import EpisodeOptions
from fsm.machine import run_episode
from hand_sim import robot
from hand_sim.scene import load_scene
from hand_sim.world import World

SQUEEZE = (
    0.004  # fsm.config.TaskConfig.lateral_squeeze_reach (the sampled pre-shape adds no margin)
)


@pytest.fixture(scope="module")
def square() -> tuple[World, ReachTarget, PerceivedPrism, list]:
    """single_square with the arm at its lateral coarse goal, and the sampled search's palm
    poses beside the block."""
    world = World.build(load_scene("single_square"))
    target = ReachTarget.from_world(world, "square")
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    ((pos, rot),) = goal_poses(target, base)["lateral"]
    goal = solve_goal(
        CollisionChecker(world, hand_q=PRESHAPE), "lateral", [(pos, rot)], world.arm_qpos()
    )
    assert goal is not None
    world.data.qpos[robot.arm_qpos_addresses(world.model)] = goal.q
    mujoco.mj_forward(world.model, world.data)
    prism = PerceivedPrism.of(target, world.scene.table.height)
    poses = lateral_poses(PoseSetting(world, world.model, target, rot), sampled=True)
    return world, target, prism, poses


@pytest.fixture(scope="module")
def samples() -> FingerSamples:
    return FingerSamples.draw()


@pytest.fixture(scope="module")
def grasps(square, samples) -> list:
    """(pose, grasp) at every palm pose of the search where one is found."""
    world, target, prism, poses = square
    pose_xy = (np.asarray(target.position_xy), target.yaw)
    out = []
    for pose in poses:
        grasp = sampled_lateral_grasp(
            world.model, pose.qpos, samples, prism, target.polygon, pose_xy, SQUEEZE
        )
        if grasp is not None:
            out.append((pose, grasp))
    return out


def test_sampled_contacts_lie_on_side_faces_where_the_sampled_fingertips_press(
    square, grasps
) -> None:
    """Every contact of every grasp found lies on a side face of the prism (signed distance 0,
    between the height margins); forward kinematics of the grasp's hand posture at the pose puts
    each fingertip 4 mm (the squeeze) inside its contact's face, within the sampling's
    tolerance; the pads are a pad spacing apart; S_G is that of the contacts on the
    unit-moment polygon."""
    world, target, prism, _ = square
    params = LateralSampling()
    assert len(grasps) >= 3
    hand_adr = robot.hand_qpos_addresses(world.model)
    unit = target.polygon.unit_moment()
    for pose, grasp in grasps:
        assert np.abs(prism.signed_distance(grasp.points)).max() < 1e-9
        assert grasp.points[:, 2].max() <= prism.top - TOP_MARGIN + 1e-9
        qpos = pose.qpos.copy()
        qpos[hand_adr] = grasp.hand_q
        depth = -prism.signed_distance(fingertips_at(world.model, qpos))
        assert np.all(depth >= SQUEEZE - params.shortfall - 1e-9)
        assert np.all(depth <= SQUEEZE + params.tolerance + 1e-9)
        frames = target.polygon.locate(grasp.theta)
        pads = frames.point + robot.PAD_RADIUS * frames.normal
        gaps = np.linalg.norm(pads[:, None] - pads[None], axis=-1) + np.eye(4)
        assert gaps.min() >= CONTACT_SEPARATION
        u = unit.locate(grasp.theta)
        assert grasp.s_g == pytest.approx(grasp_score(u.point, u.normal).s_g, abs=1e-9)
        assert grasp.load < 1.0


def test_a_square_beside_the_hand_has_a_grasp_the_hand_ik_confirms(square, grasps) -> None:
    """On single_square (faces along and across the approach) the search finds grasps that pass
    Eq. 13 (S_G <= 0.4) at several palm poses, and at three or more of them the reach test's own
    hand IK, started from the grasp's sampled posture, takes the contacts at their heights (the
    criteria of section 5.2: within 2 mm, pads facing their faces, no link in the block; the
    others fail it by a few millimetres or degrees: the FSM's search keeps only those that
    pass)."""
    world, _, prism, _ = square
    hand_adr = robot.hand_qpos_addresses(world.model)
    good = [(p, g) for p, g in grasps if g.s_g <= SUCCESS_THRESHOLD]
    assert good
    passed = 0
    for pose, grasp in good:
        qpos = pose.qpos.copy()
        qpos[hand_adr] = grasp.hand_q
        normals = np.column_stack([_world_normals(square[1], grasp.theta), np.zeros(4)])
        reach = check_reach(
            world, prism, grasp.points, normals, qpos=qpos, check_spacing=False, squeeze=SQUEEZE
        )
        passed += reach.reachable
    assert passed >= 3


def _world_normals(target: ReachTarget, theta: np.ndarray) -> np.ndarray:
    n = target.polygon.locate(theta).normal
    c, s = np.cos(target.yaw), np.sin(target.yaw)
    return n @ np.array([[c, s], [-s, c]])


def test_no_grasp_from_a_palm_far_from_the_block(square, samples) -> None:
    """With the palm 25 cm back from the block no fingertip sample reaches a face: None."""
    world, target, prism, poses = square
    qpos = poses[0].qpos.copy()
    far = ReachTarget(
        target.polygon,
        (target.position_xy[0] + 0.25, target.position_xy[1]),
        target.yaw,
        target.top_z,
    )
    pose_xy = (np.asarray(far.position_xy), far.yaw)
    far_prism = PerceivedPrism.of(far, prism.bottom)
    assert (
        sampled_lateral_grasp(world.model, qpos, samples, far_prism, far.polygon, pose_xy, SQUEEZE)
        is None
    )


@pytest.mark.parametrize("name", PAPER_OBJECTS)
def test_face_arcs_are_each_contacts_own_face_inset_from_its_corners(name: str) -> None:
    """Each contact's arc runs along the face it lies on, from 4 mm after the face's first
    vertex to 4 mm before its last (a quarter of a face shorter than 16 mm)."""
    poly = paper_object(name)
    theta = np.linspace(-np.pi, np.pi, 17)[:-1]
    arcs = face_arcs(poly, theta, 0.004)
    frames = poly.locate(theta)
    ends = poly.locate(arcs)
    np.testing.assert_array_equal(ends.edge[:, 0], frames.edge)
    np.testing.assert_array_equal(ends.edge[:, 1], frames.edge)
    v = poly.vertices
    for k, arc_pts in zip(frames.edge, ends.point, strict=True):
        a, b = v[k], v[(k + 1) % len(v)]
        inset = min(0.004, 0.25 * np.linalg.norm(b - a))
        assert np.linalg.norm(arc_pts[0] - a) == pytest.approx(inset, abs=1e-9)
        assert np.linalg.norm(arc_pts[1] - b) == pytest.approx(inset, abs=1e-9)


@pytest.mark.e2e
def test_a_lateral_grasp_from_sampled_contacts_delivers_the_square(tmp_path: Path) -> None:
    """single_square, --approach lateral, ``lateral_contacts="sampled"``: no palm pose reaches
    the pinch's contacts, so the pre-shape takes sampled contacts, the grasp holds them, and the
    block is delivered, judged physically."""
    config = dataclasses.replace(DEFAULT_CONFIG, lateral_contacts="sampled")
    options = EpisodeOptions(
        scene="single_square", approach="lateral", record=False, out=tmp_path, config=config
    )
    result = run_episode(options)
    assert result.success, result.failure_detail
    assert "sampled pre-shape" in result.visits[1].reason
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral" and cycle["s_g"] <= SUCCESS_THRESHOLD
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["options"]["config"]["lateral_contacts"] == "sampled"
