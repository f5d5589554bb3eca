"""The paper-faithful, sequential Q-learning of section 3.6.2, to check our batched deviation.

``reproduce`` trains Q-learning with the 90 trials of an epoch in one batch (each step one batched
update, the trial's last pair updated once with R = +-10 and no bootstrap; docs/learning.md). The
paper runs trials one after another and, as we read it, updates after *every* step with R = 0 and
then once more with R = +-10 when the trial is over, both with the update equation's bootstrap
``gamma max Q(s')``. This module trains that way. Trials of one learner are strictly sequential;
to use the machine, ``learners`` independent learners (own Q-table, own draws) run side by side,
one trial of each per batch, so they never see each other's updates.

``python -m experiments.paper.qlcheck --out DIR [--learners 3] [--epochs 500] [--seed 0]`` trains
them, tests each greedily on Table 2's test set and writes ``DIR/qlcheck.json``. It takes about
half an hour on one core (a step of a one-trial batch costs ~0.3 ms of numpy overhead); it is not
part of ``reproduce``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.objects import ObjectSet
from controllers.grasp.qlearning import (
    ACTIONS,
    ALPHA,
    EPOCHS,
    FINAL_REWARD,
    GAMMA,
    N_BINS,
    TRIALS_PER_OBJECT,
    QLearningComposer,
    boltzmann_choice,
    epoch_objects,
    epoch_trials,
    state_index,
    temperature_schedule,
)
from controllers.grasp.state import ControlState
from controllers.grasp.trials import PolygonBatch, run_trials
from experiments.paper.tables import average_failure, object_rows, trial_set
from graspsim_base.files import write_text


@dataclass
class SequentialQLearning:
    """K independent Q-learners (section 3.6.2), trial k of a batch belongs to learner k.

    Every step updates the previous pair with R = 0 and the bootstrap; when the trial ends, its
    last pair is updated with R = 0 (bootstrapped on the final state), then with R = +-10 and the
    same bootstrap (the update equation "with R = -10 or R = 10").
    """

    q: NDArray[np.float64]  #: (K, 900, 3)
    temperature: float = 1.0
    alpha: float = ALPHA
    gamma: float = GAMMA
    name: str = "ql-sequential"
    _prev_s: NDArray[np.int64] = field(default=None, init=False, repr=False)
    _prev_a: NDArray[np.int64] = field(default=None, init=False, repr=False)

    def begin(self, n_trials: int, rng: np.random.Generator) -> None:
        if n_trials != self.q.shape[0]:
            raise ValueError(
                f"one trial per learner: {self.q.shape[0]} learners, {n_trials} trials"
            )
        self._prev_s = np.full(n_trials, -1, dtype=np.int64)
        self._prev_a = np.zeros(n_trials, dtype=np.int64)

    def _update(self, rows, s_next, reward) -> None:
        k = np.flatnonzero(rows)
        target = reward + self.gamma * self.q[k, s_next[k]].max(axis=1)
        old = self.q[k, self._prev_s[k], self._prev_a[k]]
        self.q[k, self._prev_s[k], self._prev_a[k]] = (1 - self.alpha) * old + self.alpha * target

    def gradient(self, state: ControlState, rng: np.random.Generator) -> NDArray[np.float64]:
        s = state_index(state.eps_fc, state.eps_mc)
        act = state.active
        self._update(act & (self._prev_s >= 0), s, 0.0)
        k = np.arange(s.size)
        a = boltzmann_choice(self.q[k, s], self.temperature, rng.random(s.size))
        self._prev_s = np.where(act, s, self._prev_s)
        self._prev_a = np.where(act, a, self._prev_a)
        w = np.array(ACTIONS)[a]
        return w[:, :1] * state.grad_fc + w[:, 1:] * state.grad_mc

    def end(self, state: ControlState, success: NDArray[np.bool_]) -> None:
        s = state_index(state.eps_fc, state.eps_mc)
        done = self._prev_s >= 0
        self._update(done, s, 0.0)
        self._update(done, s, np.where(success, FINAL_REWARD, -FINAL_REWARD))


def train_sequential(
    rng: np.random.Generator,
    objects: ObjectSet,
    learners: int = 3,
    epochs: int = EPOCHS,
    trials_per_object: int = TRIALS_PER_OBJECT,
    progress: Callable[[int, NDArray[np.float64]], None] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Train ``learners`` sequential Q-learners; returns their Q-tables (K, 900, 3) and failure
    rate per epoch (epochs, K). Same object schedule as :func:`train_qlearning`."""
    polys = objects.polygons
    batch = PolygonBatch.of(polys)
    obj = epoch_objects(len(objects.names), trials_per_object, rng)
    comp = SequentialQLearning(q=np.zeros((learners, N_BINS * N_BINS, len(ACTIONS))))
    temps = temperature_schedule(epochs)
    failures = np.zeros((epochs, learners))
    for e in range(epochs):
        comp.temperature = float(temps[e])
        for i in epoch_trials(objects, obj, e, trials_per_object):
            r = run_trials(polys, np.full(learners, i), comp, rng, batch=batch)
            failures[e] += ~r.success
        failures[e] /= obj.size
        if progress is not None:
            progress(e, failures[e])
    return comp.q, failures


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.paper.qlcheck", description=__doc__)
    p.add_argument("--out", required=True, help="directory for qlcheck.json")
    p.add_argument("--learners", type=int, default=3, help="independent learners (default 3)")
    p.add_argument("--epochs", type=int, default=EPOCHS, help=f"epochs (default {EPOCHS})")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    args = p.parse_args(argv)
    if args.learners < 1 or args.epochs < 1 or args.seed < 0:
        print("error: --learners and --epochs must be >= 1, --seed >= 0", file=sys.stderr)
        return 2
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    objects = ObjectSet.paper()
    rng = np.random.default_rng(args.seed)

    def show(e: int, f: NDArray[np.float64]) -> None:
        if (e + 1) % 10 == 0:
            print(f"[qlcheck] epoch {e + 1}: failure {np.round(100 * f, 1)} %", file=sys.stderr)

    q, curves = train_sequential(rng, objects, args.learners, args.epochs, progress=show)
    ts = trial_set(objects, np.random.default_rng([args.seed, 1]))
    tables = []
    for k in range(args.learners):
        r = ts.run(QLearningComposer(q=q[k]), np.random.default_rng([args.seed, 2]))
        rows = object_rows(r, ts)
        tables.append({"rows": rows, "average_failure": average_failure(rows)})
    res = {
        "seed": args.seed,
        "learners": args.learners,
        "epochs": args.epochs,
        "tables": tables,
        "curves": curves.T.tolist(),
        "seconds": round(time.perf_counter() - t0, 1),
    }
    write_text(out / "qlcheck.json", json.dumps(res, indent=1, sort_keys=True) + "\n")
    avg = [f"{t['average_failure']:.2f}" for t in tables]
    print(f"sequential Q-learning, average failure per learner (%): {', '.join(avg)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
