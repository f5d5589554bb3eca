"""Speed of the lateral grasp search (section 5.2's reachability criteria over the hand's sampled
finger postures, :mod:`controllers.preshape.lateral_grasp`): the four-contact and then the
three-contact search at every sampled palm pose beside ``single_square``, the arm at its lateral
coarse goal, as one pre-shape search of the task cycle runs them. Prints the poses, the seconds each
search took over them and a digest of the grasps found (the number and the sum of their S_G), which
two versions of the code must share for their times to be compared.

Usage: python -m benchmarks.bench_lateral_search [--repeats 3]
"""

from __future__ import annotations

import inspect
import sys
import time
from collections.abc import Sequence

import mujoco
import numpy as np

from controllers.errors import ReachError
from controllers.hand.finger_geometry import PerceivedPrism
from controllers.hand.finger_samples import FingerSamples
from controllers.planning.cspace import CollisionChecker
from controllers.preshape import lateral_grasp
from controllers.preshape.palm_candidates import PoseSetting, lateral_poses
from controllers.reach.coarse import PRESHAPE, ReachTarget, goal_poses, solve_goal
from graspsim_base import cli
from hand_sim import robot
from hand_sim.scene import load_scene
from hand_sim.world import World

PROG = "python -m benchmarks.bench_lateral_search"
#: the sampled pre-shape's squeeze (fsm.config.TaskConfig.lateral_squeeze_reach)
SQUEEZE = 0.004


def square_at_lateral_goal() -> tuple[World, ReachTarget, PerceivedPrism, list]:
    """single_square with the arm at its lateral coarse goal and the palm poses beside it."""
    world = World.build(load_scene("single_square"))
    target = ReachTarget.from_world(world, "square")
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    ((pos, rot),) = goal_poses(target, base)["lateral"]
    goal = solve_goal(
        CollisionChecker(world, hand_q=PRESHAPE), "lateral", [(pos, rot)], world.arm_qpos()
    )
    if goal is None:
        raise ReachError("single_square has no lateral goal posture")
    world.data.qpos[robot.arm_qpos_addresses(world.model)] = goal.q
    mujoco.mj_forward(world.model, world.data)
    prism = PerceivedPrism.of(target, world.scene.table.height)
    poses = lateral_poses(PoseSetting(world, world.model, target, rot), sampled=True)
    return world, target, prism, poses


def run(repeats: int) -> None:
    world, target, prism, poses = square_at_lateral_goal()
    samples = FingerSamples.draw()
    pose_xy = (np.asarray(target.position_xy), target.yaw)
    shares = "cache" in inspect.signature(lateral_grasp.sampled_lateral_grasp).parameters
    print(f"{len(poses)} palm poses beside single_square; candidates shared: {shares}")
    for rep in range(repeats):
        times, digest = [], []
        cache: dict = {}
        extra = {"cache": cache} if shares else {}
        for search in (
            lateral_grasp.sampled_lateral_grasp,
            lateral_grasp.three_contact_lateral_grasp,
        ):
            start = time.perf_counter()
            found = [
                search(
                    world.model, p.qpos, samples, prism, target.polygon, pose_xy, SQUEEZE, **extra
                )
                for p in poses
            ]
            times.append(time.perf_counter() - start)
            grasps = [g for g in found if g is not None]
            digest.append(f"{len(grasps)} grasps, S_G sum {sum(g.s_g for g in grasps):.6f}")
        print(
            f"repeat {rep + 1}: four contacts {times[0]:.2f} s ({digest[0]}); "
            f"three contacts {times[1]:.2f} s ({digest[1]}); total {sum(times):.2f} s"
        )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark with the command line ``argv``; returns the exit status."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=(ReachError,))


def _run(argv: Sequence[str] | None) -> int:
    parser = cli.ArgumentParser(prog=PROG, description=cli.first_paragraph(__doc__))
    parser.add_argument("--repeats", type=cli.integer(1, 20), default=3, help="times to run it")
    run(parser.parse_args(argv).repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
