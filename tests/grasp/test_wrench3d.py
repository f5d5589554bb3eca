"""3-D contacts on prisms and the 3-D FC/MC controllers (Eq. 5-12 with their phi forms): geometry,
the reduction to the planar controllers, gradients against finite differences, minimizers,
convex gradients."""

import numpy as np
import pytest

from controllers.grasp import wrench
from controllers.grasp.objects import PAPER_OBJECTS, paper_object, random_convex_polygon
from controllers.grasp.polygon import wrap_angle
from controllers.grasp.polygon_batch import PolygonBatch
from controllers.grasp.prism import (
    BASE_FACE,
    TOP_FACE,
    Prism,
    face_axes,
    locate_contacts_3d,
    move_on_faces,
)
from controllers.grasp.wrench3d import (
    eps_fc,
    eps_mc,
    fc_gradient,
    fc_gradient_convex,
    fc_minimizer_phi,
    fc_minimizer_theta,
    fc_wrenches,
    mc_gradient,
    mc_gradient_convex,
    mc_minimizer_phi,
    mc_minimizer_theta,
    mc_moments,
    mc_residual,
    mc_surface_gradient,
    mc_surface_minimizer,
    mc_wrenches,
    planar_task,
)

H = 1e-6
T, N = 40, 4


def _prism(rng, top=True):
    poly = random_convex_polygon(rng).unit_moment()
    return Prism(poly, float(rng.uniform(0.3, 3.0)), top)


def _task6(rng, batch=T):
    return rng.uniform(-0.3, 0.3, (batch, 6))


def _interior(prism, rng, shape, margin=0.03):
    """Rays (theta, phi) at least ``margin`` rad from every edge of the prism (vertical edges and
    the rims of the top and base), so that small moves stay on the face."""
    va = prism.polygon.vertex_angles
    theta = rng.uniform(-np.pi, np.pi, shape)
    phi = rng.uniform(-1.2, 1.45, shape)
    while True:
        near_v = np.abs(wrap_angle(theta[..., None] - va)).min(-1) < margin
        near_rim = np.abs(np.abs(phi) - prism.edge_elevation(theta)) < margin
        near_pole = np.abs(phi) > 0.5 * np.pi - margin
        bad = near_v | near_rim | near_pole
        if not bad.any():
            return theta, phi
        theta[bad] = rng.uniform(-np.pi, np.pi, bad.sum())
        phi[bad] = rng.uniform(-1.2, 1.45, bad.sum())


# --- the prism and its contact frames ----------------------------------------------------------
def test_located_contacts_lie_on_their_faces_along_their_rays():
    rng = np.random.default_rng(0)
    prism = _prism(rng)
    theta, phi = rng.uniform(-np.pi, np.pi, (T, N)), rng.uniform(-1.5, 1.5, (T, N))
    f = prism.locate(theta, phi)
    assert set(np.unique(f.face)) >= {TOP_FACE, BASE_FACE, 0}
    back = prism.coordinates_of(f.point)
    assert np.allclose(wrap_angle(back[0] - theta), 0.0, atol=1e-12)
    assert np.allclose(back[1], phi, atol=1e-12)
    # on the face's plane, inside the prism's slab and polygon
    assert np.allclose((f.point * f.normal).sum(-1), f.offset)
    assert np.all(np.abs(f.point[..., 2]) <= prism.half_height * (1 + 1e-12))
    inside = (
        f.point[..., None, :2]
        @ np.stack([np.cos(prism.polygon.normal_angle), np.sin(prism.polygon.normal_angle)])
    )[..., 0, :]
    assert np.all(inside <= prism.polygon.offset * (1 + 1e-9))
    # the surface coordinates rebuild the point (Eq. 9's parameterization)
    n, e_t, e_p = face_axes(f.normal_theta, f.normal_phi)
    rebuilt = (
        f.offset[..., None] * n + f.surface[..., 0, None] * e_t + f.surface[..., 1, None] * e_p
    )
    assert np.allclose(rebuilt, f.point, atol=1e-12)
    side = f.face >= 0
    assert np.allclose(f.surface[side][:, 1], f.point[side][:, 2])  # r_phi = height above c.o.m.
    assert np.all(f.normal_phi[side] == 0.0)
    assert np.allclose(f.normal_phi[f.face == TOP_FACE], np.pi / 2)


def test_moments_of_eq9_are_r_cross_f():
    rng = np.random.default_rng(1)
    prism = _prism(rng)
    f = prism.locate(rng.uniform(-np.pi, np.pi, (T, N)), rng.uniform(-1.5, 1.5, (T, N)))
    assert np.allclose(mc_moments(f), np.cross(f.point, -f.normal), atol=1e-12)


def test_moving_on_faces_is_locating_again_while_no_edge_is_crossed():
    rng = np.random.default_rng(2)
    prism = _prism(rng)
    theta, phi = _interior(prism, rng, (T, N))
    f = prism.locate(theta, phi)
    moved = move_on_faces(f, theta + 0.01, phi - 0.01)
    again = prism.locate(theta + 0.01, phi - 0.01)
    same = again.face == f.face
    assert same.mean() > 0.8
    for a, b in zip(moved, again, strict=True):
        assert np.allclose(a[same], b[same], atol=1e-12)


def test_unit_moment_prism_and_allowed_faces():
    rng = np.random.default_rng(3)
    prism = _prism(rng).scaled(0.05)
    unit = prism.unit_moment()
    assert unit.max_moment == pytest.approx(1.0)
    f = unit.locate(rng.uniform(-np.pi, np.pi, (500, 2)), rng.uniform(-1.57, 1.57, (500, 2)))
    m = np.linalg.norm(mc_moments(f), axis=-1)
    assert m.max() <= 1.0 + 1e-12 and m.max() > 0.5
    assert not np.any(unit.allowed(f)[f.face == BASE_FACE])
    assert np.all(unit.allowed(f)[f.face == TOP_FACE])
    no_top = Prism(unit.polygon, unit.height, top=False)
    assert not np.any(no_top.allowed(f)[f.face == TOP_FACE])
    # a flat prism touched on its sides only has the polygon's moment scale; its top face has
    # larger moments (a vertex's distance from the axis: sqrt(2) on the unit-moment square)
    square = paper_object("square").unit_moment()
    assert Prism(square, 1e-9, top=False).max_moment == pytest.approx(1.0)
    assert Prism(square, 1e-9).max_moment == pytest.approx(np.sqrt(2.0))


# --- the reduction to the planar controllers ---------------------------------------------------
@pytest.mark.parametrize("name", PAPER_OBJECTS)
def test_reduces_to_the_planar_controllers_at_phi_zero(name):
    """All contacts on side faces at phi = 0 (r_phi = 0) with a planar task: the 3-D eps, theta
    gradients, minimizers and convex gradients are the planar ones (wrench.py); the phi
    gradients vanish (the plane of the centre of mass is an equilibrium in phi)."""
    rng = np.random.default_rng(100 + PAPER_OBJECTS.index(name))
    batch = PolygonBatch.of([paper_object(name)])  # unit-moment, as trials use them
    idx = np.zeros(T, dtype=int)
    theta = rng.uniform(-np.pi, np.pi, (T, N))
    phi = np.zeros_like(theta)
    half = rng.uniform(0.1, 2.0, T)
    for task3 in (None, rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.3, 0.3, (T, 3))):
        task6 = planar_task(task3)
        planar = batch.locate(idx, theta)
        f = locate_contacts_3d(batch.normal_angle[idx], batch.offset[idx], half, theta, phi)
        assert np.all(f.face == planar.edge) and np.all(f.surface[..., 1] == 0.0)

        def same(a, b):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)

        same(eps_fc(theta, phi, task6), wrench.eps_fc(theta, task3))
        g = fc_gradient(theta, phi, task6)
        same(g[..., 0], wrench.fc_gradient(theta, task3))
        same(g[..., 1], 0.0)
        for a, b in zip(
            fc_minimizer_theta(theta, phi, task6), wrench.fc_minimizer(theta, task3), strict=True
        ):
            same(a, b)
        same(fc_gradient_convex(theta, phi, task6)[..., 0], wrench.fc_gradient_convex(theta, task3))
        w3, w2 = mc_wrenches(f), wrench.mc_wrenches(planar)
        same(w3[..., [0, 1, 5]], w2)
        same(w3[..., 2:5], 0.0)
        same(eps_mc(f, task6), wrench.eps_mc(planar, task3))
        same(mc_residual(f, task6)[:, [0, 1, 5]], wrench.mc_residual(planar, task3))
        g = mc_gradient(f, task6)
        same(g[..., 0], wrench.mc_gradient(planar, theta, task3))
        same(g[..., 1], 0.0)
        for a, b in zip(
            mc_minimizer_theta(f, task6), wrench.mc_minimizer(planar, theta, task3), strict=True
        ):
            same(a, b)
        same(mc_gradient_convex(f, task6)[..., 0], wrench.mc_gradient_convex(planar, theta, task3))


def test_fc_wrench_model_is_section_342():
    theta, phi = np.array([[0.3, -2.0]]), np.array([[0.4, -1.1]])
    w = fc_wrenches(theta, phi)[0, 0]
    c, s = np.cos, np.sin
    assert np.allclose(w, [-c(0.3) * c(0.4), -s(0.3) * c(0.4), -s(0.4), 0, 0, 0])
    # Eq. 5 as printed
    t = np.array([0.1, -0.2, 0.3, 0.0, 0.0, 0.0])
    e = (
        (t[0] + np.mean(c(theta) * c(phi))) ** 2
        + (t[1] + np.mean(s(theta) * c(phi))) ** 2
        + (t[2] + np.mean(s(phi))) ** 2
    )
    assert eps_fc(theta, phi, t)[0] == pytest.approx(e)


def test_bad_task_is_refused():
    with pytest.raises(ValueError, match="planar_task"):
        eps_fc(np.zeros((1, 2)), np.zeros((1, 2)), task=[1.0, 2.0, 3.0])


# --- gradients against central finite differences ---------------------------------------------
def _nudge(x, k, h):
    y = x.copy()
    y[:, k] += h
    return y


@pytest.mark.parametrize("seed", [10, 11, 12])
def test_fc_gradients_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    theta, phi = rng.uniform(-np.pi, np.pi, (T, N)), rng.uniform(-1.5, 1.5, (T, N))
    task = _task6(rng)
    g = fc_gradient(theta, phi, task)
    for k in range(N):
        fd_t = (
            eps_fc(_nudge(theta, k, H), phi, task) - eps_fc(_nudge(theta, k, -H), phi, task)
        ) / (2 * H)
        fd_p = (
            eps_fc(theta, _nudge(phi, k, H), task) - eps_fc(theta, _nudge(phi, k, -H), task)
        ) / (2 * H)
        np.testing.assert_allclose(g[:, k, 0], fd_t, atol=1e-8)
        np.testing.assert_allclose(g[:, k, 1], fd_p, atol=1e-8)


@pytest.mark.parametrize("seed", [20, 21, 22, 23])
def test_mc_gradients_match_finite_differences(seed):
    """Exact (theta, phi) gradient on random prisms with contacts on side faces at random heights
    and on the top and base, random 6-D tasks: against finite differences on the faces' planes and
    against locating the contacts again."""
    rng = np.random.default_rng(seed)
    prism = _prism(rng)
    theta, phi = _interior(prism, rng, (T, N))
    task = _task6(rng)
    f = prism.locate(theta, phi)
    assert (f.face == TOP_FACE).any() and (f.face >= 0).any()
    g = mc_gradient(f, task)
    h = 1e-7
    for k in range(N):
        for j, (tp, tm) in enumerate(
            [
                ((_nudge(theta, k, h), phi), (_nudge(theta, k, -h), phi)),
                ((theta, _nudge(phi, k, h)), (theta, _nudge(phi, k, -h))),
            ]
        ):
            fd = (eps_mc(move_on_faces(f, *tp), task) - eps_mc(move_on_faces(f, *tm), task)) / (
                2 * h
            )
            np.testing.assert_allclose(g[:, k, j], fd, rtol=1e-6, atol=1e-7)
            fd2 = (eps_mc(prism.locate(*tp), task) - eps_mc(prism.locate(*tm), task)) / (2 * h)
            np.testing.assert_allclose(g[:, k, j], fd2, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("seed", [30, 31])
def test_mc_surface_gradients_match_finite_differences(seed):
    rng = np.random.default_rng(seed)
    prism = _prism(rng)
    f = prism.locate(*_interior(prism, rng, (T, N)))
    task = _task6(rng)
    g = mc_surface_gradient(f, task)
    for k in range(N):
        for j in range(2):
            sp, sm = f.surface.copy(), f.surface.copy()
            sp[:, k, j] += H
            sm[:, k, j] -= H
            fd = (eps_mc(f._replace(surface=sp), task) - eps_mc(f._replace(surface=sm), task)) / (
                2 * H
            )
            np.testing.assert_allclose(g[:, k, j], fd, atol=1e-8)


# --- minimizers ---------------------------------------------------------------------------------
def _set(x, k, value):
    y = x.copy()
    y[:, k] = value
    return y


def _along_grid(f, theta, phi, task, k, *, theta_k=None, phi_k=None):
    """The least eps_MC (T,) over contact k moved (on its face's plane) to each row of the grid
    ``theta_k`` or ``phi_k`` (G, T), the other contacts held: all G moves in one batch."""
    g = len(theta_k if theta_k is not None else phi_k)

    def tiled(x):
        return np.tile(x, (g,) + (1,) * (x.ndim - 1))

    th, ph = tiled(theta), tiled(phi)
    if theta_k is not None:
        th[:, k] = np.ravel(theta_k)
    if phi_k is not None:
        ph[:, k] = np.ravel(phi_k)
    frames = f._replace(**{name: tiled(value) for name, value in f._asdict().items()})
    return eps_mc(move_on_faces(frames, th, ph), tiled(task)).reshape(g, -1).min(0)


@pytest.mark.parametrize("seed", [40, 41])
def test_fc_minimizers_are_the_minima_along_their_coordinate(seed):
    rng = np.random.default_rng(seed)
    theta, phi = rng.uniform(-np.pi, np.pi, (T, N)), rng.uniform(-1.4, 1.4, (T, N))
    task = _task6(rng)
    grid = np.linspace(-np.pi, np.pi, 4001)
    for minimizer, j in ((fc_minimizer_theta, 0), (fc_minimizer_phi, 1)):
        star, eps_star = minimizer(theta, phi, task)
        for k in range(N):
            at = [theta, phi]
            at[j] = _set(at[j], k, star[:, k])
            assert np.allclose(eps_fc(*at, task), eps_star[:, k], atol=1e-12)
            assert np.allclose(fc_gradient(*at, task)[:, k, j], 0.0, atol=1e-12)
            # brute force along the coordinate (phi along the whole meridian great circle)
            cand = [
                np.repeat(theta[:, None, :], grid.size, 1),
                np.repeat(phi[:, None, :], grid.size, 1),
            ]
            cand[j][:, :, k] = grid
            e = eps_fc(
                cand[0].reshape(-1, N), cand[1].reshape(-1, N), np.repeat(task, grid.size, 0)
            )
            e = e.reshape(T, grid.size)
            assert np.all(eps_star[:, k] <= e.min(1) + 1e-12)
            assert np.allclose(eps_star[:, k], e.min(1), atol=1e-5)


@pytest.mark.parametrize("seed", [50, 51, 52])
def test_mc_phi_minimizer_is_the_minimum_along_phi(seed):
    """phi_k*: derivative 0, second derivative > 0 and eps_MC* there, on the face's plane (the
    minimum may lie beyond the face, as Eq. 11's theta_k* may); and a grid search along phi."""
    rng = np.random.default_rng(seed)
    prism = _prism(rng)
    theta, phi = _interior(prism, rng, (T, N))
    task = _task6(rng)
    f = prism.locate(theta, phi)
    star, eps_star = mc_minimizer_phi(f, task)
    r_star = mc_surface_minimizer(f, task)
    h = 1e-5
    for k in range(N):
        at = move_on_faces(f, theta, _set(phi, k, star[:, k]))
        np.testing.assert_allclose(at.surface[:, k, 1], r_star[:, k, 1], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(eps_mc(at, task), eps_star[:, k], rtol=1e-9, atol=1e-12)
        assert np.allclose(mc_gradient(at, task)[:, k, 1], 0.0, atol=1e-9)
        e = [
            eps_mc(move_on_faces(f, theta, _set(phi, k, star[:, k] + d)), task) for d in (-h, 0, h)
        ]
        assert np.all(e[0] + e[2] - 2 * e[1] > 0)
        # grid search along phi on the face's plane: side faces phi in (-pi/2, pi/2), the top's
        # plane phi in (0, pi), the base's (-pi, 0)
        top, base = f.face[:, k] == TOP_FACE, f.face[:, k] == BASE_FACE
        u = np.linspace(0.0, 1.0, 3001)[:, None]
        side_p, top_p = -1.5 + 3.0 * u, 0.02 + (np.pi - 0.04) * u
        p_k = np.where(top, top_p, np.where(base, -top_p, side_p))  # (grid, T)
        best = _along_grid(f, theta, phi, task, k, phi_k=p_k)
        inside = np.where(
            f.on_cap[:, k], np.abs(star[:, k]) < np.pi - 0.1, np.abs(star[:, k]) < 1.4
        )
        assert inside.sum() > T // 2
        assert np.all(eps_star[:, k] <= best + 1e-12)
        np.testing.assert_allclose(eps_star[inside, k], best[inside], atol=1e-4)


@pytest.mark.parametrize("seed", [60, 61, 62])
def test_mc_theta_minimizer_eq11(seed):
    """Side faces: theta_k* puts r_theta at r*_theta (the zero of d eps_MC / d r_theta at the
    contact's height), where eps_MC = eps_MC*, and at phi = 0 it is the minimum along theta.
    Top/base faces: the minimum turning about the vertical axis at fixed phi."""
    rng = np.random.default_rng(seed)
    prism = _prism(rng)
    theta, phi = _interior(prism, rng, (T, N))
    task = _task6(rng)
    f = prism.locate(theta, phi)
    star, eps_star = mc_minimizer_theta(f, task)
    r_star = mc_surface_minimizer(f, task)
    side, cap = f.face >= 0, f.on_cap
    for k in range(N):
        # side: r_theta = r*_theta at fixed height
        surf = f.surface.copy()
        surf[:, k, 0] = f.offset[:, k] * np.tan(star[:, k] - f.normal_theta[:, k])
        at = f._replace(surface=surf)
        s = side[:, k]
        np.testing.assert_allclose(surf[s, k, 0], r_star[s, k, 0], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(eps_mc(at, task)[s], eps_star[s, k], rtol=1e-9, atol=1e-12)
        assert np.allclose(mc_surface_gradient(at, task)[s, k, 0], 0.0, atol=1e-12)
        # cap: on the circle of fixed phi
        c = cap[:, k]
        at = move_on_faces(f, _set(theta, k, star[:, k]), phi)
        np.testing.assert_allclose(eps_mc(at, task)[c], eps_star[c, k], rtol=1e-9, atol=1e-12)
        assert np.allclose(mc_gradient(at, task)[c, k, 0], 0.0, atol=1e-9)
        grid = np.broadcast_to(np.linspace(-np.pi, np.pi, 2001)[:, None], (2001, T))
        best = _along_grid(f, theta, phi, task, k, theta_k=grid)
        assert np.all(eps_star[c, k] <= best[c] + 1e-12)
        np.testing.assert_allclose(eps_star[c, k], best[c], atol=1e-5)
    # phi = 0 on side faces: the minimum along theta itself
    flat = prism.locate(theta, np.zeros_like(phi))
    star, eps_star = mc_minimizer_theta(flat, task)
    for k in range(N):
        at = move_on_faces(flat, _set(theta, k, star[:, k]), flat.phi)
        np.testing.assert_allclose(eps_mc(at, task), eps_star[:, k], rtol=1e-9, atol=1e-12)
        assert np.allclose(mc_gradient(at, task)[:, k, 0], 0.0, atol=1e-9)


# --- convex gradients (Eq. 7, 12 and their phi forms) -------------------------------------------
@pytest.mark.parametrize("seed", [70, 71])
def test_convex_fc_gradients_keep_the_equilibrium_and_the_direction(seed):
    rng = np.random.default_rng(seed)
    theta, phi = rng.uniform(-np.pi, np.pi, (200, N)), rng.uniform(-1.4, 1.4, (200, N))
    task = _task6(rng, 200)
    exact, convex = fc_gradient(theta, phi, task), fc_gradient_convex(theta, phi, task)
    significant = np.abs(exact) > 1e-9
    assert np.all(np.sign(exact[significant]) == np.sign(convex[significant]))
    for j, minimizer in enumerate((fc_minimizer_theta, fc_minimizer_phi)):
        star, _ = minimizer(theta, phi, task)
        at = [theta, phi]
        at[j] = _set(at[j], 0, star[:, 0])
        assert np.allclose(fc_gradient_convex(*at, task)[:, 0, j], 0.0, atol=1e-9)
        assert np.allclose(fc_gradient(*at, task)[:, 0, j], 0.0, atol=1e-12)
        # near the minimum the quadratic's slope is the exact gradient's
        near = [theta, phi]
        near[j] = _set(near[j], 0, star[:, 0] + 1e-4)
        ex, cv = fc_gradient(*near, task)[:, 0, j], fc_gradient_convex(*near, task)[:, 0, j]
        curved = np.abs(ex) > 1e-7
        np.testing.assert_allclose(cv[curved] / ex[curved], 1.0, atol=1e-3)


@pytest.mark.parametrize("seed", [80, 81])
def test_convex_mc_gradients_keep_the_equilibrium_and_the_direction(seed):
    rng = np.random.default_rng(seed)
    prism = _prism(rng)
    theta, phi = _interior(prism, rng, (200, N))
    task = _task6(rng, 200)
    f = prism.locate(theta, phi)
    exact, convex = mc_gradient(f, task), mc_gradient_convex(f, task)
    # phi: eps_MC is a convex quadratic of r_phi and r_phi grows with phi on every face
    sig = np.abs(exact[..., 1]) > 1e-7
    assert np.all(np.sign(exact[..., 1][sig]) == np.sign(convex[..., 1][sig]))
    # theta: on the top and base (turning at fixed phi) and on side faces at phi = 0
    cap = f.on_cap & (np.abs(exact[..., 0]) > 1e-7)
    assert np.all(np.sign(exact[..., 0][cap]) == np.sign(convex[..., 0][cap]))
    flat = prism.locate(theta, np.zeros_like(phi))
    ex0, cv0 = mc_gradient(flat, task)[..., 0], mc_gradient_convex(flat, task)[..., 0]
    sig = np.abs(ex0) > 1e-7
    assert np.all(np.sign(ex0[sig]) == np.sign(cv0[sig]))
    # the convex gradients vanish at the minimizers, where the true coordinate minimum is
    for j, minimizer in enumerate((mc_minimizer_theta, mc_minimizer_phi)):
        star, _ = minimizer(f, task)
        at = [theta, phi]
        at[j] = _set(at[j], 0, star[:, 0])
        moved = move_on_faces(f, *at)
        assert np.allclose(mc_gradient_convex(moved, task)[:, 0, j], 0.0, atol=1e-9)
        # and the true gradient: along phi everywhere, along theta on caps (side faces: in r_theta)
        g = mc_gradient(moved, task)[:, 0, j]
        keep = np.ones(200, bool) if j == 1 else f.on_cap[:, 0]
        assert np.allclose(g[keep], 0.0, atol=1e-9)
        if j == 0:
            side = ~f.on_cap[:, 0]
            assert np.allclose(mc_surface_gradient(moved, task)[side, 0, 0], 0.0, atol=1e-9)
