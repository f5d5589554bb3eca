"""The sequential, paper-faithful Q-learning used to check the batched trainer."""

from types import SimpleNamespace

import numpy as np
import pytest

from controllers.grasp.objects import ObjectSet, paper_object
from controllers.grasp.qlearning import ALPHA, FINAL_REWARD, GAMMA, state_index
from experiments.paper.qlcheck import SequentialQLearning, train_sequential


def _state(eps_fc, eps_mc, active=(True, True)):
    n = len(eps_fc)
    return SimpleNamespace(
        eps_fc=np.array(eps_fc, float),
        eps_mc=np.array(eps_mc, float),
        active=np.array(active),
        grad_fc=np.ones((n, 4)),
        grad_mc=np.zeros((n, 4)),
    )


def test_every_step_and_the_end_update_with_the_bootstrap():
    q = np.zeros((2, 900, 3))
    s1, s2, s3 = (state_index([e], [m])[0] for e, m in ((1.0, 1.0), (0.1, 0.5), (1e-3, 0.02)))
    q[:, s1] = [5.0, 0.0, 0.0]  # greedy: FC at s1
    q[:, s2] = [0.0, 3.0, 0.0]  # greedy: MC at s2
    q[0, s3] = [0.0, 0.0, 4.0]  # learner 0 only knows s3
    comp = SequentialQLearning(q=q, temperature=1e-9)
    rng = np.random.default_rng(0)
    comp.begin(2, rng)
    g = comp.gradient(_state([1.0, 1.0], [1.0, 1.0]), rng)
    assert np.array_equal(g, np.ones((2, 4)))  # FC chosen, nothing updated yet
    comp.gradient(_state([0.1, 0.1], [0.5, 0.5]), rng)
    # Q(s1, FC) <- (1 - a) 5 + a (0 + gamma max Q(s2)) = (1 - a) 5 + a gamma 3, both learners
    assert q[:, s1, 0] == pytest.approx((1 - ALPHA) * 5 + ALPHA * GAMMA * 3)
    comp.end(_state([1e-3, 1e-3], [0.02, 0.02]), np.array([True, False]))
    for k, (boot, reward) in enumerate(((4.0, FINAL_REWARD), (0.0, -FINAL_REWARD))):
        v = (1 - ALPHA) * 3 + ALPHA * GAMMA * boot  # R = 0 after the last step
        v = (1 - ALPHA) * v + ALPHA * (reward + GAMMA * boot)  # then R = +-10
        assert q[k, s2, 1] == pytest.approx(v)
    assert q[1, s3].tolist() == [0.0, 0.0, 0.0]  # learners never share a table


def test_short_sequential_training_is_seeded_and_learns_independently():
    objs = ObjectSet.of([paper_object("square"), paper_object("triangle")])
    a, fa = train_sequential(
        np.random.default_rng(1), objs, learners=2, epochs=2, trials_per_object=2
    )
    b, fb = train_sequential(
        np.random.default_rng(1), objs, learners=2, epochs=2, trials_per_object=2
    )
    assert np.array_equal(a, b) and np.array_equal(fa, fb)
    assert fa.shape == (2, 2) and np.any(a[0] != 0) and not np.array_equal(a[0], a[1])
