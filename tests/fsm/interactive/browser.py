"""A served interactive run (``python -m fsm.interactive`` as a process) and a real browser on its
page: headless Chromium (Debian's ``chromium`` package) driven by Playwright, never a browser
Playwright downloads. Without the binary the browser tests are skipped, except in CI (``CI``
set), where ``.ci/run`` installs it and its absence is a failure."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from fsm.layout import episode_scene
from hand_sim.world import World
from vision import DEFAULT_HEIGHT, DEFAULT_WIDTH, CameraGeometry, overhead_camera
from vision.observation import geometry_of

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--headless=new",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
#: Seconds of wall time allowed for a served run to print its address, and for a cycle.
START_TIMEOUT = 120.0
CYCLE_TIMEOUT = 600.0


def need_chromium() -> None:
    """Skip without Debian's chromium (fail in CI, which installs it)."""
    if Path(CHROMIUM).exists():
        return
    message = f"{CHROMIUM} is missing: apt-get install -y chromium"
    if os.environ.get("CI"):
        pytest.fail(message)
    pytest.skip(message)


def camera_geometry(scene: str) -> CameraGeometry:
    """The overhead camera of ``scene`` as the vision sees it (the same camera the served run
    renders its image with)."""
    world = World.build(episode_scene(scene, 0, None), with_robot=False)
    with overhead_camera(world) as cam:
        return geometry_of(cam, (DEFAULT_HEIGHT, DEFAULT_WIDTH))


def pixel_of(g: CameraGeometry, xyz: tuple[float, float, float]) -> tuple[int, int]:
    u, v = np.floor(g.world_to_pixel(np.asarray(xyz, dtype=float)) + 0.5)
    return int(u), int(v)


@dataclass
class ServedRun:
    """A ``python -m fsm.interactive`` process: its page's URL, the moment it printed it
    (``time.perf_counter``), and its output lines as they come."""

    process: subprocess.Popen
    url: str
    started: float
    out: Path
    lines: queue.Queue = field(default_factory=queue.Queue)

    def output(self) -> list[str]:
        got = []
        while not self.lines.empty():
            got.append(self.lines.get())
        return got


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@contextmanager
def served_run(out: Path, *args: str) -> Iterator[ServedRun]:
    """Serve the interactive page on any free ports, writing into ``out``; the process is
    ended when the block ends (if it has not ended itself)."""
    cmd = [sys.executable, "-m", "fsm.interactive", "--port", "0", "--rerun-port", "0"]
    env = {**os.environ, "MUJOCO_GL": "egl", "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [*cmd, "--out", str(out), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        # Ctrl-C reaches the command as it does from a shell: a child inherits an ignored
        # SIGINT, and some tests of the suite leave it ignored in the worker
        preexec_fn=_default_sigint,
    )
    lines: queue.Queue = queue.Queue()

    def read() -> None:
        for line in process.stdout:
            lines.put(line.rstrip("\n"))

    threading.Thread(target=read, daemon=True).start()
    deadline = time.monotonic() + START_TIMEOUT
    url = ""
    while not url:
        assert process.poll() is None, process.stderr.read()
        assert time.monotonic() < deadline, "the served run printed no address"
        try:
            line = lines.get(timeout=0.5)
        except queue.Empty:
            continue
        if line.startswith("the page: "):
            url = line.split()[2]
    run = ServedRun(process, url, time.perf_counter(), out, lines)
    try:
        yield run
    finally:
        if process.poll() is None:
            process.kill()
        process.wait(30)


@contextmanager
def browser_page(width: int, height: int) -> Iterator[object]:
    """A page of headless Chromium with a ``width`` x ``height`` viewport."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            yield browser.new_page(viewport={"width": width, "height": height})
        finally:
            browser.close()


def click_pixel(page: object, u: int, v: int) -> None:
    """Click the middle of pixel (u, v) of ``#overhead`` at the size it is displayed."""
    img = page.locator("#overhead")
    box = img.bounding_box()
    natural = page.evaluate(
        "() => [document.getElementById('overhead').naturalWidth,"
        " document.getElementById('overhead').naturalHeight]"
    )
    x = (u + 0.5) * box["width"] / natural[0]
    y = (v + 0.5) * box["height"] / natural[1]
    img.click(position={"x": x, "y": y})


def wait_status(page: object, text: str, timeout: float = CYCLE_TIMEOUT) -> float:
    """Wait until ``#status`` holds ``text``; returns when (``time.perf_counter``)."""
    page.wait_for_function(
        "(t) => document.getElementById('status').textContent.includes(t)",
        arg=text,
        timeout=timeout * 1000,
        polling=50,
    )
    return time.perf_counter()
