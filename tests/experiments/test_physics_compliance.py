"""The grasp-compliance prediction (experiments.physics.compliance) against an independent
computation: the block displacement that minimises the springs' energy minus the load's work."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from experiments.physics.compliance import (
    UNRESISTED_TURN,
    grasp_stiffness,
    predicted_turn,
    skew,
)


def _rotation(v: np.ndarray) -> np.ndarray:
    """Rotation matrix of rotation vector ``v`` (Rodrigues)."""
    a = np.linalg.norm(v)
    if a < 1e-15:
        return np.eye(3)
    k = skew(v / a)
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k


def _energy_minimum(points, stiff, com, force) -> np.ndarray:
    """(dx, dth) minimising sum 1/2 d_i^T K_i d_i - force . dx, d_i the contact point's true
    (rotated, not linearised) displacement; a small load, so the result is the linear one."""

    def energy(x: np.ndarray) -> float:
        R = _rotation(x[3:])
        e = -force @ x[:3]
        for p, K in zip(points, stiff, strict=True):
            d = x[:3] + R @ (p - com) - (p - com)
            e += 0.5 * d @ K @ d
        return e

    # in 0.1 mm / 0.1 mrad and 10 nJ, so that the optimiser's tolerances are on numbers near one
    res = minimize(lambda y: 1e8 * energy(1e-4 * y), np.zeros(6), method="BFGS", tol=1e-12)
    return 1e-4 * res.x


@pytest.mark.parametrize("seed", range(8))
def test_predicted_turn_is_the_energy_minimum_of_random_finger_springs(seed: int) -> None:
    rng = np.random.default_rng(seed)
    com = rng.normal(0, 0.02, 3)
    points = com + rng.normal(0, 0.04, (4, 3))
    stiff = []
    for _ in range(4):  # random symmetric positive definite finger stiffness, 100-2000 N/m
        Q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        stiff.append(Q @ np.diag(rng.uniform(100, 2000, 3)) @ Q.T)
    force = rng.normal(0, 0.02, 3)  # small: the energy minimum is in the linear range
    K = grasp_stiffness(points, stiff, com)
    x = _energy_minimum(points, stiff, com, force)
    assert predicted_turn(K, force) == pytest.approx(np.linalg.norm(x[3:]), rel=2e-3)
    assert np.allclose(K, K.T)


def test_a_block_on_a_line_of_contacts_turns_freely_under_a_moment_about_it() -> None:
    """Two fingers on opposite faces at the centre of mass's height, pushed along the line at a
    point below it: nothing resists the turn about the line through the contacts."""
    com = np.zeros(3)
    points = np.array([[0.03, 0.0, 0.0], [-0.03, 0.0, 0.0]])
    stiff = [np.eye(3) * 500.0] * 2
    K = grasp_stiffness(points, stiff, com)
    assert predicted_turn(K, np.array([1.0, 0.0, 0.0])) == pytest.approx(0.0, abs=1e-12)
    # the contacts 3 cm above the centre of mass: a push along the line makes a moment about y,
    # which the fingers resist; a push across it a moment about the line, which nothing resists
    high = points + np.array([0.0, 0.0, 0.03])
    K_high = grasp_stiffness(high, stiff, com)
    assert 0.0 < predicted_turn(K_high, np.array([1.0, 0.0, 0.0])) < 0.1
    assert predicted_turn(K_high, np.array([0.0, 1.0, 0.0])) == UNRESISTED_TURN


def test_contacts_spread_in_height_turn_less_than_contacts_at_one_height() -> None:
    com = np.zeros(3)
    ring = np.array([[0.03, 0.0, 0.04], [-0.03, 0.0, 0.04], [0.0, 0.03, 0.04], [0.0, -0.03, 0.04]])
    spread = ring + np.array([[0, 0, 0.0], [0, 0, -0.02], [0, 0, 0.0], [0, 0, -0.02]])
    stiff = [np.eye(3) * 500.0] * 4
    push = np.array([1.0, 0.0, -1.0])
    assert predicted_turn(grasp_stiffness(spread, stiff, com), push) < predicted_turn(
        grasp_stiffness(ring, stiff, com), push
    )
