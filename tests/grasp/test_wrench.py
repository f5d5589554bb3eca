"""Wrench models, errors and gradients (Eq. 2-12) against finite differences and brute force."""

import numpy as np
import pytest

from controllers.grasp import paper_object, regular_polygon
from controllers.grasp.trials import PolygonBatch
from controllers.grasp.wrench import (
    eps_fc,
    eps_mc,
    fc_gradient,
    fc_gradient_convex,
    fc_minimizer,
    fc_wrenches,
    mc_gradient,
    mc_gradient_convex,
    mc_minimizer,
    mc_residual,
    mc_wrenches,
    sufficiency,
)

H = 1e-6


def test_eps_fc_values():
    assert eps_fc(np.array([[0.0, np.pi]]))[0] == pytest.approx(0.0)
    assert eps_fc(np.array([[0.3, 0.3]]))[0] == pytest.approx(1.0)
    # a task wrench moves the minimum: t_f = (-1, 0) is met by both contacts at theta = 0
    assert eps_fc(np.array([[0.0, 0.0]]), task=[-1.0, 0.0, 0.0])[0] == pytest.approx(0.0)


@pytest.mark.parametrize("n", [2, 3, 4, 6])
def test_fc_gradient_eq6_matches_finite_differences(n):
    theta = np.random.default_rng(n).uniform(-np.pi, np.pi, (20, n))
    task = np.array([0.1, -0.2, 0.0])
    g = fc_gradient(theta, task)
    for k in range(n):
        d = np.zeros_like(theta)
        d[:, k] = H
        fd = (eps_fc(theta + d, task) - eps_fc(theta - d, task)) / (2 * H)
        assert np.allclose(g[:, k], fd, atol=1e-7)


def test_fc_minimizer_eq8_is_the_brute_force_minimum():
    theta = np.random.default_rng(1).uniform(-np.pi, np.pi, (10, 4))
    star, eps_star = fc_minimizer(theta)
    grid = np.linspace(-np.pi, np.pi, 20001)
    for i in range(10):
        for k in range(4):
            t = np.repeat(theta[i : i + 1], grid.size, axis=0)
            t[:, k] = grid
            e = eps_fc(t)
            assert eps_star[i, k] == pytest.approx(e.min(), abs=1e-8)
            assert np.cos(star[i, k] - grid[np.argmin(e)]) > np.cos(1e-3)


def test_convex_fc_gradient_eq7_is_a_descent_direction_with_the_same_minimum():
    theta = np.random.default_rng(2).uniform(-np.pi, np.pi, (200, 4))
    exact = fc_gradient(theta)
    convex = fc_gradient_convex(theta)
    significant = np.abs(exact) > 1e-9
    assert np.all(np.sign(exact[significant]) == np.sign(convex[significant]))
    star, _ = fc_minimizer(theta)
    at_star = theta.copy()
    at_star[:, 0] = star[:, 0]
    assert np.allclose(fc_gradient_convex(at_star)[:, 0], 0.0, atol=1e-9)


def _interior_thetas(poly, rng, shape, margin=0.05):
    """Contact angles at least ``margin`` rad away from every vertex."""
    theta = rng.uniform(-np.pi, np.pi, shape)
    va = poly.vertex_angles
    while True:
        near = np.abs(np.angle(np.exp(1j * (theta[..., None] - va)))).min(-1) < margin
        if not near.any():
            return theta
        theta[near] = rng.uniform(-np.pi, np.pi, near.sum())


@pytest.mark.parametrize("name", ["square", "irregular_pentagon", "trapezoid"])
def test_mc_gradient_matches_finite_differences_within_a_facet(name):
    batch = PolygonBatch.of([paper_object(name)])
    poly = batch.polygons[0]
    theta = _interior_thetas(poly, np.random.default_rng(3), (30, 4))
    idx = np.zeros(30, dtype=int)
    task = np.array([0.0, 0.1, 0.2])
    g = mc_gradient(batch.locate(idx, theta), theta, task)
    for k in range(4):
        d = np.zeros_like(theta)
        d[:, k] = H
        fd = (
            eps_mc(batch.locate(idx, theta + d), task) - eps_mc(batch.locate(idx, theta - d), task)
        ) / (2 * H)
        assert np.allclose(g[:, k], fd, atol=1e-6)


def test_mc_minimizer_eq11_cancels_the_moment_when_it_lies_on_the_facet():
    batch = PolygonBatch.of([paper_object("square")])
    rng = np.random.default_rng(4)
    theta = _interior_thetas(batch.polygons[0], rng, (200, 4))
    idx = np.zeros(200, dtype=int)
    frames = batch.locate(idx, theta)
    star, eps_star = mc_minimizer(frames, theta)
    moved = theta.copy()
    moved[:, 0] = star[:, 0]
    frames_star = batch.locate(idx, moved)
    same_edge = frames_star.edge[:, 0] == frames.edge[:, 0]
    assert same_edge.sum() > 20
    w = mc_wrenches(frames_star)
    assert np.allclose(w[same_edge, :, 2].mean(-1), 0.0, atol=1e-9)
    assert np.allclose(eps_mc(frames_star)[same_edge], eps_star[same_edge, 0])


def test_convex_mc_gradient_eq12_agrees_in_sign_with_the_exact_gradient():
    batch = PolygonBatch.of([paper_object("rectangle")])
    theta = _interior_thetas(batch.polygons[0], np.random.default_rng(5), (300, 4))
    idx = np.zeros(300, dtype=int)
    frames = batch.locate(idx, theta)
    exact = mc_gradient(frames, theta)
    convex = mc_gradient_convex(frames, theta)
    significant = np.abs(exact) > 1e-6
    assert np.all(np.sign(exact[significant]) == np.sign(convex[significant]))


@pytest.mark.parametrize("sides", [3, 4, 5, 6, 7, 8])
def test_lemma_3_both_contacts_get_the_same_mc_gradient(sides):
    """Appendix B, Lemma .3: two antipodal contacts on a regular polygon move together."""
    batch = PolygonBatch.of([regular_polygon(sides, 1.0, "reg")])
    theta0 = np.random.default_rng(sides).uniform(-np.pi, np.pi, 100)
    theta = np.stack([theta0, theta0 + np.pi], axis=1)
    g = mc_gradient_convex(batch.locate(np.zeros(100, dtype=int), theta), theta)
    assert np.allclose(g[:, 0], g[:, 1], atol=1e-9)


def test_sufficiency_eq2_with_mc_wrenches_is_eps_mc():
    batch = PolygonBatch.of([paper_object("hexagon")])
    theta = np.random.default_rng(6).uniform(-np.pi, np.pi, (50, 4))
    frames = batch.locate(np.zeros(50, dtype=int), theta)
    task = np.array([0.2, 0.0, -0.1])
    assert np.allclose(sufficiency(mc_wrenches(frames), task), eps_mc(frames, task))


def test_bad_task_is_refused():
    with pytest.raises(ValueError, match="t_fx, t_fy, t_mz"):
        eps_fc(np.zeros((1, 2)), task=[1.0, 2.0])


# --- Convex gradient magnitudes (Eq. 7, 12) against minima found without fc/mc_minimizer -------


def _fc_minimum_by_search(theta, task):
    """theta_k* and eps_FC* per contact by a coarse then fine grid over theta_k alone."""
    t, n = theta.shape
    star, eps_star = np.zeros((t, n)), np.zeros((t, n))
    coarse = np.linspace(-np.pi, np.pi, 4001)
    for k in range(n):
        for centre, grid in ((None, coarse), ("fine", None)):
            if centre is None:
                cand = np.repeat(theta[:, None, :], grid.size, axis=1)
                cand[:, :, k] = grid
            else:
                fine = star[:, k, None] + np.linspace(-2e-3, 2e-3, 4001)[None, :]
                cand = np.repeat(theta[:, None, :], fine.shape[1], axis=1)
                cand[:, :, k] = fine
            e = eps_fc(cand.reshape(-1, n), task).reshape(t, -1)
            j = np.argmin(e, axis=1)
            star[:, k] = cand[np.arange(t), j, k]
            eps_star[:, k] = e[np.arange(t), j]
    return star, eps_star


@pytest.mark.parametrize("task", [None, (0.1, -0.2, 0.3)], ids=["null", "task"])
def test_convex_fc_gradient_eq7_magnitude(task):
    """Eq. 7 is 2 (eps_FC - eps_FC*) / (theta_k - theta_k*): the slope of the quadratic through
    the minimum, checked with a minimum found by search (not fc_minimizer)."""
    theta = np.random.default_rng(21).uniform(-np.pi, np.pi, (30, 4))
    star, eps_star = _fc_minimum_by_search(theta, task)
    run = np.angle(np.exp(1j * (theta - star)))
    expected = 2.0 * (eps_fc(theta, task)[:, None] - eps_star) / run
    far = np.abs(run) > 0.05  # the search's 1e-6 rad resolution is negligible here
    assert far.sum() > 80
    np.testing.assert_allclose(fc_gradient_convex(theta, task)[far], expected[far], rtol=1e-4)


@pytest.mark.parametrize("task", [None, (0.1, -0.2, 0.3)], ids=["null", "task"])
def test_convex_fc_gradient_eq7_equals_the_exact_gradient_near_the_minimum(task):
    """Near theta_k* the quadratic of Eq. 7 and eps_FC share their second derivative, so the
    convex gradient tends to the exact one (Eq. 6): a wrong factor on Eq. 7 shows as a ratio."""
    theta = np.random.default_rng(22).uniform(-np.pi, np.pi, (30, 4))
    star, _ = _fc_minimum_by_search(theta, task)
    for k in range(4):
        for delta in (1e-3, -1e-3):
            near = theta.copy()
            near[:, k] = star[:, k] + delta
            exact = fc_gradient(near, task)[:, k]
            convex = fc_gradient_convex(near, task)[:, k]
            curved = np.abs(exact) > 1e-6  # eps_FC is flat only where the minimum is degenerate
            assert curved.sum() > 20
            np.testing.assert_allclose(convex[curved] / exact[curved], 1.0, atol=1e-3)  # 1e-7 here


def _mc_minimum_on_facet(batch, theta, k, task):
    """theta_k* cancelling the moment residual on contact k's current facet (brentq on the
    residual of Eq. 10 with theta_k alone moving), or None when the facet holds no root."""
    from scipy.optimize import brentq

    idx = np.zeros(1, dtype=int)
    frames = batch.locate(idx, theta[None])
    edge = frames.edge[0, k]
    poly = batch.polygons[0]
    va = poly.vertex_angles
    lo, hi = va[edge], va[(edge + 1) % poly.n_edges]
    hi = lo + np.mod(hi - lo, 2 * np.pi)

    def moment(x):
        t = theta.copy()
        t[k] = x
        return mc_residual(batch.locate(idx, t[None]), task)[0, 2]

    a, b = lo + 1e-9, hi - 1e-9
    if moment(a) * moment(b) > 0:
        return None
    return brentq(moment, a, b, xtol=1e-14)


@pytest.mark.parametrize("task", [None, (0.05, 0.1, -0.15)], ids=["null", "task"])
@pytest.mark.parametrize("name", ["square", "hexagon"])
def test_convex_mc_gradient_eq12_magnitude(name, task):
    """Eq. 12 with theta_k* found by root search on the facet (not mc_minimizer): the convex
    gradient is 2 (eps_MC - eps_MC*) / (theta_k - theta_k*) and equals the exact gradient
    (Eq. 3, checked by finite differences above) near theta_k*."""
    batch = PolygonBatch.of([paper_object(name)])
    poly = batch.polygons[0]
    theta = _interior_thetas(poly, np.random.default_rng(23), (40, 4))
    checked = 0
    for i in range(theta.shape[0]):
        star = _mc_minimum_on_facet(batch, theta[i], 0, task)
        if star is None:
            continue
        run = np.angle(np.exp(1j * (theta[i, 0] - star)))
        if abs(run) < 0.02:
            continue
        at_star = theta[i].copy()
        at_star[0] = star
        one = np.zeros(1, dtype=int)
        eps_star = eps_mc(batch.locate(one, at_star[None]), task)[0]
        frames = batch.locate(one, theta[i][None])
        expected = 2.0 * (eps_mc(frames, task)[0] - eps_star) / run
        got = mc_gradient_convex(frames, theta[i][None], task)[0, 0]
        assert got == pytest.approx(expected, rel=1e-9, abs=1e-12)
        near = at_star.copy()
        near[0] = star + 1e-4
        f_near = batch.locate(one, near[None])
        exact = mc_gradient(f_near, near[None], task)[0, 0]
        convex = mc_gradient_convex(f_near, near[None], task)[0, 0]
        assert convex / exact == pytest.approx(1.0, abs=1e-3)  # 1e-4 here (O(delta))
        checked += 1
    assert checked >= 10


def test_mc_moment_is_the_moment_of_the_inward_normal_force():
    """Eq. 9's m_z is p x f for the unit inward force f = -n at the contact point p: the same
    sign convention as S_G (score.py), so a task moment means the same thing to both."""
    poly = paper_object("irregular_hexagon").unit_moment()
    f = poly.locate(np.random.default_rng(24).uniform(-np.pi, np.pi, (1, 50)))
    w = mc_wrenches(f)[0]
    p, force = f.point[0], -f.normal[0]
    np.testing.assert_allclose(w[:, :2], force, atol=1e-12)
    np.testing.assert_allclose(w[:, 2], p[:, 0] * force[:, 1] - p[:, 1] * force[:, 0], atol=1e-12)


@pytest.mark.parametrize("task", [None, (0.2, -0.1, 0.0)], ids=["null", "force_task"])
def test_sufficiency_eq2_with_fc_wrenches_is_eps_fc(task):
    """Eq. 5 is Eq. 2 with the FC model w = (-cos theta, -sin theta, 0)."""
    theta = np.random.default_rng(7).uniform(-np.pi, np.pi, (50, 4))
    w = fc_wrenches(theta)
    assert w.shape == (50, 4, 3)
    np.testing.assert_allclose(w[..., 0] ** 2 + w[..., 1] ** 2, 1.0)
    np.testing.assert_allclose(np.arctan2(-w[..., 1], -w[..., 0]), theta, atol=1e-12)
    np.testing.assert_allclose(sufficiency(w, task), eps_fc(theta, task))


def test_task_with_a_nan_component_is_refused():
    with pytest.raises(ValueError, match="finite"):
        eps_fc(np.zeros((1, 2)), task=[np.nan, 0.0, 0.0])


def test_a_task_per_grasp_is_applied_row_by_row():
    """A task of shape (T, 3) gives each grasp its own task wrench."""
    theta = np.random.default_rng(9).uniform(-np.pi, np.pi, (5, 3))
    tasks = np.random.default_rng(10).uniform(-0.3, 0.3, (5, 3))
    batch = PolygonBatch.of([paper_object("pentagon")])
    frames = batch.locate(np.zeros(5, dtype=int), theta)
    for i in range(5):
        one = batch.locate(np.zeros(1, dtype=int), theta[i : i + 1])
        assert eps_fc(theta, tasks)[i] == pytest.approx(eps_fc(theta[i : i + 1], tasks[i])[0])
        assert eps_mc(frames, tasks)[i] == pytest.approx(eps_mc(one, tasks[i])[0])
