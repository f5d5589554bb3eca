"""Command line of the physical grasp study: ``python -m experiments.physics --out DIR``.

Grasps of KB, QL and PI taken by the simulated hand, squeezed, pushed with m*g along +-x, +-y,
+-z and lifted; report.md with physical success per controller and object, the ROC and AUC of S_G
and pictures of dropped grasps. Bad input is one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

from controllers.grasp.objects import PAPER_OBJECTS
from controllers.grasp.task_height import HEIGHT_GAP, HEIGHT_TRIES
from graspsim_base import cli
from hand_sim.clitools import ERRORS, add_perturb_argument

PROG = "python -m experiments.physics"
#: The hands the study can put on the arm: ``hand_sim.assembly.HAND_KINDS`` and its default,
#: repeated here because the command line loads MuJoCo only when it runs (tested equal).
HANDS, DEFAULT_HAND = ("servo", "tendon"), "tendon"
#: Worker processes (more than the machine's cores only adds switching).
MAX_WORKERS = 64
#: The perturbations a grasp held in the hand can have (hand_sim.perturb): the block and the
#: pads (``object``), the hand's sensors (``sensing``) and its tendon drive (``actuation``).
#: The study sets the hand at a posture solved in its own world, so the camera, the arm's base
#: and the kinematics do not enter it.
PERTURB_KINDS = ("object", "sensing", "actuation")


def object_list(text: str) -> tuple[str, ...]:
    """``--objects``: ``all`` or paper object names, comma-separated, each once."""
    if text == "all":
        return PAPER_OBJECTS
    names = tuple(x.strip() for x in text.split(","))
    bad = [n for n in names if n not in PAPER_OBJECTS]
    if bad or len(set(names)) != len(names) or not names:
        raise argparse.ArgumentTypeError(
            f"unknown or repeated object in {text!r}; valid: all or a comma-separated list of "
            f"{', '.join(PAPER_OBJECTS)}"
        )
    return names


def run(args: argparse.Namespace) -> int:
    # lazy: the physical study needs MuJoCo and the hand, which the grasp core does not import
    from experiments.physics.report import QUICK_GRASPS, QUICK_OBJECTS, run_study, write_report
    from experiments.physics.synthesis import MODELS

    models = MODELS if args.model == "both" else (args.model,)
    if args.depth is not None and models != ("planar",):
        raise cli.CommandLineError("--depth", "it places a planar grasp: use --model planar")
    cli.prepare_dir(args.out, "--out")
    objects = QUICK_OBJECTS if args.quick and args.objects is None else args.objects
    objects = PAPER_OBJECTS if objects is None else objects
    grasps = QUICK_GRASPS if args.quick and args.grasps is None else (args.grasps or 50)
    total = len(models) * len(objects) * 3 * grasps
    from tqdm import tqdm

    t0 = time.perf_counter()
    with (
        cli.partial_results_in(args.out),
        tqdm(total=total, unit="grasp", disable=not sys.stderr.isatty()) as bar,
    ):
        results = run_study(
            objects,
            grasps,
            args.seed,
            args.workers,
            progress=bar.update,
            models=models,
            depth=args.depth,
            hand=args.hand,
            height_tries=args.height_tries,
            regrasp=args.regrasp,
            perturb=args.perturb,
        )
        summary = write_report(
            args.out,
            results,
            objects,
            grasps,
            args.seed,
            f"{PROG} {args.argv}",
            time.perf_counter() - t0,
            models=models,
            hand=args.hand,
            height_tries=args.height_tries,
            perturb=args.perturb,
        )
    print(
        f"{total} grasps, {summary['tested']} tested physically, {summary['held']} held; "
        f"AUC of S_G {summary['auc']:.3f}, best threshold {summary['best_threshold']:.3f} "
        f"(paper 0.4); {summary['seconds']:.0f} s; report: {args.out / 'report.md'}"
    )
    return 0


def build_parser() -> cli.ArgumentParser:
    ph = cli.ArgumentParser(
        prog=PROG,
        description="The physical grasp study: N grasps per object and controller (kb, ql, pi) "
        "from random initial contacts, taken by the simulated hand, squeezed, then pushed with "
        "m*g along +-x, +-y, +-z (2 s each) and lifted 10 cm; report.md with physical success "
        "per controller and object, the ROC and AUC of S_G and pictures of dropped grasps. "
        "About 10 minutes on 2 cores at the default size (--quick: about a minute).",
    )
    ph.add_argument("--out", required=True, type=cli.out_dir, metavar="DIR", help="output folder")
    ph.add_argument(
        "--objects",
        type=object_list,
        metavar="all|NAME,...",
        help="paper objects (default all; with --quick trapezoid,irregular_hexagon)",
    )
    ph.add_argument(
        "--grasps",
        type=cli.integer(1, 10_000),
        metavar="N",
        help="grasps per object and controller, 1..10000 (default 50; with --quick 4)",
    )
    ph.add_argument(
        "--model",
        choices=("planar", "3d", "both"),
        default="planar",
        help="the grasp model the controllers run on: planar (the paper's phi = 0, contacts at "
        "the fingertips' height), 3d (contacts with heights on the prism's sides, in the band a "
        "top grasp reaches) or both, from the same starts. The default, planar, differs from "
        "the task cycle's (fsm.run and experiments.bench run 3d) on purpose: this study "
        "measures the paper's own model and S_G (Eq. 13); --model 3d tests the task cycle's "
        "model, --model both compares the two",
    )
    ph.add_argument(
        "--depth",
        type=cli.number(0.02, 0.15),
        metavar="M",
        help="planar model: take every contact M metres below the block's top instead of at "
        "its fingertip's height, 0.02..0.15 (the probe behind the 3-D band)",
    )
    ph.add_argument(
        "--height-tries",
        type=cli.integer(1, 5),
        default=HEIGHT_TRIES,
        metavar="N",
        help="3-D model: common heights of the contacts the hand tries in turn, best first by "
        f"the worst-task S_G, {HEIGHT_GAP * 1000:g} mm apart, 1..5 (1: only the task's best) "
        "(default %(default)s)",
    )
    ph.add_argument(
        "--hand",
        choices=HANDS,
        default=DEFAULT_HAND,
        help="the hand on the arm: servo (models/hand.xml, position servos) or tendon (the "
        "Utah/MIT hand's tendon drive, models/utah_mit_hand/; its guards read contact forces "
        "estimated from the tendon tensions) (default %(default)s)",
    )
    ph.add_argument(
        "--regrasp",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="a grasp the hand cannot take is synthesized once more by the same controller "
        "from where the hand's best seed posture touches the block (the task cycle's return "
        "to Posture Control, section 5); counted apart in the report; --no-regrasp tests "
        "every grasp only as first synthesized",
    )
    add_perturb_argument(ph, PERTURB_KINDS)
    cli.add_seed_argument(ph)
    cli.add_workers_argument(ph, MAX_WORKERS)
    ph.add_argument("--quick", action="store_true", help="two objects, 4 grasps each (tests)")
    return ph


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit status."""
    return cli.run_command(build_parser, argv, prog=PROG, errors=ERRORS, command=run)
