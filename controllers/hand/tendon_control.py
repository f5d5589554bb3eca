"""Joint control of the tendon-driven Utah/MIT hand of section 5 (models/utah_mit_hand) on a
standalone model: the closed loop stepped for a given time, with a log of what it saw.

The control law itself (desired joint angles -> PD torques -> 32 non-negative tendon tensions, and
back from measured tensions to torques) is the hand's actuator layer, :mod:`hand_sim.tendon_drive`,
where :class:`~hand_sim.world.World` runs it at every physics step of a world built with
``hand="tendon"``; its names are re-exported here so that a controller reads them from one place.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from hand_sim.tendon_drive import (
    CONTROL_PERIOD,
    DAMPING_RATIO,
    PRETENSION,
    SERVO_KP,
    SERVO_TORQUE_LIMIT,
    PDGains,
    TendonDrive,
    TendonLayout,
    TensionCommand,
    allocate_tensions,
    joint_torques,
    torque_limit,
)

__all__ = [
    "CONTROL_PERIOD",
    "DAMPING_RATIO",
    "PRETENSION",
    "SERVO_KP",
    "SERVO_TORQUE_LIMIT",
    "PDGains",
    "TendonDrive",
    "TendonHandController",
    "TendonLayout",
    "TendonLog",
    "TensionCommand",
    "allocate_tensions",
    "joint_torques",
    "torque_limit",
]


@dataclass
class TendonHandController:
    """The joint PD loop and the tension allocation, at :data:`CONTROL_PERIOD`.

    ``command`` turns joint targets into tensions from the sensed joint angles (and the joint
    velocities: the real hand differentiated its angle sensors; here the simulator's velocity);
    ``apply`` writes them to the 32 actuators; ``run`` steps the physics with the loop closed."""

    model: mujoco.MjModel
    layout: TendonLayout
    gains: PDGains
    pretension: float = PRETENSION
    period: float = CONTROL_PERIOD

    @classmethod
    def for_model(cls, model: mujoco.MjModel, prefix: str = "") -> TendonHandController:
        """Controller with the servo-equivalent gains for ``model``."""
        layout = TendonLayout.from_model(model, prefix)
        return cls(model, layout, PDGains.servo_equivalent(model, layout))

    @property
    def drive(self) -> TendonDrive:
        """The per-step law of :mod:`hand_sim.tendon_drive` with these gains."""
        return TendonDrive(self.layout, self.gains, self.pretension)

    def torques(self, data: mujoco.MjData, target: ArrayLike) -> NDArray[np.float64]:
        """PD torques (N m) towards the 16 joint ``target`` angles, within the gains' limits."""
        return self.drive.torques(data, target)

    def command(self, data: mujoco.MjData, target: ArrayLike) -> TensionCommand:
        """Tensions for the PD torques towards ``target`` (:func:`allocate_tensions`)."""
        return self.drive.command(data, target)

    def apply(self, data: mujoco.MjData, command: TensionCommand) -> None:
        """Write the command's 32 tensions to the tendon actuators."""
        self.drive.apply(data, command)

    def run(
        self,
        data: mujoco.MjData,
        target: ArrayLike | Callable[[float], ArrayLike],
        seconds: float,
        log: TendonLog | None = None,
    ) -> TendonLog:
        """Step ``seconds`` of physics with the loop closed: every :attr:`period` the targets
        (fixed, or a function of ``data.time``) give a new command, held in between. Returns
        ``log`` (a new one if None) with one row per control update."""
        log = TendonLog() if log is None else log
        substeps = max(1, round(self.period / self.model.opt.timestep))
        for _ in range(max(1, round(seconds / (substeps * self.model.opt.timestep)))):
            q_target = target(data.time) if callable(target) else target
            cmd = self.command(data, q_target)
            self.apply(data, cmd)
            mujoco.mj_step(self.model, data, nstep=substeps)
            log.append(data, self.layout, cmd)
        return log


@dataclass
class TendonLog:
    """What :meth:`TendonHandController.run` saw at each control update: time (s), the 16 joint
    angles (rad), the 32 commanded and 32 measured tensions (N, layout order)."""

    time: list[float] = field(default_factory=list)
    angles: list[NDArray[np.float64]] = field(default_factory=list)
    commanded: list[NDArray[np.float64]] = field(default_factory=list)
    measured: list[NDArray[np.float64]] = field(default_factory=list)

    def append(self, data: mujoco.MjData, layout: TendonLayout, cmd: TensionCommand) -> None:
        """Record one control update."""
        self.time.append(float(data.time))
        self.angles.append(layout.angles(data))
        self.commanded.append(cmd.as_ctrl())
        self.measured.append(np.column_stack(layout.tensions(data)).ravel())

    def arrays(self) -> dict[str, NDArray[np.float64]]:
        """The log as arrays (rows = control updates)."""
        return {
            "time": np.asarray(self.time),
            "angles": np.asarray(self.angles),
            "commanded": np.asarray(self.commanded),
            "measured": np.asarray(self.measured),
        }
