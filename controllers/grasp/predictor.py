"""The failure/success (F/S) predictor of the pre-imaging controller (section 4.3), in torch.

A 2-3-1 network of bipolar sigmoid units, f(x) = 2 / (1 + e^-x) - 1 (outputs in (-1, 1)), trained
by backpropagation on the states visited by the knowledge-based controller: every state of a trial
carries that trial's label. Output +1 means failure expected, -1 success (Figure 11a plots failure
expectation). Success states are subsampled so both classes are equally represented (footnote 5).
Weights are saved as JSON (small, and byte-for-byte reproducible).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.errors import GraspError, ModelNotTrainedError
from controllers.grasp.objects import ObjectSet
from controllers.grasp.polygon import Polygon
from controllers.grasp.qlearning import (
    EPS_FLOOR,
    LOG_SCALE,
    N_BINS,
    as_object_set,
    epoch_objects,
    epoch_trials,
    scaled_error,
)
from controllers.grasp.trials import GAIN, PolygonBatch, run_trials
from graspsim_base.files import write_text

#: Network shape of section 4.3: two state inputs, three hidden units, one output.
N_INPUTS, N_HIDDEN, N_OUTPUTS = 2, 3, 1
#: Training length of section 4.3: 10 epochs of 90 knowledge-based trials (10 per object).
PREDICTOR_EPOCHS = 10
TRIALS_PER_OBJECT = 10
#: Backpropagation settings (the paper gives none; our choice): plain SGD on the mean squared
#: error, this learning rate and mini-batch, this many passes over the balanced set at the end
#: of each epoch. The set is drawn from all states visited so far ("a fraction of all visited
#: states", section 4.3). That reading was chosen after seeing that one epoch's states place the
#: F/S boundary less consistently; ``reproduce`` reports PI (c) with both (docs/learning.md).
LEARNING_RATE = 0.5
BATCH_SIZE = 16
PASSES_PER_EPOCH = 3
#: Targets: failure +1, success -1; a state is predicted to fail when the output exceeds this.
FAILURE_TARGET, SUCCESS_TARGET = 1.0, -1.0
FAILURE_THRESHOLD = 0.0
#: Largest Eq. 14 value fed to the network (the top state bin, eps = 1).
INPUT_CAP = float(N_BINS - 1)


def network_input(eps_fc: ArrayLike, eps_mc: ArrayLike) -> NDArray[np.float32]:
    """The scaled state (Eq. 14, not binned, capped at 29) mapped to [-1, 1]: x = eps'/14.5 - 1."""
    s = np.stack([scaled_error(eps_fc), scaled_error(eps_mc)], axis=-1)
    return (np.minimum(s, INPUT_CAP) / LOG_SCALE - 1.0).astype(np.float32)


def bipolar_sigmoid(x: torch.Tensor) -> torch.Tensor:
    """The bipolar sigmoid 2 / (1 + e^-x) - 1 = tanh(x / 2) (section 4.3)."""
    return 2.0 * torch.sigmoid(x) - 1.0


class FSNetwork(torch.nn.Module):
    """2-3-1 feed-forward network, bipolar sigmoid hidden and output units (section 4.3)."""

    def __init__(self, generator: torch.Generator) -> None:
        super().__init__()
        self.hidden = torch.nn.Linear(N_INPUTS, N_HIDDEN)
        self.out = torch.nn.Linear(N_HIDDEN, N_OUTPUTS)
        with torch.no_grad():  # seeded init, PyTorch's default range U(-1/sqrt(fan_in), ..)
            for layer in (self.hidden, self.out):
                bound = 1.0 / np.sqrt(layer.in_features)
                layer.weight.uniform_(-bound, bound, generator=generator)
                layer.bias.uniform_(-bound, bound, generator=generator)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return bipolar_sigmoid(self.out(bipolar_sigmoid(self.hidden(x)))).squeeze(-1)


@dataclass(frozen=True)
class FSPredictor:
    """Trained F/S predictor weights (numpy copies, float32) and how to evaluate them."""

    w1: NDArray[np.float32]  #: (3, 2)
    b1: NDArray[np.float32]  #: (3,)
    w2: NDArray[np.float32]  #: (1, 3)
    b2: NDArray[np.float32]  #: (1,)

    @classmethod
    def of(cls, net: FSNetwork) -> FSPredictor:
        def grab(t: torch.Tensor) -> NDArray[np.float32]:
            return t.detach().numpy().astype(np.float32).copy()

        return cls(
            grab(net.hidden.weight), grab(net.hidden.bias), grab(net.out.weight), grab(net.out.bias)
        )

    def failure_expectation(self, eps_fc: ArrayLike, eps_mc: ArrayLike) -> NDArray[np.float32]:
        """Network output in (-1, 1) for each state; > 0 predicts failure."""
        x = torch.from_numpy(network_input(eps_fc, eps_mc))
        with torch.no_grad():
            h = bipolar_sigmoid(x @ torch.from_numpy(self.w1).T + torch.from_numpy(self.b1))
            y = bipolar_sigmoid(h @ torch.from_numpy(self.w2).T + torch.from_numpy(self.b2))
        return y[..., 0].numpy()

    def predicts_failure(self, eps_fc: ArrayLike, eps_mc: ArrayLike) -> NDArray[np.bool_]:
        return self.failure_expectation(eps_fc, eps_mc) > FAILURE_THRESHOLD

    def fs_map(self, n: int = N_BINS) -> NDArray[np.float32]:
        """Failure expectation over the state space (Figure 11a): (n, n), rows eps'_FC from 0 to
        29, columns eps'_MC from 0 to 29 (bin centres when n = 30)."""
        s = (np.arange(n) + 0.5) * (N_BINS / n)
        eps = EPS_FLOOR * 10.0 ** (s / LOG_SCALE)  # inverse of Eq. 14
        fc, mc = np.meshgrid(eps, eps, indexing="ij")
        return self.failure_expectation(fc, mc)

    def save(self, path: Path, meta: dict | None = None) -> None:
        """Write the weights (and ``meta``) as JSON, atomically; float32 values round-trip
        exactly."""
        payload = {
            "kind": "fs_predictor",
            "layers": [N_INPUTS, N_HIDDEN, N_OUTPUTS],
            "w1": self.w1.tolist(),
            "b1": self.b1.tolist(),
            "w2": self.w2.tolist(),
            "b2": self.b2.tolist(),
            "meta": meta or {},
        }
        write_text(path, json.dumps(payload, indent=1, sort_keys=True) + "\n")

    @classmethod
    def load(cls, path: Path, train_hint: str = "") -> FSPredictor:
        """Read weights written by :meth:`save`; ModelNotTrainedError if there is no file."""
        path = Path(path)
        if not path.is_file():
            raise ModelNotTrainedError(f"no trained F/S predictor at {path}{train_hint}")
        try:
            d = json.loads(path.read_text())
            arrays = [np.array(d[k], dtype=np.float32) for k in ("w1", "b1", "w2", "b2")]
        except (ValueError, KeyError) as e:
            raise GraspError(f"{path} is not an F/S predictor file: {e}") from e
        shapes = [(N_HIDDEN, N_INPUTS), (N_HIDDEN,), (N_OUTPUTS, N_HIDDEN), (N_OUTPUTS,)]
        if [a.shape for a in arrays] != shapes:
            raise GraspError(
                f"{path}: weight shapes {[a.shape for a in arrays]}, expected {shapes}"
            )
        return cls(*arrays)

    @staticmethod
    def load_meta(path: Path) -> dict:
        """The ``meta`` a file written by :meth:`save` carries (empty if none); call after
        :meth:`load` has checked the file."""
        meta = json.loads(Path(path).read_text()).get("meta", {})
        return meta if isinstance(meta, dict) else {}


def visited_states(states: NDArray[np.float64], success: NDArray[np.bool_]):
    """All (eps_FC, eps_MC) rows of recorded trials (T, steps, 2) and each row's trial outcome."""
    valid = ~np.isnan(states[..., 0])
    rows = states[valid]
    label = np.broadcast_to(success[:, None], valid.shape)[valid]
    return rows, label


def balance_classes(
    states: NDArray[np.float64], success: NDArray[np.bool_], rng: np.random.Generator
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Footnote 5: discard success states at random until there are no more of them than failure
    states; the result is in random order. Empty when there are no failure states."""
    fail = np.flatnonzero(~success)
    succ = np.flatnonzero(success)
    if fail.size == 0:
        return states[:0], success[:0]
    keep = succ if succ.size <= fail.size else rng.choice(succ, size=fail.size, replace=False)
    order = rng.permutation(np.concatenate([fail, np.sort(keep)]))
    return states[order], success[order]


@dataclass(frozen=True)
class PredictorTraining:
    """A trained predictor and what it was trained on."""

    predictor: FSPredictor
    failure_per_epoch: NDArray[np.float64]  #: knowledge-based failure rate of each training epoch
    loss_per_epoch: NDArray[np.float64]  #: mean squared error on the epoch's balanced set (after)
    samples_per_epoch: NDArray[np.int64]  #: balanced training instances presented per pass
    objects: tuple[str, ...]


def fit_epoch(
    net: FSNetwork,
    opt: torch.optim.Optimizer,
    x: NDArray[np.float32],
    y: NDArray[np.float32],
    rng: np.random.Generator,
    passes: int = PASSES_PER_EPOCH,
    batch_size: int = BATCH_SIZE,
) -> float:
    """Backpropagation on one epoch's balanced set, in random order each pass; returns the MSE."""
    xt, yt = torch.from_numpy(x), torch.from_numpy(y)
    for _ in range(passes):
        order = torch.from_numpy(rng.permutation(len(x)))
        for i in range(0, len(x), batch_size):
            j = order[i : i + batch_size]
            opt.zero_grad()
            loss = torch.mean((net(xt[j]) - yt[j]) ** 2)
            loss.backward()
            opt.step()
    with torch.no_grad():
        return float(torch.mean((net(xt) - yt) ** 2)) if len(x) else float("nan")


def train_predictor(
    rng: np.random.Generator,
    polygons: ObjectSet | Sequence[Polygon] | None = None,
    epochs: int = PREDICTOR_EPOCHS,
    trials_per_object: int = TRIALS_PER_OBJECT,
    gain: float = GAIN,
    torch_seed: int | None = None,
    progress: Callable[[int, float], None] | None = None,
    cumulative: bool = True,
) -> PredictorTraining:
    """Train the F/S predictor on knowledge-based trials (section 4.3): after each epoch, a
    class-balanced sample of all states visited so far (``cumulative``; else of that epoch's
    states only) is presented in random order.

    ``rng`` draws the trials, the balancing and the presentation order; ``torch_seed`` (default:
    drawn from ``rng``) seeds the initial weights. Same inputs, same weights, bit for bit.
    """
    objects = as_object_set(polygons)
    polys = objects.polygons
    batch = PolygonBatch.of(polys)
    seed = int(rng.integers(2**31)) if torch_seed is None else torch_seed
    net = FSNetwork(torch.Generator().manual_seed(seed))
    opt = torch.optim.SGD(net.parameters(), lr=LEARNING_RATE)
    obj = epoch_objects(len(objects.names), trials_per_object, rng)
    failures, losses, counts = np.zeros(epochs), np.full(epochs, np.nan), np.zeros(epochs, np.int64)
    seen_rows: list[NDArray[np.float64]] = []
    seen_labels: list[NDArray[np.bool_]] = []
    for e in range(epochs):
        idx = epoch_trials(objects, obj, e, trials_per_object)
        result = run_trials(
            polys, idx, KnowledgeBased(), rng, gain=gain, batch=batch, record_states=True
        )
        failures[e] = result.failure_rate
        rows, label = visited_states(result.states, result.success)
        if not cumulative:
            seen_rows.clear()
            seen_labels.clear()
        seen_rows.append(rows)
        seen_labels.append(label)
        rows, label = balance_classes(np.concatenate(seen_rows), np.concatenate(seen_labels), rng)
        counts[e] = len(rows)
        if len(rows):
            x = network_input(rows[:, 0], rows[:, 1])
            y = np.where(label, SUCCESS_TARGET, FAILURE_TARGET).astype(np.float32)
            losses[e] = fit_epoch(net, opt, x, y, rng)
        if progress is not None:
            progress(e, failures[e])
    return PredictorTraining(FSPredictor.of(net), failures, losses, counts, objects.names)
