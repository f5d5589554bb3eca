"""Speed of the task cycle: wall and CPU time per state, the simulated/wall time ratio of
episodes, and how far the episode is from the cost of its physics alone.

Runs ``python -m fsm.run``'s episode loop (fsm.machine.run_episode) on a scene, with and without the
recording, and prints one row per state (summed over the episodes) and the totals. Each episode's
control inputs are captured at every simulation step; the same steps are then replayed on a freshly
built world of the same scene and hand, with nothing but ``mj_step`` (and, for the tendon hand, its
joint loop before every step; no planning, no vision, no recording): the physics-only time. The last
lines give the process's wall time since it started (imports included) and the ratio of the
episode's wall time to the physics-only time.

Usage: python -m benchmarks.bench_fsm [--scene clutter3] [--seeds 1] [--controller pi]
[--hand tendon|servo] [--no-record]
"""

from __future__ import annotations

import sys
import tempfile
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fsm.context import CONTROLLERS, EpisodeOptions
from fsm.run import add_hand
from hand_sim.clitools import ERRORS, ArgumentParser, first_paragraph, integer, run_main

PROG = "python -m benchmarks.bench_fsm"


def process_wall_seconds() -> float:
    """Wall time (s) since this process started, from the kernel's record of its start (Linux
    ``/proc``); elsewhere, since this module was imported."""
    try:
        ticks = int(Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        import os

        return uptime - ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return time.perf_counter() - _IMPORTED


_IMPORTED = time.perf_counter()


@dataclass
class StepLog:
    """The control inputs of every ``World.step`` call of an episode: ``ctrl`` (k, nu) and the
    number of MuJoCo steps each call took (k,)."""

    ctrl: list[NDArray[np.float64]] = field(default_factory=list)
    steps: list[int] = field(default_factory=list)
    last_time: float = 0.0
    world: Any = None  #: the episode's world (its final state is the replay's reference)


class CapturingRecorder:
    """Wraps an episode's recorder: on each step tick it notes the world's control inputs and
    the steps taken since the last tick, then passes every call on."""

    def __init__(self, inner: Any, log: StepLog, timestep: float) -> None:
        self._inner = inner
        self._log = log
        self._timestep = timestep

    def tick(self, world: Any) -> None:
        log = self._log
        n = round((world.time - log.last_time) / self._timestep)
        if n > 0:
            log.ctrl.append(world.data.ctrl.copy())
            log.steps.append(n)
            log.last_time = world.time
        self._inner.tick(world)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


@dataclass(frozen=True)
class Replay:
    """The physics-only replay of an episode: wall and CPU seconds of the ``mj_step`` calls,
    MuJoCo steps taken, and the largest difference (m or rad) of the final joint positions from
    the episode's (0 when the replay is the same trajectory)."""

    wall: float
    cpu: float
    steps: int
    final_qpos_error: float


def replay_physics(options: EpisodeOptions, log: StepLog, final_qpos: NDArray) -> Replay:
    """Build ``options``'s scene afresh, with its hand, and step it with the logged control
    inputs only: MuJoCo's own stepping for the servo hand; for the tendon hand, its joint loop
    (:meth:`hand_sim.tendon_drive.TendonDrive.step`, the tensions computed before every physics
    step) is part of the physics and is replayed too."""
    import mujoco

    from fsm.layout import episode_scene
    from hand_sim.world import World

    scene = episode_scene(options.scene, options.seed, options.blocks)
    world = World.build(scene, hand=options.hand)
    m, d = world.model, world.data
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for ctrl, n in zip(log.ctrl, log.steps, strict=True):
        d.ctrl[:] = ctrl
        if world.tendon_drive is None:
            mujoco.mj_step(m, d, nstep=n)
        else:
            world.step(n)
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    error = float(np.abs(d.qpos - final_qpos).max())
    return Replay(wall, cpu, int(sum(log.steps)), error)


def run(argv: list[str] | None) -> int:
    ap = ArgumentParser(prog=PROG, description=first_paragraph(__doc__))
    ap.add_argument("--scene", default="clutter3", help="scene name or .toml path")
    ap.add_argument("--seeds", type=integer(1, 100), default=1, help="episodes (seeds 0..N-1)")
    ap.add_argument("--controller", default="pi", choices=CONTROLLERS, help="grasp controller")
    ap.add_argument("--no-record", action="store_true", help="time only the run without the .rrd")
    add_hand(ap)
    args = ap.parse_args(argv)
    from fsm.machine import run_episode
    from fsm.recorder_protocol import NullRecorder
    from fsm.recording import EpisodeRecorder

    modes = (False,) if args.no_record else (False, True)
    with tempfile.TemporaryDirectory() as tmp:
        for record in modes:
            per_state: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0.0, 0])
            sim = wall = cpu = physics_wall = physics_cpu = 0.0
            ok = steps = 0
            worst_replay = 0.0
            size = 0.0
            for seed in range(args.seeds):
                out = Path(tmp) / f"{seed}-{record}"
                options = EpisodeOptions(
                    scene=args.scene,
                    seed=seed,
                    controller=args.controller,
                    hand=args.hand,
                    out=out,
                    record=True,  # the recorder factory below decides what is recorded
                )
                log = StepLog()

                def factory(path: Path, world: Any, log: StepLog = log, rec: bool = record) -> Any:
                    inner = EpisodeRecorder(path, world) if rec else NullRecorder()
                    log.world = world
                    return CapturingRecorder(inner, log, world.model.opt.timestep)

                marks: list[float] = []
                cpu0 = time.process_time()
                result = run_episode(
                    options,
                    announce=lambda _line, marks=marks: marks.append(time.process_time()),
                    recorder_factory=factory,
                )
                cpu_end = time.process_time()
                marks.append(cpu_end)
                replay = replay_physics(options, log, log.world.data.qpos.copy())
                ok += result.success
                sim += result.sim_time
                wall += result.wall_time
                cpu += cpu_end - cpu0
                physics_wall += replay.wall
                physics_cpu += replay.cpu
                steps += replay.steps
                worst_replay = max(worst_replay, replay.final_qpos_error)
                for k, v in enumerate(result.visits):
                    row = per_state[v.state]
                    row[0] += v.wall_seconds
                    row[1] += marks[k + 1] - marks[k]
                    row[2] += v.sim_seconds
                    row[3] += 1
                size = (out / "episode.rrd").stat().st_size / 1e6 if record else 0.0
            label = "with recording" if record else "without recording"
            print(f"# {args.scene}, {args.seeds} episode(s), {label}: {ok} delivered")
            print(
                f"{'state':18s} {'visits':>6s} {'wall s':>8s} {'CPU s':>8s} {'sim s':>8s} "
                f"{'sim/wall':>9s}"
            )
            for state, (w, c, s, n) in per_state.items():
                ratio = s / w if w > 0 else float("nan")
                print(f"{state:18s} {int(n):6d} {w:8.2f} {c:8.2f} {s:8.2f} {ratio:9.1f}")
            print(
                f"{'episode':18s} {'':6s} {wall:8.2f} {cpu:8.2f} {sim:8.2f} {sim / wall:9.1f}"
                + (f"   last .rrd {size:.1f} MB" if record else "")
            )
            print(
                f"{'physics only':18s} {'':6s} {physics_wall:8.2f} {physics_cpu:8.2f} "
                f"{sim:8.2f} {sim / physics_wall:9.1f}"
                f"   {steps} mj_step replayed, final qpos within {worst_replay:.1e}"
            )
            print(
                f"episode / physics only: wall {wall / physics_wall:.1f}x, "
                f"CPU {cpu / physics_cpu:.1f}x"
            )
    print(f"process wall time since start: {process_wall_seconds():.1f} s")
    return 0


def main(argv: list[str] | None = None) -> int:
    return run_main(lambda: run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    sys.exit(main())
