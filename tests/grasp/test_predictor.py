"""F/S predictor (section 4.3): class balancing, network, save/load, determinism."""

import numpy as np
import pytest
import torch

from controllers.grasp.errors import ModelNotTrainedError
from controllers.grasp.predictor import FSPredictor, network_input
from controllers.grasp.predictor_training import (
    FSNetwork,
    balance_classes,
    bipolar_sigmoid,
    predictor_of,
    train_predictor,
    visited_states,
)


def test_balancing_keeps_every_failure_and_as_many_successes():
    rng = np.random.default_rng(0)
    states = rng.random((1000, 2))
    success = np.arange(1000) >= 100  # 100 failures, 900 successes
    x, y = balance_classes(states, success, rng)
    assert (~y).sum() == 100 and y.sum() == 100
    fail_rows = {tuple(r) for r in states[:100]}
    assert fail_rows == {tuple(r) for r in x[~y]}
    assert not np.all(np.diff(np.flatnonzero(~y)) == 1)  # shuffled, not failures first


def test_balancing_without_failures_gives_nothing():
    x, y = balance_classes(np.ones((5, 2)), np.ones(5, bool), np.random.default_rng(0))
    assert len(x) == 0 and len(y) == 0


def test_visited_states_label_every_step_with_the_trial_outcome():
    states = np.full((2, 4, 2), np.nan)
    states[0, :3] = 0.5
    states[1, :2] = 0.1
    rows, label = visited_states(states, np.array([True, False]))
    assert len(rows) == 5 and label.tolist() == [True] * 3 + [False] * 2


def test_bipolar_sigmoid_is_tanh_half():
    x = torch.linspace(-5, 5, 11)
    assert torch.allclose(bipolar_sigmoid(x), torch.tanh(x / 2), atol=1e-6)
    net = FSNetwork(torch.Generator().manual_seed(0))
    y = net(torch.from_numpy(network_input(np.array([0.0, 1.0]), np.array([0.5, 0.001]))))
    assert torch.all(y.abs() < 1)


def test_numpy_evaluation_matches_the_torch_network():
    """The controllers evaluate the predictor in numpy (no torch import): the same float32
    output as the network it was trained as, to 1e-6, and the same failure verdicts."""
    net = FSNetwork(torch.Generator().manual_seed(3))
    predictor = predictor_of(net)
    rng = np.random.default_rng(0)
    eps_fc, eps_mc = 10.0 ** rng.uniform(-6, 0, (2, 20000))
    with torch.no_grad():
        want = net(torch.from_numpy(network_input(eps_fc, eps_mc))).numpy()
    got = predictor.failure_expectation(eps_fc, eps_mc)
    assert got.dtype == np.float32 and got.shape == want.shape
    assert np.abs(got - want).max() < 1e-6
    assert np.array_equal(got > 0.0, want > 0.0)


def test_seeded_training_is_bit_identical_and_saves_exactly(tmp_path):
    a = train_predictor(np.random.default_rng(5), epochs=2, trials_per_object=4)
    b = train_predictor(np.random.default_rng(5), epochs=2, trials_per_object=4)
    for f in ("w1", "b1", "w2", "b2"):
        assert np.array_equal(getattr(a.predictor, f), getattr(b.predictor, f))
    a.predictor.save(tmp_path / "p.json")
    b.predictor.save(tmp_path / "q.json")
    assert (tmp_path / "p.json").read_bytes() == (tmp_path / "q.json").read_bytes()
    back = FSPredictor.load(tmp_path / "p.json")
    assert np.array_equal(back.fs_map(), a.predictor.fs_map())


def test_trained_predictor_separates_failure_attractors_from_success():
    p = train_predictor(np.random.default_rng(0), epochs=4).predictor
    # A 3-vs-1 grasp of two parallel faces: eps_FC ~ 0, force residual 0.5 -> eps_MC = 0.25.
    assert p.predicts_failure(np.array([1e-4]), np.array([0.25]))[0]
    assert not p.predicts_failure(np.array([1e-4]), np.array([1e-3]))[0]


def test_missing_predictor_file_is_not_trained(tmp_path):
    with pytest.raises(ModelNotTrainedError):
        FSPredictor.load(tmp_path / "none.json")


def test_the_predictor_does_not_import_its_training():
    """Evaluating the predictor needs neither its training module nor torch (no import circle:
    only the training imports the predictor)."""
    import ast
    import inspect

    from controllers.grasp import predictor

    tree = ast.parse(inspect.getsource(predictor))
    modules = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    modules |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert "controllers.grasp.predictor_training" not in modules and "torch" not in modules
