"""Knowledge-based composition (section 3.6.1): the paper's Luce rule and constants, pinned."""

import numpy as np
import pytest

from controllers.grasp import KnowledgeBased, luce_activation, paper_object
from controllers.grasp.trials import PolygonBatch, control_state


def paper_alpha_fc(eps_fc, eps_mc, k_fc, k_mc, b):
    """alpha_FC of section 3.6.1, written exactly as the paper prints it."""
    up = np.exp(k_fc * eps_fc + b)
    return up / (up + np.exp(k_mc * eps_mc - b))


def test_knowledge_based_uses_the_papers_constants():
    """Section 3.6.1: k_FC = 4,000, b = -10 and k_MC = 0."""
    kb = KnowledgeBased()
    assert (kb.k_fc, kb.b, kb.k_mc) == (4000.0, -10.0, 0.0)
    # with k_MC = 0, alpha_FC = 1/2 where k_FC eps_FC + b = -b: eps_FC = -2b / k_FC = 0.005
    assert -2.0 * kb.b / kb.k_fc == pytest.approx(0.005)


def test_luce_rule_is_the_papers_formula():
    rng = np.random.default_rng(0)
    eps_fc, eps_mc = rng.uniform(0.0, 0.02, 200), rng.uniform(0.0, 0.5, 200)
    for k_fc, k_mc, b in ((4000.0, 0.0, -10.0), (1500.0, 30.0, -4.0), (800.0, -20.0, 3.0)):
        np.testing.assert_allclose(
            luce_activation(eps_fc, eps_mc, k_fc, k_mc, b),
            paper_alpha_fc(eps_fc, eps_mc, k_fc, k_mc, b),
            rtol=1e-12,
            atol=1e-15,
        )


def test_luce_rule_saturates_without_overflow():
    with np.errstate(all="raise"):
        a = luce_activation(np.array([0.0, 10.0]), np.array([10.0, 0.0]), 4000.0, 200.0, -10.0)
    assert a[0] == pytest.approx(0.0, abs=1e-300) and a[1] == 1.0


def test_knowledge_based_gradient_blends_fc_and_mc_by_the_luce_rule():
    """grad = alpha_FC dEps_FC/dtheta + (1 - alpha_FC) dEps_MC/dtheta (section 3.6.1)."""
    polys = [paper_object("square"), paper_object("hexagon")]
    batch = PolygonBatch.of(polys)
    rng = np.random.default_rng(1)
    # starts around the switch: antipodal pairs perturbed so eps_FC spans 0 .. 0.02
    base = rng.uniform(-np.pi, np.pi, (400, 1))
    theta = np.concatenate([base, base + np.pi, base + 0.5, base + 0.5 + np.pi], axis=1)
    theta += rng.normal(0.0, 1.0, theta.shape) * rng.uniform(0.0, 0.25, (400, 1))
    idx = rng.integers(0, 2, 400)
    state = control_state(batch, idx, theta, 0, np.ones(400, bool))
    assert (state.eps_fc < 0.003).sum() > 50 and (state.eps_fc > 0.008).sum() > 50
    alpha = paper_alpha_fc(state.eps_fc, state.eps_mc, 4000.0, 0.0, -10.0)[:, None]
    expected = alpha * state.grad_fc + (1.0 - alpha) * state.grad_mc
    got = KnowledgeBased().gradient(state, rng)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)
    # well below the switch the MC controller acts alone, well above FC does
    low, high = state.eps_fc < 0.002, state.eps_fc > 0.01
    np.testing.assert_allclose(got[low], state.grad_mc[low], rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(got[high], state.grad_fc[high], rtol=1e-4, atol=1e-6)
