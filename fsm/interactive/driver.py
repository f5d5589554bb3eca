"""The interactive run's task cycle: one thread (the one that calls :meth:`Driver.run`) builds the
world, runs every cycle on it and does every render; the HTTP threads only read the
:class:`~fsm.interactive.hub.Hub` and post to the :class:`~fsm.interactive.hub.Mailbox`.

A cycle is one pick and place, from Wait for Block to the machine's return to Wait for Block
(or to Failed): :func:`fsm.machine.run_cycles` with its own recording and summary in
``OUT/cycle-NNN/``. The world persists from cycle to cycle: the blocks stay where they were put.
A cycle in which no block was clicked (the run ended while waiting for one) leaves no folder."""

from __future__ import annotations

import base64
import contextlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fsm.context import EpisodeOptions, out_paths
from fsm.interactive.hub import Hub, Mailbox
from fsm.interactive.live_view import LiveView, encode_jpeg
from fsm.judge import block_state_text
from fsm.machine import EpisodeResult, episode_world, new_episode, new_result, run_cycles
from fsm.recorder_protocol import SynthesisRecord, TablePoint, TaskRecorder, VisionView
from fsm.states import Failure, State, TaskFailedError
from fsm.user_protocol import WAITING_FOR_BLOCK, Pixel
from hand_sim.camera import OverheadCamera
from hand_sim.world import World
from vision import DEFAULT_HEIGHT, DEFAULT_WIDTH

#: JPEG quality of the overhead image the user clicks on.
OVERHEAD_QUALITY = 85
#: What each wait asks the user to do.
PROMPTS = {
    WAITING_FOR_BLOCK: "click on a block in the overhead image",
    "a place point": "click on the table where the block should go",
}
#: Failures after which the world cannot be trusted to go on: the run ends.
WORLD_LOST = (Failure.SIMULATION_UNSTABLE.value, Failure.INTERNAL_ERROR.value)
WAIT_STATES = (State.WAIT_FOR_BLOCK.value, State.WAIT_FOR_PLACE.value)


def cycle_folder(out: Path, number: int) -> Path:
    """The folder of cycle ``number`` (1, 2, ...) of the run writing into ``out``."""
    return out / f"cycle-{number:03d}"


class Page:
    """What the task cycle's thread tells the page: the status line (the last cycle's outcome
    kept in front of what the system waits for or does now) and the events."""

    def __init__(self, hub: Hub) -> None:
        self.hub = hub
        self.outcome = ""
        self.cycle = 0

    def status(self, now: str) -> None:
        text = f"{self.outcome}; {now}" if self.outcome else now
        self.hub.publish("status", {"text": text})

    def publish(self, kind: str, data: dict[str, Any]) -> None:
        self.hub.publish(kind, data)


class PageUser:
    """The user of the run (a :class:`fsm.user_protocol.UserChannel`): the overhead image and the
    prompts go to the page, the clicks come from the mailbox."""

    def __init__(self, page: Page, mailbox: Mailbox) -> None:
        self.page = page
        self.mailbox = mailbox
        self._pixel: Pixel | None = None
        self._refused = ""  # the last click's refusal, said until a click is taken

    def show_view(self, rgb: NDArray[np.uint8], waiting_for: str | None) -> None:
        version = self.page.hub.set_image(encode_jpeg(rgb, OVERHEAD_QUALITY))
        height, width = rgb.shape[:2]
        self.page.publish(
            "view",
            {"version": version, "width": width, "height": height, "waiting_for": waiting_for},
        )

    def next_click(self, waiting_for: str) -> Pixel | None:
        prompt = f"waiting for {waiting_for}: {PROMPTS.get(waiting_for, 'click')}"
        self.page.status(f"refused: {self._refused}; {prompt}" if self._refused else prompt)
        self._pixel = self.mailbox.wait_click(waiting_for)
        return self._pixel

    def refuse(self, message: str) -> None:
        self.page.publish("refused", {"message": message, "pixel": self._pixel})
        self._refused = message
        self.mailbox.answer(False, message)

    def accept(self, message: str, contour: NDArray[np.float64] | None = None) -> None:
        if contour is not None:  # a block: its modelled outline over the image
            points = np.asarray(contour, dtype=float).round(1).tolist()
            self.page.publish("polygon", {"points": points, "label": message})
            self.page.outcome = ""
        elif self._pixel is not None:  # a place point: marked where it was clicked
            self.page.publish("mark", {"u": self._pixel[0], "v": self._pixel[1]})
        self._refused = ""
        self.page.status(f"taken: {message}")
        self.mailbox.busy_with(f"the robot took the last click ({message})")
        self.mailbox.answer(True, message)


class PageRecorder(TaskRecorder):
    """The cycle's recorder (``inner``: its ``.rrd``) and the page: each transition to the page
    as it happens, live frames of the arm and hand while the world steps, and the run's stop,
    which ends a busy cycle at its next physics step (``interrupted``)."""

    def __init__(self, inner: TaskRecorder, page: Page, mailbox: Mailbox, view: LiveView) -> None:
        self.inner = inner
        self.page = page
        self.mailbox = mailbox
        self.view = view
        self._stopped = False

    def frame(self, world: World) -> None:
        """Send the live view of ``world`` now."""
        jpeg = base64.b64encode(self.view.frame(world)).decode("ascii")
        self.page.publish("frame", {"jpeg": jpeg, "sim_time": round(world.time, 3)})

    def tick(self, world: World) -> None:
        self.inner.tick(world)
        if self.view.due():
            self.frame(world)
        reason = self.mailbox.stop_reason
        if reason is not None and not self._stopped:
            self._stopped = True
            raise TaskFailedError(Failure.INTERRUPTED, f"{reason}, while the robot was busy")

    def set_target(self, block_name: str | None) -> None:
        self.inner.set_target(block_name)

    def log_transition(
        self, from_state: str, to_state: str, reason: str, *, level: str = "INFO"
    ) -> None:
        self.inner.log_transition(from_state, to_state, reason, level=level)
        self.page.publish(
            "state",
            {
                "cycle": self.page.cycle,
                "from": from_state,
                "to": to_state,
                "reason": reason,
                "level": level,
            },
        )
        if to_state in WAIT_STATES and from_state == to_state:
            return  # the wait's own events: its prompt says what it waits for
        if to_state in (State.DONE.value, State.FAILED.value):
            return  # the cycle's outcome is said once its files are written
        doing = f"{to_state} (cycle {self.page.cycle})"
        self.mailbox.busy_with(f"the robot is in {doing}")
        if to_state not in WAIT_STATES:
            self.page.status(f"busy: {doing}, after {from_state}: {reason}")

    def log_vision(self, view: VisionView) -> None:
        self.inner.log_vision(view)

    def log_synthesis(self, record: SynthesisRecord) -> None:
        self.inner.log_synthesis(record)

    def log_place(self, asked: TablePoint | None, used: TablePoint | None, table_z: float) -> None:
        self.inner.log_place(asked, used, table_z)

    def log_reachability(self, loop: int, reachable: bool, reason: str) -> None:
        self.inner.log_reachability(loop, reachable, reason)

    def log_verdict(self, success: bool, text: str) -> None:
        self.inner.log_verdict(success, text)

    def close(self) -> None:
        self.inner.close()


class Driver:
    """Runs the interactive task cycle for ``options`` (its ``out``: the run's folder),
    publishing to ``hub`` and taking clicks from ``mailbox``. ``recorder_factory(path, world)``
    makes each cycle's recording (an :class:`fsm.recording.EpisodeRecorder`, streaming to the
    run's rerun server); ``announce`` receives the machine's line per state entered."""

    def __init__(
        self,
        options: EpisodeOptions,
        hub: Hub,
        mailbox: Mailbox,
        recorder_factory: Callable[[Path, World], TaskRecorder],
        announce: Callable[[str], None] | None = None,
    ) -> None:
        self.options = options
        self.page = Page(hub)
        self.mailbox = mailbox
        self.recorder_factory = recorder_factory
        self.announce = announce
        #: each cycle's result, in order (the cycles that picked a block)
        self.results: list[EpisodeResult] = []
        #: why the run ended ("" while it runs)
        self.ended = ""
        #: the world (built by :meth:`run`, in its thread); for tests, read it only while the
        #: task cycle waits for a click
        self.world: World | None = None

    def run(self) -> int:
        """Build the world and run cycles until the user stops the run, closes the page, or
        the world cannot go on; returns the exit status (0, or 1 when the world was lost).
        Ctrl-C (KeyboardInterrupt) ends the cycle running as interrupted, with its files
        written, and is raised again."""
        page, options = self.page, self.options
        page.status("starting: building the world")
        world, perturbation = episode_world(options)
        self.world = world
        user = PageUser(page, self.mailbox)
        # a first look for the page while the rest is set up (no click is taken yet); Wait for
        # Block's own look, the one the clicks are read on, replaces it
        with OverheadCamera(world, DEFAULT_WIDTH, DEFAULT_HEIGHT) as camera:
            user.show_view(camera.rgb(), None)
        page.status("starting: the grasp controller, the recording, the camera")
        ep = new_episode(options, world)
        ep.user = user
        view = LiveView(world)
        status = 0
        try:
            number = 0
            while self.mailbox.stop_reason is None:
                number += 1
                folder = cycle_folder(options.out, number)
                rrd, summary = out_paths(folder)
                ep.cycle, page.cycle = number - 1, number
                recorder = PageRecorder(self.recorder_factory(rrd, world), page, self.mailbox, view)
                ep.recorder = recorder
                recorder.frame(world)
                result = new_result(options, world, rrd, perturbation)
                try:
                    run_cycles(
                        ep,
                        result,
                        summary,
                        announce=self.announce,
                        start=State.WAIT_FOR_BLOCK,
                        pause_at=State.WAIT_FOR_BLOCK,
                    )
                finally:
                    if not result.cycles:  # no block was clicked: no cycle, no folder
                        _discard(folder)
                if not result.cycles:
                    break
                self.results.append(result)
                self._report(number, folder, result)
                if result.failure in WORLD_LOST:
                    self.ended = f"the world cannot go on after cycle {number}: {result.failure}"
                    status = 1
                    break
        except KeyboardInterrupt:
            self.ended = "interrupted (Ctrl-C)"
            raise
        finally:
            view.close()
            self.ended = self.ended or f"the run ended: {self.mailbox.stop_reason or 'stopped'}"
            written = f"{len(self.results)} cycle(s) written in {options.out}"
            page.status(f"{self.ended}; {written}")
            page.publish("end", {"text": f"{self.ended}; {written}"})
        return status

    def _report(self, number: int, folder: Path, result: EpisodeResult) -> None:
        """Say the cycle's outcome, its files written, and serve them to the page."""
        cycle = result.cycles[-1]
        name = folder.name
        routes = {}
        for path in out_paths(folder):
            if path.exists():
                route = f"/files/{name}/{path.name}"
                self.page.hub.add_file(route, path)
                routes[path.name] = route
        if result.success:
            j = cycle["judgement"]
            used = ", ".join(f"{v:.3f}" for v in cycle["place_used"])
            text = (
                f"delivered {cycle['block']} {j['place_error_mm']:.1f} mm from the place point "
                f"({used}) (cycle {number}, {name}/)"
            )
        else:
            judged = block_state_text(cycle.get("block_at_failure"), cycle.get("block"))
            text = (
                f"cycle {number} failed: {result.failure}: {result.failure_detail}"
                + (f"; {judged}" if judged else "")
                + f" ({name}/)"
            )
        self.page.outcome = text
        self.page.publish(
            "cycle",
            {
                "cycle": number,
                "block": cycle["block"],
                "success": result.success,
                "failure": result.failure,
                "text": text,
                "files": routes,
            },
        )
        self.page.status(text)
        if self.announce is not None:
            self.announce(text)


def _discard(folder: Path) -> None:
    """Remove a cycle's files and folder (a cycle in which no block was clicked)."""
    for path in out_paths(folder):
        path.unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        folder.rmdir()
