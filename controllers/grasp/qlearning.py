"""Learning-derived composition by Q-learning (section 3.6.2), trained on arrays of trials.

State: the controllers' errors on the log scale of Eq. 14, binned 30 x 30. Actions: the bang-bang
activations {FC, MC, FC+MC}. The Q-table is updated after every control step with R = 0 and, at
the end of a trial, with R = +10 (success, S_G <= 0.4) or -10 (failure).

Deviation from a strictly sequential learner (documented in docs/learning.md): the 90 trials of
an epoch run together, so each control step makes one batched update. When k trials update the
same (state, action) pair in one step, the pair gets the exact result of k sequential updates
toward the mean of their targets: Q <- (1 - alpha)^k Q + (1 - (1 - alpha)^k) mean(target).
All targets of a step are computed from the table as it was before that step.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.errors import GraspError, ModelNotTrainedError
from controllers.grasp.objects import ObjectSet
from controllers.grasp.polygon import Polygon
from controllers.grasp.run_folder import TRAIN_HINT
from controllers.grasp.state import ControlState
from controllers.grasp.trials import GAIN, PolygonBatch, run_trials
from graspsim_base.files import atomic_path

#: Eq. 14: eps' = LOG_SCALE * log10(max(EPS_FLOOR, eps) / EPS_FLOOR). The paper writes "log";
#: its example (eps = 1 gives eps' = 29) fixes the base: 14.5 * log10(100) = 29 (ln: 66.8).
LOG_SCALE = 14.5
#: Eq. 14: errors at or below this share the lowest bin.
EPS_FLOOR = 0.01
#: Bins per state variable (section 3.6.2: 30 x 30 = 900 states).
N_BINS = 30
#: Bang-bang actions (alpha_FC, alpha_MC): FC alone, MC alone, both (never both 0).
ACTIONS: tuple[tuple[float, float], ...] = ((1.0, 0.0), (0.0, 1.0), (1.0, 1.0))
ACTION_NAMES: tuple[str, ...] = ("FC", "MC", "FC+MC")
#: Learning rate and discount of the update equation (section 3.6.2).
ALPHA = 0.02
GAMMA = 0.9
#: |R| at the end of a trial: +10 for a success, -10 for a failure; R = 0 after every other step.
FINAL_REWARD = 10.0
#: The Boltzmann temperature range of section 3.6.2.
TEMPERATURE_START = 20.0
TEMPERATURE_END = 0.005
#: Training length (section 3.6.2): 500 epochs of 10 trials on each of the nine objects.
EPOCHS = 500
TRIALS_PER_OBJECT = 10
#: File name of a saved Q-table inside a model directory.
QL_MODEL_FILE = "ql_q.npy"


def scaled_error(eps: ArrayLike) -> NDArray[np.float64]:
    """Eq. 14, log-scale state variable eps' in [0, inf) (29 at eps = 1), not yet binned."""
    e = np.maximum(EPS_FLOOR, np.asarray(eps, dtype=float))
    return LOG_SCALE * np.log10(e / EPS_FLOOR)


def state_bin(eps: ArrayLike) -> NDArray[np.int64]:
    """Bin index of Eq. 14's eps' (floor, clipped to N_BINS - 1)."""
    return np.minimum(np.floor(scaled_error(eps)), N_BINS - 1).astype(np.int64)


def state_index(eps_fc: ArrayLike, eps_mc: ArrayLike) -> NDArray[np.int64]:
    """Flat index of S = <eps'_FC, eps'_MC> in the 900-state table (FC bin major)."""
    return state_bin(eps_fc) * N_BINS + state_bin(eps_mc)


def temperature_schedule(
    epochs: int, start: float = TEMPERATURE_START, end: float = TEMPERATURE_END
):
    """Boltzmann temperature per epoch: geometric from ``start`` (epoch 0) to ``end`` (last epoch).

    The paper gives only the range [20, 0.005]; the geometric schedule is our choice.
    """
    if epochs < 1:
        raise GraspError(f"epochs must be >= 1, got {epochs}")
    if epochs == 1:
        return np.array([end])
    return start * (end / start) ** (np.arange(epochs) / (epochs - 1))


def boltzmann_choice(q: NDArray[np.float64], temperature: float, u: NDArray[np.float64]):
    """Sample one action per row of ``q`` (T, A) with Pr(a) ~ exp(Q(s, a) / temperature), using
    uniform draws ``u`` (T,) (section 2.2.1, "Action selection"). temperature 0 is greedy."""
    if temperature <= 0.0:
        return np.argmax(q, axis=1)
    z = (q - q.max(axis=1, keepdims=True)) / temperature
    p = np.exp(z)
    c = np.cumsum(p, axis=1)
    c /= c[:, -1:]
    return np.minimum((u[:, None] > c).sum(axis=1), q.shape[1] - 1)


def batched_q_update(
    q: NDArray[np.float64], flat_sa: NDArray[np.int64], target: NDArray[np.float64], alpha: float
) -> None:
    """Apply Q <- (1 - alpha) Q + alpha target to flat (state, action) entries, in place.

    k updates of one entry in the same batch act as k sequential updates toward their mean target.
    """
    if flat_sa.size == 0:
        return
    flat = q.reshape(-1)
    hit, inverse, count = np.unique(flat_sa, return_inverse=True, return_counts=True)
    total = np.bincount(inverse, weights=target, minlength=hit.size)
    keep = (1.0 - alpha) ** count
    flat[hit] = keep * flat[hit] + (1.0 - keep) * total / count


@dataclass
class QLearningComposer:
    """Q-learning composition (section 3.6.2) as a :class:`Composer`.

    With ``learn`` it explores (Boltzmann at ``temperature``) and updates ``q`` in place; without,
    it follows the greedy policy (argmax, ties to the first action) and leaves ``q`` untouched.
    """

    q: NDArray[np.float64] = field(
        default_factory=lambda: np.zeros((N_BINS * N_BINS, len(ACTIONS)))
    )
    temperature: float = 0.0
    learn: bool = False
    alpha: float = ALPHA
    gamma: float = GAMMA
    name: str = "ql"
    _prev_s: NDArray[np.int64] = field(default=None, init=False, repr=False)
    _prev_a: NDArray[np.int64] = field(default=None, init=False, repr=False)
    _action_counts: NDArray[np.int64] = field(default=None, init=False, repr=False)

    def begin(self, n_trials: int, rng: np.random.Generator) -> None:
        self._prev_s = np.full(n_trials, -1, dtype=np.int64)
        self._prev_a = np.zeros(n_trials, dtype=np.int64)
        self._action_counts = np.zeros(len(ACTIONS), dtype=np.int64)

    def gradient(self, state: ControlState, rng: np.random.Generator) -> NDArray[np.float64]:
        s = state_index(state.eps_fc, state.eps_mc)
        act = state.active
        if self.learn:
            # R = 0 update of the previous step's pair, bootstrapped on the state reached.
            upd = act & (self._prev_s >= 0)
            target = self.gamma * self.q[s[upd]].max(axis=1)
            flat = self._prev_s[upd] * len(ACTIONS) + self._prev_a[upd]
            batched_q_update(self.q, flat, target, self.alpha)
        u = rng.random(s.shape[0])
        a = boltzmann_choice(self.q[s], self.temperature if self.learn else 0.0, u)
        self._prev_s = np.where(act, s, self._prev_s)
        self._prev_a = np.where(act, a, self._prev_a)
        self._action_counts += np.bincount(a[act], minlength=len(ACTIONS))
        w = np.array(ACTIONS)[a]
        return w[:, :1] * state.grad_fc + w[:, 1:] * state.grad_mc

    def end(self, state: ControlState, success: NDArray[np.bool_]) -> None:
        if not self.learn:
            return
        # The trial's last pair gets the final reward; the end of a trial is terminal (value 0).
        done = self._prev_s >= 0
        reward = np.where(success, FINAL_REWARD, -FINAL_REWARD)[done]
        flat = self._prev_s[done] * len(ACTIONS) + self._prev_a[done]
        batched_q_update(self.q, flat, reward, self.alpha)

    @property
    def action_counts(self) -> NDArray[np.int64]:
        """How often each action was taken by active trials in the last batch."""
        return self._action_counts


@dataclass(frozen=True)
class QLearningResult:
    """A trained Q-table and its learning curve (section 3.6.3, Figure 7)."""

    q: NDArray[np.float64]  #: (900, 3) Q(s, a), s = FC bin * 30 + MC bin
    failure_per_epoch: NDArray[np.float64]  #: (epochs,) failure rate of each training epoch
    temperature: NDArray[np.float64]  #: (epochs,) Boltzmann temperature used
    object_order: tuple[str, ...]  #: the random, fixed order the objects were presented in

    @property
    def policy(self) -> NDArray[np.int64]:
        """Greedy action per state, (30, 30), FC bin by MC bin."""
        return np.argmax(self.q, axis=1).reshape(N_BINS, N_BINS)


def epoch_objects(
    n_objects: int, trials_per_object: int, rng: np.random.Generator
) -> NDArray[np.int64]:
    """Object index of each trial of an epoch: the objects in a random, fixed order, each repeated
    ``trials_per_object`` times (section 3.6.2, "Training")."""
    order = rng.permutation(n_objects)
    return np.repeat(order, trials_per_object)


def epoch_trials(
    objects: ObjectSet, object_index: NDArray[np.int64], epoch: int, trials_per_object: int
) -> NDArray[np.int64]:
    """Flat polygon index of each trial of epoch ``epoch``: trial j of an object in that epoch is
    its (epoch * trials_per_object + j)-th trial, on the family member of that number (modulo the
    family size), so training cycles through every member of a family."""
    j = np.tile(np.arange(trials_per_object), object_index.size // trials_per_object)
    return objects.polygon_index(object_index, epoch * trials_per_object + j)


def as_object_set(objects: ObjectSet | Sequence[Polygon] | None) -> ObjectSet:
    """An :class:`ObjectSet`: the paper's nine objects with their families when None, a family of
    one per polygon for a plain sequence of polygons."""
    if objects is None:
        return ObjectSet.paper()
    return objects if isinstance(objects, ObjectSet) else ObjectSet.of(list(objects))


def train_qlearning(
    rng: np.random.Generator,
    polygons: ObjectSet | Sequence[Polygon] | None = None,
    epochs: int = EPOCHS,
    trials_per_object: int = TRIALS_PER_OBJECT,
    gain: float = GAIN,
    progress: Callable[[int, float], None] | None = None,
) -> QLearningResult:
    """Train the Q-learning composer (section 3.6.2); the trials of each epoch run as one batch.

    ``polygons``: the objects (default: the nine paper objects with their shape families; a family
    is visited member by member, see :func:`epoch_trials`). ``progress(epoch, failure_rate)`` is
    called after every epoch. The same ``rng`` state gives a bit-identical Q-table.
    """
    objects = as_object_set(polygons)
    polys = objects.polygons
    batch = PolygonBatch.of(polys)
    obj = epoch_objects(len(objects.names), trials_per_object, rng)
    temps = temperature_schedule(epochs)
    composer = QLearningComposer(learn=True)
    failures = np.zeros(epochs)
    for e in range(epochs):
        composer.temperature = float(temps[e])
        idx = epoch_trials(objects, obj, e, trials_per_object)
        result = run_trials(polys, idx, composer, rng, gain=gain, batch=batch)
        failures[e] = result.failure_rate
        if progress is not None:
            progress(e, failures[e])
    order = tuple(objects.names[i] for i in obj[::trials_per_object])
    return QLearningResult(composer.q.copy(), failures, temps, order)


def save_q_table(q: NDArray[np.float64], path: Path) -> None:
    """Write a Q-table as .npy (byte-for-byte reproducible), atomically."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.save(f, np.ascontiguousarray(q, dtype=np.float64))


def load_ql_composer(model_dir: Path) -> QLearningComposer:
    """The greedy Q-learning composer saved in ``model_dir`` by ``reproduce``."""
    path = Path(model_dir) / QL_MODEL_FILE
    if not path.is_file():
        raise ModelNotTrainedError(f"no trained Q-learning policy at {path}: {TRAIN_HINT}")
    q = np.load(path)
    if q.shape != (N_BINS * N_BINS, len(ACTIONS)):
        raise GraspError(
            f"{path} holds a {q.shape} array, expected ({N_BINS * N_BINS}, {len(ACTIONS)})"
        )
    return QLearningComposer(q=q, learn=False)
