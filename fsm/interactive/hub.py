"""What the page is told (:class:`Hub`) and what it asks (:class:`Mailbox`), between the thread
that runs the task cycle and the HTTP threads. Neither holds anything of MuJoCo: the task cycle's
thread publishes events and images as bytes and plain data, and takes the user's clicks one at a
time."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fsm.user_protocol import Pixel

#: Events kept for a page that connects later (the transitions and messages, oldest dropped).
HISTORY = 300
#: Events waiting for one page at most; a page that falls further behind loses the oldest.
QUEUE_LIMIT = 2000
#: Events of which a page needs only the latest (a newer one replaces one not sent yet).
LATEST_ONLY = frozenset({"frame", "status"})
#: Events that describe the page's state now: the latest of each is sent to a page that connects.
STICKY = frozenset({"status", "view", "polygon", "mark", "frame", "rerun", "end"})
#: Events for the pages connected when they happen only (the answer to a click just made).
TRANSIENT = frozenset({"refused"})


class Subscription:
    """One connected page's queue of events (``(kind, data)``)."""

    def __init__(self, hub: Hub) -> None:
        self._hub = hub
        self.queue: deque[tuple[str, dict[str, Any]]] = deque()

    def next(self, timeout: float) -> tuple[str, dict[str, Any]] | None:
        """The next event, or None after ``timeout`` seconds without one (or once the hub is
        closed and the queue empty)."""
        with self._hub.cond:
            if not self.queue and not self._hub.closed:
                self._hub.cond.wait(timeout)
            event = self.queue.popleft() if self.queue else None
            if not self.queue:
                self._hub.cond.notify_all()  # a drain may be waiting for the queues to empty
            return event


class Hub:
    """Events for the pages, in order (Server-Sent Events: ``status``, ``view``, ``polygon``,
    ``mark``, ``frame``, ``state``, ``refused``, ``cycle``, ``rerun``, ``end``), the current
    overhead image as JPEG bytes, the files of the cycles written so far, and how many pages are
    connected."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.closed = False
        self._subscribers: list[Subscription] = []
        self._latest: dict[str, dict[str, Any]] = {}
        self._history: deque[tuple[str, dict[str, Any]]] = deque(maxlen=HISTORY)
        self._image: tuple[bytes, int] | None = None
        self._files: dict[str, Path] = {}
        self.connected = 0
        self.ever_connected = False
        self.last_disconnect = time.monotonic()

    # --- the task cycle's side ------------------------------------------------------------
    def publish(self, kind: str, data: dict[str, Any]) -> None:
        """Send ``kind`` with ``data`` (JSON-able) to every connected page, and keep it for the
        pages that connect later (the latest of a sticky kind; the others in the history)."""
        with self.cond:
            if kind in STICKY:
                self._latest[kind] = data
                if kind == "view":  # a new image: the marks drawn on the old one are gone
                    self._latest.pop("polygon", None)
                    self._latest.pop("mark", None)
            elif kind not in TRANSIENT:
                self._history.append((kind, data))
            for sub in self._subscribers:
                if kind in LATEST_ONLY:
                    stale = [e for e in sub.queue if e[0] == kind]
                    for e in stale:
                        sub.queue.remove(e)
                if len(sub.queue) >= QUEUE_LIMIT:
                    sub.queue.popleft()
                sub.queue.append((kind, data))
            self.cond.notify_all()

    def set_image(self, jpeg: bytes) -> int:
        """Make ``jpeg`` the overhead image served; returns its version (1, 2, ...)."""
        with self.cond:
            version = 1 if self._image is None else self._image[1] + 1
            self._image = (jpeg, version)
            return version

    def add_file(self, route: str, path: Path) -> None:
        """Serve the file ``path`` (written by this run) at ``route`` (``/files/...``)."""
        with self.cond:
            self._files[route] = path

    def drain(self, timeout: float) -> None:
        """Wait until every connected page has been sent its events, ``timeout`` seconds at
        most."""
        deadline = time.monotonic() + timeout
        with self.cond:
            while any(sub.queue for sub in self._subscribers):
                left = deadline - time.monotonic()
                if left <= 0:
                    return
                self.cond.wait(min(left, 0.05))

    def close(self) -> None:
        """No more events: every page's stream ends once its queue is sent."""
        with self.cond:
            self.closed = True
            self.cond.notify_all()

    # --- the HTTP side --------------------------------------------------------------------
    def image(self) -> tuple[bytes, int] | None:
        """The overhead image (JPEG bytes) and its version, or None before the first."""
        with self.cond:
            return self._image

    def file(self, route: str) -> Path | None:
        """The file served at ``route``, or None: only the files this run registered."""
        with self.cond:
            return self._files.get(route)

    def snapshot(self) -> dict[str, Any]:
        """The page's state now (``/state.json``): the latest of each sticky event but the live
        frame, the recent events, the files."""
        with self.cond:
            latest = {k: v for k, v in self._latest.items() if k != "frame"}
            return {
                **latest,
                "events": [{"kind": k, **d} for k, d in self._history],
                "files": sorted(self._files),
            }

    @contextmanager
    def subscribe(self) -> Iterator[Subscription]:
        """A page connects: its queue starts with the history and the latest sticky events."""
        sub = Subscription(self)
        with self.cond:
            sub.queue.extend(self._history)
            sub.queue.extend((k, v) for k, v in self._latest.items() if k != "end")
            if "end" in self._latest:
                sub.queue.append(("end", self._latest["end"]))
            self._subscribers.append(sub)
            self.connected += 1
            self.ever_connected = True
        try:
            yield sub
        finally:
            with self.cond:
                self._subscribers.remove(sub)
                self.connected -= 1
                self.last_disconnect = time.monotonic()


@dataclass(frozen=True)
class Answer:
    """The task cycle's answer to a click: taken or refused, and why."""

    accepted: bool
    message: str


class Mailbox:
    """The user's clicks and stop, from the HTTP threads to the task cycle's thread: a click is
    taken only while a wait state waits for one, and one at a time (the next waits for the
    answer to the last); a stop ends the wait, or the busy cycle at its next physics step."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self._cond = threading.Condition()
        self._waiting_for: str | None = None
        self._busy_with = "starting"
        self._click: Pixel | None = None
        self._checking = False  # the click was handed to the wait state, not answered yet
        self._answer: Answer | None = None
        self._stop: str | None = None

    @property
    def stop_reason(self) -> str | None:
        """Why the run is to end (None: it goes on)."""
        return self._stop

    @property
    def waiting_for(self) -> str | None:
        """What a wait state waits for now (None: the robot is busy)."""
        with self._cond:
            return self._waiting_for

    # --- the HTTP side --------------------------------------------------------------------
    def offer(self, pixel: Pixel, timeout: float) -> tuple[str, Answer]:
        """Hand the click ``pixel`` to the waiting state and wait for its answer; returns
        ("taken" | "refused" | "busy" | "ended" | "timeout", answer)."""
        with self._cond:
            if self._stop is not None:
                return "ended", Answer(False, f"the run has ended ({self._stop})")
            if self._waiting_for is None:
                return "busy", Answer(
                    False,
                    f"busy: {self._busy_with}; the page asks for a click when the robot waits "
                    "for one",
                )
            if self._click is not None:
                return "busy", Answer(False, "busy: the last click is being checked")
            self._click, self._answer = pixel, None
            self._cond.notify_all()
            deadline = time.monotonic() + timeout
            while self._answer is None and self._stop is None:
                left = deadline - time.monotonic()
                if left <= 0:
                    return "timeout", Answer(False, "no answer yet: the click is being checked")
                self._cond.wait(min(left, 0.5))
            if self._answer is None:
                return "ended", Answer(False, f"the run has ended ({self._stop})")
            answer = self._answer
            return ("taken" if answer.accepted else "refused"), answer

    def stop(self, reason: str) -> None:
        """End the run (the first reason given is kept)."""
        with self._cond:
            if self._stop is None:
                self._stop = reason
            self._cond.notify_all()

    # --- the task cycle's side ------------------------------------------------------------
    def wait_click(self, waiting_for: str) -> Pixel | None:
        """Wait for the next click (the wait state now waits for ``waiting_for``); None when
        the run is to end."""
        with self._cond:
            if self._checking:  # the state that took the last click ended without an answer
                self._answer = Answer(False, "the click was not taken: the robot moved on")
                self._click, self._checking = None, False
                self._cond.notify_all()
            self._waiting_for = waiting_for
            while self._click is None and self._stop is None:
                self._cond.wait(0.5)  # a timeout, so that Ctrl-C reaches the main thread
            if self._stop is not None:
                self._waiting_for = self._click = None
                return None
            self._checking = True
            return self._click

    def answer(self, accepted: bool, message: str) -> None:
        """Answer the click being checked; a click taken ends the wait."""
        with self._cond:
            self._answer = Answer(accepted, message)
            self._click, self._checking = None, False
            if accepted:
                self._waiting_for = None
            self._cond.notify_all()

    def busy_with(self, what: str) -> None:
        """The robot is busy with ``what`` (said in the answer to a click meanwhile): no state
        waits for a click."""
        with self._cond:
            self._busy_with = what
            self._waiting_for = None
