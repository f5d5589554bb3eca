"""Command-line plumbing of ``hand_sim`` and of every command built on it (``hand_sim.show``, the
benchmarks, ``vision``, ``fsm.run``): the shared toolkit of :mod:`graspsim_base.cli`
(one-line errors with exit status 2, Ctrl-C as one line with exit status 130, checked numbers and
output paths) and the errors a ``hand_sim`` command reports as bad input.

A command looks like this::

    PROG = "python -m hand_sim.show"

    def run(argv):
        p = ArgumentParser(prog=PROG, description=first_paragraph(__doc__))
        p.add_argument("--seed", type=seed, default=0, help="random seed")
        p.add_argument("--out", type=out_dir, required=True, help="output folder")
        args = p.parse_args(argv)
        prepare_dir(args.out, "--out")          # before any work
        with partial_results_in(args.out):      # Ctrl-C: "interrupted; partial results in DIR"
            ...
        return 0

    def main(argv=None):
        return run_main(lambda: run(argv), prog=PROG, errors=ERRORS)
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from controllers.grasp.errors import GraspError
from graspsim_base.cli import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    SEED_MAX,
    ArgumentParser,
    CommandLineError,
    Interrupted,
    add_json_argument,
    add_seed_argument,
    add_workers_argument,
    first_paragraph,
    integer,
    number,
    numbers,
    one_line,
    out_dir,
    out_file,
    partial_results_in,
    prepare_dir,
    prepare_file,
    run_command,
    run_main,
    seed,
)
from hand_sim.assembly import MAX_RENDER_HEIGHT, MAX_RENDER_WIDTH
from hand_sim.errors import HandSimError
from hand_sim.perturb import KINDS, MAX_SCALE, NAMES, NONE, WOES, PerturbError, PerturbSpec
from hand_sim.random_scene import MAX_RANDOM_BLOCKS
from hand_sim.scene import RANDOM_SCENE, Scene
from hand_sim.scene_seed import episode_scene

#: Errors a hand_sim command reports as bad input (scene files, scene names, image sizes, a
#: simulation that went wrong, and the polygons scenes are made of).
ERRORS: tuple[type[BaseException], ...] = (HandSimError, GraspError)

#: Argument types of an image's width and height (pixels), within what hand_sim renders.
image_width = integer(16, MAX_RENDER_WIDTH)
image_height = integer(16, MAX_RENDER_HEIGHT)


def add_scene_arguments(parser: argparse.ArgumentParser, scene_help: str, blocks_help: str) -> None:
    """``--scene`` (default clutter3), ``--seed`` (default 0) and, for ``--scene random`` only,
    ``--blocks`` (default None: the random scene's own; :func:`check_scene_arguments` refuses it
    with another scene). The seed picks the layout as ``python -m fsm.run`` does
    (:func:`scene_from_arguments`). ``blocks_help`` starts the help of ``--blocks``."""
    parser.add_argument("--scene", default="clutter3", help=scene_help)
    parser.add_argument(
        "--seed",
        type=seed,
        default=0,
        help=f"draws --scene random; jitters a scene file's block poses when > 0 (the layout "
        f"`python -m fsm.run` runs for the same --scene and --seed), 0..{SEED_MAX}",
    )
    parser.add_argument(
        "--blocks",
        type=integer(1, MAX_RANDOM_BLOCKS),
        default=None,
        help=f"{blocks_help} of --scene random, 1..{MAX_RANDOM_BLOCKS} (default 3)",
    )


def check_scene_arguments(args: argparse.Namespace) -> None:
    """Refuse ``--blocks`` (:func:`add_scene_arguments`) with a scene other than ``random``."""
    if args.scene != RANDOM_SCENE and args.blocks is not None:
        raise CommandLineError(
            "--blocks", f"applies to --scene {RANDOM_SCENE} only, not to {args.scene!r}"
        )


def scene_from_arguments(args: argparse.Namespace) -> Scene:
    """The scene of ``--scene``, ``--seed`` and ``--blocks``: the layout ``python -m fsm.run``
    runs for them (:func:`hand_sim.scene_seed.episode_scene`)."""
    return episode_scene(args.scene, args.seed, args.blocks)


def perturbation(kinds: tuple[str, ...] = KINDS) -> Callable[[str], str]:
    """Argument type of ``--perturb NAME[=SCALE],...`` (:mod:`hand_sim.perturb`) allowing the
    perturbations ``kinds`` (``woes`` only when all are allowed): the checked value, written as
    :meth:`~hand_sim.perturb.PerturbSpec.text` writes it (``none`` when nothing is perturbed)."""
    names = (*kinds, WOES) if set(kinds) == set(KINDS) else kinds
    valid = f"valid: {', '.join(names)} (NAME or NAME=SCALE, SCALE 0..{MAX_SCALE:g}), or {NONE}"

    def parse(text: str) -> str:
        for part in text.split(","):
            name = part.partition("=")[0].strip()
            if name and name != NONE and name not in names:
                where = "" if name not in NAMES else " for this command"
                raise argparse.ArgumentTypeError(f"unknown perturbation {name!r}{where}; {valid}")
        try:
            return PerturbSpec.parse(text).text()
        except PerturbError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    return parse


def add_perturb_argument(parser: argparse.ArgumentParser, kinds: tuple[str, ...] = KINDS) -> None:
    """``--perturb NAME[=SCALE],...`` (perturbations ``kinds`` and, when all are allowed,
    ``woes``), default None: the scene file's ``[perturb]`` table."""
    names = ", ".join((*kinds, WOES) if set(kinds) == set(KINDS) else kinds)
    parser.add_argument(
        "--perturb",
        type=perturbation(kinds),
        default=None,
        metavar="NAME[=SCALE],...",
        help=f"make the simulated world differ from what the robot believes (section 5.3's "
        f"woes; docs/robustness.md), drawn from --seed: NAME one of {names}; SCALE "
        f"0..{MAX_SCALE:g} multiplies its magnitudes (1 when left out); none: unperturbed "
        "(default: a scene file's [perturb] table; random scenes are unperturbed)",
    )


def add_image_size_arguments(
    parser: argparse.ArgumentParser,
    what: str,
    width: int = MAX_RENDER_WIDTH,
    height: int = MAX_RENDER_HEIGHT,
) -> None:
    """``--width`` and ``--height`` (pixels, 16 up to what hand_sim renders, default ``width``
    x ``height``) of the image ``what`` names."""
    parser.add_argument(
        "--width",
        type=image_width,
        default=width,
        help=f"{what} width, pixels, 16..{MAX_RENDER_WIDTH}",
    )
    parser.add_argument(
        "--height",
        type=image_height,
        default=height,
        help=f"{what} height, pixels, 16..{MAX_RENDER_HEIGHT}",
    )


__all__ = [
    "ERRORS",
    "EXIT_BAD_INPUT",
    "EXIT_INTERRUPTED",
    "SEED_MAX",
    "ArgumentParser",
    "CommandLineError",
    "Interrupted",
    "add_image_size_arguments",
    "add_json_argument",
    "add_perturb_argument",
    "add_scene_arguments",
    "add_seed_argument",
    "add_workers_argument",
    "check_scene_arguments",
    "first_paragraph",
    "image_height",
    "image_width",
    "integer",
    "number",
    "numbers",
    "one_line",
    "out_dir",
    "out_file",
    "partial_results_in",
    "perturbation",
    "prepare_dir",
    "prepare_file",
    "run_command",
    "run_main",
    "scene_from_arguments",
    "seed",
]
