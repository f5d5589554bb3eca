"""controllers.posture.ik_progress: an IK reach is given up only when its error cannot reach the
tolerance at the rate it is falling, and never while it converges."""

from __future__ import annotations

import numpy as np

from controllers.posture.ik_progress import STALL_WINDOW, ReachProgress


def first_hopeless(errors: np.ndarray, tolerance: float, budget: int) -> int | None:
    """The iterate at which :class:`ReachProgress` gives up, or None."""
    watch = ReachProgress(tolerance, budget)
    for k, e in enumerate(errors):
        if watch.hopeless(float(e)):
            return k
    return None


def test_a_flat_error_above_the_tolerance_is_given_up_after_one_window() -> None:
    errors = np.r_[np.linspace(0.02, 0.008, 10), np.full(240, 0.008)]
    # the best error stops falling at iterate 9: one window later the reach is given up
    assert first_hopeless(errors, 0.002, 250) == 9 + STALL_WINDOW


def test_a_converging_reach_is_never_given_up() -> None:
    errors = 0.02 * 0.97 ** np.arange(250)  # reaches 2 mm after about 76 iterations
    assert first_hopeless(errors, 0.002, 250) is None


def test_a_slow_but_sufficient_descent_is_kept() -> None:
    # 0.1 mm per window from 4 mm: 2 mm is reached at iterate 400 of a 450-iterate budget
    errors = 0.004 - 5e-6 * np.arange(450)
    assert first_hopeless(errors, 0.002, 450) is None
    # the same descent with too few iterations left is given up
    assert first_hopeless(errors, 0.002, 200) == STALL_WINDOW


def test_an_error_within_the_tolerance_is_never_hopeless() -> None:
    assert first_hopeless(np.full(100, 0.0015), 0.002, 100) is None
