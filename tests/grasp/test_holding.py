"""The 3-D grasp force programme (controllers.grasp.holding): a hand-derived two-finger pinch,
an independent polyhedral LP that brackets the exact cone, the solution's own equilibrium and
cones, and bad input."""

import numpy as np
import pytest
from scipy.optimize import linprog

from controllers.grasp.holding import holding_forces
from controllers.grasp.objects import random_convex_polygon
from controllers.grasp.prism3d import prism_contacts
from controllers.grasp.score3d import ContactError, tangent_basis, unit_wrenches

FACETS = 64


def pyramid_reserve(points, normals, centre, weight, total, lo, hi, mu, scale):
    """The reserve of the programme with each friction disc replaced by a regular FACETS-gon of
    radius ``scale`` (mu N - lambda) (an independent LP with scipy's HiGHS): scale 1 circumscribes
    the disc (a looser constraint, a reserve at least the exact one), cos(pi / FACETS) inscribes
    it (at most the exact one). None when the LP is infeasible."""
    n = len(points)
    basis = tangent_basis(normals)
    arm = points - centre
    nv = 3 * n + 1  # N, T1, T2, lambda
    a_eq = np.zeros((6, nv))
    a_eq[:, :n] = unit_wrenches(arm, -normals)
    a_eq[:, n : 2 * n] = unit_wrenches(arm, basis[:, 0])
    a_eq[:, 2 * n : 3 * n] = unit_wrenches(arm, basis[:, 1])
    a_eq = np.vstack([a_eq, np.r_[np.ones(n), np.zeros(2 * n + 1)]])
    b_eq = np.array([0.0, 0.0, weight, 0.0, 0.0, 0.0, total])
    angles = 2 * np.pi * np.arange(FACETS) / FACETS
    rows = []
    for i in range(n):
        for a in angles:  # cos a T1 + sin a T2 <= scale (mu N - lambda)
            r = np.zeros(nv)
            r[n + i], r[2 * n + i] = np.cos(a), np.sin(a)
            r[i], r[-1] = -scale * mu, scale
            rows.append(r)
    c = np.zeros(nv)
    c[-1] = -1.0
    bounds = [(lo, hi)] * n + [(None, None)] * (2 * n + 1)
    res = linprog(
        c,
        A_ub=np.array(rows),
        b_ub=np.zeros(len(rows)),
        A_eq=a_eq,
        b_eq=b_eq,
        bounds=bounds,
        method="highs",
    )
    assert res.status in (0, 2)  # solved, or infeasible
    return float(res.x[-1]) if res.status == 0 else None


def test_an_opposed_pinch_spares_mu_n_less_half_the_weight() -> None:
    # two fingers either side of the centre, one height: the total splits evenly and each
    # finger carries half the weight by friction, so the reserve is mu F / 2 - W / 2
    # (hand-derived)
    points = np.array([[0.02, 0.0, 0.0], [-0.02, 0.0, 0.0]])
    normals = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    for weight, mu, total in ((1.5, 1.0, 8.0), (3.0, 0.5, 12.0), (20.0, 1.0, 4.0)):
        hold = holding_forces(
            points, normals, np.zeros(3), weight, total=total, max_force=6.0, friction=mu
        )
        assert hold.solved
        np.testing.assert_allclose(hold.normal_forces, [total / 2] * 2, atol=1e-5)
        assert hold.reserve == pytest.approx(mu * total / 2 - weight / 2, abs=1e-5)
        assert hold.holds == (mu * total > weight)


def random_prism_grasp(rng: np.random.Generator):
    """Four contacts at random heights on the sides of a random prism 0.2 m tall, in its
    centre-of-mass frame (prism_contacts)."""
    poly = random_convex_polygon(rng)
    theta, z = rng.uniform(0, 2 * np.pi, 4), rng.uniform(0.01, 0.19, 4)
    return prism_contacts(poly, theta, z, 0.2, unit_moment=False)


def test_the_solution_holds_the_weight_within_its_cones_and_its_bounds() -> None:
    rng = np.random.default_rng(7)
    solved = 0
    for _ in range(20):
        points, normals = random_prism_grasp(rng)
        weight = float(rng.uniform(0.5, 3.0))
        hold = holding_forces(
            points, normals, np.zeros(3), weight, total=14.0, max_force=6.0, min_force=0.6
        )
        if not hold.solved:  # e.g. three contacts on one face: their bounds cannot balance
            continue
        solved += 1
        N, T = hold.normal_forces, hold.tangential_forces
        forces = (
            -N[:, None] * normals + T[:, :1] * hold.tangents[:, 0] + T[:, 1:] * hold.tangents[:, 1]
        )
        wrench = unit_wrenches(points, forces).sum(axis=1)
        np.testing.assert_allclose(wrench, [0, 0, weight, 0, 0, 0], atol=1e-6)
        assert N.sum() == pytest.approx(14.0, abs=1e-6)
        assert np.all(N >= 0.6 - 1e-6) and np.all(N <= 6.0 + 1e-6)
        assert np.all(np.linalg.norm(T, axis=1) <= N - hold.reserve + 1e-6)
    assert solved >= 15


def test_the_reserve_lies_between_the_inscribed_and_circumscribed_pyramids() -> None:
    rng = np.random.default_rng(11)
    solved = 0
    for _ in range(20):
        points, normals = random_prism_grasp(rng)
        mu = float(rng.uniform(0.4, 1.0))
        hold = holding_forces(
            points, normals, np.zeros(3), 1.5, total=12.0, max_force=6.0, friction=mu
        )
        args = (points, normals, np.zeros(3), 1.5, 12.0, 0.0, 6.0, mu)
        outer = pyramid_reserve(*args, 1.0)
        if not hold.solved:  # infeasible: so is the looser polyhedral programme
            assert outer is None
            continue
        solved += 1
        inner = pyramid_reserve(*args, np.cos(np.pi / FACETS))
        assert inner - 1e-5 <= hold.reserve <= outer + 1e-5
        assert outer - inner < 0.02 * max(1.0, abs(outer))
    assert solved >= 15


def test_a_thumb_below_two_fingers_needs_friction_for_the_moment() -> None:
    # the lateral hand's shape: two fingers on one face (x = +2 cm, y = +-1.5 cm, z = 5 cm), the
    # thumb on the opposite face (x = -2 cm) at z_t, 12 N in all, weight 1.5 N at the origin.
    # Force balance along x: the thumb presses 6 N, the fingers 6 N together. Moments about y:
    # -0.05 * 6 + z_t * (-6) ... the normal forces' couple 6 (0.05 - z_t) must be carried by the
    # vertical friction 4 cm apart: Fz_t - Fz_f = 6 (0.05 - z_t) / 0.02 - with Fz_t + Fz_f = 1.5
    # the thumb's reserve is 6 - Fz_t (hand-derived): 5.25 level, -6.75 and -12.75 below
    normals = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])

    def reserve(thumb_z: float) -> float:
        points = np.array([[0.02, 0.015, 0.05], [0.02, -0.015, 0.05], [-0.02, 0.0, thumb_z]])
        return holding_forces(points, normals, np.zeros(3), 1.5, total=12.0, max_force=6.0).reserve

    # level: the thumb spares 6 - 0.75, each finger 3 - 0.375: the fingers' 2.625 is the least
    assert reserve(0.05) == pytest.approx(2.625, abs=1e-5)
    assert reserve(-0.03) == pytest.approx(6.0 - (1.5 + 6.0 * 0.08 / 0.02) / 2, abs=1e-5)
    assert reserve(-0.07) == pytest.approx(6.0 - (1.5 + 6.0 * 0.12 / 0.02) / 2, abs=1e-5)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"weight": 0.0}, "weight"),
        ({"weight": float("nan")}, "weight"),
        ({"max_force": -1.0}, "max_force"),
        ({"min_force": 7.0}, "min_force"),
        ({"total": 13.0}, "total"),
        ({"total": float("inf")}, "total"),
        ({"friction": 0.0}, "friction"),
        ({"centre": [0.0, 0.0]}, "centre"),
        ({"centre": [0.0, np.nan, 0.0]}, "centre"),
        ({"normals": [[2.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]}, "unit"),
    ],
)
def test_bad_input_is_refused_with_a_clear_message(kwargs, message) -> None:
    args = {
        "points": [[0.02, 0.0, 0.0], [-0.02, 0.0, 0.0]],
        "normals": [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]],
        "centre": [0.0, 0.0, 0.0],
        "weight": 1.5,
        "total": 8.0,
        "max_force": 6.0,
    }
    args.update(kwargs)
    with pytest.raises(ContactError, match=message):
        holding_forces(**args)
