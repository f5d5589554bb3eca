"""The PI composer (section 4.3): the noise and its readings, gating by the predictor, the
predictor-gradient action, effect on failures."""

import numpy as np
import pytest

from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.errors import ModelNotTrainedError, UnknownNameError
from controllers.grasp.objects import paper_object, polygon_set
from controllers.grasp.predictor import FSPredictor
from controllers.grasp.preimaging import (
    NOISE_BOUND,
    NOISE_READINGS,
    NOISE_SIGMA,
    PREDICTOR_STEP,
    PreImaging,
    failure_gradient,
    load_pi_composer,
    noise_displacement,
    preimage_noise,
)
from controllers.grasp.qlearning import scaled_error
from controllers.grasp.registry import make_composer
from controllers.grasp.trials import GAIN, PolygonBatch, control_state, run_trials
from controllers.grasp.wrench import eps_fc, eps_mc


class _Rule:
    """A stand-in predictor: failure expected (+1) when eps'_MC >= threshold, else -1."""

    def __init__(self, threshold: float) -> None:
        self.threshold = threshold

    def failure_expectation(self, eps_fc, eps_mc):
        return np.where(scaled_error(eps_mc) >= self.threshold, 1.0, -1.0)


def _state(polys, theta, idx=None):
    batch = PolygonBatch.of(polys)
    idx = np.zeros(theta.shape[0], int) if idx is None else idx
    return control_state(batch, idx, theta, 0, np.ones(theta.shape[0], bool))


def test_noise_is_bounded_with_the_paper_sigma():
    n = preimage_noise(np.random.default_rng(0), (20000,))
    assert np.abs(n).max() <= NOISE_BOUND
    assert n.std() == pytest.approx(NOISE_SIGMA, rel=0.05)
    assert abs(n.mean()) < 1e-3
    assert np.array_equal(
        preimage_noise(np.random.default_rng(0), (50,), 6.0),
        6.0 * preimage_noise(np.random.default_rng(0), (50,)),
    )


def test_each_reading_moves_contacts_by_its_own_amount():
    theta = np.random.default_rng(1).uniform(-np.pi, np.pi, (40, 4))
    state = _state([paper_object("rectangle")], theta)
    noise = preimage_noise(np.random.default_rng(2), theta.shape)
    d = {r: noise_displacement(r, noise, state, GAIN) for r in NOISE_READINGS}
    assert np.array_equal(d["literal"], noise)
    assert np.allclose(d["gradient"], GAIN * noise)
    assert np.allclose(d["turn"], 2 * np.pi * noise)
    # perimeter: the contact slides noise x perimeter along the outline; check by measuring the
    # straight distance between old and new point where both lie on the same edge
    unit = state.batch.polygons[0]
    perimeter = np.linalg.norm(np.roll(unit.vertices, -1, 0) - unit.vertices, axis=1).sum()
    before, after = unit.locate(theta), unit.locate(theta + d["perimeter"])
    same = before.edge == after.edge
    assert same.mean() > 0.8
    dist = np.linalg.norm(after.point - before.point, axis=-1)
    assert np.allclose(dist[same], perimeter * np.abs(noise[same]), rtol=1e-9, atol=1e-12)
    means = [np.abs(v).mean() for v in d.values()]
    assert len({round(m, 6) for m in means}) == len(means)  # four different sizes


def test_arc_length_round_trip_on_random_polygons():
    polys = polygon_set("train", 12)
    batch = PolygonBatch.of(polys)
    rng = np.random.default_rng(3)
    idx = rng.integers(len(polys), size=300)
    theta = rng.uniform(-np.pi, np.pi, (300, 4))
    arc = batch.arc_of(idx, batch.locate(idx, theta))
    back = batch.theta_at_arc(idx, arc + batch.perimeter[idx][:, None] * 3.0)  # three turns on
    assert np.allclose(np.angle(np.exp(1j * (back - theta))), 0.0, atol=1e-12)
    assert np.all((arc >= -1e-12) & (arc <= batch.perimeter[idx][:, None] + 1e-12))


@pytest.mark.parametrize("bad", [{"reading": "degrees"}, {"action": "pray"}])
def test_unknown_reading_or_action_is_refused_with_the_valid_names(bad):
    with pytest.raises(UnknownNameError, match="valid"):
        PreImaging(_Rule(0.0), **bad)


def test_every_reading_changes_the_trials():
    """Same predictor, same starts, same noise draws: each reading ends elsewhere."""
    square = [paper_object("square")]
    theta0 = np.random.default_rng(4).uniform(0, 2 * np.pi, (60, 4))
    finals = {}
    for r in NOISE_READINGS:
        res = run_trials(
            square,
            np.zeros(60, int),
            PreImaging(_Rule(14.5), reading=r),
            np.random.default_rng(0),
            theta_initial=theta0,
            max_steps=40,
        )
        finals[r] = res.theta_final
    names = list(finals)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert not np.allclose(finals[a], finals[b]), (a, b)


def test_pi_without_predicted_failure_is_the_baseline():
    square = [paper_object("square")]
    theta0 = np.random.default_rng(2).uniform(0, 2 * np.pi, (30, 4))
    kb = run_trials(
        square, np.zeros(30, int), KnowledgeBased(), np.random.default_rng(0), theta_initial=theta0
    )
    for reading in NOISE_READINGS:
        pi = run_trials(
            square,
            np.zeros(30, int),
            PreImaging(_Rule(np.inf), reading=reading),
            np.random.default_rng(0),
            theta_initial=theta0,
        )
        assert np.array_equal(kb.theta_final, pi.theta_final)


def test_pre_image_action_turns_failures_into_successes():
    square = [paper_object("square")]
    theta0 = np.random.default_rng(4).uniform(0, 2 * np.pi, (150, 4))
    kb = run_trials(
        square, np.zeros(150, int), KnowledgeBased(), np.random.default_rng(0), theta_initial=theta0
    )
    comp = PreImaging(_Rule(14.5), reading="turn")
    pi = run_trials(
        square, np.zeros(150, int), comp, np.random.default_rng(0), theta_initial=theta0
    )
    assert kb.failure_rate > 0.05
    assert pi.failure_rate < kb.failure_rate / 2
    assert comp.triggered_steps.sum() > 0


def _predictor(seed: int = 0) -> FSPredictor:
    rng = np.random.default_rng(seed)
    return FSPredictor(
        rng.normal(size=(3, 2)).astype(np.float32),
        rng.normal(size=3).astype(np.float32),
        rng.normal(size=(1, 3)).astype(np.float32),
        rng.normal(size=1).astype(np.float32),
    )


def test_failure_gradient_matches_finite_differences():
    """d(output)/d theta by the chain rule against central differences of the output of
    eps_FC(theta), eps_MC(theta), on contacts away from vertices."""
    pred = _predictor(1)
    poly = paper_object("irregular_pentagon")
    theta = np.random.default_rng(5).uniform(-np.pi, np.pi, (30, 4))
    state = _state([poly], theta)
    g = failure_gradient(pred, state)
    unit = state.batch.polygons[0]

    def f(th):
        frames = unit.locate(th)
        e_fc, e_mc = eps_fc(th), eps_mc(frames)
        # float64 here: network_input rounds to float32, too coarse for differences
        x = np.stack([scaled_error(e_fc), scaled_error(e_mc)], -1).clip(max=29.0) / 14.5 - 1
        h = np.tanh(0.5 * (x @ pred.w1.T.astype(float) + pred.b1))
        return np.tanh(0.5 * (h @ pred.w2.T.astype(float) + pred.b2))[:, 0]

    h = 1e-6
    fd = np.stack(
        [(f(theta + h * np.eye(4)[k]) - f(theta - h * np.eye(4)[k])) / (2 * h) for k in range(4)],
        axis=1,
    )
    same_edge = np.all(unit.locate(theta + h).edge == unit.locate(theta - h).edge, axis=1)
    assert same_edge.sum() > 20 and np.abs(g).max() > 1e-3
    assert np.allclose(g[same_edge], fd[same_edge], rtol=1e-3, atol=1e-5)


def test_predictor_action_descends_the_failure_expectation():
    pred = _predictor(2)
    theta = np.random.default_rng(6).uniform(-np.pi, np.pi, (50, 4))
    state = _state([paper_object("hexagon")], theta)
    comp = PreImaging(pred, action="predictor")
    d = comp.displacement(state, np.random.default_rng(0))
    moving = np.abs(d).max(axis=1) > 0
    assert moving.sum() > 20
    assert np.allclose(np.abs(d[moving]).max(axis=1), PREDICTOR_STEP)
    small = _state([paper_object("hexagon")], theta + 1e-4 * d / PREDICTOR_STEP)
    before = pred.failure_expectation(state.eps_fc, state.eps_mc)
    after = pred.failure_expectation(small.eps_fc, small.eps_mc)
    assert np.all(after[moving] <= before[moving] + 1e-6)
    assert np.mean(after[moving] < before[moving]) > 0.8


def test_saved_settings_travel_with_the_predictor(tmp_path):
    pred = _predictor(3)
    pred.save(tmp_path / "p.json", {"settings": {"reading": "perimeter", "threshold": -0.5}})
    comp = load_pi_composer(tmp_path, "p.json")
    assert (comp.reading, comp.threshold) == ("perimeter", -0.5)
    assert load_pi_composer(tmp_path, "p.json", reading="turn").reading == "turn"


def test_untrained_pi_error_names_the_training_command(tmp_path):
    with pytest.raises(ModelNotTrainedError, match=r"python -m experiments\.paper reproduce"):
        make_composer("pi", tmp_path)
