"""The set-down's arm IK (controllers.deliver.plan.set_down_ik) on random scene 11 (three blocks):
the lateral grasp holds the hand with the arm's waist near its end stop (2.9 rad), and the
place point lies further round, so the transit's start turned with the waist asks for 3.5 rad.
The joint clips the seed and the damped least squares stalls with the palm 0.40 m short; the
coarse reach's elbow-up seeds with the waist towards the palm reach it."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.deliver.plan import set_down_ik
from controllers.planning.cspace import CollisionChecker, rotation_error
from controllers.reach.coarse import PRESHAPE
from fsm.layout import episode_scene
from hand_sim.world import World

#: An arm posture holding a lateral palm above random 11's place point, and the transit's
#: start of that episode turned with the waist towards it (past the waist's 2.9 rad limit).
HELD_ABOVE_PLACE = np.array([-2.765, -0.68, -2.066, 1.174, -1.571])
TURNED_START = np.array([3.51, -0.585, -2.373, 1.386, -1.571])


@pytest.fixture(scope="module")
def checker() -> CollisionChecker:
    """Random 11's world, the hand pre-shaped, the planning clearance."""
    return CollisionChecker(World.build(episode_scene("random", 11, 3)), hand_q=PRESHAPE)


def test_a_waist_turned_past_its_limit_stalls_alone_and_the_elbow_up_seeds_reach_the_palm(
    checker: CollisionChecker,
) -> None:
    """From the turned start alone the IK ends 0.4 m from the palm; set_down_ik returns a
    posture within the joint limits whose palm is at the pose asked for (checked by forward
    kinematics) and that keeps the planning clearance."""
    p, R = checker.palm_pose(HELD_ABOVE_PLACE)
    assert not checker.collides(HELD_ABOVE_PLACE)
    alone = checker.solve_ik(p, R, TURNED_START)
    assert not alone.found and alone.position_error > 0.2
    ik = set_down_ik(checker, p, R, TURNED_START)
    assert ik.found
    lo, hi = checker.arm_limits.T
    assert np.all(ik.q >= lo) and np.all(ik.q <= hi)
    p_at, R_at = checker.palm_pose(ik.q)
    assert np.linalg.norm(p_at - p) < 1e-3
    assert np.linalg.norm(rotation_error(R, R_at)) < 1e-2
    assert not checker.collides(ik.q)


def test_a_seed_that_reaches_the_palm_is_kept(checker: CollisionChecker) -> None:
    """Where the least squares from the seed reaches a collision-free posture, that posture is
    the answer (the set-downs that worked before are unchanged)."""
    p, R = checker.palm_pose(HELD_ABOVE_PLACE)
    seed = HELD_ABOVE_PLACE + np.array([0.05, -0.04, 0.03, 0.02, 0.0])
    alone = checker.solve_ik(p, R, seed)
    assert alone.found and not checker.collides(alone.q)
    np.testing.assert_array_equal(set_down_ik(checker, p, R, seed).q, alone.q)
