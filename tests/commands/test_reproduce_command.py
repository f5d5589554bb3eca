"""The command that trains the models is named right wherever a user reads it: in every file the
repository ships (packages, README, docs, the shipped models' provenance) and in every command's
``--help``. The models are trained by ``python -m experiments.paper reproduce``; the grasp core's
own command (``python -m controllers.grasp``) has no ``reproduce``."""

from __future__ import annotations

import contextlib
import importlib
import io
import re
import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest

from controllers.grasp.run_folder import REPRODUCE, REPRODUCE_COMMAND, TRAIN_HINT
from experiments.paper.cli import PROG as PAPER_PROG

ROOT = Path(__file__).resolve().parents[2]
#: The wrong command, spelled in two pieces so that this file does not hold it.
WRONG = "controllers.grasp" + " reproduce"
#: Folders that are not shipped: tooling, caches, build output, runs and the tests themselves.
NOT_SHIPPED = {".git", ".venv", "__pycache__", "build", "out", "runs", "tests", ".ruff_cache"}
TEXT_SUFFIXES = {".py", ".md", ".json", ".toml", ".txt", ".cff", ".cfg", ".in", ".xml", ".yaml"}


def shipped_text_files() -> list[Path]:
    files = []
    for path in ROOT.rglob("*"):
        rel = path.relative_to(ROOT).parts
        if any(p in NOT_SHIPPED or p.endswith(".egg-info") for p in rel):
            continue
        if path.is_file() and (path.suffix in TEXT_SUFFIXES or path.name == "LICENSE"):
            files.append(path)
    return files


def entry_points() -> dict[str, Callable[[list[str]], int]]:
    """Every console script of pyproject.toml, by name, as its ``main(argv)``."""
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    mains = {}
    for name, target in scripts.items():
        module, func = target.split(":")
        mains[name] = getattr(importlib.import_module(module), func)
    return mains


def help_text(main: Callable[[list[str]], int], argv: list[str]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main([*argv, "--help"]) == 0
    return out.getvalue()


def subcommands(text: str) -> list[str]:
    """The sub-commands a ``COMMAND ...`` help lists (one per line, indented under COMMAND)."""
    if "COMMAND ..." not in text:
        return []
    block = text.split("\n  COMMAND\n", 1)[1].split("\n\n", 1)[0]
    return re.findall(r"^    (\w+)\s", block, flags=re.MULTILINE)


def test_the_messages_name_the_paper_command() -> None:
    assert f"{PAPER_PROG} reproduce" == REPRODUCE_COMMAND
    assert REPRODUCE.startswith(REPRODUCE_COMMAND) and REPRODUCE_COMMAND in TRAIN_HINT


def test_no_shipped_file_names_the_wrong_command() -> None:
    files = shipped_text_files()
    assert any(p.name == "provenance.json" for p in files)  # the shipped models' provenance
    found = [
        str(p.relative_to(ROOT))
        for p in files
        if WRONG in p.read_text(encoding="utf-8", errors="replace")
    ]
    assert found == []


@pytest.mark.parametrize("name", sorted(entry_points()))
def test_no_help_names_the_wrong_command(name: str) -> None:
    main = entry_points()[name]
    top = help_text(main, [])
    texts = [top, *(help_text(main, [sub]) for sub in subcommands(top))]
    wrong = [t.splitlines()[0] for t in texts if WRONG in " ".join(t.split())]  # help wraps
    assert wrong == []
