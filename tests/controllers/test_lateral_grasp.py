"""Lateral contacts from the hand's own reach (issue 23, controllers.preshape.lateral_grasp): the
sampled grasp at a palm pose beside the block is checked against independent computations (the
prism's signed distance, forward kinematics, S_G of the contacts on the unit-moment polygon, and the
reach test's own hand IK), and a whole lateral episode from it is judged physically."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

import fsm.handlers.fine_reach as fine_reach_handler
from controllers.grasp.objects import PAPER_OBJECTS, paper_object
from controllers.grasp.score import SUCCESS_THRESHOLD, grasp_score
from controllers.hand.finger_geometry import PerceivedPrism, fingertips_at
from controllers.hand.reachability import CONTACT_SEPARATION, TOP_MARGIN, check_reach
from controllers.preshape.lateral_grasp import (
    LateralSampling,
    sampled_lateral_grasp,
    three_contact_lateral_grasp,
)
from controllers.preshape.palm_candidates import (
    DEFAULT_PALM_POSE,
    PoseSetting,
    face_arcs,
    lateral_poses,
)
from controllers.reach.coarse import ReachTarget, lateral_frame
from controllers.reach.fine import reach_along_normals
from fsm.config import TaskConfig
from fsm.context import EpisodeOptions
from fsm.machine import run_episode
from hand_sim import robot
from hand_sim.world import World
from tests.controllers.conftest import grasps_beside

SQUEEZE = (
    0.004  # fsm.config.TaskConfig.lateral_squeeze_reach (the sampled pre-shape adds no margin)
)


@pytest.fixture(scope="module")
def grasps(square, samples) -> list:
    """(pose, grasp) at every palm pose of the search where one is found."""
    return grasps_beside(square, samples, sampled_lateral_grasp, SQUEEZE)


def test_sampled_contacts_lie_on_side_faces_where_the_sampled_fingertips_press(
    square, grasps
) -> None:
    """Every contact of every grasp found lies on a side face of the prism (signed distance 0,
    between the height margins); forward kinematics of the grasp's hand posture at the pose puts
    each fingertip 4 mm (the squeeze) inside its contact's face, within the sampling's
    tolerance; the pads are a pad spacing apart where they take their contacts; S_G is that of
    the contacts on the unit-moment polygon."""
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
        # the pads apart where they take their contacts, heights included
        normals = np.column_stack([_world_normals(target, grasp.theta), np.zeros(4)])
        pads = grasp.points + robot.PAD_RADIUS * normals
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
def test_a_lateral_grasp_from_sampled_contacts_delivers_the_hexagon(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """single_hexagon, --approach lateral, the default ``lateral_contacts="sampled-first"``
    (the pinch's contacts converged to a weak grasp there, S_G 0.58): the pre-shape takes
    sampled contacts; Fine Reach brings each fingertip in along its contact's normal (measured
    in the simulation: the fingertips' moves point into their faces, the block stays put), the
    grasp holds them, and the block is delivered, judged physically."""
    reaches = []

    def measured(world, name, hand_to, targets, **kwargs):
        before = world.fingertip_positions(), world.block_pose(name)[0]
        result = reach_along_normals(world, name, hand_to, targets, **kwargs)
        after = world.fingertip_positions(), world.block_pose(name)[0]
        reaches.append((before, after, targets.normals))
        return result

    monkeypatch.setattr(fine_reach_handler, "reach_along_normals", measured)
    options = EpisodeOptions(scene="single_hexagon", approach="lateral", record=False, out=tmp_path)
    result = run_episode(options)
    assert "sampled pre-shape" in result.visits[1].reason
    assert reaches, "Fine Reach did not come in along the normals"
    for (tips0, block0), (tips1, block1), normals in reaches:
        move = tips1 - tips0
        inward = -np.sum(move * normals, axis=1)
        # each fingertip came in towards its face, most of its move along the normal (the tip
        # site also swings a little as the finger's pad turns)
        assert np.all(inward > 0.002), inward
        assert np.all(inward > 0.6 * np.linalg.norm(move, axis=1))
        assert np.linalg.norm(block1 - block0) < 0.001
    assert result.success, result.failure_detail
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral" and cycle["s_g"] <= SUCCESS_THRESHOLD
    assert cycle["approach_pitch_deg"] == pytest.approx(0.0, abs=1.0)
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    # recorded like a top grasp: contacts, S_G and the approach in the summary
    (recorded,) = json.loads((tmp_path / "summary.json").read_text())["cycles"]
    assert recorded["approach"] == "lateral" and recorded["s_g"] == pytest.approx(cycle["s_g"])
    assert len(recorded["contacts"]) == 4 and recorded["approach_pitch_deg"] is not None


@pytest.mark.e2e
def test_a_block_near_the_arms_base_is_grasped_from_a_pitched_lateral_approach(
    tmp_path: Path,
) -> None:
    """Random scene 26 (one block 0.49 m from the arm's base), --approach lateral: no level
    lateral goal exists (the hand would hit the arm's own forearm), so Coarse Reach pitches the
    approach axis 15 deg down (controllers.reach.coarse.LATERAL_TILTS), says so in the log and the
    summary, and the block is delivered, judged physically."""
    options = EpisodeOptions(
        scene="random", seed=26, blocks=1, approach="lateral", record=False, out=tmp_path
    )
    result = run_episode(options)
    assert "lateral approach (axis pitched 15 deg down)" in result.visits[1].reason
    assert result.success, result.failure_detail
    (cycle,) = result.cycles
    assert cycle["approach"] == "lateral"
    assert cycle["approach_pitch_deg"] == pytest.approx(15.0, abs=1.0)
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]


def test_an_unknown_source_of_lateral_contacts_is_refused() -> None:
    """``TaskConfig.lateral_contacts`` takes one of its named sources; a misspelt one is an
    error naming the valid ones, not a silent pinch."""
    with pytest.raises(ValueError, match="pinch, sampled, sampled-first"):
        TaskConfig(lateral_contacts="sample")


@pytest.mark.e2e
def test_a_wider_lateral_gate_takes_a_thumb_against_three_fingers_and_delivers(
    tmp_path: Path,
) -> None:
    """Random scene 91 (a rectangle alone), --approach lateral: beside it the hand's sampled
    grasps put the thumb against three fingers on parallel faces, S_G 0.50 (Eq. 13), above
    the paper's 0.4, so the default gate leaves it no pre-shape. With ``lateral_gate`` 0.6
    (a study setting) the pre-shape takes such a grasp, the hand holds the block at the lift,
    and it is delivered, judged physically; the summary records the gate. (Three-contact grasps,
    which score 0.33 here and come before a grasp above 0.4, are switched off, and the gate is
    the S_G itself: ``lateral_gate_rule`` "paper".)"""
    config = replace(
        TaskConfig(), lateral_gate=0.6, lateral_three_contacts=False, lateral_gate_rule="paper"
    )
    options = EpisodeOptions(
        scene="random",
        seed=91,
        blocks=1,
        approach="lateral",
        record=False,
        out=tmp_path,
        config=config,
    )
    result = run_episode(options)
    coarse = result.visits[1].reason
    assert "sampled pre-shape" in coarse, coarse
    taken = float(coarse.split("sampled contacts S_G ")[1].split()[0])
    assert SUCCESS_THRESHOLD < taken <= 0.6
    assert result.success, result.failure_detail
    (cycle,) = result.cycles
    assert SUCCESS_THRESHOLD < cycle["s_g"] <= 0.6
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["options"]["config"]["lateral_gate"] == 0.6
    assert summary["options"]["config"]["lateral_gate_rule"] == "paper"


@pytest.mark.parametrize("gate", [0.0, -0.4, float("nan"), float("inf")])
def test_a_lateral_gate_that_is_not_a_positive_s_g_is_refused(gate: float) -> None:
    """``TaskConfig.lateral_gate`` is the S_G (Eq. 13) a lateral grasp must reach: zero, a
    negative, NaN or an infinite gate is an error naming the paper's, not a gate that passes
    every grasp or none."""
    with pytest.raises(ValueError, match=r"lateral_gate must be a positive S_G.*0\.4"):
        TaskConfig(lateral_gate=gate)


def test_the_lateral_gate_counts_from_the_thumbs_opposition_by_default() -> None:
    """``TaskConfig.lateral_gate_for``: by default a lateral grasp of n contacts passes at the
    gate plus Eq. 13's floor for a thumb against n - 1 fingers (0.9 for four, 0.4 + 1/3 for
    three, 0.4 for a pinch); by the rule "paper" at the gate itself; an unknown rule is an
    error naming the two."""
    config = TaskConfig()
    assert config.lateral_gate_rule == "opposition"
    assert config.lateral_gate_for(4) == pytest.approx(0.9)
    assert config.lateral_gate_for(3) == pytest.approx(0.4 + 1.0 / 3.0)
    assert config.lateral_gate_for(2) == pytest.approx(0.4)
    paper = TaskConfig(lateral_gate_rule="paper", lateral_gate=0.6)
    assert {paper.lateral_gate_for(n) for n in (2, 3, 4)} == {0.6}
    with pytest.raises(ValueError, match="opposition, paper"):
        TaskConfig(lateral_gate_rule="thumb")


def test_palm_poses_beside_the_block_keep_a_pitched_coarse_goals_pitch(square) -> None:
    """Where the coarse reach's lateral goal is pitched down
    (controllers.reach.coarse.LATERAL_TILTS),
    every palm pose of the pre-shape's search is pitched the same (forward kinematics of its
    arm posture), faces the block along the radial line through the palm, and keeps the finger
    row level up to its roll."""
    world, target, _, _ = square
    base, radial = _radial(world, target)
    tilt = np.deg2rad(15.0)
    poses = lateral_poses(PoseSetting(world, world.model, target, lateral_frame(radial, tilt)))
    assert len(poses) >= 10
    for R, through in _palm_frames(world, base, poses):
        assert np.arcsin(-R[2, 2]) == pytest.approx(tilt, abs=np.deg2rad(1.5))
        assert _off_radial_deg(R, through) < 2.0
        assert abs(R[2, 0]) < np.sin(np.deg2rad(11.0))  # the finger row level, rolled <= 10 deg


def _radial(world: World, target: ReachTarget) -> tuple[np.ndarray, np.ndarray]:
    """The arm base's (x, y) and the unit radial direction from it to the block."""
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    radial = np.array([*(np.asarray(target.position_xy) - base), 0.0])
    return base, radial / np.linalg.norm(radial)


def _palm_frames(world: World, base: np.ndarray, poses: list) -> list:
    """(palm rotation, (x, y, 0) from the base to the palm) of each pose (forward kinematics)."""
    data = mujoco.MjData(world.model)
    palm = world.model.body(robot.hand_name(robot.PALM_BODY)).id
    out = []
    for pose in poses:
        data.qpos[:] = pose.qpos
        mujoco.mj_kinematics(world.model, data)
        through = np.array([*(data.xpos[palm][:2] - base), 0.0])
        out.append((data.xmat[palm].reshape(3, 3).copy(), through))
    return out


def _off_radial_deg(R: np.ndarray, through: np.ndarray) -> float:
    """Angle (deg) between the approach axis's horizontal part and the radial line through the
    palm."""
    horizontal = R[:, 2] * np.array([1.0, 1.0, 0.0])
    cos = horizontal @ through / np.linalg.norm(horizontal) / np.linalg.norm(through)
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


@pytest.mark.parametrize("roll_deg", [180.0, 90.0, -90.0])
def test_palm_poses_at_the_more_rolls_turn_the_hand_about_its_approach_axis(
    square, roll_deg: float
) -> None:
    """The wider wrist rolls a sampled pre-shape searches where none is taken at the default
    ones (``PalmPoseParams.lateral_more_rolls``): at 180 deg the arm holds the hand upside down
    (hand y pointing down: the thumb on the other side of the block), at +-90 deg its finger
    row vertical; the approach axis stays level and radial (forward kinematics of each pose's
    arm posture)."""
    world, target, _, _ = square
    params = replace(DEFAULT_PALM_POSE, lateral_rolls=(np.deg2rad(roll_deg),))
    assert np.deg2rad(roll_deg) in DEFAULT_PALM_POSE.lateral_more_rolls
    base, radial = _radial(world, target)
    setting = PoseSetting(world, world.model, target, lateral_frame(radial, 0.0))
    poses = lateral_poses(setting, params, sampled=True)
    assert len(poses) >= 5
    for R, through in _palm_frames(world, base, poses):
        assert abs(R[2, 2]) < np.sin(np.deg2rad(2.0))  # the approach axis level
        assert _off_radial_deg(R, through) < 2.0
        if roll_deg == 180.0:
            assert R[2, 1] < -np.cos(np.deg2rad(2.0))  # hand y down
        else:
            assert abs(R[2, 0]) > np.cos(np.deg2rad(2.0))  # the finger row vertical


@pytest.mark.e2e
def test_a_sampled_grasp_the_controller_moves_out_of_reach_is_taken_where_the_hand_took_it(
    tmp_path: Path,
) -> None:
    """single_square, --approach lateral: the sampled pre-shape stacks fingers on one face (a
    pad spacing apart in height, not in the plane); the planar controller's first steps push
    them apart in the plane until a pad is turned 80 deg off its face, out of the hand's reach.
    Wrench Closure stops at the pre-shape's own contacts, which the hand reached and which pass
    Eq. 13, and the block is delivered, judged physically."""
    options = EpisodeOptions(scene="single_square", approach="lateral", record=False, out=tmp_path)
    result = run_episode(options)
    closure = next(v for v in result.visits if v.state == "Wrench Closure")
    assert "stopped at step 0's contacts, the last the hand reached" in closure.reason
    assert result.success, result.failure_detail
    (cycle,) = result.cycles
    assert cycle["s_g"] <= SUCCESS_THRESHOLD
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]


def test_the_four_and_three_contact_searches_share_each_poses_candidates(square, samples) -> None:
    """With one candidate cache (``cache=``), the three-contact search at a palm pose takes the
    fingers' candidate contacts the four-contact search found there (one entry per pose, none
    added) and both find exactly the grasps they find each on their own."""
    world, target, prism, poses = square
    pose_xy = (np.asarray(target.position_xy), target.yaw)
    cache: dict = {}
    for pose in poses[:6]:
        args = (world.model, pose.qpos, samples, prism, target.polygon, pose_xy, SQUEEZE)
        before = len(cache)
        shared = [sampled_lateral_grasp(*args, cache=cache)]
        assert len(cache) == before + 1
        shared.append(three_contact_lateral_grasp(*args, cache=cache))
        assert len(cache) == before + 1  # the three-contact search found them there
        alone = [sampled_lateral_grasp(*args), three_contact_lateral_grasp(*args)]
        for a, b in zip(shared, alone, strict=True):
            assert (a is None) == (b is None)
            if a is not None:
                np.testing.assert_array_equal(a.theta, b.theta)
                np.testing.assert_array_equal(a.hand_q, b.hand_q)
                assert (a.s_g, a.load, a.idle) == (b.s_g, b.load, b.idle)
