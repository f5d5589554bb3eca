"""The output folder of a ``reproduce`` run, and when its models may be used.

A run marks its folder unfinished before it writes anything (``results.json`` holds only
``{"run": {"seed": S, "finished": false}}``) and finished as its very last write: ``results.json``
with ``run = {"seed": S, "finished": true, "models": {file: SHA-256}}``. Every file is written
atomically (:mod:`graspsim_base.files`), so an interrupted run leaves the unfinished mark, and
a model file that a later, interrupted run replaced no longer matches the recorded hash.
:func:`check_finished_run` refuses both, saying why.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from controllers.grasp.errors import RunFolderError
from graspsim_base.files import sha256_of, write_text

#: The results file; it carries the run's mark.
RESULTS_FILE = "results.json"
#: The command that trains the models (:mod:`experiments.paper.reproduce`), for the messages.
REPRODUCE_COMMAND = "python -m experiments.paper reproduce"
#: The command that (re)creates a folder, for the messages.
REPRODUCE = f"{REPRODUCE_COMMAND} --out"


#: What to do when a learned controller finds no model (the README's main command).
TRAIN_HINT = (
    f"train the models with `{REPRODUCE} runs/paper` (about 7 minutes on 2 idle cores), "
    "then pass `--models runs/paper`"
)


def _dump(payload: dict) -> str:
    return json.dumps(payload, indent=1, sort_keys=True) + "\n"


def mark_started(out: Path, seed: int) -> None:
    """Mark ``out`` as holding an unfinished run (replaces an earlier run's results file)."""
    write_text(Path(out) / RESULTS_FILE, _dump({"run": {"seed": seed, "finished": False}}))


def finished_mark(out: Path, seed: int, model_files: Sequence[str]) -> dict:
    """The ``run`` entry of a finished run's results: its seed and each model file's hash."""
    return {
        "seed": seed,
        "finished": True,
        "models": {name: sha256_of(Path(out) / name) for name in model_files},
    }


def write_results(out: Path, results: dict) -> None:
    """Write ``results`` (holding a :func:`finished_mark` under ``run``) as the run's last file."""
    write_text(Path(out) / RESULTS_FILE, _dump(results))


def check_finished_run(folder: Path, flag: str = "models") -> int:
    """The seed of the finished run in ``folder``; :class:`RunFolderError` (message starting with
    ``flag``) when the folder holds no run, an unfinished one, or models of another run."""
    folder = Path(folder)
    again = f"run `{REPRODUCE} {folder}` again"
    if not folder.exists():
        raise RunFolderError(
            f"{flag}: there is no folder {str(folder)!r}; run `{REPRODUCE} {folder}` first "
            "(about 7 minutes on 2 idle cores)"
        )
    if not folder.is_dir():
        raise RunFolderError(
            f"{flag}: {str(folder)!r} is not a folder; give the folder of a finished "
            f"`{REPRODUCE} DIR` run"
        )
    results = folder / RESULTS_FILE
    if not results.is_file():
        raise RunFolderError(
            f"{flag}: {folder} holds no reproduce run (no {RESULTS_FILE}); "
            f"run `{REPRODUCE} {folder}` first (about 7 minutes on 2 idle cores)"
        )
    try:
        run = json.loads(results.read_text(encoding="utf-8"))["run"]
        seed, finished = run["seed"], run["finished"]
    except (ValueError, KeyError, TypeError) as e:
        raise RunFolderError(
            f"{flag}: {results} carries no completion mark (not written by a finished run of "
            f"this version: {type(e).__name__} {e}); {again}"
        ) from e
    if finished is not True:
        raise RunFolderError(
            f"{flag}: the reproduce run in {folder} (seed {seed}) did not finish (interrupted, or "
            f"still running); {again}"
        )
    for name, digest in dict(run.get("models", {})).items():
        path = folder / name
        if not path.is_file():
            raise RunFolderError(f"{flag}: {path} is missing from the finished run; {again}")
        if sha256_of(path) != digest:
            raise RunFolderError(
                f"{flag}: {path} was not written by the finished run recorded in {results} "
                f"(seed {seed}): the folder mixes runs; {again}"
            )
    return int(seed)
