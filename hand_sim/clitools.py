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

from controllers.grasp.errors import GraspError
from graspsim_base.cli import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    SEED_MAX,
    ArgumentParser,
    CommandLineError,
    Interrupted,
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
    run_main,
    seed,
)
from hand_sim.assembly import MAX_RENDER_HEIGHT, MAX_RENDER_WIDTH
from hand_sim.errors import HandSimError

#: Errors a hand_sim command reports as bad input (scene files, scene names, image sizes, a
#: simulation that went wrong, and the polygons scenes are made of).
ERRORS: tuple[type[BaseException], ...] = (HandSimError, GraspError)

#: Argument types of an image's width and height (pixels), within what hand_sim renders.
image_width = integer(16, MAX_RENDER_WIDTH)
image_height = integer(16, MAX_RENDER_HEIGHT)

__all__ = [
    "ERRORS",
    "EXIT_BAD_INPUT",
    "EXIT_INTERRUPTED",
    "SEED_MAX",
    "ArgumentParser",
    "CommandLineError",
    "Interrupted",
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
    "prepare_dir",
    "prepare_file",
    "run_main",
    "seed",
]
