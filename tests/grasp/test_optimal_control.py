"""Appendix A: time-optimal bang-bang activation on the square."""

import numpy as np
import pytest

from controllers.grasp.optimal_control import (
    PAPER_THETA_T,
    d2_eps_wc,
    d_eps_fc,
    d_eps_wc,
    eps_fc,
    eps_wc,
    solve_time_optimal,
)


def test_final_theta_matches_the_paper():
    path = solve_time_optimal()
    assert path.converged
    assert abs(path.theta_final - PAPER_THETA_T) < 1e-3


def test_activation_is_bang_bang_and_switches():
    path = solve_time_optimal()
    assert set(np.unique(path.alpha)) <= {0.0, 1.0}
    assert path.switches >= 2


@pytest.mark.parametrize("theta", [0.3, 1.0, 2.0, 3.3, 4.5, 5.9])
def test_derivatives_match_finite_differences(theta):
    h = 1e-6
    assert (eps_wc(theta + h) - eps_wc(theta - h)) / (2 * h) == pytest.approx(
        d_eps_wc(theta), abs=1e-6
    )
    assert (d_eps_wc(theta + h) - d_eps_wc(theta - h)) / (2 * h) == pytest.approx(
        d2_eps_wc(theta), abs=1e-5
    )
    assert (eps_fc(theta + h) - eps_fc(theta - h)) / (2 * h) == pytest.approx(
        d_eps_fc(theta), abs=1e-6
    )


def test_final_theta_minimizes_eps_wc_on_the_opposite_face():
    grid = np.linspace(3 * np.pi / 4 + 1e-3, 5 * np.pi / 4 - 1e-3, 20001)
    best = grid[np.argmin(eps_wc(grid))]
    assert abs(solve_time_optimal().theta_final - best) < 1e-3
