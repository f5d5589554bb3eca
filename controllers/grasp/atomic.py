"""Section 2: a grasp controller of atomic actions learned by Q-learning on a geometric state.

The object outline is cut into 12 angular sectors of 30 degrees about the centroid; a grasp state
is the 4-tuple of the contacts' sector indices (12^4 states). Each contact moves one sector
clockwise, stays, or moves one sector counterclockwise (3^4 = 81 joint actions).

Choices where the paper is silent (docs/learning.md): a contact sits at its sector's centre
(polar angle 15 + 30 k degrees), so "a fixed angular distance" is one sector (30 degrees) and the
S_G of every configuration can be cached; contacts may share a sector after the first step; a
trial is tested for convergence (S_G <= 0.4) after each step, not before the first.
"""

from __future__ import annotations

import gzip
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.errors import GraspError, ModelNotTrainedError
from controllers.grasp.polygon import Polygon
from controllers.grasp.qlearning import (
    ALPHA,
    FINAL_REWARD,
    GAMMA,
    batched_q_update,
    boltzmann_choice,
    temperature_schedule,
)
from controllers.grasp.run_folder import TRAIN_HINT
from controllers.grasp.score import SUCCESS_THRESHOLD, grasp_score
from graspsim_base.files import atomic_path

#: Angular sectors of the object surface (section 2.2.1: 12 bins of 30 degrees).
N_SECTORS = 12
SECTOR = 2.0 * np.pi / N_SECTORS
#: Four-fingered grasps; three atomic actions per contact (-1, 0, +1 sector).
N_FINGERS = 4
MOVES = (-1, 0, 1)
N_STATES = N_SECTORS**N_FINGERS
N_ACTIONS = len(MOVES) ** N_FINGERS
#: At most this many control steps per trial (section 2.2.1).
MAX_ATOMIC_STEPS = 10
#: Training (section 2.2.1): 500 epochs of 90 trials on the irregular triangle.
ATOMIC_EPOCHS = 500
ATOMIC_TRIALS = 90
#: Test (section 2.3): 200 trials, the triangle as trained and rotated by 30 degrees.
TEST_TRIALS = 200
TEST_ROTATION_DEG = 30.0
#: Configurations shown per test (Figure 2: the four most frequent).
TOP_CONFIGURATIONS = 4
#: Paper results (section 2.3): failure rate (%) and distinct configurations (satisfactory).
PAPER_ATOMIC = {
    "trained": {"failure": 0.0, "configurations": 99, "satisfactory": 99},
    "rotated": {"failure": 29.0, "configurations": 81, "satisfactory": 55},
}
#: File name of the saved atomic Q-table inside a model directory (gzip-compressed .npy).
ATOMIC_MODEL_FILE = "atomic_q.npy.gz"

_POWERS = N_SECTORS ** np.arange(N_FINGERS)


def encode(sectors: NDArray[np.int64]) -> NDArray[np.int64]:
    """State index of sector tuples (..., 4): sum_i b_i 12^i."""
    return (sectors * _POWERS).sum(-1)


def decode(state: NDArray[np.int64]) -> NDArray[np.int64]:
    """Sector tuples (..., 4) of state indices."""
    return (np.asarray(state)[..., None] // _POWERS) % N_SECTORS


def action_moves(action: NDArray[np.int64]) -> NDArray[np.int64]:
    """Per-contact moves in {-1, 0, +1} of joint actions, shape (..., 4); contact i's move is
    the i-th base-3 digit of the action minus 1."""
    return ((np.asarray(action)[..., None] // 3 ** np.arange(N_FINGERS)) % 3) - 1


def sector_angle(sectors: NDArray[np.int64]) -> NDArray[np.float64]:
    """Polar angle of a contact at the centre of each sector (rad)."""
    return (np.asarray(sectors) + 0.5) * SECTOR


class ScoreTable:
    """S_G of every sector configuration of one polygon, computed on first use and cached."""

    def __init__(self, polygon: Polygon) -> None:
        self.polygon = polygon
        self.unit = polygon.unit_moment()
        self.s_g = np.full(N_STATES, np.nan)

    def scores(self, states: NDArray[np.int64]) -> NDArray[np.float64]:
        """S_G (inf when infeasible) of each state index."""
        states = np.asarray(states, dtype=np.int64)
        todo = np.unique(states[np.isnan(self.s_g[states])])
        if todo.size:
            frames = self.unit.locate(sector_angle(decode(todo)))
            self.s_g[todo] = [
                grasp_score(frames.point[i], frames.normal[i]).s_g for i in range(todo.size)
            ]
        return self.s_g[states]

    def success(self, states: NDArray[np.int64]) -> NDArray[np.bool_]:
        return self.scores(states) <= SUCCESS_THRESHOLD


def initial_states(rng: np.random.Generator, n_trials: int) -> NDArray[np.int64]:
    """Four contacts in four different random sectors per trial (section 2.2.1)."""
    sectors = np.argsort(rng.random((n_trials, N_SECTORS)), axis=1)[:, :N_FINGERS]
    return encode(sectors)


@dataclass(frozen=True)
class AtomicTrials:
    """Outcome of a batch of atomic-action trials."""

    final_state: NDArray[np.int64]  #: (T,) sector configuration at the end
    success: NDArray[np.bool_]
    s_g: NDArray[np.float64]
    steps: NDArray[np.int64]

    @property
    def failure_rate(self) -> float:
        return float(1.0 - self.success.mean())


def run_atomic_trials(
    q: NDArray[np.float64],
    table: ScoreTable,
    rng: np.random.Generator,
    n_trials: int,
    temperature: float = 0.0,
    learn: bool = False,
    alpha: float = ALPHA,
    gamma: float = GAMMA,
) -> AtomicTrials:
    """Run ``n_trials`` trials at once; with ``learn`` update ``q`` (12^4, 81) in place.

    R = 0 after each step that does not end the trial; the step that ends it (a satisfactory grasp,
    or the 10th step) is updated with R = +-10 and no bootstrap (the end is terminal).
    """
    s = initial_states(rng, n_trials)
    active = np.ones(n_trials, dtype=bool)
    success = np.zeros(n_trials, dtype=bool)
    steps = np.zeros(n_trials, dtype=np.int64)
    for k in range(MAX_ATOMIC_STEPS):
        a = boltzmann_choice(q[s], temperature if learn else 0.0, rng.random(n_trials))
        nxt = encode((decode(s) + action_moves(a)) % N_SECTORS)
        nxt = np.where(active, nxt, s)
        good = table.success(nxt) & active
        last = active & (good | (k == MAX_ATOMIC_STEPS - 1))
        if learn:
            flat = s * N_ACTIONS + a
            go_on = active & ~last
            target_on = gamma * q[nxt[go_on]].max(axis=1)
            target_end = np.where(good[last], FINAL_REWARD, -FINAL_REWARD)
            batched_q_update(
                q,
                np.concatenate([flat[go_on], flat[last]]),
                np.concatenate([target_on, target_end]),
                alpha,
            )
        steps[active] = k + 1
        success |= good
        s = nxt
        active &= ~last
        if not active.any():
            break
    return AtomicTrials(s, success, table.scores(s), steps)


@dataclass(frozen=True)
class AtomicResult:
    """A trained atomic-action policy and its learning curve (Figure 1)."""

    q: NDArray[np.float64]  #: (12^4, 81)
    failure_per_epoch: NDArray[np.float64]
    temperature: NDArray[np.float64]


def train_atomic(
    polygon: Polygon,
    rng: np.random.Generator,
    epochs: int = ATOMIC_EPOCHS,
    trials_per_epoch: int = ATOMIC_TRIALS,
    table: ScoreTable | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> AtomicResult:
    """Q-learning of atomic grasp actions on ``polygon`` (section 2.2.1); trials of an epoch run
    together with batched updates (as in :mod:`controllers.grasp.qlearning`)."""
    table = table or ScoreTable(polygon)
    q = np.zeros((N_STATES, N_ACTIONS))
    temps = temperature_schedule(epochs)
    failures = np.zeros(epochs)
    for e in range(epochs):
        out = run_atomic_trials(q, table, rng, trials_per_epoch, float(temps[e]), learn=True)
        failures[e] = out.failure_rate
        if progress is not None:
            progress(e, failures[e])
    return AtomicResult(q, failures, temps)


@dataclass(frozen=True)
class AtomicTest:
    """Section 2.3's test of a policy on one object orientation."""

    label: str
    rotation_deg: float
    failure_rate: float
    configurations: int  #: distinct final configurations
    satisfactory: int  #: of which have S_G <= 0.4
    most_frequent: tuple[tuple[tuple[int, ...], int, float], ...]  #: (sectors, count, S_G), top 4
    most_frequent_failures: tuple[tuple[tuple[int, ...], int, float], ...]  #: top 4 with S_G > 0.4


def evaluate_atomic(
    q: NDArray[np.float64],
    polygon: Polygon,
    rng: np.random.Generator,
    rotation_deg: float = 0.0,
    trials: int = TEST_TRIALS,
    label: str = "",
) -> AtomicTest:
    """Greedy policy on ``polygon`` rotated by ``rotation_deg`` (section 2.3). Configurations are
    counted as unordered sets of sectors (which finger is where does not matter)."""
    table = ScoreTable(polygon.rotated(np.deg2rad(rotation_deg)))
    out = run_atomic_trials(q, table, rng, trials)
    configs = [tuple(sorted(int(b) for b in decode(s))) for s in out.final_state]
    counts = Counter(configs)
    sg = {c: float(s) for c, s in zip(configs, out.s_g, strict=True)}
    ranked = [(c, n, sg[c]) for c, n in counts.most_common()]
    top = tuple(ranked[:TOP_CONFIGURATIONS])
    bad = tuple(r for r in ranked if not r[2] <= SUCCESS_THRESHOLD)[:TOP_CONFIGURATIONS]
    satisfactory = sum(1 for c in counts if sg[c] <= SUCCESS_THRESHOLD)
    return AtomicTest(label, rotation_deg, out.failure_rate, len(counts), satisfactory, top, bad)


def save_atomic_q(q: NDArray[np.float64], path: Path) -> None:
    """Write the atomic Q-table as gzip-compressed .npy (mtime 0: byte-for-byte reproducible),
    atomically."""
    with (
        atomic_path(path) as tmp,
        open(tmp, "wb") as raw,
        gzip.GzipFile(filename="", fileobj=raw, mode="wb", mtime=0) as f,
    ):
        np.save(f, np.ascontiguousarray(q, dtype=np.float64))


def load_atomic_q(path: Path) -> NDArray[np.float64]:
    """Read a table written by :func:`save_atomic_q`."""
    path = Path(path)
    if not path.is_file():
        raise ModelNotTrainedError(f"no atomic-action Q-table at {path}: {TRAIN_HINT}")
    with gzip.open(path, "rb") as f:
        q = np.load(f)
    if q.shape != (N_STATES, N_ACTIONS):
        raise GraspError(f"{path} holds a {q.shape} array, expected ({N_STATES}, {N_ACTIONS})")
    return q
