"""The task cycle's corrections for a world that differs from the robot's model (section 5.3's
woes: "imprecise object models, discretization errors, calibration drifts, and kinematic model
imprecision"), each from what the robot senses, never from the simulation's truth
(docs/robustness.md):

- the overhead camera checks its calibration against the table in every view it takes
  (:mod:`vision.calibration`; ``camera_check``);
- the lift asks the wrist only whether the hand holds *something* (``held_floor``), not the
  block's nominal weight: a real block's density is not known. The weight the wrist measures
  once the block is off the table is what the carry's check expects after (``sensed_weight``).

Each is a switch of :class:`ClosedLoopParams` (``TaskConfig.closed_loop``), on by default; a
study turns one off to measure what it does.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ClosedLoopParams:
    """The closed-loop corrections' switches and thresholds (module docstring)."""

    #: The overhead camera's calibration is checked against the table in each view and, where
    #: it has drifted, replaced by the table's (vision.calibration.calibrate).
    camera_check: bool = True
    #: The lift's held test: the wrist must carry at least this much (N) more than the empty
    #: hand. A fifth of a newton (20 g): above a wrist sensor's resolution (the simulated one
    #: reads an empty hand after a lift to 1 mN) and below any block the hand lifts (the lightest
    #: of the nine paper objects weighs 1.5 N in wood, 0.37 N at a quarter of wood's density).
    #: Chosen before any run. With ``sensed_weight`` off: ``TaskConfig.min_held_share`` of the
    #: block's nominal weight instead (a block lighter than wood fails it).
    held_floor: float = 0.2
    #: The weight the wrist measures after the lift is the block's weight from then on (the
    #: carry's check); off: the nominal weight (perceived volume x wood's density).
    sensed_weight: bool = True

    def __post_init__(self) -> None:
        if not self.held_floor >= 0.0:
            raise ValueError(f"held_floor must be a force of 0 N or more; got {self.held_floor!r}")
