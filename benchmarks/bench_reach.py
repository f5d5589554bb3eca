"""Speed and path quality of the reach controllers (section 5.2): harmonic solves on large
grids, the 4-D coarse-reach obstacle grid (MuJoCo collision checks) and its solve at several
resolutions, path length against the straight-line joint distance, the full coarse-reach plan,
mink iterations per second of posture control (and of the reach test's hand step, by mink and on
the moving joints only), and fine reach.

Run: ``.venv/bin/python -m benchmarks.bench_reach [--scene clutter3] [--resolutions 10 14 18]
[--random 8 --blocks 4]``.
Prints figures; asserts nothing.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence

import mink
import numpy as np

from controllers.deliver.plan import plan_delivery
from controllers.errors import ReachError
from controllers.planning.cspace import CollisionChecker
from controllers.planning.harmonic import ascend, solve_harmonic
from controllers.posture.manipulability import ManipulabilityTask
from controllers.posture.reduced_ik import ReducedStep
from controllers.posture.solver import (
    IK_DAMPING,
    IK_DT,
    PAD_CENTRE_COST,
    QP_SOLVER,
    TIP_COST,
    _frozen_dofs,
    _point_tasks,
    mink_velocity,
    moving_dofs,
    solve_posture,
)
from controllers.reach.arm_path import execute_path, plan_arm_path
from controllers.reach.coarse import (
    PRESHAPE,
    ReachTarget,
    goal_poses,
    plan_coarse_reach,
    solve_goal,
)
from controllers.reach.fine import fine_reach
from hand_sim import clitools as cli
from hand_sim import robot
from hand_sim.indices import RobotIndices
from hand_sim.random_scene import MAX_RANDOM_BLOCKS
from hand_sim.scene import load_scene
from hand_sim.world import World

#: Side of the free 4-D grid of the pure-planner figure, and the corridor length.
FREE_GRID_SIDE = 20
CORRIDOR_LENGTH = 400
#: mink iterations timed.
MINK_ITERATIONS = 200


def bench_harmonic() -> None:
    """Harmonic solve on a 20^4 grid with a wall, and a flat-potential corridor."""
    n = FREE_GRID_SIDE
    free = np.ones((n,) * 4, dtype=bool)
    free[n // 2, :, : n - 3, :] = False
    goal = np.zeros_like(free)
    goal[-2, -2, -2, -2] = True
    t0 = time.perf_counter()
    field = solve_harmonic(free, goal)
    t1 = time.perf_counter()
    path = ascend(field, [1.0, 1.0, 1.0, 1.0])
    t2 = time.perf_counter()
    print(
        f"harmonic {n}^4 = {free.size} cells, wall with a slot: solve {t1 - t0:.2f} s "
        f"({field.cg_iterations} CG iterations, {field.n_levels} levels), path {t2 - t1:.3f} s, "
        f"found={path.found}, length {path.length:.1f} cells"
    )
    L = CORRIDOR_LENGTH
    free = np.zeros((3, L + 2), dtype=bool)
    free[1, 1 : L + 1] = True
    goal = np.zeros_like(free)
    goal[1, 1] = True
    t0 = time.perf_counter()
    field = solve_harmonic(free, goal)
    t1 = time.perf_counter()
    path = ascend(field, [1.0, float(L)])
    print(
        f"corridor 1 x {L}: solve {t1 - t0:.2f} s, {field.n_levels} rescaled levels, "
        f"log(1-u) at the far end {field.log_phi[1, L]:.1f} (u == 1.0 in float64 at "
        f"{int(np.count_nonzero(field.u[1, 1 : L + 1] == 1.0))} cells), path found={path.found}"
    )


def bench_grids(world: World, resolutions: Sequence[int]) -> None:
    """4-D obstacle grid build and solve at several resolutions, for each approach."""
    target = ReachTarget.from_world(world, world.scene.target)
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    q0 = world.arm_qpos()
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    poses = goal_poses(target, base)
    print(
        "approach  resolution  nodes    build_s  us/node  solve+path_s  obstacles  found  "
        "path_rad  straight_rad  ratio  repairs"
    )
    for approach in ("top", "lateral"):
        goal = solve_goal(checker, approach, poses[approach], q0)
        if goal is None:
            print(f"{approach:8s}  no collision-free goal posture")
            continue
        for r in resolutions:
            res = plan_arm_path(checker, q0, goal.q, resolution=r)
            nodes = r**4
            ratio = res.length / res.straight_distance if res.found else float("nan")
            print(
                f"{approach:8s}  {r:10d}  {nodes:6d}  {res.build_seconds:7.2f}  "
                f"{1e6 * res.build_seconds / nodes:7.1f}  {res.solve_seconds:12.2f}  "
                f"{res.n_obstacles:9d}  {res.found!s:5}  {res.length:8.2f}  "
                f"{res.straight_distance:12.2f}  {ratio:5.2f}  {res.n_repairs:7d}"
                + ("" if res.found else f"  ({res.reason})")
            )


def bench_plan(world: World) -> None:
    """The full coarse-reach plan (both approaches), then its execution."""
    target = ReachTarget.from_world(world, world.scene.target)
    t0 = time.perf_counter()
    plan = plan_coarse_reach(world, target)
    t1 = time.perf_counter()
    for name, p in plan.candidates.items():
        print(f"  {name}: found={p.found} ({p.reason}) length {p.length:.2f} rad")
    for name in plan.no_goal:
        print(f"  {name}: no collision-free goal posture")
    print(f"coarse-reach plan: {t1 - t0:.2f} s, found={plan.found}, approach={plan.approach!r}")
    if plan.found:
        t0 = time.perf_counter()
        run = execute_path(world, plan.path.path, hand_q=plan.hand_q)
        print(
            f"execution: {run.seconds:.1f} s simulated in {time.perf_counter() - t0:.2f} s, "
            f"contacts {run.contacts or 'none'}, final joint error {run.final_error:.4f} rad"
        )


def bench_mink(world: World) -> None:
    """mink iterations per second: fingertip tasks alone, and with the manipulability task."""
    cfg = mink.Configuration(world.model)
    cfg.update(world.data.qpos.copy())
    tips = []
    for site in robot.FINGERTIP_SITES:
        task = mink.FrameTask(
            robot.qualified(site), "site", position_cost=1.0, orientation_cost=0.0, lm_damping=1e-3
        )
        task.set_target_from_configuration(cfg)
        tips.append(task)
    limits = [mink.ConfigurationLimit(world.model)]
    manip = ManipulabilityTask(world.model)
    for label, tasks in (
        ("4 fingertip FrameTasks", tips),
        ("+ ManipulabilityTask", [*tips, manip]),
    ):
        t0 = time.perf_counter()
        for _ in range(MINK_ITERATIONS):
            v = mink.solve_ik(cfg, tasks, IK_DT, QP_SOLVER, damping=IK_DAMPING, limits=limits)
            cfg.integrate_inplace(v, 1e-6)
        dt = time.perf_counter() - t0
        print(f"mink ({label}, nv={world.model.nv}): {MINK_ITERATIONS / dt:.0f} iterations/s")
    bench_reach_step(world, cfg)
    t0 = time.perf_counter()
    res = solve_posture(world)
    print(
        f"posture control: {time.perf_counter() - t0:.2f} s, {res.iterations} iterations, "
        f"M {res.log_manipulability_start:.2f} -> {res.log_manipulability_end:.2f}, "
        f"max tip drift {1e3 * res.tip_error.max():.3f} mm (kinematic)"
    )


def bench_reach_step(world: World, cfg: mink.Configuration) -> None:
    """The reach test's hand IK step (fingertip and pad-centre targets 1 cm off, the arm and the
    blocks frozen) by mink and on the moving joints only (:class:`ReducedStep`)."""
    model = world.model
    idx = RobotIndices.of(model)
    tips = cfg.data.site_xpos[idx.tip_sites] + 0.01
    tasks = _point_tasks(robot.FINGERTIP_SITES, tips, TIP_COST) + _point_tasks(
        robot.PAD_CENTRE_SITES, tips, PAD_CENTRE_COST
    )
    frozen = _frozen_dofs(model, idx, "hand")
    limits = [mink.ConfigurationLimit(model)]
    constraints = [mink.DofFreezingTask(model, dof_indices=frozen)]
    reduced = ReducedStep(
        model,
        tasks,
        moving_dofs(model, frozen),
        limits,
        damping=IK_DAMPING,
        solver=QP_SOLVER,
    )
    rates = {}
    for label, step in (
        ("mink", lambda: mink_velocity(cfg, tasks, limits, constraints)),
        ("moving joints only", lambda: reduced.velocity(cfg, IK_DT)),
    ):
        t0 = time.perf_counter()
        for _ in range(MINK_ITERATIONS):
            step()
        rates[label] = MINK_ITERATIONS / (time.perf_counter() - t0)
    print(
        f"reach test's hand step (8 site tasks, nv={model.nv}, {len(reduced.free)} moving): "
        + ", ".join(f"{k} {v:.0f} steps/s" for k, v in rates.items())
    )


def bench_fine(world: World) -> None:
    """Fine reach from the coarse-reach posture."""
    t0 = time.perf_counter()
    res = fine_reach(world, world.scene.target)
    print(
        f"fine reach: {time.perf_counter() - t0:.2f} s wall, {res.periods} control periods, "
        f"reached={res.reached}, tip errors {np.round(1e3 * res.tip_error, 2).tolist()} mm, "
        f"max penetration {1e3 * res.max_penetration:.2f} mm"
    )


def bench_random(n_scenes: int, n_blocks: int) -> None:
    """Coarse reach, execution, fine reach and delivery planning on random scenes (seeds
    0..n-1)."""
    planned = clean = reached = delivered = 0
    times = []
    for seed in range(n_scenes):
        scene = load_scene("random", seed=seed, blocks=n_blocks)
        world = World.build(scene)
        t0 = time.perf_counter()
        plan = plan_coarse_reach(world, ReachTarget.from_world(world, scene.target))
        times.append(time.perf_counter() - t0)
        if not plan.found:
            print(f"  seed {seed}: no plan ({plan.reason})")
            continue
        planned += 1
        run = execute_path(world, plan.path.path, hand_q=plan.hand_q)
        clean += run.contacts == ()
        fine = fine_reach(world, scene.target)
        reached += fine.reached
        t0 = time.perf_counter()
        delivery = plan_delivery(world, scene.target, scene.place)
        delivered += delivery.found
        print(
            f"  seed {seed}: {plan.approach} in {times[-1]:.2f} s, contacts "
            f"{run.contacts or 'none'}, fine reach max error {1e3 * fine.tip_error.max():.1f} mm, "
            f"delivery plan {delivery.found} in {time.perf_counter() - t0:.2f} s"
        )
    print(
        f"random scenes ({n_blocks} blocks): planned {planned}/{n_scenes}, executed without "
        f"contact {clean}/{planned}, fine reach reached {reached}/{planned}, delivery planned "
        f"{delivered}/{planned}, "
        f"plan time median {np.median(times):.2f} s, max {max(times):.2f} s"
    )


PROG = "python -m benchmarks.bench_reach"
#: Grid cells per joint axis of the 4-D c-space grid: resolution^4 cells are collision-checked.
MAX_RESOLUTION = 24


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark with the command line ``argv``; returns the exit status."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=(*cli.ERRORS, ReachError))


def _run(argv: Sequence[str] | None) -> int:
    p = cli.ArgumentParser(prog=PROG, description=cli.first_paragraph(__doc__))
    p.add_argument("--scene", default="clutter3", help="scene name or .toml file")
    p.add_argument(
        "--resolutions",
        type=cli.integer(4, MAX_RESOLUTION),
        nargs="+",
        default=[10, 14, 18],
        metavar="N",
        help=f"c-space grid cells per joint, 4..{MAX_RESOLUTION}",
    )
    p.add_argument(
        "--random",
        type=cli.integer(0, 1000),
        default=0,
        help="also plan in this many random scenes (seeds 0, 1, ...)",
    )
    p.add_argument(
        "--blocks",
        type=cli.integer(1, MAX_RANDOM_BLOCKS),
        default=4,
        help=f"blocks per random scene, 1..{MAX_RANDOM_BLOCKS}",
    )
    args = p.parse_args(argv)
    scene = load_scene(args.scene)  # a bad scene is refused before any work
    bench_harmonic()
    world = World.build(scene)
    bench_grids(world, args.resolutions)
    bench_plan(world)
    bench_mink(world)
    bench_fine(world)
    if args.random > 0:
        bench_random(args.random, args.blocks)
    return 0


if __name__ == "__main__":
    sys.exit(main())
