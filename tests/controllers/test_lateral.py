"""The lateral grasp of section 5.2 (issue 9: "a lateral pre-shape that cannot grasp is a defect to
fix"): the pieces it is built from, each checked against an independent computation, and a whole
lateral episode on the rectangle judged physically."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.errors import GraspError
from controllers.grasp.objects import PAPER_OBJECTS, paper_object
from controllers.grasp.synthesis import GraspSynthesis, clamp_to_arcs
from controllers.hand.finger_samples import Criteria, FingerSamples
from controllers.hand.grip import backed_off_hand, balanced_shares, normal_squeeze
from controllers.planning.cspace import CollisionChecker
from controllers.posture.solver import solve_posture
from controllers.preshape.moves import BlockSite, clear_backoff
from controllers.preshape.palm_candidates import lateral_arcs
from controllers.reach.coarse import PRESHAPE, ReachTarget, goal_poses, solve_goal
from fsm.layout import episode_scene
from fsm.run import main
from hand_sim import robot
from hand_sim.indices import RobotIndices
from hand_sim.scene import load_scene
from hand_sim.world import World


@pytest.fixture(scope="module")
def world() -> World:
    return World.build(load_scene("single_rectangle"))


@pytest.fixture(scope="module")
def samples() -> FingerSamples:
    return FingerSamples.draw(n=2000, seed=1)


# --- sliding contact heights --------------------------------------------------------------------
def test_sliding_targets_keep_their_place_and_take_the_fingertips_height(world: World) -> None:
    """A contact on a vertical face is a vertical line: targets 5 cm above the fingertips are out
    of the hand's reach with the arm held, but with their heights free to slide the fingertips
    reach their horizontal places, at heights inside the range given."""
    tips = world.fingertip_positions()
    idx = RobotIndices.of(world.model)
    # each target a millimetre from its fingertip horizontally, 5 cm above it
    goal = tips + np.array([0.001, -0.001, 0.05])
    fixed = solve_posture(world, goal, optimize=False, joints="hand")
    assert not fixed.reachable
    lo, hi = tips[:, 2].min() - 0.02, tips[:, 2].max() + 0.01
    slid = solve_posture(world, goal, optimize=False, joints="hand", slide=(lo, hi))
    assert slid.reachable, slid.tip_error
    assert slid.targets is not None
    np.testing.assert_allclose(slid.targets[:, :2], goal[:, :2])
    assert np.all((slid.targets[:, 2] >= lo) & (slid.targets[:, 2] <= hi))
    # the targets are where the fingertips are (forward kinematics of the solution)
    data = mujoco.MjData(world.model)
    data.qpos[:] = world.data.qpos
    data.qpos[idx.finger_qpos.ravel()] = slid.hand_q
    mujoco.mj_kinematics(world.model, data)
    reached = data.site_xpos[idx.tip_sites]
    assert np.linalg.norm(reached - slid.targets, axis=1).max() < 1e-3


# --- sampled finger postures --------------------------------------------------------------------
def test_finger_samples_are_the_hands_forward_kinematics_in_the_palm_frame(
    world: World, samples: FingerSamples
) -> None:
    again = FingerSamples.draw(n=2000, seed=1)
    np.testing.assert_array_equal(again.q, samples.q)  # seeded
    m = world.model
    data = mujoco.MjData(m)
    data.qpos[:] = world.data.qpos
    idx = RobotIndices.of(m)
    palm = m.body(robot.hand_name(robot.PALM_BODY)).id
    for i in (0, 17, 1999):
        data.qpos[idx.finger_qpos.ravel()] = samples.q[i].ravel()
        mujoco.mj_kinematics(m, data)
        R, p = data.xmat[palm].reshape(3, 3), data.xpos[palm]
        np.testing.assert_allclose(
            (data.site_xpos[idx.tip_sites] - p) @ R, samples.tip[i], atol=1e-9
        )


def test_the_best_sample_takes_its_contact_and_none_takes_one_out_of_reach(
    samples: FingerSamples,
) -> None:
    criteria = Criteria(0.003, np.deg2rad(90.0), 0.8, 0.2, 0.0015, 0.004)
    far = lambda pts: np.full(pts.shape[:-1], 1.0)  # noqa: E731 - no block anywhere near
    # a contact where sample 5's index fingertip is, the face turned against its pad
    k = 5
    n = -samples.pad[k, 0] * np.array([1.0, 1.0, 0.0])
    n /= np.linalg.norm(n)
    point = samples.tip[k, 0] + criteria.squeeze * n
    q, score = samples.best(0, np.zeros(3), np.eye(3), point, n, (-1.0, 1.0), far, criteria)
    assert q is not None and score < 1.0
    j = int(np.flatnonzero(np.all(samples.q[:, 0] == q, axis=1))[0])
    target = point - criteria.squeeze * n
    off = samples.tip[j, 0] - target
    assert np.linalg.norm(off[:2]) < criteria.tolerance  # on the vertical line (world z = up)
    q, score = samples.best(
        0, np.zeros(3), np.eye(3), point + np.array([0.5, 0.0, 0.0]), n, (-1.0, 1.0), far, criteria
    )
    assert q is None and score == np.inf


# --- the squeeze --------------------------------------------------------------------------------
def _net_wrench(points: np.ndarray, normals: np.ndarray, forces: np.ndarray) -> np.ndarray:
    push = -normals * forces[:, None]
    arm = points - points.mean(axis=0)
    return np.concatenate([push.sum(axis=0), np.cross(arm, push).sum(axis=0)])


def test_balanced_shares_balance_the_block_in_three_dimensions() -> None:
    # the rectangle's pinch: first and middle finger on one long face, ring finger and thumb on
    # the other, the middle finger high and the thumb low
    n = np.array([[0, 1, 0], [0, 1, 0], [0, -1, 0], [0, -1, 0]], float)
    level = np.array([[0.009, 0.012, 0.85], [-0.012, 0.012, 0.85], [0.009, -0.012, 0.85]])
    level = np.vstack([level, [-0.012, -0.012, 0.85]])
    planar = np.ones(4)  # opposed pairs: equal forces balance them in the plane
    np.testing.assert_allclose(balanced_shares(level, n, planar), planar, atol=1e-6)
    tall = level.copy()
    tall[:, 2] = [0.842, 0.906, 0.85, 0.775]
    assert np.abs(_net_wrench(tall, n, planar)[3:]).max() > 0.05  # the planar shares tip it
    shares = balanced_shares(tall, n, planar)
    assert shares.mean() == pytest.approx(1.0) and shares.min() >= 0.1 - 1e-9
    assert np.abs(_net_wrench(tall, n, shares)).max() < 0.02
    with pytest.raises(Exception, match="must be"):
        balanced_shares(tall[:3], n, planar)


def test_the_normal_squeeze_pushes_along_the_contact_normal(world: World) -> None:
    """Servo torques K d along the squeeze direction d are those of a fingertip force along the
    inward normal (J^T F = K d has F parallel to -n), and moving along d drives the fingertip
    into the face."""
    m = world.model
    idx = RobotIndices.of(m)
    qpos = world.data.qpos.copy()
    qpos[idx.finger_qpos.ravel()] = [0.0, 0.9, 0.7, 0.4] * 4
    normals = np.array([[1.0, 0, 0], [0, 1.0, 0], [-0.6, 0.8, 0], [0, 0, 1.0]])
    direction, rate = normal_squeeze(m, qpos, normals)
    data = mujoco.MjData(m)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(m, data)
    mujoco.mj_comPos(m, data)
    actuators = [m.actuator(robot.qualified(a)).id for a in robot.HAND_ACTUATORS]
    kp = m.actuator_gainprm[actuators, 0]
    jac = np.zeros((3, m.nv))
    for f, site in enumerate(idx.tip_sites):
        mujoco.mj_jacSite(m, data, jac, None, int(site))
        J = jac[:, idx.finger_dofs[f]]
        torque = kp[4 * f : 4 * f + 4] * direction[4 * f : 4 * f + 4]
        force, *_ = np.linalg.lstsq(J.T, torque, rcond=None)
        assert force @ -normals[f] / np.linalg.norm(force) > 0.999
        assert rate[f] > 0
    # backing off moves every fingertip out along its normal, to first order
    before = data.site_xpos[idx.tip_sites].copy()
    data.qpos[idx.finger_qpos.ravel()] = backed_off_hand(m, qpos, normals, 0.002)
    mujoco.mj_kinematics(m, data)
    out = np.einsum("fd,fd->f", data.site_xpos[idx.tip_sites] - before, normals)
    np.testing.assert_allclose(out, 0.002, atol=3e-4)


# --- the lateral approach -----------------------------------------------------------------------
def test_the_lateral_goal_has_the_thumb_below(world: World) -> None:
    target = ReachTarget.from_world(world, "rectangle")
    ((_, rot),) = goal_poses(target, (-0.6, 0.0))["lateral"]
    assert rot[2, 1] == pytest.approx(1.0)  # hand y (thumb to middle finger) points up
    assert abs(rot[2, 2]) < 1e-9  # the approach axis horizontal


# --- the faces a lateral hand takes -------------------------------------------------------------
@pytest.mark.parametrize("name", PAPER_OBJECTS)
@pytest.mark.parametrize("yaw_deg", [0.0, 37.0, 144.0])
def test_lateral_arcs_hold_the_side_faces_and_leave_the_near_and_far_ones(
    name: str, yaw_deg: float
) -> None:
    """Each side's arc lies on faces turned from the across direction on that side at most 45
    deg away from the palm and 15 deg towards it (when any face is; else on the faces nearest
    that), checked by sampling the arc's points on the polygon; the pentagon's near faces,
    turned 54 deg towards the palm, are left out."""
    poly = paper_object(name)
    yaw = np.deg2rad(yaw_deg)
    target = ReachTarget(poly, (0.02, -0.05), yaw, 0.95)
    arcs = lateral_arcs(target, (-0.6, 0.0))
    axis = np.array([0.62, -0.05]) / np.linalg.norm([0.62, -0.05])
    across = np.array([-axis[1], axis[0]])
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s], [s, c]])
    edge_normals = np.stack([np.cos(poly.normal_angle), np.sin(poly.normal_angle)], 1) @ R.T
    lo_turn, hi_turn = -np.deg2rad(15.0), np.deg2rad(45.0)

    def excess(normals: np.ndarray, side: float) -> np.ndarray:
        turn = np.degrees(np.arctan2(normals @ axis, normals @ (side * across)))
        return np.maximum(turn - np.degrees(hi_turn), np.degrees(lo_turn) - turn)

    for row, side in enumerate((1.0, -1.0)):
        lo, hi = arcs[row]
        span = np.mod(hi - lo, 2 * np.pi)
        assert 0.0 < span < np.pi
        frames = poly.locate(lo + np.linspace(0.01, 0.99, 25) * span)
        allowed = max(0.0, excess(edge_normals, side).min())  # 0 when some face qualifies
        assert np.all(excess(frames.normal @ R.T, side) <= allowed + 1e-6)
    if yaw_deg == 0.0 and name == "pentagon":
        # a corner points at the arm: no arc point on the near faces (54 deg towards the palm)
        for lo, hi in arcs:
            frames = poly.locate(lo + np.linspace(0.0, 1.0, 25) * np.mod(hi - lo, 2 * np.pi))
            assert np.all(frames.normal @ R.T @ axis > -np.sin(np.deg2rad(20.0)))


def test_grasp_synthesis_keeps_each_contact_on_its_arc() -> None:
    """With arcs the controller's contacts never leave them, and the grasp it converges to on
    the pentagon's two far side faces still passes S_G; without arcs the same start leaves
    them."""
    poly = paper_object("pentagon")
    target = ReachTarget(poly, (0.0, 0.0), 0.0, 0.95)
    arcs = lateral_arcs(target, (-0.6, 0.0))
    theta0 = np.array([0.9, 1.7, -0.9, -1.7])
    per_contact = arcs[[0, 0, 1, 1]]
    pads = {"min_separation": 0.021, "separation_offset": 0.0085}
    syn = GraspSynthesis(
        poly, KnowledgeBased(), theta0, np.random.default_rng(0), arcs=per_contact, **pads
    )
    free = GraspSynthesis(poly, KnowledgeBased(), theta0, np.random.default_rng(0), **pads)
    left = []
    while not syn.done:
        syn.step()
        np.testing.assert_allclose(clamp_to_arcs(syn.theta, per_contact), syn.theta)
    while not free.done:
        free.step()
        left.append(not np.allclose(clamp_to_arcs(free.theta, per_contact), free.theta))
    assert any(left)
    assert syn.converged and syn.finish().success
    with pytest.raises(GraspError, match="one \\(lo, hi\\) interval per contact"):
        GraspSynthesis(poly, KnowledgeBased(), theta0, np.random.default_rng(0), arcs=arcs)


def test_a_synthesis_stopped_at_earlier_contacts_is_done_there_and_scored_there() -> None:
    """A lateral grasp whose controller's contacts leave the hand's reach stops at the last ones
    it reached (Wrench Closure): the run is then done, not converged, its contacts are those,
    and its score is theirs (checked against a fresh synthesis started there)."""
    poly = paper_object("square")
    theta0 = np.array([0.3, 1.2, -2.8, -1.9])
    syn = GraspSynthesis(poly, KnowledgeBased(), theta0, np.random.default_rng(0))
    for _ in range(5):
        syn.step()
    assert not np.allclose(syn.theta, theta0)
    syn.stop_at(theta0)
    assert syn.done and syn.stopped and not syn.converged
    np.testing.assert_allclose(syn.theta, theta0)
    fresh = GraspSynthesis(poly, KnowledgeBased(), theta0, np.random.default_rng(0))
    assert syn.score_at(theta0).s_g == pytest.approx(fresh.score().s_g)
    assert syn.finish().s_g == pytest.approx(fresh.score().s_g)
    with pytest.raises(GraspError, match="already finished"):
        syn.step()


def test_a_lateral_hand_backs_out_only_as_far_as_it_stays_clear() -> None:
    """Random scene 1004 (2 blocks) has a neighbour between the arm's base and the target: from
    the lateral coarse goal, backing the palm out the full ``backoff`` along the approach axis
    collides (it pushed the neighbour 149 mm), ``clear_backoff`` stops short of that, and every
    step up to it is collision-free (checked independently here)."""
    world = World.build(episode_scene("random", 1004, 2))
    target = ReachTarget.from_world(world, "square_0")
    checker = CollisionChecker(world, hand_q=PRESHAPE)  # the coarse reach's hand
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    goal = solve_goal(checker, "lateral", goal_poses(target, base)["lateral"], world.arm_qpos())
    assert goal is not None
    world.data.qpos[robot.arm_qpos_addresses(world.model)] = goal.q
    world.data.qpos[robot.hand_qpos_addresses(world.model)] = PRESHAPE
    mujoco.mj_forward(world.model, world.data)
    site = BlockSite(world, world.model, target, world.block_body_id("square_0"),
                     goal.palm_rotation[:, 2], lateral=True)  # fmt: skip
    back = clear_backoff(site)
    full = site.params.backoff
    assert 0.0 <= back < full
    # touching counts: the motion's clearance (0)
    checker = CollisionChecker(world, hand_q=PRESHAPE, clearance=site.params.reposition_clearance)
    assert not checker.collides(goal.q)
    palm, R = checker.palm_pose(goal.q)
    q = goal.q
    for d in np.arange(site.params.approach_step, full + 1e-9, site.params.approach_step):
        ik = checker.solve_ik(palm - d * site.axis, R, q)
        blocked = not ik.found or checker.collides(ik.q)
        assert blocked == (d > back + 1e-9), d
        if blocked:
            break
        q = ik.q
    else:
        pytest.fail("the full backoff is clear")


def _lateral_rectangle(out: Path, *model: str) -> tuple[int, dict]:
    """``fsm.run`` on single_rectangle, lateral approach, kb, seed 0, unrecorded, with the
    extra arguments ``model``: its exit status and summary."""
    argv = ["--scene", "single_rectangle", "--approach", "lateral", "--controller", "kb"]
    code = main([*argv, *model, "--out", str(out), "--no-record"])
    return code, json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module")
def lateral_rectangle(tmp_path_factory) -> tuple[int, dict]:
    """The default (3-D model) lateral episode of single_rectangle, run once for the module."""
    return _lateral_rectangle(tmp_path_factory.mktemp("lateral") / "3d")


@pytest.mark.e2e
def test_a_lateral_grasp_of_the_rectangle_delivers_it(lateral_rectangle) -> None:
    code, s = lateral_rectangle
    assert code == 0 and s["success"], s["failure_detail"]
    (cycle,) = s["cycles"]
    assert cycle["approach"] == "lateral"
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]


@pytest.mark.e2e
def test_the_3d_model_keeps_the_planar_lateral_grasp_by_default(
    lateral_rectangle, tmp_path: Path
) -> None:
    """A lateral grasp keeps the planar model (docs/findings.md, "The lateral grasp in 3-D"),
    so the default ``--model 3d`` and ``--model planar`` run the same lateral episode: the same
    transitions, contacts, S_G and judgement."""
    runs = {}
    for model, (code, s) in (
        ("3d", lateral_rectangle),
        ("planar", _lateral_rectangle(tmp_path / "planar", "--model", "planar")),
    ):
        assert code == 0
        assert s["options"]["grasp_model"] == model
        visits = [(v["state"], v["next"], v["reason"], v["sim_seconds"]) for v in s["visits"]]
        runs[model] = (s["success"], visits, s["cycles"])
    assert runs["3d"] == runs["planar"]
    (cycle,) = runs["3d"][2]
    assert cycle["approach"] == "lateral" and cycle["judgement"]["place_error_mm"] < 20.0


@pytest.mark.e2e
def test_a_lateral_grasp_of_the_pentagon_takes_its_side_faces_and_delivers_it(
    tmp_path: Path,
) -> None:
    """Issue 23: the pentagon, a corner towards the arm, failed laterally (mf on a near face,
    96 deg from its pad). Its contacts are now on the side faces beyond the near ones (whose
    points lie at x < -0.8 cm), and the block is delivered, judged physically."""
    out = tmp_path / "pentagon"
    code = main(
        ["--scene", "single_pentagon", "--approach", "lateral", "--out", str(out), "--no-record"]
    )
    s = json.loads((out / "summary.json").read_text())
    assert code == 0 and s["success"], s["failure_detail"]
    (cycle,) = s["cycles"]
    assert cycle["approach"] == "lateral" and cycle["s_g"] <= 0.4
    assert np.asarray(cycle["contacts"])[:, 0].min() > -0.007
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
