"""The interactive task cycle driven through its HTTP endpoints, in one process (no browser): the
page's server and the task cycle's thread on clutter3. Every wrong click gets its message and
loses nothing; a block click gives the block's polygon; a place click the arm cannot take is
refused while the block stays held (the world frozen, the fingers on it); a good one delivers,
judged physically; a failed cycle writes its files and the run goes back to waiting for a
block; the stop ends the run with every cycle's files written."""

from __future__ import annotations

import http.client
import json
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from fsm import handlers
from fsm.context import EpisodeOptions
from fsm.interactive.driver import Driver
from fsm.interactive.hub import Hub, Mailbox
from fsm.interactive.server import PageServer
from fsm.layout import episode_scene
from fsm.recording import EpisodeRecorder
from fsm.states import Failure, State, TaskFailedError
from hand_sim.world import World
from vision import DEFAULT_HEIGHT, DEFAULT_WIDTH, ExtractionError, Selection, overhead_camera
from vision.observation import geometry_of

#: Simulated-time-free bound (s of wall time) on each wait; generous for a loaded machine.
TIMEOUT = 600.0


def wait_until(what: str, ready: Callable[[], bool], thread: threading.Thread) -> None:
    deadline = time.monotonic() + TIMEOUT
    while not ready():
        assert thread.is_alive(), f"the task cycle's thread ended before {what}"
        assert time.monotonic() < deadline, f"no {what} within {TIMEOUT} s"
        time.sleep(0.05)


def post(port: int, path: str, body: object | None = None) -> tuple[int, dict]:
    data = b"" if body is None else json.dumps(body).encode()
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=TIMEOUT)
    try:
        conn.request("POST", path, body=data, headers={"Content-Type": "application/json"})
        r = conn.getresponse()
        return r.status, json.loads(r.read())
    finally:
        conn.close()


def pixels_of(scene_name: str, points: dict[str, tuple[float, float, float]]) -> dict:
    """The overhead image's pixel (u, v) of each world point, from the camera the vision uses."""
    scene = episode_scene(scene_name, 0, None)
    world = World.build(scene, with_robot=False)
    with overhead_camera(world) as cam:
        g = geometry_of(cam, (DEFAULT_HEIGHT, DEFAULT_WIDTH))
    return {
        k: tuple(int(c) for c in np.floor(g.world_to_pixel(p) + 0.5)) for k, p in points.items()
    }


def robot_parts_on(world: World, block: str) -> set[str]:
    """The robot's bodies in contact with ``block`` (the simulation's truth)."""
    m, d = world.model, world.data
    b = world.block_body_id(block)
    parts = set()
    for c in d.contact[: d.ncon]:
        pair = (int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2]))
        if b in pair:
            other = pair[1] if pair[0] == b else pair[0]
            name = m.body(other).name
            if "hand" in name or "arm" in name:
                parts.add(name)
    return parts


@pytest.mark.e2e
def test_clicks_drive_the_task_cycle_and_every_wrong_click_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    scene = episode_scene("clutter3", 0, None)
    z_table = scene.table.height
    block = {b.name: b for b in scene.blocks}
    top = {n: (*b.position, z_table + b.height) for n, b in block.items()}
    place = (0.0, -0.25, z_table)
    px = pixels_of(
        "clutter3",
        {
            **top,
            "bare table": (0.3, -0.3, z_table),
            "off the table": (0.56, 0.0, z_table),
            "out of reach": (0.40, 0.30, z_table),
            "occupied": (*block["rectangle"].position, z_table),
            "place": place,
        },
    )
    # the vision refuses the triangle while this is on (a block it cannot model)
    refuse = {"triangle": True}
    model = Selection.model

    def refusing_model(self: Selection, index: int):
        if refuse["triangle"] and self.names[index] == "triangle":
            raise ExtractionError("the triangle's edges do not close (stand-in)")
        return model(self, index)

    monkeypatch.setattr(Selection, "model", refusing_model)

    hub, mailbox = Hub(), Mailbox(DEFAULT_WIDTH, DEFAULT_HEIGHT)
    server = PageServer(("127.0.0.1", 0), hub, mailbox)
    server.start()
    options = EpisodeOptions(scene="clutter3", out=tmp_path)
    driver = Driver(options, hub, mailbox, EpisodeRecorder)
    thread = threading.Thread(target=driver.run, name="task-cycle", daemon=True)
    thread.start()
    port = server.port

    def click(name: str) -> tuple[int, dict]:
        u, v = px[name]
        return post(port, "/click", {"u": u, "v": v})

    def status() -> str:
        return hub.snapshot().get("status", {}).get("text", "")

    try:
        wait_until("the wait for a block", lambda: mailbox.waiting_for == "a block", thread)
        assert "waiting for a block" in status()
        # wrong clicks: the bare table, a block the vision refuses; nothing is lost
        code, answer = click("bare table")
        assert code == 422 and answer["message"].startswith("no block there: click on a block")
        code, answer = click("triangle")
        assert code == 422 and "polygon not modelled" in answer["message"]
        assert "the triangle's edges do not close" in answer["message"]
        assert not list(tmp_path.glob("cycle-*/summary.json"))
        refuse["triangle"] = False

        # a block: its polygon, drawn over the image, around the block's pixel
        t0 = time.perf_counter()
        code, answer = click("pentagon")
        took = time.perf_counter() - t0
        assert code == 200 and answer["accepted"] and answer["message"].startswith("pentagon")
        polygon = np.array(hub.snapshot()["polygon"]["points"])
        assert len(polygon) == 5
        assert np.linalg.norm(polygon.mean(axis=0) - px["pentagon"]) < 15.0
        print(f"click to polygon: {took:.2f} s")
        # the robot is busy: a click is refused with why
        code, answer = click("rectangle")
        assert code == 409 and answer["message"].startswith("busy: the robot "), answer

        wait_until(
            "the wait for a place point", lambda: mailbox.waiting_for == "a place point", thread
        )
        assert "waiting for a place point" in status()
        world = driver.world
        frozen_at = world.time
        holding = robot_parts_on(world, "pentagon")
        assert len(holding) >= 3, holding
        for name, message in (
            ("off the table", "off the table"),
            ("out of reach", "out of reach"),
            ("occupied", "occupied: "),
        ):
            code, answer = click(name)
            assert code == 422 and answer["message"].startswith(message), answer
            assert "pentagon stays in the hand" in answer["message"]
            # the block stays held: nothing stepped, the same fingers on it
            assert world.time == frozen_at and robot_parts_on(world, "pentagon") == holding
            assert mailbox.waiting_for == "a place point"
        assert "taken by rectangle" in click("occupied")[1]["message"]

        code, answer = click("place")
        assert code == 200 and answer["accepted"]
        wait_until("the delivery", lambda: "delivered" in status(), thread)
        summary = json.loads((tmp_path / "cycle-001" / "summary.json").read_text())
        assert summary["success"] and (tmp_path / "cycle-001" / "episode.rrd").stat().st_size > 0
        (cycle,) = summary["cycles"]
        assert cycle["place_chosen_by"] == "user"
        # judged physically: the block stands within 20 mm of the point clicked
        clicked = np.array(cycle["place_asked"])
        assert np.linalg.norm(clicked - place[:2]) < 0.003  # the pixel read back on the table
        final = np.array(cycle["judgement"]["final_position"])
        assert np.linalg.norm(final[:2] - clicked) < 0.020
        assert cycle["judgement"]["tilt_deg"] < 10.0
        states = [v["state"] for v in summary["visits"]]
        assert states[:2] == ["Wait for Block", "Select/Model"]
        assert states.index("Wait for Place") == states.index("Grasp Object") + 1
        assert summary["transitions"][-1].startswith("Deliver -> Wait for Block")

        # a failed cycle: its named failure, its files written, back to waiting for a block
        def no_path(ep):
            monkeypatch.setitem(handlers.HANDLERS, State.COARSE_REACH, coarse)
            raise TaskFailedError(Failure.NO_COARSE_PATH, "stand-in: no path")

        coarse = handlers.HANDLERS[State.COARSE_REACH]
        monkeypatch.setitem(handlers.HANDLERS, State.COARSE_REACH, no_path)
        wait_until("the next wait for a block", lambda: mailbox.waiting_for == "a block", thread)
        assert click("triangle")[0] == 200
        wait_until("the failure", lambda: "failed" in status(), thread)
        wait_until("the wait after the failure", lambda: mailbox.waiting_for == "a block", thread)
        assert "cycle 2 failed: no coarse path" in status() and "waiting for a block" in status()
        failed = json.loads((tmp_path / "cycle-002" / "summary.json").read_text())
        assert failed["failure"] == Failure.NO_COARSE_PATH.value
        assert (tmp_path / "cycle-002" / "episode.rrd").stat().st_size > 0

        # the files are linked from the page; the stop ends the run, every cycle's files kept
        files = hub.snapshot()["files"]
        assert "/files/cycle-001/summary.json" in files and "/files/cycle-002/episode.rrd" in files
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
        conn.request("GET", "/files/cycle-001/summary.json")
        assert json.loads(conn.getresponse().read())["success"]
        conn.close()
        assert post(port, "/stop")[0] == 200
        thread.join(120)
        assert not thread.is_alive()
        assert "stopped from the page" in driver.ended
        assert sorted(p.name for p in tmp_path.iterdir()) == ["cycle-001", "cycle-002"]
        assert hub.snapshot()["end"]["text"].startswith("the run ended: stopped from the page")
    finally:
        mailbox.stop("the test ended")
        thread.join(120)
        server.stop()
