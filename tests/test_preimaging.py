"""The PI composer (section 4.3): noise, gating by the predictor, effect on failures."""

import numpy as np
import pytest

from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.errors import ModelNotTrainedError
from controllers.grasp.objects import paper_object
from controllers.grasp.preimaging import NOISE_BOUND, NOISE_SIGMA, PreImaging, preimage_noise
from controllers.grasp.qlearning import scaled_error
from controllers.grasp.registry import make_composer
from controllers.grasp.trials import run_trials


class _Rule:
    """A stand-in predictor: failure expected when eps'_MC >= threshold."""

    def __init__(self, threshold: float) -> None:
        self.threshold = threshold

    def predicts_failure(self, eps_fc, eps_mc):
        return scaled_error(eps_mc) >= self.threshold


def test_noise_is_bounded_with_the_paper_sigma():
    n = preimage_noise(np.random.default_rng(0), (20000,))
    assert np.abs(n).max() <= NOISE_BOUND
    assert n.std() == pytest.approx(NOISE_SIGMA, rel=0.05)
    assert abs(n.mean()) < 1e-3


def test_pi_without_predicted_failure_is_the_baseline():
    square = [paper_object("square")]
    theta0 = np.random.default_rng(2).uniform(0, 2 * np.pi, (30, 4))
    kb = run_trials(
        square, np.zeros(30, int), KnowledgeBased(), np.random.default_rng(0), theta_initial=theta0
    )
    pi = run_trials(
        square,
        np.zeros(30, int),
        PreImaging(_Rule(np.inf)),
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
    comp = PreImaging(_Rule(14.5))
    pi = run_trials(
        square, np.zeros(150, int), comp, np.random.default_rng(0), theta_initial=theta0
    )
    assert kb.failure_rate > 0.05
    assert pi.failure_rate < kb.failure_rate / 2
    assert comp.triggered_steps.sum() > 0


def test_untrained_pi_error_names_the_training_command(tmp_path):
    with pytest.raises(ModelNotTrainedError, match=r"python -m controllers\.grasp reproduce"):
        make_composer("pi", tmp_path)
