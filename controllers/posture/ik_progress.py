"""When to give up an inverse-kinematics reach that cannot succeed.

Posture Control's palm-pose searches (section 5.2; :mod:`controllers.preshape.palm_search`) and the
reach test (:mod:`controllers.hand.reachability`) solve hundreds of fingertip IK problems per
search, and most of them are out of reach: over the slow random scenes of
``python -m experiments.bench`` the reach test's hand IK converges in about 6 iterations when the
contacts are reachable and spends all of its 250 when they are not, its error long flat at several
millimetres. :class:`ReachProgress` watches the worst fingertip error of an IK's iterates and says
when, at the rate it fell over the last :data:`STALL_WINDOW` iterations, it cannot come within the
tolerance in the iterations left; the IK then stops with the same verdict (unreachable) early.
"""

from __future__ import annotations

from dataclasses import dataclass, field

#: Iterations over which the IK's progress is measured.
STALL_WINDOW = 20
#: Progress (m) per window that counts as none: the error could still fall this much per window
#: until the last iteration.
STALL_PROGRESS = 1e-5


@dataclass
class ReachProgress:
    """Watches one IK reach: the worst fingertip error (m) of each iterate against
    ``tolerance`` (m), with ``budget`` iterations in all."""

    tolerance: float
    budget: int
    window: int = STALL_WINDOW
    floor: float = STALL_PROGRESS
    best: list[float] = field(default_factory=list)  #: smallest error so far, per iterate

    def hopeless(self, error: float) -> bool:
        """Record the error of the next iterate; True when it is above the tolerance and the
        best error, falling at its rate over the last window (or ``floor`` per window, if
        more) for the iterations left, would still end above the tolerance."""
        best = min(error, self.best[-1]) if self.best else error
        self.best.append(best)
        k = len(self.best) - 1
        if error <= self.tolerance or k < self.window:
            return False
        rate = max(self.best[k - self.window] - best, self.floor)
        windows_left = (self.budget - k) / self.window
        return best - rate * windows_left > self.tolerance
