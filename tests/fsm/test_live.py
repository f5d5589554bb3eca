"""The live rerun stream of an episode (``fsm.run --live`` / ``--connect``, :mod:`fsm.live`): the
recording written with a viewer attached is the one written without, the viewer receives what
the file holds, and the addresses are checked before any work starts. The viewer is rerun's own
(``rerun --save FILE``: headless, it writes what it receives)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from rerun.chunk import RrdReader

from fsm.live import listen_port
from fsm.recording import EpisodeRecorder
from fsm.run import main
from hand_sim.recorder import read_recording
from hand_sim.scene import load_scene
from hand_sim.world import World
from tests.fsm.clutter3 import shared_clutter3_run

#: A viewer stopped by the test leaves its file without rerun's footer (read all the same).
pytestmark = pytest.mark.filterwarnings("ignore:RRD file has no footer")
RERUN = Path(sys.executable).with_name("rerun")
#: Seconds a viewer gets to receive a whole recording.
VIEWER_TIMEOUT = 120.0


def free_port() -> int:
    return listen_port("127.0.0.1", 0, "--port")


def events(path: Path) -> list[str]:
    """The text events of a recording, in order."""
    out = []
    with warnings.catch_warnings():  # a viewer's file is read while it writes it: no footer yet
        warnings.simplefilter("ignore")
        chunks = list(RrdReader(str(path)).stream().to_chunks())
    for chunk in chunks:
        if chunk.entity_path == "/events":
            batch = chunk.to_record_batch()
            column = next(n for n in batch.schema.names if n.endswith(":text"))
            out += [row[0] for row in batch.column(column).to_pylist()]
    return out


@contextmanager
def viewer(save: Path, *url: str) -> Iterator[subprocess.Popen]:
    """A headless rerun viewer writing what it receives into ``save``: connected to ``url``,
    or, without one, listening on a port of its own (``rerun --save`` ends only when told)."""
    port = free_port()
    process = subprocess.Popen(
        [str(RERUN), *url, "--save", str(save), "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # the script runs the viewer's binary as its child: end both
    )
    process.port = port
    try:
        yield process
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGTERM)
        process.wait(30)


def wait_listening(port: int) -> None:
    """Wait until something listens on ``port`` of this machine."""
    deadline = time.monotonic() + VIEWER_TIMEOUT
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            assert time.monotonic() < deadline, f"nothing listens on port {port}"
            time.sleep(0.1)


def wait_for_events(path: Path, expected: list[str]) -> None:
    """Wait until the viewer's file ``path`` holds the ``expected`` events."""
    deadline = time.monotonic() + VIEWER_TIMEOUT
    got: list[str] = []
    while time.monotonic() < deadline:
        try:
            got = events(path) if path.exists() else []
        except (OSError, ValueError, RuntimeError):  # a file still being written
            got = []
        if got == expected:
            return
        time.sleep(0.2)
    raise AssertionError(f"the viewer received {len(got)} of {len(expected)} events")


def record(path: Path, live: object | None = None) -> None:
    """A stand-in episode on clutter3: the arm's world stepping with the recorder ticking, a
    transition and a verdict."""
    world = World.build(load_scene("clutter3"))
    with EpisodeRecorder(path, world, live=live) as rec:
        world.on_step = rec.tick
        rec.set_target("pentagon")
        for k in range(40):
            world.step(25)
            if k == 20:
                rec.log_transition("Select/Model", "Coarse Reach", "picked pentagon")
        rec.log_verdict(True, "delivered")


def test_a_viewer_gets_what_the_file_holds_and_the_file_is_the_same_without_it(
    tmp_path: Path,
) -> None:
    import rerun as rr

    record(tmp_path / "alone.rrd")
    with viewer(tmp_path / "viewer.rrd") as v:
        wait_listening(v.port)
        record(tmp_path / "live.rrd", rr.GrpcSink(f"rerun+http://127.0.0.1:{v.port}/proxy"))
        expected = events(tmp_path / "live.rrd")
        assert expected[-1] == "SUCCESS: delivered"
        wait_for_events(tmp_path / "viewer.rrd", expected)
    alone = read_recording(tmp_path / "alone.rrd")
    assert read_recording(tmp_path / "live.rrd") == alone
    assert read_recording(tmp_path / "viewer.rrd") == alone
    assert events(tmp_path / "alone.rrd") == expected


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--live", "--no-record"], "--live: streams the recording"),
        (["--connect", "1"], "--connect: no viewer listens at rerun+http://127.0.0.1:1/proxy"),
        (["--connect", "http://127.0.0.1:9/proxy"], "--connect: must be a viewer's URL"),
        (["--connect", "rerun+http://127.0.0.1:9/x"], "the URL's path must be /proxy"),
        (["--live", "99999"], "--live"),
        (["--live", "1", "--connect", "9"], "not allowed with"),
    ],
)
def test_bad_live_flags_are_one_line_and_exit_2(argv, message, tmp_path: Path, capsys) -> None:
    code = main(["--scene", "clutter3", "--out", str(tmp_path / "o"), *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and message in err[0], err
    assert not (tmp_path / "o").exists()


def test_a_live_port_in_use_is_refused(tmp_path: Path, capsys) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code = main(["--scene", "clutter3", "--out", str(tmp_path / "o"), "--live", str(port)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and f"--live: cannot listen on 127.0.0.1:{port}" in err[0]


@pytest.mark.e2e
def test_fsm_run_live_serves_the_episode_to_a_viewer_and_writes_the_same_rrd(
    tmp_path: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    """clutter3 with ``--live`` and a viewer attached: the viewer receives the whole recording,
    and the ``.rrd`` holds the same entities, rows and transitions as the episode without."""
    out = tmp_path / "live"
    cmd = [sys.executable, "-m", "fsm.run", "--scene", "clutter3", "--controller", "pi"]
    env = {**os.environ, "MUJOCO_GL": "egl", "PYTHONUNBUFFERED": "1"}
    run = subprocess.Popen(
        [*cmd, "--live", "0", "--out", str(out)], stdout=subprocess.PIPE, text=True, env=env
    )
    line = run.stdout.readline()
    assert line.startswith("live: the recording is served rerun+http://127.0.0.1:"), line
    url = line.split()[5].rstrip(";")
    assert line.strip().endswith(f"open it with: rerun --connect {url}")
    wait_listening(int(url.rsplit(":", 1)[1].split("/")[0]))  # served once the world is built
    with viewer(tmp_path / "viewer.rrd", url):
        rest = run.stdout.read()
        assert run.wait(600) == 0, rest
        expected = events(out / "episode.rrd")
        wait_for_events(tmp_path / "viewer.rrd", expected)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["success"]
    remaining = iter(expected)  # every transition of the summary, in order, as an event
    assert all(any(e == t for e in remaining) for t in summary["transitions"])
    live = read_recording(out / "episode.rrd")
    assert read_recording(tmp_path / "viewer.rrd") == live
    without, code = shared_clutter3_run(tmp_path_factory)
    assert code == 0
    assert live == read_recording(without / "episode.rrd")
    assert expected == events(without / "episode.rrd")
