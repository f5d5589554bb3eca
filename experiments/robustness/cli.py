"""``python -m experiments.robustness``: the task cycle on random scenes when the simulated world
differs from the robot's model (section 5.3's woes), per perturbation and scale.

``run`` runs ``python -m experiments.bench --scene random --seeds FIRST:END --blocks LO:HI
--perturb NAME=SCALE`` for every perturbation and scale asked for, one after another (each its
own folder ``OUT/NAME=SCALE``; a folder already there is resumed), then writes the report;
``report`` writes the report of bench folders already run. The report is ``OUT/report.md``,
``OUT/summary.json`` and ``OUT/success_vs_scale.png`` (:mod:`experiments.robustness.report`).

Exit status: 0 the report is written, 1 a bench failed (the folders so far are kept), 2 bad
input (one line on stderr, nothing written), 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

from graspsim_base import cli
from graspsim_base.files import write_text
from hand_sim.perturb import KINDS, MAX_SCALE, NAMES

PROG = "python -m experiments.robustness"
#: The scales of the report (1: the magnitudes of hand_sim.perturb).
DEFAULT_SCALES = (0.5, 1.0, 2.0)


def names(text: str) -> tuple[str, ...]:
    """``--perturb``: ``all`` or perturbation names, comma-separated, each once."""
    if text == "all":
        return NAMES
    got = tuple(n.strip() for n in text.split(","))
    bad = [n for n in got if n not in NAMES]
    if bad or len(set(got)) != len(got) or not got:
        raise argparse.ArgumentTypeError(
            f"unknown or repeated perturbation in {text!r}; valid: all or a comma-separated "
            f"list of {', '.join(NAMES)}"
        )
    return got


def scales(text: str) -> tuple[float, ...]:
    """``--scales``: numbers in (0, MAX_SCALE], comma-separated."""
    try:
        got = tuple(float(s) for s in text.split(","))
    except ValueError:
        got = ()
    if not got or not all(0.0 < s <= MAX_SCALE for s in got):
        raise argparse.ArgumentTypeError(
            f"must be numbers in (0, {MAX_SCALE:g}], comma-separated, e.g. 0.5,1,2; got {text!r}"
        )
    return got


def folder_name(name: str, scale: float) -> str:
    """The bench folder of ``name`` at ``scale``."""
    return f"{name}={scale:g}"


def _bench(name: str, scale: float, args: argparse.Namespace, out: Path) -> list[str]:
    """The bench command of one perturbation and scale."""
    argv = [
        sys.executable,
        "-m",
        "experiments.bench",
        "--scene",
        "random",
        "--seeds",
        args.seeds,
        "--blocks",
        args.blocks,
        "--perturb",
        f"{name}={scale:g}",
        "--workers",
        str(args.workers),
        "--out",
        str(out),
    ]
    if (out / "results.jsonl").is_file():
        argv.append("--resume")
    return argv


def run(args: argparse.Namespace) -> int:
    out = cli.prepare_dir(args.out, "--out")
    folders = []
    with cli.partial_results_in(out):
        if args.command == "run":
            for name in args.perturb:
                for scale in args.scales:
                    folder = out / folder_name(name, scale)
                    done = subprocess.run(_bench(name, scale, args, folder), check=False)
                    if done.returncode != 0:
                        print(f"{PROG}: the bench of {name}={scale:g} failed", file=sys.stderr)
                        return 1
                    folders.append(folder)
        else:
            folders = [Path(f) for f in args.runs]
        if args.baseline is not None:
            folders.append(Path(args.baseline))
        from experiments.robustness.report import as_json, write_report

        rows = write_report(folders, out, f"{PROG} {args.argv}")
        write_text(out / "summary.json", json.dumps(as_json(rows), indent=1) + "\n")
    print(f"{len(rows)} runs; wrote {out / 'report.md'}")
    return 0


def _check_folders(text: str) -> str:
    path = Path(text)
    if not ((path / "results.jsonl").is_file() and (path / "bench.json").is_file()):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a bench folder (results.jsonl and bench.json)"
        )
    return text


def build_parser() -> cli.ArgumentParser:
    ap = cli.ArgumentParser(prog=PROG, description=cli.first_paragraph(__doc__))
    sub = ap.add_subparsers(dest="command", required=True)
    r = sub.add_parser("run", help="run the benches, then write the report")
    r.add_argument(
        "--perturb",
        type=names,
        default=NAMES,
        metavar="all|NAME,...",
        help=f"perturbations, one bench each ({', '.join(KINDS)}, woes) (default all)",
    )
    r.add_argument(
        "--scales",
        type=scales,
        default=DEFAULT_SCALES,
        metavar="S,...",
        help="scales, one bench each (default 0.5,1,2)",
    )
    r.add_argument("--seeds", default="0:100", help="as experiments.bench (default 0:100)")
    r.add_argument("--blocks", default="3:5", help="as experiments.bench (default 3:5)")
    r.add_argument("--workers", type=cli.integer(1, 64), default=2, help="as experiments.bench")
    rep = sub.add_parser("report", help="the report of bench folders already run")
    rep.add_argument("runs", nargs="+", type=_check_folders, help="bench folders")
    for p in (r, rep):
        p.add_argument("--out", required=True, type=cli.out_dir, help="output folder")
        p.add_argument(
            "--baseline",
            type=_check_folders,
            default=None,
            help="an unperturbed bench folder of the same seeds, drawn at scale 0",
        )
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv``; returns the exit status."""
    return cli.run_command(build_parser, argv, prog=PROG, command=run)
