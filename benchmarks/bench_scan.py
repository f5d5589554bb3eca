"""Speed of the arm planner's c-space scan (:meth:`controllers.cspace.CollisionChecker.scan`) on
1 and 2 threads: the coarse reach's 4-D grid of the scene's target (top approach, 14^4 =
38,416 arm postures, a MuJoCo collision check each), wall and CPU seconds per scan, and whether
every thread count gives the same result, bit for bit.

Run: ``.venv/bin/python -m benchmarks.bench_scan [--scene clutter3] [--repeats 3]``.
Prints figures; asserts nothing. The wall time of 2 threads falls only when a second core is
free: compare the CPU seconds on a busy machine.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence

import numpy as np

from controllers.arm_path import DEFAULT_RESOLUTION, ROLL, _grid_box
from controllers.cspace import CollisionChecker, Scan
from controllers.errors import ReachError
from controllers.reach import PRESHAPE, ReachTarget, goal_poses, solve_goal
from hand_sim import clitools as cli
from hand_sim import robot
from hand_sim.scene import load_scene
from hand_sim.world import World

PROG = "python -m benchmarks.bench_scan"
#: Thread counts compared.
THREADS = (1, 2)


def grid_configs(world: World, checker: CollisionChecker) -> np.ndarray:
    """The arm postures of the coarse reach's grid (top approach) from the home posture."""
    target = ReachTarget.from_world(world, world.scene.target)
    q0 = world.arm_qpos()
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    goal = solve_goal(checker, "top", goal_poses(target, base)["top"], q0)
    if goal is None:
        raise ReachError("no collision-free top goal posture in this scene")
    spec = _grid_box(checker, np.stack([q0, goal.q]), DEFAULT_RESOLUTION)
    nodes = spec.node_configs()
    return np.column_stack([nodes, np.full(len(nodes), goal.q[ROLL])])


def timed_scan(checker: CollisionChecker, configs: np.ndarray) -> tuple[Scan, float, float]:
    """A scan with its wall and CPU seconds (the process's: every thread counts)."""
    wall, cpu = time.perf_counter(), time.process_time()
    scan = checker.scan(configs)
    return scan, time.perf_counter() - wall, time.process_time() - cpu


def same(a: Scan, b: Scan) -> bool:
    """Whether two scans agree bit for bit."""
    return all(
        np.array_equal(getattr(a, f), getattr(b, f))
        for f in ("collides", "palm_position", "approach_axis")
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark with the command line ``argv``; returns the exit status."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=(*cli.ERRORS, ReachError))


def _run(argv: Sequence[str] | None) -> int:
    p = cli.ArgumentParser(prog=PROG, description=cli.first_paragraph(__doc__))
    p.add_argument("--scene", default="clutter3", help="scene name or .toml file")
    p.add_argument("--repeats", type=cli.integer(1, 20), default=3, help="scans per thread count")
    args = p.parse_args(argv)
    world = World.build(load_scene(args.scene))
    configs = grid_configs(world, CollisionChecker(world, hand_q=PRESHAPE))
    print(f"# {len(configs)} postures per scan; load average before {os.getloadavg()[0]:.1f}")
    print("threads  wall_s (median)  cpu_s (median)  same as 1 thread")
    first: Scan | None = None
    for threads in THREADS:
        checker = CollisionChecker(world, hand_q=PRESHAPE, threads=threads)
        runs = [timed_scan(checker, configs) for _ in range(args.repeats)]
        first = runs[0][0] if first is None else first
        agree = all(same(first, scan) for scan, _, _ in runs)
        wall = float(np.median([w for _, w, _ in runs]))
        cpu = float(np.median([c for _, _, c in runs]))
        print(f"{threads:7d}  {wall:15.2f}  {cpu:14.2f}  {'yes' if agree else 'NO'}")
    print(f"load average after {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
