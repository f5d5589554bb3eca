"""One episode of ``python -m experiments.bench`` as a job a worker runs, and the results file it
feeds.

A :class:`Job` is everything a worker needs to run one episode (section 5.2's task cycle, one
pick and place); :func:`run_job` runs it in a temporary folder and returns the episode's summary
as a ``results.jsonl`` line, with the recording's bytes when the bench keeps it. Nothing is shared
between jobs but what they return: a worker on this machine, another process or a Ray node
produce the same line for the same job, and the bench (the only writer) appends it.

The number of blocks of a random scene is drawn per seed by :func:`blocks_for_seed`, from the
seed alone, so that it does not depend on which worker runs the seed or in what order.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import tempfile
import traceback
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from hand_sim.errors import HandSimError

#: Second word of the seed sequence the block count is drawn from (any fixed number would do; it
#: keeps the draw apart from the scene generator's own stream, which is seeded by the seed alone).
BLOCKS_STREAM = 12
#: ``failure`` of an episode that raised an unexpected exception (a bug, not a named reason).
CRASHED = "episode crashed"
#: Name of the results file in the bench folder, and of the kept recordings' folder.
RESULTS_FILE = "results.jsonl"
RRD_DIR = "rrd"


class BenchError(HandSimError):
    """The bench folder cannot be used as asked (a results file that is not ours, or is
    corrupt); reported as bad input."""


def blocks_for_seed(seed: int, low: int, high: int) -> int:
    """Number of blocks of the random scene of ``seed`` when the bench asks for ``low``..``high``
    (both included): ``numpy.random.default_rng([seed, BLOCKS_STREAM]).integers(low, high + 1)``,
    or ``low`` when the range holds one value. Every count is equally likely and the same seed
    always gets the same count, whoever runs it."""
    if low == high:
        return low
    rng = np.random.default_rng([seed, BLOCKS_STREAM])
    return int(rng.integers(low, high + 1))


@dataclass(frozen=True)
class Job:
    """One episode to run (the options of ``python -m fsm.run`` the bench varies)."""

    seed: int
    scene: str = "random"
    blocks: int | None = None  #: blocks of a random scene (None: the generator's default)
    controller: str = "pi"
    approach: str = "auto"
    #: "planar" or "3d" (fsm.run --model); None: fsm.run's default
    grasp_model: str | None = None
    models: str | None = None  #: trained models folder (None: the shipped ones)
    keep_rrd: bool = False  #: return the recording of a success too
    cycles: int | None = 1  #: blocks picked one after another (None: clear the table)
    place_fallback: str = "none"  #: as fsm.run's --place-fallback
    hand: str = "tendon"  #: as fsm.run's --hand
    lateral_gate: float = 0.4  #: as fsm.run's --lateral-gate
    lateral_gate_rule: str = "opposition"  #: as fsm.run's --lateral-gate-rule
    #: as fsm.run's --perturb (None: the scene file's [perturb] table, if any)
    perturb: str | None = None


@dataclass(frozen=True)
class JobResult:
    """What a worker sends back: the results line and, when it is kept, the recording."""

    seed: int
    line: dict[str, Any] = field(default_factory=dict)
    rrd: bytes | None = None


def rrd_name(seed: int) -> str:
    """Path, relative to the bench folder, of seed ``seed``'s kept recording."""
    return f"{RRD_DIR}/seed-{seed:06d}.rrd"


def _limit_threads(controller: str) -> None:
    """One core per episode: the pool runs one episode per core, so torch, if something in the
    worker has imported it, must not start a thread per core (an episode itself does not import
    it: the pre-imaging controller evaluates its trained predictor in numpy)."""
    torch = sys.modules.get("torch")
    if controller == "pi" and torch is not None:
        torch.set_num_threads(1)


#: Fields of two runs of one job that must agree for a replay to be the same episode.
SAME_EPISODE = ("success", "failure", "failure_detail", "sim_time", "cycles")


def run_job(job: Job) -> JobResult:
    """Run ``job``'s episode (in a temporary folder) and return its ``results.jsonl`` line: the
    episode's ``summary.json`` plus ``seed`` and ``blocks`` (the scene's block count).
    ``options.out`` is null (the folder is gone) and ``rrd`` names the kept recording, if any.

    The episode runs without recording unless ``job.keep_rrd`` (recording every episode costs
    about a quarter of its wall time, docs/bench.md); a failed one is then run again, recorded,
    for its ``.rrd`` (an episode is a function of its seed and options, and the recording does
    not touch the physics). The line is the first run's; ``replay`` says whether the recorded
    run ended the same (:data:`SAME_EPISODE`), and its summary is kept under ``replay`` when not.

    An exception other than Ctrl-C outside the task cycle's states (the episode names any inside
    them) does not stop the bench: the line then says ``failure = "episode crashed"`` with the
    exception in ``failure_detail`` and ``traceback``."""
    from fsm.layout import episode_scene

    n_blocks: int | None = job.blocks
    with contextlib.suppress(Exception):  # the episode's own run reports it
        n_blocks = len(episode_scene(job.scene, job.seed, job.blocks).blocks)
    summary, rrd = _episode(job, record=job.keep_rrd)
    if not summary["success"] and rrd is None:
        again, rrd = _episode(job, record=True)
        same = all(again.get(k) == summary.get(k) for k in SAME_EPISODE)
        summary["replay"] = {"recorded": rrd is not None, "same": same}
        if not same:
            summary["replay"]["summary"] = again
    keep = rrd is not None and (job.keep_rrd or not summary["success"])
    summary["rrd"] = rrd_name(job.seed) if keep else None
    line = {"seed": job.seed, "blocks": n_blocks, **summary}
    return JobResult(job.seed, line, rrd if keep else None)


def _episode(job: Job, *, record: bool) -> tuple[dict[str, Any], bytes | None]:
    """One run of ``job``'s episode in a temporary folder: its summary (with the options the
    bench varies) and, when ``record`` and it was written, its recording's bytes."""
    from fsm.config import DEFAULT_CONFIG
    from fsm.context import DEFAULT_GRASP_MODEL, EpisodeOptions, out_paths
    from fsm.machine import run_episode

    with tempfile.TemporaryDirectory(prefix="graspsim-bench-") as tmp:
        options = EpisodeOptions(
            scene=job.scene,
            seed=job.seed,
            blocks=job.blocks,
            controller=job.controller,
            approach=job.approach,
            grasp_model=job.grasp_model or DEFAULT_GRASP_MODEL,
            cycles=job.cycles,
            place_fallback=job.place_fallback,
            out=Path(tmp),
            record=record,
            models=None if job.models is None else Path(job.models),
            hand=job.hand,
            config=replace(
                DEFAULT_CONFIG,
                lateral_gate=job.lateral_gate,
                lateral_gate_rule=job.lateral_gate_rule,
            ),
            perturb=job.perturb,
        )
        rrd_path, summary_path = out_paths(options.out)
        extra: dict[str, Any] = {}
        try:
            _limit_threads(job.controller)
            run_episode(options)
        except Exception as e:  # any bug of one episode must not stop the bench
            detail = "".join(traceback.format_exception_only(type(e), e)).strip()
            extra = {
                "success": False,
                "failure": CRASHED,
                "failure_detail": detail,
                "traceback": "".join(traceback.format_exception(e)),
            }
        if summary_path.is_file():
            summary = json.loads(summary_path.read_text())
        else:  # failed before the episode started (the scene could not be drawn)
            summary = {"visits": [], "cycles": [], "sim_time": 0.0, "wall_time": 0.0}
        summary.update(extra)
        summary.setdefault("options", {}).update(
            {"scene": job.scene, "seed": job.seed, "controller": job.controller, "out": None}
        )
        rrd = rrd_path.read_bytes() if record and rrd_path.is_file() else None
        return summary, rrd


# --- results.jsonl ----------------------------------------------------------------------------


def append_line(path: Path, record: dict[str, Any]) -> None:
    """Append ``record`` as one JSON line to ``path`` with a single ``write`` on a file opened
    for appending, then flush it to disk: a reader sees the whole line or none of it (a process
    killed in the middle of the write leaves at most a final line without its newline, which
    :func:`read_results` ignores and :func:`drop_torn_tail` removes)."""
    data = (json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n").encode()
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view) :]
        os.fsync(fd)
    finally:
        os.close(fd)


def read_results(path: Path) -> list[dict[str, Any]]:
    """The lines of a results file, in file order; a final line without its newline (torn by a
    kill) is left out. :class:`BenchError` for any other line that is not a JSON object with an
    integer ``seed``."""
    if not path.is_file():
        return []
    text = path.read_text(encoding="utf-8")
    complete = text[: text.rfind("\n") + 1]
    out = []
    for number, raw in enumerate(complete.splitlines(), start=1):
        if not raw.strip():
            continue
        try:
            record = json.loads(raw)
        except json.JSONDecodeError:
            record = None
        if not isinstance(record, dict) or not isinstance(record.get("seed"), int):
            raise BenchError(
                f"{path}: line {number} is not an episode's results line; remove it, or give "
                "another --out"
            )
        out.append(record)
    return out


def without_wall_times(line: dict[str, Any]) -> dict[str, Any]:
    """A results line with what depends on the machine's load taken out."""
    out = json.loads(json.dumps(line))
    out.pop("wall_time")
    for v in out["visits"]:
        v.pop("wall_seconds")
    return out


def drop_torn_tail(path: Path) -> bool:
    """Cut a final line without its newline off ``path`` (left by a process killed while it
    appended), so that the next line starts on a line of its own. True when something was cut."""
    if not path.is_file():
        return False
    data = path.read_bytes()
    if not data or data.endswith(b"\n"):
        return False
    with open(path, "r+b") as f:
        f.truncate(data.rfind(b"\n") + 1)
    return True
