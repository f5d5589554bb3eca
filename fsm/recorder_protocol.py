"""What the task cycle tells its recorder (:class:`TaskRecorder`), and :class:`NullRecorder`, the
recorder of an episode that is not recorded: the machine and the handlers call the recorder
unconditionally. The recording one is :class:`fsm.recording.EpisodeRecorder`; this module does
not import it (nor rerun), so an unrecorded episode never loads the recording code."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from hand_sim.world import World

#: A point on the table, world (x, y) in metres.
TablePoint = tuple[float, float]


@dataclass(frozen=True)
class VisionView:
    """What :meth:`TaskRecorder.log_vision` records: the Select/Model image ``rgb`` (H, W, 3)
    uint8 of the camera ``name``, its pinhole (``K`` 3x3 pixels, ``pose`` 4x4 camera-to-world in
    OpenCV axes), the extracted contour ``pixel_contour`` (k, 2) pixels and the perceived polygon
    ``polygon_world`` (k, 2) world xy at height ``z_top``."""

    rgb: NDArray[np.uint8]
    K: ArrayLike
    pose: ArrayLike
    polygon_world: ArrayLike
    pixel_contour: ArrayLike
    z_top: float
    name: str = "vision"


@dataclass(frozen=True)
class SynthesisRecord:
    """What :meth:`TaskRecorder.log_synthesis` records of one Wrench Closure controller step:
    its ``step`` number in the run, eps_FC, eps_MC, the F/S predictor's output (None: no
    predictor), the virtual contacts ``contacts_world`` (n, 3) world points and S_G (None: not
    computed)."""

    step: int
    eps_fc: float
    eps_mc: float
    predicted_failure: bool | None
    contacts_world: ArrayLike
    s_g: float | None = None


@runtime_checkable
class TaskRecorder(Protocol):
    """The calls the task cycle (:mod:`fsm.machine`, :mod:`fsm.handlers`) makes on a recorder;
    see :class:`fsm.recording.EpisodeRecorder` for what each records. Each body records nothing
    (an explicit ``return None``, so that a subclass such as :class:`NullRecorder` inherits it
    rather than a type checker taking it for abstract)."""

    def tick(self, world: World) -> None:
        """Called after every :meth:`World.step` (``World.on_step``)."""
        return None

    def set_target(self, block_name: str | None) -> None:
        """The block whose contacts with the robot are recorded (None: none)."""
        return None

    def log_transition(
        self, from_state: str, to_state: str, reason: str, *, level: str = "INFO"
    ) -> None:
        """A state transition of the machine, with its reason."""
        return None

    def log_vision(self, view: VisionView) -> None:
        """The Select/Model image and the perceived polygon."""
        return None

    def log_synthesis(self, record: SynthesisRecord) -> None:
        """One Wrench Closure controller step."""
        return None

    def log_place(self, asked: TablePoint | None, used: TablePoint | None, table_z: float) -> None:
        """The place point asked for (None: the task cycle chose it) and the one the block is
        taken to, world xy on the table top at height ``table_z``."""
        return None

    def log_reachability(self, loop: int, reachable: bool, reason: str) -> None:
        """One turn of the Wrench Closure <-> Posture Control loop."""
        return None

    def log_verdict(self, success: bool, text: str) -> None:
        """The episode's final verdict."""
        return None

    def close(self) -> None:
        """Finish the recording (idempotent)."""
        return None


class NullRecorder(TaskRecorder):
    """A :class:`TaskRecorder` that records nothing: every call returns at once (the
    protocol's bodies)."""
