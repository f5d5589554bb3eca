"""Three-contact lateral grasps (issue 23;
controllers.preshape.lateral_grasp.three_contact_lateral_grasp): the thumb against two fingers, the
third finger held clear of the block. Eq. 13 is checked against its closed-form values, the grasps
found beside single_square against independent computations (S_G of their contacts, forward
kinematics of the hand's links against the prism), and the reach test, the finger assignment and the
grip plan keep the idle finger where it is."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from controllers.grasp.score import SUCCESS_THRESHOLD, grasp_score, opposition_floor
from controllers.hand.finger_assignment import ranked_assignments
from controllers.hand.finger_geometry import finger_clearance, fingertips_at
from controllers.hand.grip import GRIP_FORCE, plan_grip
from controllers.hand.reachability import check_reach
from controllers.preshape.lateral_grasp import IDLE_CLEARANCE, three_contact_lateral_grasp
from hand_sim import robot
from tests.controllers.conftest import grasps_beside

SQUEEZE = 0.004  # fsm.config.TaskConfig.lateral_squeeze_reach


def test_eq13_scores_a_thumb_against_two_fingers_a_third_and_against_three_a_half() -> None:
    """Eq. 13 on a unit square, fingers on the face y = 1, the thumb opposite on y = -1 (each
    N_i >= 1): against two fingers placed symmetrically about it the thumb pushes 2, S_G =
    (1 + 1 + 2) / 3 - 1 = 1/3; against three it pushes 3, S_G = (1 + 1 + 1 + 3) / 4 - 1 = 1/2.
    So Eq. 13's 0.4 passes the first and not the second."""
    up, down = [0.0, 1.0], [0.0, -1.0]
    two = grasp_score([[-0.4, 1.0], [0.4, 1.0], [0.0, -1.0]], [up, up, down])
    three = grasp_score([[-0.4, 1.0], [0.0, 1.0], [0.4, 1.0], [0.0, -1.0]], [up, up, up, down])
    assert two.s_g == pytest.approx(1.0 / 3.0, abs=1e-6)
    assert three.s_g == pytest.approx(0.5, abs=1e-6)
    assert two.success and not three.success


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_the_opposition_floor_is_eq13_of_a_thumb_against_the_other_fingers(n: int) -> None:
    """``opposition_floor(n)`` against Eq. 13's LP: one contact on y = -1 opposite n - 1 on y =
    1 placed symmetrically about it scores exactly the floor (n - 2) / n, and moving the one
    off the others' centre, or tilting a face, only raises S_G above it."""
    up, down = [0.0, 1.0], [0.0, -1.0]
    xs = np.linspace(-0.4, 0.4, n - 1) if n > 2 else np.zeros(1)
    points = [[x, 1.0] for x in xs] + [[0.0, -1.0]]
    normals = [up] * (n - 1) + [down]
    assert grasp_score(points, normals).s_g == pytest.approx(opposition_floor(n), abs=1e-6)
    off = [[x, 1.0] for x in xs] + [[0.3, -1.0]]
    assert grasp_score(off, normals).s_g > opposition_floor(n) + 1e-3
    tilted = np.array(normals, dtype=float)
    tilted[0] = [np.sin(0.3), np.cos(0.3)]
    assert grasp_score(points, tilted).s_g >= opposition_floor(n) - 1e-6


def test_an_opposition_needs_two_contacts() -> None:
    """One contact opposes nothing: an error, not a floor."""
    with pytest.raises(ValueError, match="at least two contacts"):
        opposition_floor(1)


@pytest.fixture(scope="module")
def three_grasps(square, samples) -> list:
    """(pose, grasp) at every palm pose beside single_square that has a three-contact grasp."""
    return grasps_beside(square, samples, three_contact_lateral_grasp, SQUEEZE)


def _at(world, pose, hand_q) -> np.ndarray:
    qpos = pose.qpos.copy()
    qpos[robot.hand_qpos_addresses(world.model)] = hand_q
    return qpos


def test_three_contacts_press_with_the_thumb_and_two_fingers_the_third_held_clear(
    square, three_grasps
) -> None:
    """Each grasp found: the thumb and two fingers take contacts (the idle one is ff, mf or rf),
    S_G is Eq. 13's of the three contacts on the unit-moment polygon, forward kinematics puts
    the pressing fingertips 4 mm inside the block (within the sampling's tolerance) and every
    link of the idle finger, pad included, at least IDLE_CLEARANCE outside it (measured on the
    model's capsules, not the samples'); some pass Eq. 13's 0.4."""
    world, target, prism, _ = square
    assert len(three_grasps) >= 3
    unit = target.polygon.unit_moment()
    data = mujoco.MjData(world.model)
    for pose, grasp in three_grasps:
        assert grasp.idle in (0, 1, 2)
        pressing = [f for f in range(4) if f != grasp.idle]
        assert grasp.theta.shape == (3,) and grasp.points.shape == (3, 3)
        u = unit.locate(grasp.theta)
        assert grasp.s_g == pytest.approx(grasp_score(u.point, u.normal).s_g, abs=1e-9)
        qpos = _at(world, pose, grasp.hand_q)
        depth = -prism.signed_distance(fingertips_at(world.model, qpos))
        assert np.all(depth[pressing] > 0.0)
        data.qpos[:] = qpos
        mujoco.mj_kinematics(world.model, data)
        clearance = finger_clearance(world.model, data, prism)
        # the capsules' axes are sampled more finely here than in the search: a millimetre
        assert clearance[grasp.idle] >= IDLE_CLEARANCE - 1e-3
    assert min(g.s_g for _, g in three_grasps) <= SUCCESS_THRESHOLD


def test_the_reach_test_and_the_assignment_leave_the_idle_finger_where_it_is(
    square, three_grasps
) -> None:
    """The six assignments of three contacts to the three pressing fingers give the idle finger
    no contact (its own fingertip, a zero normal, theta NaN, index -1); the reach test from the
    grasp's posture leaves the idle finger's joints exactly as they were and passes at some
    poses."""
    world, target, prism, _ = square
    passed = 0
    for pose, grasp in three_grasps:
        qpos = _at(world, pose, grasp.hand_q)
        given = ranked_assignments(
            world,
            prism,
            target,
            grasp.theta,
            qpos=qpos,
            heights=grasp.points[:, 2],
            idle=grasp.idle,
        )
        assert len(given) == 6
        tip = fingertips_at(world.model, qpos)[grasp.idle]
        for contacts in given:
            assert contacts.idle == grasp.idle
            np.testing.assert_allclose(contacts.points[grasp.idle], tip)
            assert np.all(contacts.normals[grasp.idle] == 0.0)
            assert np.isnan(contacts.theta[grasp.idle])
            assert contacts.contact_of_finger[grasp.idle] == -1
            assert sorted(contacts.contact_of_finger) == [-1, 0, 1, 2]
        first = given[0]
        reach = check_reach(
            world,
            prism,
            first.points,
            first.normals,
            qpos=qpos,
            check_spacing=False,
            squeeze=SQUEEZE,
            idle=grasp.idle,
        )
        rows = robot.FINGER_JOINT_SLICES[grasp.idle]
        np.testing.assert_array_equal(reach.hand_q[rows], grasp.hand_q[rows])
        passed += reach.reachable
    assert passed >= 1


def test_a_grip_plan_gives_the_idle_finger_no_force_and_no_motion(square, three_grasps) -> None:
    """plan_grip with an idle finger: its pre-contact and inside postures are its start
    posture's, its force 0 and it counts as touching (closing waits for the other three only);
    the three pressing fingers' forces average the grip force."""
    world, target, prism, _ = square
    pose, grasp = min(three_grasps, key=lambda pg: pg[1].s_g)
    qpos = _at(world, pose, grasp.hand_q)
    (contacts,) = ranked_assignments(
        world,
        prism,
        target,
        grasp.theta,
        qpos=qpos,
        heights=grasp.points[:, 2],
        count=1,
        idle=grasp.idle,
    )
    state = world.data.qpos.copy()
    world.data.qpos[:] = qpos
    mujoco.mj_forward(world.model, world.data)
    try:
        grip = plan_grip(
            world,
            contacts.points,
            contacts.normals,
            np.array([1.0, 2.0, 1.5, 2.5]),
            prism=prism,
            along_normal=True,
            start=grasp.hand_q,
            squeeze_reach=SQUEEZE,
            idle=grasp.idle,
        )
    finally:
        world.data.qpos[:] = state
        mujoco.mj_forward(world.model, world.data)
    rows = robot.FINGER_JOINT_SLICES[grasp.idle]
    np.testing.assert_array_equal(grip.q_pre[rows], grasp.hand_q[rows])
    np.testing.assert_array_equal(grip.q_in[rows], grasp.hand_q[rows])
    assert grip.forces[grasp.idle] == 0.0
    assert grip.touched[grasp.idle] and grip.touched.sum() == 1
    pressing = [f for f in range(4) if f != grasp.idle]
    assert grip.forces[pressing].mean() == pytest.approx(GRIP_FORCE)
