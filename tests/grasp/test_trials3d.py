"""The 3-D grasp controllers on prisms (theta and height): the reduction to the planar trials,
the height step against finite differences of an independently built moment error, the band,
KB/QL/PI on the 3-D state, the task-set common height, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.grasp.errors import GraspError
from controllers.grasp.objects import PAPER_OBJECTS, paper_object, random_convex_polygon
from controllers.grasp.prism3d import worst_task_score
from controllers.grasp.registry import make_composer
from controllers.grasp.task_height import ranked_shifts
from controllers.grasp.trials import run_trials
from controllers.grasp.trials3d import (
    HeightBand,
    PrismBatch,
    control_state_3d,
    height_gradient,
    run_trials_3d,
)

HEIGHT = 0.2
POLYGONS = [paper_object(n) for n in PAPER_OBJECTS]


def _at_centre(polygons):
    """Prisms whose band is the centre of mass's height alone."""
    return PrismBatch.of(polygons, [HEIGHT] * len(polygons), [HeightBand(0.1, 0.1)] * len(polygons))


@pytest.mark.parametrize("controller", ["kb", "ql", "pi"])
def test_contacts_held_at_the_centre_of_mass_height_move_as_the_planar_trials(controller):
    idx = np.repeat(np.arange(len(POLYGONS)), 6)
    theta0 = np.random.default_rng(3).uniform(0.0, 2.0 * np.pi, (idx.size, 4))
    flat = run_trials_3d(
        _at_centre(POLYGONS),
        idx,
        make_composer(controller),
        np.random.default_rng(4),
        initial=(theta0, np.zeros_like(theta0)),
    )
    planar = run_trials(
        POLYGONS, idx, make_composer(controller), np.random.default_rng(4), theta_initial=theta0
    )
    assert np.abs(np.angle(np.exp(1j * (flat.theta_final - planar.theta_final)))).max() < 1e-9
    np.testing.assert_array_equal(flat.steps, planar.steps)
    np.testing.assert_array_equal(flat.success, planar.success)
    ok = planar.feasible
    np.testing.assert_allclose(flat.s_g[ok], planar.s_g[ok], atol=1e-6)
    np.testing.assert_allclose(flat.z_final, 0.0)


def _eps_mc_about(points, normals, centre, task):
    """eps_MC (Eq. 10, 6-D) with unit inward normal forces and moments about ``centre``, built
    from the contact points directly (not the package's face coordinates); the task is given
    about the centre of mass (the origin), so its moment about ``centre`` is m - c x f."""
    f = -normals
    m = np.cross(points - centre, f)
    t = np.zeros(6) if task is None else task.copy()
    t[3:] -= np.cross(centre, t[:3])
    rho = t - np.concatenate([f, m], axis=-1).mean(0)
    return float((rho**2).sum())


@pytest.mark.parametrize("seed", range(6))
def test_the_height_step_is_the_newton_step_of_the_moment_error(seed):
    rng = np.random.default_rng(seed)
    poly = random_convex_polygon(rng)
    batch = PrismBatch.of([poly], [HEIGHT])
    idx = np.zeros(1, dtype=np.int64)
    theta = rng.uniform(0, 2 * np.pi, (1, 4))
    z = rng.uniform(-2.0, 2.0, (1, 4))
    task = rng.normal(scale=0.1, size=6) if seed % 2 else None
    frames = batch.locate(idx, theta, z)
    step = height_gradient(frames, task)[0]
    centre = np.array([0.0, 0.0, z.mean()])  # the reference the step is taken about, held
    n, h = 4, 1e-6
    for k in range(n):
        up, down = frames.point[0].copy(), frames.point[0].copy()
        up[k, 2] += h
        down[k, 2] -= h
        nrm = frames.normal[0]
        d = (_eps_mc_about(up, nrm, centre, task) - _eps_mc_about(down, nrm, centre, task)) / (
            2 * h
        )
        # exact gradient = step * curvature 2 / n^2
        assert d == pytest.approx(step[k] * 2.0 / n**2, abs=1e-7)


def test_a_balanced_grasp_at_one_height_gets_no_height_step():
    square = paper_object("square")
    batch = PrismBatch.of([square], [HEIGHT])
    theta = np.array([[0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi]])
    for z in (-3.0, 0.0, 2.0):
        frames = batch.locate(np.zeros(1, dtype=np.int64), theta, np.full((1, 4), z))
        np.testing.assert_allclose(height_gradient(frames), 0.0, atol=1e-12)


@pytest.mark.parametrize("controller", ["kb", "ql", "pi"])
def test_every_contact_ends_inside_its_band_and_the_same_seed_repeats(controller):
    rng = np.random.default_rng(11)
    polys = [random_convex_polygon(rng) for _ in range(5)]
    bands = [HeightBand.below_top(HEIGHT, 0.04, 0.04 + 0.01 * i) for i in range(5)]
    batch = PrismBatch.of(polys, [HEIGHT] * 5, bands)
    idx = np.repeat(np.arange(5), 4)
    runs = [
        run_trials_3d(batch, idx, make_composer(controller), np.random.default_rng(5))
        for _ in range(2)
    ]
    np.testing.assert_array_equal(runs[0].theta_final, runs[1].theta_final)
    np.testing.assert_array_equal(runs[0].z_final, runs[1].z_final)
    metres = runs[0].points[..., 2] * batch.scale[idx][:, None] + 0.5 * HEIGHT
    for i, k in enumerate(idx):
        assert bands[k].low - 1e-12 <= metres[i].min() <= metres[i].max() <= bands[k].high + 1e-12
    # the 3-D S_G is the one of the final contacts (recomputed independently of the runner)
    assert np.isfinite(runs[0].s_g[runs[0].feasible]).all()


def test_kb_in_3d_fails_no_more_often_than_kb_in_the_plane_on_the_paper_objects():
    """The controllers move heights only through moment closure; they do not make the
    planar part worse (KB, 20 trials per object, heights in a 2 cm band)."""
    idx = np.repeat(np.arange(len(POLYGONS)), 20)
    band = [HeightBand.below_top(HEIGHT, 0.04, 0.06)] * len(POLYGONS)
    three = run_trials_3d(
        PrismBatch.of(POLYGONS, [HEIGHT] * len(POLYGONS), band),
        idx,
        make_composer("kb"),
        np.random.default_rng(2),
    )
    planar = run_trials(POLYGONS, idx, make_composer("kb"), np.random.default_rng(2))
    assert three.failure_rate <= planar.failure_rate + 0.02


def test_the_predictor_gradient_action_is_refused_in_3d():
    pi = make_composer("pi")
    pi.action = "predictor"
    batch = PrismBatch.of([paper_object("square")], [HEIGHT])
    with pytest.raises(GraspError, match="planar only"):
        run_trials_3d(batch, np.zeros(2, dtype=np.int64), pi, np.random.default_rng(0))


def test_the_task_lowers_a_grasp_above_the_centre_of_mass_to_its_lowest_worst_task_score():
    square = paper_object("square")
    batch = PrismBatch.of([square], [HEIGHT])
    theta = np.array([[0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi]])
    z = np.full((1, 4), 3.0)  # 6 cm above the centre of mass, unit-moment frame (2 cm unit)
    frames = batch.locate(np.zeros(1, dtype=np.int64), theta, z)
    p, n = frames.point[0], frames.normal[0]
    chosen = ranked_shifts(p, n, 1.0, 4.0, load=0.5)[0]
    # independently: every shift on a fine grid scores no better than the one chosen
    for d in np.linspace(-2.0, 1.0, 13):
        q = p.copy()
        q[:, 2] += d
        assert worst_task_score(q, n, 0.5)[1].s_g >= chosen.score.s_g - 1e-7
    assert chosen.shift == pytest.approx(-2.0)  # as low as the band allows
    # a band the contacts already fill leaves them where they are
    assert [t.shift for t in ranked_shifts(p, n, 3.0, 3.0, load=0.5)] == [0.0]


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: HeightBand(0.1, 0.05), "above its high"),
        (lambda: HeightBand(float("nan"), 0.1), "finite"),
        (lambda: HeightBand.below_top(0.2, 0.05, 0.3), "depths"),
        (lambda: PrismBatch.of(POLYGONS[:2], [0.2]), "heights"),
        (lambda: PrismBatch.of(POLYGONS[:1], [-0.2]), "positive"),
        (lambda: PrismBatch.of(POLYGONS[:1], [0.2], [HeightBand(0.0, 0.3)]), "above its prism"),
        (lambda: ranked_shifts(np.zeros((4, 2)), np.zeros((4, 3)), 0.0, 1.0, 0.5), "(n, 3)"),
        (lambda: ranked_shifts(np.zeros((4, 3)), np.zeros((4, 3)), 1.0, 0.0, 0.5), "interval"),
    ],
)
def test_bad_input_raises_a_grasp_error_naming_the_problem(make, message):
    with pytest.raises(GraspError, match=message):
        make()


def test_a_control_state_has_theta_then_height_gradients():
    batch = PrismBatch.of(POLYGONS[:2], [HEIGHT] * 2)
    idx = np.array([0, 1])
    theta = np.random.default_rng(0).uniform(0, 2 * np.pi, (2, 4))
    z = np.zeros((2, 4))
    s = control_state_3d(batch, idx, theta, z, 0, np.ones(2, dtype=bool))
    assert s.grad_fc.shape == s.grad_mc.shape == s.coordinates.shape == (2, 8)
    np.testing.assert_array_equal(s.grad_fc[:, 4:], 0.0)  # FC never moves a height


@pytest.mark.parametrize("controller", ["kb", "pi"])
def test_one_grasp_stepped_is_the_trial_runner_and_the_task_then_sets_its_height(controller):
    from controllers.grasp.synthesis3d import GraspSynthesis3D

    poly = paper_object("pentagon")
    band = HeightBand.below_top(HEIGHT, 0.04, 0.06)
    theta0 = np.array([0.3, 1.5, 2.9, 4.4])
    z0 = np.array([0.05, 0.055, 0.045, 0.058])  # m above the centre of mass
    kw = {"min_separation": 0.021, "separation_offset": 0.0085}
    syn = GraspSynthesis3D(
        poly, HEIGHT, band, make_composer(controller), theta0, z0, np.random.default_rng(1), **kw
    )
    while not syn.done:
        syn.step()
    score = syn.finish()
    batch = PrismBatch.of([poly], [HEIGHT], [band])
    runner = run_trials_3d(
        batch,
        np.zeros(1, dtype=np.int64),
        make_composer(controller),
        np.random.default_rng(1),
        initial=(theta0[None], z0[None] / batch.scale[0]),
        **kw,
    )
    np.testing.assert_allclose(syn.theta, runner.theta_final[0], atol=1e-12)
    np.testing.assert_allclose(syn.heights, runner.z_final[0] * batch.scale[0], atol=1e-12)
    assert syn.steps == runner.steps[0] and score.s_g == pytest.approx(runner.s_g[0], abs=1e-9)
    # with the task: the same contacts moved together, as low as the band allows
    tasked = GraspSynthesis3D(
        poly,
        HEIGHT,
        band,
        make_composer(controller),
        theta0,
        z0,
        np.random.default_rng(1),
        load=0.3,
        **kw,
    )
    while not tasked.done:
        tasked.step()
    shift = tasked.heights - syn.heights
    np.testing.assert_allclose(shift, shift[0], atol=1e-12)
    assert tasked.heights.min() == pytest.approx(band.low - 0.5 * HEIGHT, abs=1e-9)
