"""Command-line plumbing shared by every graspsim command (``controllers.grasp``'s, ``hand_sim``'s,
``vision``'s, ``fsm``'s, the experiments' and the benchmarks'; the simulation's commands reach it
through ``hand_sim.clitools``, which adds the simulation's errors).

The promise each command keeps:
- bad input is one line on stderr, ``<prog>: <flag or field>: <problem and what to do>``, exit
  status 2, and nothing is written. Every number is checked (finite, in range, the range in the
  message) by the argument types below when the command line is parsed, every output path by
  :func:`prepare_dir` / :func:`prepare_file` before any work starts;
- Ctrl-C is one line, ``<prog>: interrupted; partial results in DIR`` (or ``nothing was
  written``), exit status 130; a second Ctrl-C while the command cleans up is ignored;
- result files are written atomically (:mod:`graspsim_base.files`).

Use: ``main(argv)`` builds an :class:`ArgumentParser`, parses, checks paths and runs; the module's
``__main__`` calls ``sys.exit(run_main(lambda: main(argv), prog=PROG, errors=ERRORS))``, or
``main`` itself returns ``run_main(...)`` so that tests can call it in-process.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

EXIT_BAD_INPUT = 2
#: 128 + SIGINT, what shells report for a command stopped by Ctrl-C.
EXIT_INTERRUPTED = 130
#: Seeds are integers 0..SEED_MAX (numpy's SeedSequence takes any non-negative integer; this
#: bound keeps them plain 32-bit values, as most tools print and accept them).
SEED_MAX = 2**32 - 1
#: An option value starting with '-' then a digit or '.digit' is a (negative) number, not an
#: option: ``--points -0.01,0.02;...``, ``--pick-pixel -1,-1`` (argparse alone accepts only a
#: lone negative number such as ``-1`` or ``-0.5``).
NEGATIVE_NUMBER = re.compile(r"^-\.?\d")
#: Errors every command reports as bad input besides :class:`CommandLineError` (a package adds
#: its own: ``controllers.grasp.cli.ERRORS``, ``hand_sim.clitools.ERRORS``...).
ERRORS: tuple[type[BaseException], ...] = ()


class CommandLineError(ValueError):
    """A command-line value that parsed but cannot be used (a path that cannot be written, a
    pixel outside the image...). The message starts with the flag."""

    def __init__(self, flag: str, problem: str) -> None:
        super().__init__(f"{flag}: {problem}")


class Interrupted(KeyboardInterrupt):
    """A Ctrl-C that stopped a command while it was writing results into ``where``."""

    def __init__(self, where: Path) -> None:
        super().__init__(str(where))
        self.where = where


@contextmanager
def partial_results_in(where: str | Path) -> Iterator[None]:
    """Turn a Ctrl-C inside the block into :class:`Interrupted` naming ``where``, so that
    :func:`run_main` can say where the partial results are."""
    try:
        yield
    except Interrupted:
        raise
    except KeyboardInterrupt:
        raise Interrupted(Path(where)) from None


# --- the parser -----------------------------------------------------------------------------


class HelpFormatter(argparse.HelpFormatter):
    """Help lines that end with the default, when there is one worth showing."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        if (
            "%(default)" not in text
            and action.option_strings
            and not any(default is x for x in (None, False, argparse.SUPPRESS))
        ):
            text += " (default: %(default)s)"
        return text


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` with graspsim's conventions: a usage error is one line on stderr
    and exit status 2, defaults are shown in ``--help``, and option values may be negative numbers
    or lists of them (``--pick-pixel -1,-1``). Sub-parsers inherit all of it."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str) -> Any:  # argparse's signature: NoReturn
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: {one_line(message)} (see --help)\n")


def first_paragraph(doc: str | None) -> str:
    """A module docstring's first paragraph on one line: the ``description`` of a parser (its first
    line alone may stop mid-sentence)."""
    return " ".join((doc or "").strip().split("\n\n")[0].split())


def one_line(message: str) -> str:
    """``message`` on a single line (line breaks become '; ')."""
    parts = [p.strip() for p in str(message).splitlines() if p.strip()]
    return "; ".join(parts)


# --- argument types: each refuses with a message naming the valid range -------------------------


def _range_text(lo: float, hi: float, lo_open: bool = False, hi_open: bool = False) -> str:
    if math.isinf(lo) and math.isinf(hi):
        return "a finite number"
    if math.isinf(hi):
        return f"a finite number {'>' if lo_open else '>='} {lo:g}"
    if math.isinf(lo):
        return f"a finite number {'<' if hi_open else '<='} {hi:g}"
    return f"a number in {'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'}"


def integer(lo: int, hi: int) -> Callable[[str], int]:
    """Argument type: an integer in [lo, hi]."""

    def parse(text: str) -> int:
        try:
            value = int(text.strip())
        except ValueError:
            value = None
        if value is None or not lo <= value <= hi:
            raise argparse.ArgumentTypeError(
                f"must be an integer from {lo:,} to {hi:,}, got {text!r}"
            )
        return value

    parse.__name__ = f"integer {lo}..{hi}"
    return parse


def number(
    lo: float = -math.inf, hi: float = math.inf, *, lo_open: bool = False, hi_open: bool = False
) -> Callable[[str], float]:
    """Argument type: a finite number in the range (bounds open or closed)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        ok = (
            math.isfinite(value)
            and (lo < value if lo_open else lo <= value)
            and (value < hi if hi_open else value <= hi)
        )
        if not ok:
            raise argparse.ArgumentTypeError(
                f"must be {_range_text(lo, hi, lo_open, hi_open)}, got {text!r}"
            )
        return value

    parse.__name__ = "number"
    return parse


def numbers(
    count: int | tuple[int, ...], form: str, lo: float = -math.inf, hi: float = math.inf
) -> Callable[[str], tuple[float, ...]]:
    """Argument type: ``count`` comma-separated finite numbers (or any of several counts), each in
    [lo, hi] (``form`` is how the message shows them, e.g. ``'U,V'``)."""
    counts = (count,) if isinstance(count, int) else tuple(count)
    how_many = " or ".join(str(c) for c in counts)

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(float(c) for c in text.split(","))
        except ValueError:
            values = ()
        ok = len(values) in counts and all(math.isfinite(v) and lo <= v <= hi for v in values)
        if not ok:
            bound = "" if math.isinf(lo) and math.isinf(hi) else f" in [{lo:g}, {hi:g}]"
            raise argparse.ArgumentTypeError(
                f"must be {how_many} finite numbers{bound} written {form!r}, got {text!r}"
            )
        return values

    parse.__name__ = form
    return parse


#: Argument type of every ``--seed``.
seed = integer(0, SEED_MAX)


def out_dir(text: str) -> Path:
    """Argument type: an output folder. Refuses an empty name (it would mean the current folder,
    usually an unset shell variable), the root folder and an existing file."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must name a folder, got an empty string")
    path = Path(text).expanduser()
    resolved = path.resolve()
    if resolved == Path(resolved.anchor):
        raise argparse.ArgumentTypeError(
            f"will not write into the root folder {text!r}; give a folder such as runs/demo"
        )
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r} is a file, not a folder")
    return path


def out_file(*suffixes: str) -> Callable[[str], Path]:
    """Argument type: an output file, with one of ``suffixes`` (any when none is given)."""

    def parse(text: str) -> Path:
        if not text.strip():
            raise argparse.ArgumentTypeError("must name a file, got an empty string")
        path = Path(text).expanduser()
        if text.endswith(("/", os.sep)) or path.is_dir():
            raise argparse.ArgumentTypeError(f"{text!r} is a folder; give a file name in it")
        if suffixes and path.suffix.lower() not in suffixes:
            raise argparse.ArgumentTypeError(f"must end in {' or '.join(suffixes)}, got {text!r}")
        return path

    parse.__name__ = "file"
    return parse


# --- output paths, checked before the work starts -------------------------------------------


def prepare_dir(path: Path, flag: str) -> Path:
    """Create the output folder ``path`` (and its parents) and check that a file can be written
    in it; :class:`CommandLineError` naming ``flag`` otherwise."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".graspsim-write-test-")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise CommandLineError(
            flag, f"cannot write into {str(path)!r} ({e.strerror or e}); give a writable folder"
        ) from e
    return path


def prepare_file(path: Path, flag: str) -> Path:
    """Check that the output file ``path`` can be written (its folder is created)."""
    prepare_dir(path.parent, flag)
    return path


# --- running a command ----------------------------------------------------------------------


@contextmanager
def _first_interrupt_only() -> Iterator[None]:
    """The first Ctrl-C raises KeyboardInterrupt; later ones are ignored while the command unwinds
    (closing a recording, removing temporary files). Nothing changes when SIGINT is not Python's
    default handler (ignored by the caller, or handled by someone else) or off the main thread."""
    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGINT) is not signal.default_int_handler
    ):
        yield
        return

    def on_sigint(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _say(prog: str, message: str) -> None:
    print(f"{prog}: {one_line(message)}", file=sys.stderr, flush=True)


def run_main(
    body: Callable[[], int | None],
    *,
    prog: str,
    errors: Sequence[type[BaseException]] = ERRORS,
) -> int:
    """Run a command's ``body`` and return its exit status: the body's (0 for None), 2 with one
    line on stderr for :class:`CommandLineError` and ``errors`` (the package's expected errors),
    argparse's status for ``--help`` (0) and usage errors (2), 130 with one line for Ctrl-C."""
    expected = (CommandLineError, *errors)
    with _first_interrupt_only():
        try:
            return int(body() or 0)
        except SystemExit as e:  # argparse: --help, or a usage error it has printed already
            if e.code is None:
                return 0
            return e.code if isinstance(e.code, int) else EXIT_BAD_INPUT
        except Interrupted as e:
            _say(prog, f"interrupted; partial results in {e.where}")
            return EXIT_INTERRUPTED
        except KeyboardInterrupt:
            _say(prog, "interrupted; nothing was written")
            return EXIT_INTERRUPTED
        except expected as e:
            _say(prog, str(e) or type(e).__name__)
            return EXIT_BAD_INPUT


def run_command(
    build_parser: Callable[[], ArgumentParser],
    argv: Sequence[str] | None,
    *,
    prog: str,
    errors: Sequence[type[BaseException]] = ERRORS,
    command: Callable[[argparse.Namespace], int | None] | None = None,
) -> int:
    """:func:`run_main` of a command whose parser ``build_parser`` makes: parse ``argv`` (default
    ``sys.argv[1:]``), keep it as ``args.argv`` (the command line, for the records a run writes)
    and run ``command(args)`` (default ``args.func``, the sub-command's, set by
    ``set_defaults(func=...)``)."""

    def body() -> int | None:
        args = build_parser().parse_args(argv)
        args.argv = " ".join(sys.argv[1:] if argv is None else argv)
        return (command or args.func)(args)

    return run_main(body, prog=prog, errors=errors)


# --- arguments several commands share ---------------------------------------------------------


def add_seed_argument(parser: argparse.ArgumentParser) -> None:
    """``--seed``: the random seed, 0..SEED_MAX, default 0."""
    parser.add_argument("--seed", type=seed, default=0, help=f"random seed, 0..{SEED_MAX}")


def add_workers_argument(parser: argparse.ArgumentParser, most: int) -> None:
    """``--workers``: worker processes, 1..``most``, default 2 (the cores of a small machine)."""
    parser.add_argument(
        "--workers", type=integer(1, most), default=2, help=f"worker processes, 1..{most}"
    )


def add_json_argument(parser: argparse.ArgumentParser, help_text: str) -> None:
    """``--json FILE``: a JSON file the results are written to (``help_text`` says which)."""
    parser.add_argument("--json", type=out_file(".json"), metavar="FILE", help=help_text)


def command_parser(
    prog: str, description: str
) -> tuple[ArgumentParser, argparse._SubParsersAction[ArgumentParser]]:
    """The parser of a command with sub-commands, and the sub-parsers to add them to
    (:func:`add_command`); its description ends with how to see a sub-command's flags and what
    bad input and Ctrl-C do."""
    parser = ArgumentParser(
        prog=prog,
        description=f"{description} `{prog} COMMAND --help` shows a command's flags. Bad input "
        "is one line on stderr and exit status 2; Ctrl-C stops with exit status 130.",
    )
    return parser, parser.add_subparsers(dest="command", required=True, metavar="COMMAND")


def add_command(
    commands: argparse._SubParsersAction[ArgumentParser],
    name: str,
    help_text: str,
    description: str | None = None,
) -> ArgumentParser:
    """Sub-command ``name``: ``help_text`` in the command list, and as its ``--help``
    description unless ``description`` is given."""
    return commands.add_parser(name, help=help_text, description=description or help_text)
