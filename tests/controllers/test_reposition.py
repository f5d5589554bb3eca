"""How far a lateral reposition backs a posture out along the approach axis
(:func:`controllers.preshape.moves.clear_back`, issue 23): the last step of an independent walk at
which the hand is still clear, for the posture the arm is at and for the new one it goes to."""

from __future__ import annotations

import mujoco
import numpy as np

from controllers.planning.cspace import CollisionChecker
from controllers.preshape.moves import BlockSite, clear_back
from controllers.reach.coarse import PRESHAPE, ReachTarget, goal_poses, solve_goal
from fsm.layout import episode_scene
from hand_sim import robot
from hand_sim.world import World


def _last_clear(world: World, q: np.ndarray, hand_q: np.ndarray, site: BlockSite) -> float:
    """The furthest back-out (m) from ``q`` along ``-site.axis``, in approach steps, up to which
    the palm's IK finds every posture and each is clear of the world with ``hand_q`` (touching
    counts)."""
    p = site.params
    checker = CollisionChecker(world, hand_q=hand_q, clearance=p.reposition_clearance)
    palm, R = checker.palm_pose(q)
    clear = 0.0
    for d in np.arange(p.approach_step, p.backoff + 1e-9, p.approach_step):
        ik = checker.solve_ik(palm - d * site.axis, R, q)
        if not ik.found or checker.collides(ik.q):
            break
        clear, q = float(d), ik.q
    return clear


def test_a_posture_is_backed_out_as_far_as_its_hand_is_clear() -> None:
    """Random scene 1004 (2 blocks): a neighbour stands between the arm's base and the target,
    so the lateral goal backs out clear only part of ``backoff`` with the pre-shaped hand, and
    ``clear_back`` stops at the last clear step of an independent walk. With the fingers
    straight out (every joint at zero) the hand is in the block at the posture itself, and the
    full ``backoff`` is taken: only further out helps."""
    world = World.build(episode_scene("random", 1004, 2))
    target = ReachTarget.from_world(world, "square_0")
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    goal = solve_goal(checker, "lateral", goal_poses(target, base)["lateral"], world.arm_qpos())
    assert goal is not None
    mujoco.mj_forward(world.model, world.data)
    site = BlockSite(world, world.model, target, world.block_body_id("square_0"),
                     goal.palm_rotation[:, 2], lateral=True)  # fmt: skip
    preshape = np.asarray(PRESHAPE, dtype=float)
    back = clear_back(site, goal.q, preshape)
    assert back == _last_clear(world, goal.q, preshape, site)
    assert 0.0 < back < site.params.backoff  # the neighbour stops it short
    straight = np.zeros_like(preshape)
    touching = CollisionChecker(world, hand_q=straight, clearance=0.0)
    assert touching.collides(goal.q)
    assert clear_back(site, goal.q, straight) == site.params.backoff
