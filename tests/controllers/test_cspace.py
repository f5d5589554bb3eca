"""Tests of the arm's c-space collision checker and IK (controllers.planning.cspace)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from controllers.errors import ReachError
from controllers.planning.cspace import CollisionChecker, rotation_error
from controllers.reach.coarse import PRESHAPE
from hand_sim import robot
from hand_sim.scene import load_scene
from hand_sim.world import World

N_POSTURES = 300


@pytest.fixture(scope="module")
def world():
    return World.build(load_scene("clutter3"))


def random_postures(checker: CollisionChecker, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo, hi = checker.arm_limits.T
    return rng.uniform(lo, hi, (n, len(lo)))


def raw_collides(world: World, q_arm: np.ndarray, hand_q) -> bool:
    """Penetration of a robot geom into anything, straight from MuJoCo on the world's own model
    (not the checker's copy): pairs inside the hand and the turret resting on its pedestal are
    not collisions."""
    m = world.model
    d = mujoco.MjData(m)
    d.qpos[:] = world.data.qpos
    for names, values in ((robot.ARM_JOINTS, q_arm), (robot.HAND_JOINTS, hand_q)):
        for n, v in zip(names, values, strict=True):
            d.qpos[m.jnt_qposadr[m.joint(robot.qualified(n)).id]] = v
    mujoco.mj_forward(m, d)
    for c in d.contact[: d.ncon]:
        if c.dist >= 0:
            continue
        names = {m.body(m.geom_bodyid[g]).name for g in (c.geom1, c.geom2)}
        on_robot = [n.startswith(robot.ARM_PREFIX) for n in names]
        in_hand = [n.startswith(robot.HAND_PREFIX) for n in names]
        if not any(on_robot) or (len(names) == 2 and all(in_hand)):
            continue
        if names == {robot.arm_name("arm_base"), robot.arm_name("turret")}:
            continue
        return True
    return False


def test_collisions_agree_with_mujoco_on_the_world_model(world):
    checker = CollisionChecker(world, clearance=0.0, hand_q=PRESHAPE)
    qs = random_postures(checker, N_POSTURES, 0)
    mine = checker.scan(qs).collides
    raw = np.array([raw_collides(world, q, PRESHAPE) for q in qs])
    assert 0.1 < raw.mean() < 0.9  # both kinds of posture are sampled
    np.testing.assert_array_equal(mine, raw)
    assert all(checker.collides(q) == hit for q, hit in zip(qs[:20], mine[:20], strict=True))


def test_clearance_only_adds_near_misses(world):
    tight = CollisionChecker(world, clearance=0.0, hand_q=PRESHAPE)
    loose = CollisionChecker(world, clearance=0.02, hand_q=PRESHAPE)
    qs = random_postures(tight, N_POSTURES, 1)
    a, b = tight.scan(qs).collides, loose.scan(qs).collides
    assert np.all(b[a])  # every collision is also within the clearance
    near = np.flatnonzero(b & ~a)
    assert near.size > 0
    for i in near[:10]:
        dists = [c.distance for c in loose.contacts(qs[i])]
        assert dists and 0.0 <= min(dists) < 0.02


def test_ik_reaches_the_palm_pose_of_a_known_posture(world):
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    q_true = np.array([0.3, 0.4, 1.4, 1.2, -0.5])
    p, R = checker.palm_pose(q_true)
    res = checker.solve_ik(p, R, q_true + np.array([0.2, -0.15, 0.2, -0.2, 0.3]))
    assert res.found
    p2, R2 = checker.palm_pose(res.q)
    assert np.linalg.norm(p2 - p) < 1e-3
    assert np.linalg.norm(rotation_error(R, R2)) < 1e-2
    assert np.all(res.q >= checker.arm_limits[:, 0]) and np.all(res.q <= checker.arm_limits[:, 1])


def test_carried_block_moves_rigidly_with_the_palm(world):
    checker = CollisionChecker(world, carried="pentagon")
    q0 = world.arm_qpos()
    p0, R0 = checker.palm_pose(q0)
    b0, _ = checker.carried_pose(q0)
    rel = R0.T @ (b0 - p0)
    for q in random_postures(checker, 5, 2):
        p, R = checker.palm_pose(q)
        b, quat = checker.carried_pose(q)
        np.testing.assert_allclose(R.T @ (b - p), rel, atol=1e-9)
        assert abs(np.linalg.norm(quat) - 1.0) < 1e-9
    with pytest.raises(ReachError, match="carries no block"):
        CollisionChecker(world).carried_pose(q0)
    with pytest.raises(ReachError, match="clearance"):
        CollisionChecker(world, clearance=-0.1)
    with pytest.raises(ReachError, match="5 finite"):
        checker.collides([0.0, 0.0])


def test_nearest_obstacle_agrees_with_mujocos_geom_distance(world):
    """The closest robot-environment pair: its distance and the normal that moves the robot away
    from it, against MuJoCo's own distance query between the two geoms (the segment between
    their closest points). Near misses are found on the way from the clear home posture to
    random ones."""
    checker = CollisionChecker(world, clearance=0.03, hand_q=PRESHAPE)
    home = world.arm_qpos()
    assert checker.nearest_obstacle(home) is None and not checker.collides(home)
    checked = 0
    for q_far in random_postures(checker, N_POSTURES, 3):
        for q in home + np.linspace(0.0, 1.0, 60)[:, None] * (q_far - home):
            near = checker.nearest_obstacle(q)
            pairs = checker.contacts(q)
            if near is None:
                # nothing within the clearance, or a pair of the robot's own links is
                env = [checker.kind[checker.model.geom(c.geom1).id] == "env" for c in pairs]
                env2 = [checker.kind[checker.model.geom(c.geom2).id] == "env" for c in pairs]
                assert not pairs or any(a == b for a, b in zip(env, env2, strict=True))
                continue
            assert near.distance == pytest.approx(min(c.distance for c in pairs), abs=1e-12)
            if near.distance < 2e-3:
                break  # touching geoms' closest points give no direction
            robot_id = checker.model.geom(near.robot_geom).id
            env_id = checker.model.geom(near.env_geom).id
            assert checker.kind[robot_id] != "env" and checker.kind[env_id] == "env"
            fromto = np.zeros(6)
            m, d = checker.model, checker.data
            dist = mujoco.mj_geomDistance(m, d, env_id, robot_id, 0.1, fromto)
            assert dist == pytest.approx(near.distance, abs=2e-4)
            segment = fromto[3:] - fromto[:3]
            np.testing.assert_allclose(near.away, segment / np.linalg.norm(segment), atol=0.05)
            checked += 1
            break  # the first near miss on the way
    assert checked >= 8
