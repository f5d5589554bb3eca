"""Command line of the paper's experiments on the grasp core:
``python -m experiments.paper {table1,reproduce}``.

``table1`` is Table 1's knowledge-based column beside the paper's (section 3.6.3); ``reproduce``
runs every experiment of the paper (Tables 1-2, section 2, Appendix A, the figures) over several
seeds and writes report.md, results.json, the figures and the trained models. Bad input is one
line on stderr and exit status 2 (:mod:`graspsim_base.cli`).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

from controllers.grasp.cli import (
    ERRORS,
    GAIN_HELP,
    MAX_TRIALS,
    gain_type,
    prepare_json,
    trials_type,
    write_json,
)
from controllers.grasp.objects import FAMILY_OBJECTS, FAMILY_SIZE, PAPER_LABELS
from controllers.grasp.trials import GAIN
from experiments.paper.tables import (
    FAMILY_TRIALS,
    PAPER_TABLE1_AVERAGE,
    PAPER_TABLE1_KB,
    average_failure,
    table1_rows,
)
from graspsim_base import cli

PROG = "python -m experiments.paper"
#: Seeds a reproduce run may average over.
MAX_SEEDS = 16
#: Worker processes of reproduce (more than the machine's cores only adds switching).
MAX_WORKERS = 64


def cmd_table1(args: argparse.Namespace) -> int:
    prepare_json(args)
    start = time.perf_counter()
    rows = table1_rows(args.trials, args.seed, gain=args.gain)
    elapsed = time.perf_counter() - start
    print(
        f"Table 1, knowledge-based composition: {args.trials} trials per regular object, "
        f"{FAMILY_TRIALS} per shape of the * families ({FAMILY_SIZE} shapes, 5-95 % range), "
        f"seed {args.seed}"
    )
    print(f"{'Object':18s} {'ours (%)':>9s} {'range':>11s} {'paper (%)':>10s} {'mean S_G':>9s}")
    for name, r in rows.items():
        spread = "" if "spread" not in r else f"{r['spread'][0]:.1f}-{r['spread'][1]:.1f}"
        label = PAPER_LABELS[name] + (" *" if name in FAMILY_OBJECTS else "")
        print(
            f"{label:18s} {r['failure']:9.2f} {spread:>11s} {PAPER_TABLE1_KB[name]:10.2f} "
            f"{r['mean_s_g']:9.3f}"
        )
    avg = average_failure(rows)
    print(f"{'Average':18s} {avg:9.2f} {'':>11s} {PAPER_TABLE1_AVERAGE['kb']:10.2f}")
    print(f"({elapsed:.2f} s)")
    write_json(args.json, {"rows": rows, "average_failure": avg, "seconds": elapsed})
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    from experiments.paper.reproduce import ReproduceConfig, reproduce

    cli.prepare_dir(args.out, "--out")
    extra = {"workers": args.workers, "command": f"{PROG} {args.argv}"}
    if args.seeds is not None:
        extra["seeds"] = args.seeds
    cfg = ReproduceConfig.quick_run(**extra) if args.quick else ReproduceConfig.paper(**extra)
    with cli.partial_results_in(args.out):
        res = reproduce(args.out, config=cfg)
    avg = {k: res["tables"][k]["average_failure"]["mean"] for k in ("kb", "ql", "pi", "pi5")}
    held = res["general"]["heldout"]
    print(
        f"average failure (%) over seeds {','.join(map(str, cfg.seeds))}: kb {avg['kb']:.2f}, "
        f"ql {avg['ql']:.2f}, pi {avg['pi']:.2f}, pi (5 objects) {avg['pi5']:.2f}; held-out "
        f"polygons: kb {held['kb']['failure']['mean']:.2f}, general pi "
        f"{held['general']['failure']['mean']:.2f}; report: {args.out / 'report.md'}"
    )
    return 0


def seed_list(text: str) -> tuple[int, ...]:
    """``--seeds``: distinct integers 0..SEED_MAX, comma-separated, at most MAX_SEEDS."""
    parse = cli.seed
    try:
        seeds = tuple(parse(x) for x in text.split(","))
    except argparse.ArgumentTypeError as e:
        raise argparse.ArgumentTypeError(f"{e} (seeds are written like 0,1,2)") from None
    if len(set(seeds)) != len(seeds) or len(seeds) > MAX_SEEDS:
        raise argparse.ArgumentTypeError(
            f"must be 1..{MAX_SEEDS} distinct seeds like 0,1,2, got {text!r}"
        )
    return seeds


def build_parser() -> cli.ArgumentParser:
    p, sub = cli.command_parser(
        PROG,
        "The paper's experiments on the grasp core: Table 1's knowledge-based column, and every "
        "experiment of the paper over several seeds.",
    )
    tb = cli.add_command(sub, "table1", "knowledge-based column of Table 1 beside the paper's")
    tb.add_argument(
        "--trials", type=trials_type, default=200, help=f"trials per object, 1..{MAX_TRIALS}"
    )
    cli.add_seed_argument(tb)
    tb.add_argument("--gain", type=gain_type, default=GAIN, help=GAIN_HELP)
    cli.add_json_argument(tb, "write the rows to this JSON file")
    tb.set_defaults(func=cmd_table1)

    r = cli.add_command(
        sub,
        "reproduce",
        "train and test every learned controller; write report, figures, models",
        "Every experiment of the paper (Tables 1-2, the noise readings, section 2, "
        "Appendix A, figures) and PI on held-out polygons, over several seeds: train and test "
        "every learned controller and write report.md, results.json, the figures and the "
        "trained models into --out. About 13 CPU-minutes: 7 minutes on 2 idle cores "
        "(--quick: under one).",
    )
    r.add_argument(
        "--out",
        required=True,
        type=cli.out_dir,
        metavar="DIR",
        help="output folder (report.md, results.json, PNGs, models); a finished run is marked "
        "in results.json",
    )
    r.add_argument(
        "--quick", action="store_true", help="reduced sizes for CI (well under a minute)"
    )
    r.add_argument(
        "--seeds",
        type=seed_list,
        metavar="S,S,...",
        help=f"seeds, 0..{cli.SEED_MAX}; tables are mean +- sd over them "
        "(default 0,1,2; with --quick 0)",
    )
    cli.add_workers_argument(r, MAX_WORKERS)
    r.set_defaults(func=cmd_reproduce)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit status."""
    return cli.run_command(build_parser, argv, prog=PROG, errors=ERRORS)


def reproduce_main(argv: Sequence[str] | None = None) -> int:
    """``graspsim-reproduce ARGS`` is ``python -m experiments.paper reproduce ARGS``."""
    args = sys.argv[1:] if argv is None else list(argv)
    return main(["reproduce", *args])
