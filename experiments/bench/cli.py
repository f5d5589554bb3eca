"""``python -m experiments.bench``: many task-cycle episodes (section 5.2, one pick and place
each) run headless and in parallel, with a report of how often and why they fail.

Each seed is one episode on a fresh scene (``--scene random``: drawn from the seed, with a block
count drawn per seed from ``--blocks LO:HI``), run with the same code and options as
``python -m fsm.run --seed S``. Episodes run in a pool of ``--workers`` processes on this machine
(``spawn`` start method), or on a Ray cluster with ``--ray ADDRESS`` (``local``: a private instance
on this machine; ``auto``: the cluster this machine belongs to; needs the extra ``graspsim[ray]``).
The same seeds give the same episodes whichever way they run (wall times aside).

Writes into ``--out DIR``: ``results.jsonl`` (one line per episode, appended as each finishes: the
episode's ``summary.json`` plus ``seed`` and ``blocks``), ``bench.json`` (the options the results
belong to), ``rrd/seed-NNNNNN.rrd`` (the recording of every failed episode; of every episode with
``--keep-rrd``), and ``report.md`` with ``success.png``, ``failures.png``, ``place_error.png`` and
``wall_per_state.png``. ``--resume`` runs only the seeds not yet in ``results.jsonl``.

Exit status: 0 the episodes ran and the report is written (whatever their success rate), 1 a worker
process died (the results so far are kept; ``--resume`` continues), 2 bad input (one line on
stderr, nothing written), 130 interrupted (Ctrl-C; the finished episodes are kept and reported).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import time
from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from controllers.grasp.run_folder import REPRODUCE
from experiments.bench.jobs import (
    RESULTS_FILE,
    BenchError,
    Job,
    blocks_for_seed,
    drop_torn_tail,
    read_results,
)
from experiments.bench.runners import RAY_LOCAL
from experiments.bench.stats import DELIVERED, ELSEWHERE, outcome
from fsm.run import (
    MAX_CYCLES,
    add_controller_and_approach,
    add_hand,
    add_lateral_gate,
    add_place_fallback,
    parse_cycles,
)
from hand_sim.clitools import (
    ERRORS,
    SEED_MAX,
    ArgumentParser,
    CommandLineError,
    add_perturb_argument,
    first_paragraph,
    integer,
    one_line,
    out_dir,
    partial_results_in,
    prepare_dir,
    run_main,
)
from hand_sim.random_scene import MAX_RANDOM_BLOCKS

PROG = "python -m experiments.bench"
#: File of the options a bench folder's results belong to.
SETTINGS_FILE = "bench.json"
#: Options that must match for ``--resume`` to add to a folder's results.
RESUME_KEYS = (
    "scene",
    "blocks",
    "controller",
    "approach",
    "grasp_model",
    "models",
    "cycles",
    "place_fallback",
    "hand",
    "lateral_gate",
    "lateral_gate_rule",
    "perturb",
)
#: What a bench folder whose settings lack an entry ran (older folders: the planar grasp model,
#: one cycle, the servo hand, and a place point the hand could not set down at moved to a free
#: slot unreported, so that their results are not resumed under the rule that judges at the
#: point asked for).
SETTING_DEFAULTS = {
    "grasp_model": "planar",
    "cycles": "1",
    "place_fallback": "a free slot, unreported (old rule)",
    "hand": "servo",
    "lateral_gate": 0.4,
    "lateral_gate_rule": "paper",
    "perturb": None,
}
#: The command-line flag of a setting whose name is not the flag's.
FLAG_OF = {"grasp_model": "model"}
#: Most episodes one command may ask for.
MAX_EPISODES = 100_000
MAX_WORKERS = 1024


@dataclass(frozen=True)
class BlockRange:
    """``--blocks LO:HI``: a random scene's block count, LO to HI included."""

    low: int
    high: int

    def __str__(self) -> str:
        return str(self.low) if self.low == self.high else f"{self.low}:{self.high}"


def seed_range(text: str) -> range:
    """Argument type of ``--seeds FIRST:END``: seeds FIRST, FIRST+1, ..., END-1 (END excluded,
    as in Python's ``range``)."""
    try:
        first, end = (int(p) for p in text.split(":"))
    except ValueError:
        first, end = -1, -1
    if not 0 <= first < end <= SEED_MAX + 1 or end - first > MAX_EPISODES:
        raise argparse.ArgumentTypeError(
            f"must be FIRST:END with 0 <= FIRST < END <= {SEED_MAX + 1} (END excluded, at most "
            f"{MAX_EPISODES:,} seeds), e.g. 0:200, got {text!r}"
        )
    return range(first, end)


def block_range(text: str) -> BlockRange:
    """Argument type of ``--blocks``: ``K`` or ``LO:HI`` (both included)."""
    parts = text.split(":")
    try:
        low, high = (int(parts[0]), int(parts[-1])) if len(parts) <= 2 else (0, 0)
    except ValueError:
        low = high = 0
    if not 1 <= low <= high <= MAX_RANDOM_BLOCKS:
        raise argparse.ArgumentTypeError(
            f"must be K or LO:HI (both included) with 1 <= LO <= HI <= {MAX_RANDOM_BLOCKS}, "
            f"e.g. 3:5, got {text!r}"
        )
    return BlockRange(low, high)


def parser() -> ArgumentParser:
    ap = ArgumentParser(prog=PROG, description=first_paragraph(__doc__))
    ap.add_argument(
        "--scene", default="random", help="scene name or .toml path (as python -m fsm.run)"
    )
    ap.add_argument(
        "--seeds",
        type=seed_range,
        default=seed_range("0:200"),
        metavar="FIRST:END",
        help="episodes' seeds, END excluded (default: 0:200)",
    )
    ap.add_argument(
        "--blocks",
        type=block_range,
        default=None,
        metavar="LO:HI",
        help="blocks of --scene random, LO to HI included; each seed's count is drawn from the "
        "seed alone (numpy default_rng([seed, 12]).integers(LO, HI + 1)) "
        "(default: the generator's, scenes/random.toml)",
    )
    add_controller_and_approach(ap)
    ap.add_argument(
        "--cycles",
        default="1",
        help=f"blocks each episode picks and places one after another (1-{MAX_CYCLES}), or "
        "'all' to clear its table (as python -m fsm.run)",
    )
    add_place_fallback(ap)
    add_hand(ap)
    add_lateral_gate(ap)
    add_perturb_argument(ap)
    ap.add_argument(
        "--workers",
        type=integer(1, MAX_WORKERS),
        default=None,
        help="episodes run at once: processes on this machine (default: its cores), CPUs of "
        "--ray local (default: this machine's cores), at most this many Ray tasks on a cluster "
        "(default: as many as it has CPUs for)",
    )
    ap.add_argument(
        "--ray",
        default=None,
        metavar="ADDRESS",
        help="run the episodes as Ray tasks: 'local' (a private instance here), 'auto' (the "
        "running cluster) or the cluster's address; needs pip install 'graspsim[ray]'",
    )
    ap.add_argument(
        "--out",
        type=out_dir,
        default=None,
        help="output folder (default runs/bench-<scene>-<controller>)",
    )
    ap.add_argument(
        "--resume",
        action="store_true",
        help="keep --out's results.jsonl and run only the seeds not in it",
    )
    ap.add_argument(
        "--keep-rrd",
        action="store_true",
        help=(
            "record every episode and keep the recordings of successes too (default: episodes "
            "run unrecorded; a failed one is run again, recorded, for its .rrd)"
        ),
    )
    ap.add_argument(
        "--models",
        default=None,
        help=f"trained models folder from `{REPRODUCE} DIR` (default: the shipped ones)",
    )
    return ap


def machine_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


@dataclass(frozen=True)
class Plan:
    """A checked command line: the folder, its options and the jobs still to run."""

    out: Path
    settings: dict[str, Any]
    seeds: range
    jobs: tuple[Job, ...]
    done: tuple[dict[str, Any], ...]  #: lines already in results.jsonl (--resume)
    workers: int | None
    ray: str | None


def _episodes(n: int) -> str:
    return f"{n} episode" + ("" if n == 1 else "s")


def _check_resume(out: Path, settings: dict[str, Any], resume: bool) -> list[dict[str, Any]]:
    results = out / RESULTS_FILE
    lines = read_results(results)
    if not resume:
        if results.is_file() and results.stat().st_size > 0:
            raise CommandLineError(
                "--out",
                f"{out} already holds {RESULTS_FILE} ({_episodes(len(lines))}); pass --resume to "
                "add to it, or give another folder",
            )
        return []
    saved_path = out / SETTINGS_FILE
    if saved_path.is_file():
        try:
            saved = json.loads(saved_path.read_text())
        except json.JSONDecodeError:
            saved = None
        if not isinstance(saved, dict):
            raise BenchError(f"{saved_path} is not a bench's settings file; give another --out")
        differ = [k for k in RESUME_KEYS if saved.get(k, SETTING_DEFAULTS.get(k)) != settings[k]]
        if differ:
            was = ", ".join(
                f"--{FLAG_OF.get(k, k.replace('_', '-'))} {saved.get(k, SETTING_DEFAULTS.get(k))}"
                if saved.get(k, SETTING_DEFAULTS.get(k)) is not None
                else f"no --{k}"
                for k in differ
            )
            raise CommandLineError(
                "--resume",
                f"{out} holds results of {was}; resume with the same options or give another --out",
            )
    elif lines:
        raise BenchError(f"{out} has {RESULTS_FILE} but no {SETTINGS_FILE}; give another --out")
    return lines


def plan_from_args(argv: Sequence[str] | None) -> Plan:
    """Parse and check every flag before any work starts (:class:`CommandLineError` otherwise)."""
    args = parser().parse_args(argv)
    cycles = parse_cycles(args.cycles)
    from fsm.layout import episode_scene

    if args.blocks is not None and args.scene != "random":
        raise CommandLineError("--blocks", "applies to --scene random only")
    blocks = args.blocks
    # a scene file is named by its absolute path: workers may not share this folder
    scene = str(Path(args.scene).resolve()) if args.scene.endswith(".toml") else args.scene
    first = args.seeds[0]
    episode_scene(scene, first, blocks and blocks_for_seed(first, blocks.low, blocks.high))
    if args.models is not None and not Path(args.models).is_dir():
        raise CommandLineError("--models", f"{args.models!r} is not a folder")
    from controllers.grasp.registry import make_composer

    # a learned controller without its models fails here, once, rather than in every episode
    make_composer(args.controller, **({"model_dir": Path(args.models)} if args.models else {}))
    if args.ray is not None:
        if importlib.util.find_spec("ray") is None:
            raise CommandLineError(
                "--ray",
                "Ray is not installed; pip install 'graspsim[ray]' (ray==2.60.0), or run "
                "without --ray",
            )
        if not args.ray.strip():
            raise CommandLineError("--ray", "give 'local', 'auto' or a cluster address")
    stem = Path(args.scene).stem if args.scene.endswith(".toml") else args.scene
    out = prepare_dir(args.out or Path("runs") / f"bench-{stem}-{args.controller}", "--out")
    models = None if args.models is None else str(Path(args.models).resolve())
    settings = {
        "scene": scene,
        "blocks": None if blocks is None else str(blocks),
        "controller": args.controller,
        "approach": args.approach,
        "grasp_model": args.model,
        "models": models,
        "cycles": "all" if cycles is None else str(cycles),
        "place_fallback": args.place_fallback,
        "hand": args.hand,
        "lateral_gate": args.lateral_gate,
        "lateral_gate_rule": args.lateral_gate_rule,
        "perturb": args.perturb,
    }
    done = _check_resume(out, settings, args.resume)
    finished = {int(line["seed"]) for line in done}
    jobs = tuple(
        Job(
            seed=s,
            scene=scene,
            blocks=None if blocks is None else blocks_for_seed(s, blocks.low, blocks.high),
            controller=args.controller,
            approach=args.approach,
            grasp_model=args.model,
            models=models,
            keep_rrd=args.keep_rrd,
            cycles=cycles,
            place_fallback=args.place_fallback,
            hand=args.hand,
            lateral_gate=args.lateral_gate,
            lateral_gate_rule=args.lateral_gate_rule,
            perturb=args.perturb,
        )
        for s in args.seeds
        if s not in finished
    )
    workers = args.workers
    if workers is None and (args.ray is None or args.ray == RAY_LOCAL):
        workers = machine_cores()
    if args.ray is None and workers is not None:  # no idle processes
        workers = max(1, min(workers, len(jobs)))
    return Plan(out, settings, args.seeds, jobs, tuple(done), workers, args.ray)


def _enter_runner(stack: ExitStack, plan: Plan) -> Any:
    """Start where the episodes run (a Ray that cannot be started or reached is bad input)."""
    from experiments.bench.runners import open_runner

    try:
        return stack.enter_context(open_runner(plan.workers, plan.ray))
    except (ConnectionError, RuntimeError, ValueError, TimeoutError) as e:
        if plan.ray is None:
            raise
        raise CommandLineError(
            "--ray", f"cannot start or reach Ray at {plan.ray!r} ({one_line(str(e))})"
        ) from e


def _pct(x: float) -> str:
    return f"{100.0 * x:.1f} %"


def _run_jobs(plan: Plan, lines: list[dict[str, Any]]) -> None:
    """Run the plan's jobs, appending each finished episode to ``results.jsonl`` (and to
    ``lines``) and keeping its recording when it is returned."""
    from tqdm import tqdm

    from experiments.bench.jobs import append_line
    from graspsim_base.files import write_bytes, write_text

    results = plan.out / RESULTS_FILE
    ok = sum(1 for line in lines if line["seed"] in plan.seeds and outcome(line) == DELIVERED)
    failed = len(plan.seeds) - len(plan.jobs) - ok
    with ExitStack() as stack:
        runner = _enter_runner(stack, plan) if plan.jobs else None
        write_text(plan.out / SETTINGS_FILE, json.dumps(plan.settings, indent=2) + "\n")
        drop_torn_tail(results)
        if runner is None:
            return
        bar = stack.enter_context(
            tqdm(
                total=len(plan.seeds),
                initial=len(plan.seeds) - len(plan.jobs),
                unit="episode",
                desc=f"{plan.settings['controller']} episodes",
                smoothing=0.0,
                dynamic_ncols=True,
                file=sys.stderr,
            )
        )
        bar.set_postfix_str(f"{ok} delivered, {failed} not", refresh=False)
        for result in runner.run(plan.jobs):
            line = result.line
            if result.rrd is not None:
                write_bytes(plan.out / line["rrd"], result.rrd)
            append_line(results, line)
            lines.append(line)
            kind = outcome(line)
            if kind == DELIVERED:
                ok += 1
            else:  # delivered elsewhere is not counted as delivered
                failed += 1
                detail = one_line(str(line.get("failure_detail", "")))
                what = ELSEWHERE if kind == ELSEWHERE else f"{line.get('failure')}: {detail[:200]}"
                bar.write(f"seed {line['seed']}: {what}")
            bar.set_postfix_str(f"{ok} delivered, {failed} not", refresh=False)
            bar.update(1)


def run(argv: Sequence[str] | None) -> int:
    plan = plan_from_args(argv)
    from experiments.bench.report import write_report
    from experiments.bench.runners import WorkerLostError
    from experiments.bench.stats import summarize

    lines = list(plan.done)
    wall0 = time.perf_counter()
    code = 0
    try:
        with partial_results_in(plan.out):
            _run_jobs(plan, lines)
    except WorkerLostError as e:
        print(f"{PROG}: {one_line(str(e))}", file=sys.stderr)
        code = 1
    except KeyboardInterrupt:
        if lines:  # the workers are stopped; report what is done
            write_report(plan.out, lines, plan.settings)
        raise
    if not lines:
        return code
    report = write_report(plan.out, lines, plan.settings)
    s = summarize(lines)
    print(
        f"{_episodes(s.episodes)} in {plan.out / RESULTS_FILE}: {s.successes} delivered "
        f"({_pct(s.rate.estimate)}, Wilson 95 % [{_pct(s.rate.low)}, {_pct(s.rate.high)}]), "
        f"{s.elsewhere} delivered elsewhere, {s.episodes - s.successes - s.elsewhere} failed; "
        f"{len(lines) - len(plan.done)} run now in "
        f"{time.perf_counter() - wall0:.0f} s; wrote {report}"
    )
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """Run the bench; see the module docstring for the exit status."""
    return run_main(lambda: run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    sys.exit(main())
