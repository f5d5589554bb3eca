"""The interactive page's server without a world: every malformed or unwanted request is refused
with its status and message before it reaches the task cycle; a click is taken only while a
wait state waits for one, one at a time; the stop ends the wait; only registered files are
served; events reach a page connected later."""

from __future__ import annotations

import http.client
import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from fsm.interactive.hub import Hub, Mailbox
from fsm.interactive.server import PageServer, is_loopback, parse_click

W, H = 1920, 1440


@pytest.fixture
def served() -> Iterator[tuple[PageServer, Hub, Mailbox]]:
    hub, mailbox = Hub(), Mailbox(W, H)
    server = PageServer(("127.0.0.1", 0), hub, mailbox)
    server.start()
    try:
        yield server, hub, mailbox
    finally:
        mailbox.stop("the test ended")
        server.stop()


def request(
    server: PageServer,
    method: str,
    path: str,
    body: bytes | None = None,
    headers: dict[str, str] | None = None,
) -> tuple[int, dict[str, str], bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
    try:
        conn.request(method, path, body=body, headers=headers or {})
        r = conn.getresponse()
        return r.status, dict(r.getheaders()), r.read()
    finally:
        conn.close()


def click(server: PageServer, body: object, **headers: str) -> tuple[int, dict]:
    data = body if isinstance(body, bytes) else json.dumps(body).encode()
    status, _, raw = request(
        server, "POST", "/click", data, {"Content-Type": "application/json", **headers}
    )
    return status, json.loads(raw)


def test_the_page_carries_the_automation_contract(served) -> None:
    server, _, _ = served
    status, headers, body = request(server, "GET", "/")
    assert status == 200 and headers["Content-Type"].startswith("text/html")
    page = body.decode()
    assert 'id="overhead"' in page and 'id="status"' in page
    assert "naturalWidth" in page  # clicks are mapped through the displayed size
    assert (
        headers["X-Frame-Options"] == "DENY"
        and "frame-ancestors 'none'" in headers["Content-Security-Policy"]
    )


@pytest.mark.parametrize(
    ("method", "path"),
    [
        ("GET", "/nope"),
        ("GET", "/../etc/passwd"),
        ("GET", "/files/../../etc/passwd"),
        ("GET", "/files/cycle-001/summary.json"),  # not written by this run
        ("GET", "/?x=1"),
        ("GET", "/overhead.jpg?v=abc"),
        ("GET", "/overhead.jpg?path=/etc/passwd"),
        ("POST", "/nope"),
        ("POST", "/click?u=1"),
    ],
)
def test_unknown_routes_are_404(served, method: str, path: str) -> None:
    status, _, body = request(served[0], method, path, b"" if method == "POST" else None)
    assert status == 404 and "no such page" in json.loads(body)["error"]


def test_no_image_before_the_camera_looked_then_the_latest(served) -> None:
    server, hub, _ = served
    assert request(server, "GET", "/overhead.jpg")[0] == 404
    hub.set_image(b"\xff\xd8first")
    version = hub.set_image(b"\xff\xd8second")
    status, headers, body = request(server, "GET", f"/overhead.jpg?v={version}")
    assert status == 200 and body == b"\xff\xd8second" and headers["X-Image-Version"] == "2"


def test_only_the_files_the_run_registered_are_served(served, tmp_path: Path) -> None:
    server, hub, _ = served
    summary = tmp_path / "cycle-001" / "summary.json"
    summary.parent.mkdir()
    summary.write_text('{"success": true}')
    (tmp_path / "secret.txt").write_text("no")
    hub.add_file("/files/cycle-001/summary.json", summary)
    status, headers, body = request(server, "GET", "/files/cycle-001/summary.json")
    assert status == 200 and json.loads(body) == {"success": True}
    assert headers["Content-Type"].startswith("application/json")
    assert request(server, "GET", "/files/secret.txt")[0] == 404
    assert request(server, "GET", "/files/cycle-001/../secret.txt")[0] == 404


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (b"not json", "must be JSON"),
        ({"u": 1}, "nothing else"),
        ({"u": 1, "v": 2, "w": 3}, "nothing else"),
        ([1, 2], "nothing else"),
        ({"u": 1.5, "v": 2}, "integers"),
        ({"u": "1", "v": 2}, "integers"),
        ({"u": True, "v": 2}, "integers"),
        ({"u": -1, "v": 2}, "outside the 1920x1440 overhead image"),
        ({"u": 1920, "v": 2}, "outside the 1920x1440 overhead image"),
        ({"u": 5, "v": 1440}, "outside the 1920x1440 overhead image"),
    ],
)
def test_a_malformed_click_is_400_with_what_is_wrong(served, body, message: str) -> None:
    status, data = click(served[0], body)
    assert status == 400 and message in data["error"], data


def test_requests_that_are_not_the_pages_are_refused(served) -> None:
    server, _, _ = served
    body = json.dumps({"u": 5, "v": 5}).encode()
    # another name for this machine (DNS rebinding): refused on a loopback server
    assert request(server, "GET", "/", headers={"Host": "attacker.example:80"})[0] == 403
    # a click sent by another page
    status, data = click(server, {"u": 5, "v": 5}, Origin="http://attacker.example")
    assert status == 403 and "own page" in data["error"]
    # not JSON (a form post another page could send without asking), no length, too long
    status, _, _ = request(server, "POST", "/click", body, {"Content-Type": "text/plain"})
    assert status == 415
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=10)
    conn.putrequest("POST", "/click")
    conn.putheader("Content-Type", "application/json")
    conn.endheaders()
    assert conn.getresponse().status == 411
    conn.close()
    status, _, _ = request(
        server, "POST", "/click", b" " * 1000, {"Content-Type": "application/json"}
    )
    assert status == 413


def test_a_click_while_the_robot_is_busy_is_refused_with_why(served) -> None:
    server, _, mailbox = served
    mailbox.busy_with("the robot is in Coarse Reach (cycle 1)")
    status, data = click(server, {"u": 10, "v": 10})
    assert status == 409 and not data["accepted"]
    assert "busy: the robot is in Coarse Reach (cycle 1)" in data["message"]


def test_clicks_go_to_the_waiting_state_one_at_a_time(served) -> None:
    """A stand-in for a wait state: it refuses the first click, takes the second; meanwhile a
    click made while the first is being checked is refused as busy."""
    server, _, mailbox = served
    seen: list[tuple[int, int]] = []
    checking = threading.Event()
    release = threading.Event()

    def wait_state() -> None:
        pixel = mailbox.wait_click("a block")
        seen.append(pixel)
        checking.set()
        release.wait(10)
        mailbox.answer(False, "no block there: click on a block")
        seen.append(mailbox.wait_click("a block"))
        mailbox.answer(True, "pentagon")

    worker = threading.Thread(target=wait_state, daemon=True)
    worker.start()
    while mailbox.waiting_for is None:
        time.sleep(0.01)
    first: list = []
    t = threading.Thread(target=lambda: first.append(click(server, {"u": 1, "v": 2})))
    t.start()
    checking.wait(10)
    status, data = click(server, {"u": 3, "v": 4})
    assert status == 409 and "being checked" in data["message"]
    release.set()
    t.join(10)
    assert first[0][0] == 422 and "no block there" in first[0][1]["message"]
    status, data = click(server, {"u": 5, "v": 6})
    assert status == 200 and data["accepted"] and data["message"] == "pentagon"
    worker.join(10)
    assert seen == [(1, 2), (5, 6)]
    status, data = click(server, {"u": 5, "v": 6})  # nothing waits any more
    assert status == 409


def test_the_stop_ends_the_wait_and_later_clicks(served) -> None:
    server, _, mailbox = served
    got: list = []
    worker = threading.Thread(target=lambda: got.append(mailbox.wait_click("a place point")))
    worker.start()
    status, _, body = request(server, "POST", "/stop", b"")
    assert status == 200 and "files are kept" in json.loads(body)["message"]
    worker.join(10)
    assert got == [None] and mailbox.stop_reason == "stopped from the page"
    status, data = click(server, {"u": 5, "v": 6})
    assert status == 409 and "the run has ended" in data["message"]


def test_a_page_that_connects_later_gets_the_state_and_the_log(served) -> None:
    server, hub, _ = served
    hub.publish("status", {"text": "old"})
    hub.publish("state", {"from": "Wait for Block", "to": "Select/Model", "reason": "clicked"})
    hub.publish("refused", {"message": "no block there"})  # only for pages connected then
    hub.publish("status", {"text": "waiting for a block: click on a block"})
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=10)
    conn.request("GET", "/events")
    r = conn.getresponse()
    assert r.status == 200 and r.getheader("Content-Type").startswith("text/event-stream")
    hub.publish("end", {"text": "the run ended"})
    events = []
    while len(events) < 3:
        line = r.fp.readline().decode()
        if line.startswith("event: "):
            events.append(line.split(": ", 1)[1].strip())
    conn.close()
    assert events == ["state", "status", "end"]
    snapshot = json.loads(request(server, "GET", "/state.json")[2])
    assert snapshot["status"]["text"].startswith("waiting for a block")
    assert [e["kind"] for e in snapshot["events"]] == ["state"]


def test_closing_the_page_stops_the_run(monkeypatch) -> None:
    monkeypatch.setattr("fsm.interactive.server.PAGE_GRACE", 0.3)
    monkeypatch.setattr("fsm.interactive.server.KEEPALIVE", 0.2)
    hub, mailbox = Hub(), Mailbox(W, H)
    server = PageServer(("127.0.0.1", 0), hub, mailbox)
    server.start()
    try:
        conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=10)
        conn.request("GET", "/events")
        conn.getresponse()
        time.sleep(0.6)
        assert mailbox.stop_reason is None  # a page is connected
        conn.close()
        deadline = time.monotonic() + 10
        while mailbox.stop_reason is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert mailbox.stop_reason == "the page was closed"
    finally:
        server.stop()


def test_parse_click_and_loopback_names() -> None:
    assert parse_click(b'{"u": 0, "v": 1439}', W, H) == (0, 1439)
    assert isinstance(parse_click(b'{"u": 0, "v": 1440}', W, H), str)
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("[::1]")
    assert not is_loopback("0.0.0.0") and not is_loopback("example.com")
