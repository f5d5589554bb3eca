"""Speed of the simulated world: physics steps per second for a scene with the arm and the hand
(and the ratio to real time at the 2 ms step), and milliseconds per overhead render.

Run: ``.venv/bin/python -m benchmarks.bench_sim [--scene clutter3] [--seconds 5]``. Prints figures.
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from hand_sim import clitools as cli
from hand_sim.camera import OverheadCamera
from hand_sim.recorder import Recorder
from hand_sim.scene import load_scene
from hand_sim.world import World

#: Renders timed per image kind (after one warm-up render).
N_RENDERS = 30
#: Recorder frames timed (each: 10 physics steps, then log_world), and the steps per frame.
N_FRAMES, STEPS_PER_FRAME = 300, 10


def time_calls(fn: Callable[[], object], n: int) -> float:
    """Median wall time (ms) of ``n`` calls of ``fn`` after one warm-up call."""
    fn()
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1000.0 * float(np.median(times))


PROG = "python -m benchmarks.bench_sim"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark with the command line ``argv``; returns the exit status."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=cli.ERRORS)


def _run(argv: Sequence[str] | None) -> int:
    p = cli.ArgumentParser(prog=PROG, description=cli.first_paragraph(__doc__))
    p.add_argument("--scene", default="clutter3", help="scene name or .toml file")
    p.add_argument(
        "--seconds",
        type=cli.number(0.0, 600.0, lo_open=True),
        default=5.0,
        help="simulated seconds to time, in (0, 600]",
    )
    p.add_argument(
        "--width", type=cli.image_width, default=640, help="overhead render width, pixels"
    )
    p.add_argument(
        "--height", type=cli.image_height, default=480, help="overhead render height, pixels"
    )
    args = p.parse_args(argv)

    t0 = time.perf_counter()
    world = World.build(load_scene(args.scene))
    build_s = time.perf_counter() - t0
    m = world.model
    dt = m.opt.timestep
    n = round(args.seconds / dt)
    # Move the arm and close the hand halfway through, so the servos work while we time.
    home = world.arm_targets()
    world.step(100)
    t0 = time.perf_counter()
    world.set_arm_targets(home + np.array([0.3, -0.1, 0.2, 0.2, 0.5]))
    world.step(n // 2)
    world.set_arm_targets(home)
    world.step(n - n // 2)
    wall = time.perf_counter() - t0
    print(
        f"scene {args.scene}: nq={m.nq} nv={m.nv} nu={m.nu} nbody={m.nbody} ngeom={m.ngeom}, "
        f"build {build_s:.2f} s"
    )
    print(
        f"physics: {n} steps of {dt * 1000:g} ms in {wall:.2f} s = {n / wall:,.0f} steps/s, "
        f"{n * dt / wall:.1f}x real time, ncon at end {world.data.ncon}"
    )

    with tempfile.TemporaryDirectory() as tmp:
        rrd = Path(tmp) / "bench.rrd"
        t0 = time.perf_counter()
        for _ in range(N_FRAMES):
            world.step(STEPS_PER_FRAME)
        steps_only = time.perf_counter() - t0
        with Recorder(rrd, world) as rec:
            t0 = time.perf_counter()
            for _ in range(N_FRAMES):
                world.step(STEPS_PER_FRAME)
                rec.log_world(world)
            with_log = time.perf_counter() - t0
        size_kb = rrd.stat().st_size / 1024
    log_ms = 1000.0 * (with_log - steps_only) / N_FRAMES
    print(
        f"recorder: log_world {log_ms:.3f} ms per frame ({m.nbody - 1} bodies), "
        f"{N_FRAMES} frames -> {size_kb:.0f} kB"
    )

    with OverheadCamera(world, args.width, args.height) as cam:
        rgb_ms = time_calls(cam.rgb, N_RENDERS)
        depth_ms = time_calls(cam.depth, N_RENDERS)
        seg_ms = time_calls(cam.segmentation, N_RENDERS)
    print(
        f"overhead render {args.width}x{args.height}: rgb {rgb_ms:.1f} ms, "
        f"depth {depth_ms:.1f} ms, segmentation {seg_ms:.1f} ms (median of {N_RENDERS})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
