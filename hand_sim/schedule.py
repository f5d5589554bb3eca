"""Rates of simulated time: what a per-step hook (``World.on_step``) should do now.

A :class:`Rate` is due once per period of *simulated* time, whatever the number of physics steps
between two ticks; a :class:`RateSchedule` asks several named rates at once. Telemetry uses them to
log body poses, images, scalars and contacts each at its own rate (:mod:`hand_sim.telemetry`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from hand_sim.errors import HandSimError

#: Rates are compared on a grid of simulated time with this slack (s), so that a tick at
#: t = 0.2 s counts as t = 0.2 s whatever the rounding of MuJoCo's time accumulator.
TIME_SLACK = 1e-6


class Rate:
    """Due once per period of simulated time: at the first tick at or after each multiple of
    1/hz (hz = 0: never). Simulated time going backwards (a world reset) starts it afresh.

    ``what`` names the rate in the error raised for a negative or non-finite ``hz``."""

    def __init__(self, what: str, hz: float) -> None:
        if not (math.isfinite(hz) and hz >= 0.0):
            raise HandSimError(f"{what} must be a finite rate >= 0 Hz (0 = never), got {hz!r}")
        self.what = what
        self.hz = float(hz)
        self._slot = -1
        self._time = -math.inf

    def due(self, t: float) -> bool:
        """Whether the rate is due at simulated time ``t`` (s); a True answer uses up the
        period that ``t`` falls in."""
        if self.hz == 0.0:
            return False
        if t < self._time:
            self._slot = -1
        self._time = t
        slot = math.floor(t * self.hz + TIME_SLACK)
        if slot <= self._slot:
            return False
        self._slot = slot
        return True

    def restart(self) -> None:
        """Forget the periods already used: the next tick is due (as for a new rate)."""
        self._slot = -1
        self._time = -math.inf


class RateSchedule:
    """Named :class:`Rate`\\ s asked together: ``{name: rate in Hz}``, each checked at once.

    ``what`` (a format string with ``{name}``) names a rate in the errors, e.g.
    ``"{name}_rate_hz"``."""

    def __init__(self, rates_hz: Mapping[str, float], what: str = "{name}") -> None:
        self._rates = {name: Rate(what.format(name=name), hz) for name, hz in rates_hz.items()}

    @property
    def names(self) -> tuple[str, ...]:
        """The rates' names, in the order given."""
        return tuple(self._rates)

    def hz(self, name: str) -> float:
        """The rate ``name`` in Hz."""
        return self._rates[name].hz

    def due(self, t: float) -> dict[str, bool]:
        """Which rates are due at simulated time ``t`` (each one asked, in order)."""
        return {name: rate.due(t) for name, rate in self._rates.items()}

    def restart(self, name: str) -> None:
        """Start the rate ``name`` afresh (see :meth:`Rate.restart`)."""
        self._rates[name].restart()
