"""Speed-up of ``python -m experiments.bench`` with N worker processes over one: the same episodes
(task cycles on random scenes) run first one after another in this process (``--workers 1``), then
in a pool of N ``spawn``ed processes (``--workers N``, the pool's start-up included), and the
elapsed wall times compared. Also checks that both gave the same results (wall times aside).

Run: ``python -m benchmarks.bench_parallel [--seeds 0:4] [--blocks 3] [--controller kb]
[--workers 2]``. The machine's load average is printed before and after: on shared cores the
figures are only as good as the machine was idle.
"""

from __future__ import annotations

import os
import resource
import sys
import time
from collections.abc import Sequence

from experiments.bench.cli import block_range, machine_cores, seed_range
from experiments.bench.jobs import Job, JobResult, blocks_for_seed, without_wall_times
from experiments.bench.runners import open_runner
from fsm.context import CONTROLLERS
from hand_sim.clitools import ERRORS, ArgumentParser, first_paragraph, integer, run_main

PROG = "python -m benchmarks.bench_parallel"


def _cpu_seconds() -> float:
    """CPU time (user + system) of this process and of its waited-for children."""
    usage = (resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN))
    return sum(u.ru_utime + u.ru_stime for u in usage)


def _timed(workers: int, jobs: Sequence[Job]) -> tuple[float, float, dict[int, JobResult]]:
    """Elapsed and CPU seconds of running ``jobs`` with ``workers`` (the pool's processes are
    joined when it closes, so their CPU time is counted)."""
    t0, c0 = time.perf_counter(), _cpu_seconds()
    with open_runner(workers, None) as runner:
        results = {r.seed: r for r in runner.run(jobs)}
    return time.perf_counter() - t0, _cpu_seconds() - c0, results


def run(argv: Sequence[str] | None) -> int:
    ap = ArgumentParser(prog=PROG, description=first_paragraph(__doc__))
    ap.add_argument("--seeds", type=seed_range, default=seed_range("0:4"), metavar="FIRST:END")
    ap.add_argument("--blocks", type=block_range, default=block_range("3"), metavar="LO:HI")
    ap.add_argument("--controller", default="kb", choices=CONTROLLERS, help="grasp controller")
    ap.add_argument("--workers", type=integer(2, 1024), default=2, help="processes of the pool")
    args = ap.parse_args(argv)
    b = args.blocks
    jobs = [
        Job(seed=s, blocks=blocks_for_seed(s, b.low, b.high), controller=args.controller)
        for s in args.seeds
    ]
    print(
        f"# {len(jobs)} episodes (seeds {args.seeds.start}:{args.seeds.stop}, --blocks {b}, "
        f"{args.controller}); {machine_cores()} cores; load average before "
        f"{os.getloadavg()[0]:.1f}"
    )
    print(
        f"{'workers':>7s} {'elapsed s':>10s} {'episodes/min':>13s} {'speed-up':>9s} "
        f"{'CPU s/episode':>14s} {'cores used':>11s}"
    )
    base = 0.0
    runs = {}
    for workers in (1, args.workers):
        elapsed, cpu, runs[workers] = _timed(workers, jobs)
        base = base or elapsed
        print(
            f"{workers:7d} {elapsed:10.1f} {60 * len(jobs) / elapsed:13.2f} "
            f"{base / elapsed:9.2f} {cpu / len(jobs):14.1f} {cpu / elapsed:11.2f}"
        )
    first, second = runs[1], runs[args.workers]
    same = all(
        without_wall_times(first[s].line) == without_wall_times(second[s].line) for s in first
    )
    delivered = sum(bool(r.line["success"]) for r in first.values())
    print(
        f"same results with 1 and {args.workers} workers: {'yes' if same else 'NO'}; "
        f"{delivered}/{len(jobs)} delivered; load average after {os.getloadavg()[0]:.1f}"
    )
    return 0 if same else 1


def main(argv: Sequence[str] | None = None) -> int:
    return run_main(lambda: run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    sys.exit(main())
