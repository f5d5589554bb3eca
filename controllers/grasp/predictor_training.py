"""Training of the F/S predictor (section 4.3), in torch: the 2-3-1 network of bipolar sigmoid
units, trained by backpropagation on the states visited by the knowledge-based controller, every
state of a trial labelled with the trial's outcome, success states subsampled so both classes are
equally represented (footnote 5). The trained weights become a
:class:`controllers.grasp.predictor.FSPredictor`, which needs no torch to evaluate.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from numpy.typing import NDArray

from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.objects import ObjectSet
from controllers.grasp.polygon import Polygon
from controllers.grasp.predictor import (
    BATCH_SIZE,
    FAILURE_TARGET,
    LEARNING_RATE,
    N_HIDDEN,
    N_INPUTS,
    N_OUTPUTS,
    PASSES_PER_EPOCH,
    PREDICTOR_EPOCHS,
    SUCCESS_TARGET,
    TRIALS_PER_OBJECT,
    FSPredictor,
    network_input,
)
from controllers.grasp.qlearning import as_object_set, epoch_objects, epoch_trials
from controllers.grasp.trials import GAIN, PolygonBatch, run_trials


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


def predictor_of(net: FSNetwork) -> FSPredictor:
    """The trained weights of ``net`` as an :class:`FSPredictor` (numpy float32 copies)."""

    def grab(t: torch.Tensor) -> NDArray[np.float32]:
        return t.detach().numpy().astype(np.float32).copy()

    return FSPredictor(
        grab(net.hidden.weight), grab(net.hidden.bias), grab(net.out.weight), grab(net.out.bias)
    )


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
    return PredictorTraining(predictor_of(net), failures, losses, counts, objects.names)
