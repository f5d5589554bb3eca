"""Ctrl-C keeps the promise too (issue 10): one line on stderr, exit status 130, and no
half-written file that a later command would accept."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from rerun.chunk import RrdReader

from controllers.grasp import cli as grasp_cli
from experiments.paper.reproduce import reproduce
from hand_sim import show
from hand_sim.recorder import read_recording
from tests.experiments.tiny_reproduce import tiny_config

PAPER = [sys.executable, "-m", "experiments.paper"]
TINY = tiny_config((1,))


def _default_sigint() -> None:
    """In the child: Ctrl-C handled as a terminal would deliver it, even when this test runs in
    a process that ignores SIGINT (a background job), which the child would inherit."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.e2e  # two whole experiment runs: one finished, one interrupted
def test_sigint_on_reproduce_leaves_no_run_that_trials_would_accept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    reproduce(out, TINY, progress=lambda _: None)  # an earlier, finished run
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    p = subprocess.Popen(
        [*PAPER, "reproduce", "--quick", "--seeds", "2", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MUJOCO_GL": "egl"},
        preexec_fn=_default_sigint,
    )
    lines = []
    assert p.stderr is not None
    for line in p.stderr:  # the first task of the pool is done, the others are not
        lines.append(line)
        if " done in " in line:
            p.send_signal(signal.SIGINT)
            break
    rest, _ = p.stderr.read(), p.wait(timeout=120)
    lines += rest.splitlines(keepends=True)
    assert p.returncode == 130, "".join(lines)
    assert "Traceback" not in "".join(lines)
    assert (
        lines[-1].strip() == f"python -m experiments.paper: interrupted; partial results in {out}"
    )
    assert p.stdout is not None and p.stdout.read() == ""
    # no temporary file is left; the seed-1 models left in the folder are refused as a run
    assert not [q.name for q in out.iterdir() if q.name.startswith(".")]
    assert json.loads((out / "results.json").read_text()) == {"run": {"seed": 2, "finished": False}}
    assert (out / "ql_q.npy").read_bytes() == before["ql_q.npy"]  # models come last
    for ctrl in ("ql", "pi"):  # in-process: the same command as a later shell call
        argv = ["trials", "--controller", ctrl, "--models", str(out), "--trials", "5"]
        assert grasp_cli.main(argv) == 2
        r = capsys.readouterr()
        assert r.out == "" and r.err.count("\n") == 1 and "(seed 2) did not finish" in r.err


def test_interrupted_show_closes_its_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    segments = []
    real = show.run_segment

    def interrupted_segment(*args, **kwargs) -> None:
        segments.append(1)
        if len(segments) == 2:
            raise KeyboardInterrupt
        real(*args, **kwargs)

    monkeypatch.setattr(show, "run_segment", interrupted_segment)
    out = tmp_path / "demo"
    assert show.main(["--out", str(out), "--width", "160", "--height", "120"]) == 130
    captured = capsys.readouterr()
    assert captured.err == f"python -m hand_sim.show: interrupted; partial results in {out}\n"
    assert captured.out == ""
    assert sorted(p.name for p in out.iterdir()) == ["episode.rrd", "overhead.png"]
    got = read_recording(out / "episode.rrd")  # complete and readable
    assert got["/images/overhead"]["EncodedImage:blob"] == 1
    events = [
        text[0]
        for chunk in RrdReader(str(out / "episode.rrd")).stream().to_chunks()
        if chunk.entity_path == "/events"
        for text in chunk.to_record_batch().column("TextLog:text").to_pylist()
    ]
    assert len(events) == 4  # the scene, moves 1 and 2, and the interruption as an ERROR event
    assert sum(e.startswith("move 2/") for e in events) == 1
    assert sum(e.startswith("episode raised KeyboardInterrupt") for e in events) == 1


def test_interrupted_trials_writes_no_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(grasp_cli, "run_trials", interrupted)
    target = tmp_path / "r.json"
    assert grasp_cli.main(["trials", "--json", str(target)]) == 130
    assert (
        capsys.readouterr().err == "python -m controllers.grasp: interrupted; nothing was written\n"
    )
    assert list(tmp_path.iterdir()) == []
