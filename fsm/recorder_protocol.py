"""What the task cycle tells its recorder (:class:`TaskRecorder`), and :class:`NullRecorder`, the
recorder of an episode that is not recorded: the machine and the handlers call the recorder
unconditionally. The recording one is :class:`fsm.recording.EpisodeRecorder`; this module does
not import it (nor rerun), so an unrecorded episode never loads the recording code."""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from hand_sim.world import World


@runtime_checkable
class TaskRecorder(Protocol):
    """The calls the task cycle (:mod:`fsm.machine`, :mod:`fsm.handlers`) makes on a recorder;
    see :class:`fsm.recording.EpisodeRecorder` for what each records."""

    def tick(self, world: World) -> None:
        """Called after every :meth:`World.step` (``World.on_step``)."""

    def set_target(self, block_name: str | None) -> None:
        """The block whose contacts with the robot are recorded (None: none)."""

    def log_transition(
        self, from_state: str, to_state: str, reason: str, *, level: str = "INFO"
    ) -> None:
        """A state transition of the machine, with its reason."""

    def log_vision(
        self,
        rgb: NDArray[np.uint8],
        K: ArrayLike,
        pose: ArrayLike,
        polygon_world: ArrayLike,
        pixel_contour: ArrayLike,
        z_top: float,
        *,
        name: str = "vision",
    ) -> None:
        """The Select/Model image and the perceived polygon."""

    def log_synthesis(
        self,
        step: int,
        eps_fc: float,
        eps_mc: float,
        predicted_failure: bool | None,
        contacts_world: ArrayLike,
        s_g: float | None = None,
    ) -> None:
        """One Wrench Closure controller step."""

    def log_reachability(self, loop: int, reachable: bool, reason: str) -> None:
        """One turn of the Wrench Closure <-> Posture Control loop."""

    def log_verdict(self, success: bool, text: str) -> None:
        """The episode's final verdict."""

    def close(self) -> None:
        """Finish the recording (idempotent)."""


class NullRecorder:
    """A :class:`TaskRecorder` that records nothing: every call returns at once."""

    def tick(self, world: World) -> None:
        """Nothing to record."""

    def set_target(self, block_name: str | None) -> None:
        """Nothing to record."""

    def log_transition(
        self, from_state: str, to_state: str, reason: str, *, level: str = "INFO"
    ) -> None:
        """Nothing to record."""

    def log_vision(
        self,
        rgb: NDArray[np.uint8],
        K: ArrayLike,
        pose: ArrayLike,
        polygon_world: ArrayLike,
        pixel_contour: ArrayLike,
        z_top: float,
        *,
        name: str = "vision",
    ) -> None:
        """Nothing to record."""

    def log_synthesis(
        self,
        step: int,
        eps_fc: float,
        eps_mc: float,
        predicted_failure: bool | None,
        contacts_world: ArrayLike,
        s_g: float | None = None,
    ) -> None:
        """Nothing to record."""

    def log_reachability(self, loop: int, reachable: bool, reason: str) -> None:
        """Nothing to record."""

    def log_verdict(self, success: bool, text: str) -> None:
        """Nothing to record."""

    def close(self) -> None:
        """Nothing to close."""
