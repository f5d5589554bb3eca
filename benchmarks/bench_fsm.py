"""Speed of the task cycle: wall time per state and the simulated/wall time ratio of episodes.

Runs ``python -m fsm.run``'s episode loop (fsm.machine.run_episode) on a scene, with and without
the recording, and prints one row per state (summed over the episode) and the totals.

Usage: python -m benchmarks.bench_fsm [--scene clutter3] [--seeds 0] [--controller pi] [--no-record]
"""

from __future__ import annotations

import sys
import tempfile
from collections import defaultdict
from pathlib import Path

from fsm.context import CONTROLLERS, EpisodeOptions
from hand_sim.clitools import ERRORS, ArgumentParser, first_paragraph, integer, run_main

PROG = "python -m benchmarks.bench_fsm"


def run(argv: list[str] | None) -> int:
    ap = ArgumentParser(prog=PROG, description=first_paragraph(__doc__))
    ap.add_argument("--scene", default="clutter3", help="scene name or .toml path")
    ap.add_argument("--seeds", type=integer(1, 100), default=1, help="episodes (seeds 0..N-1)")
    ap.add_argument("--controller", default="pi", choices=CONTROLLERS, help="grasp controller")
    ap.add_argument("--no-record", action="store_true", help="time only the run without the .rrd")
    args = ap.parse_args(argv)
    from fsm.machine import run_episode

    modes = (False,) if args.no_record else (False, True)
    with tempfile.TemporaryDirectory() as tmp:
        for record in modes:
            per_state: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0])
            sim = wall = 0.0
            ok = 0
            for seed in range(args.seeds):
                out = Path(tmp) / f"{seed}-{record}"
                options = EpisodeOptions(
                    scene=args.scene,
                    seed=seed,
                    controller=args.controller,
                    out=out,
                    record=record,
                )
                result = run_episode(options)
                ok += result.success
                sim += result.sim_time
                wall += result.wall_time
                for v in result.visits:
                    row = per_state[v.state]
                    row[0] += v.wall_seconds
                    row[1] += v.sim_seconds
                    row[2] += 1
                size = (out / "episode.rrd").stat().st_size / 1e6 if record else 0.0
            label = "with recording" if record else "without recording"
            print(f"# {args.scene}, {args.seeds} episode(s), {label}: {ok} delivered")
            print(f"{'state':18s} {'visits':>6s} {'wall s':>8s} {'sim s':>8s} {'sim/wall':>9s}")
            for state, (w, s, n) in per_state.items():
                ratio = s / w if w > 0 else float("nan")
                print(f"{state:18s} {n:6d} {w:8.2f} {s:8.2f} {ratio:9.1f}")
            print(
                f"{'episode':18s} {'':6s} {wall:8.2f} {sim:8.2f} {sim / wall:9.1f}"
                + (f"   last .rrd {size:.1f} MB" if record else "")
            )
    return 0


def main(argv: list[str] | None = None) -> int:
    return run_main(lambda: run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    sys.exit(main())
