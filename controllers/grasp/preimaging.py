"""The pre-imaging (PI) grasp controller (section 4.3, Figure 8).

Baseline: the knowledge-based composer (section 3.6.1). Whenever the F/S predictor expects failure
in a trial's current state, the pre-image action perturbs that trial's contacts. The paper's action
(its option (1)) "adds a zero mean, gaussian noise signal, bounded to [-0.05, 0.05] radians
(standard deviation 0.0167), to the current control gradient". It does not give the gain that
turns the gradient into a contact displacement, nor say in what unit the contact coordinate is, so
the noise has several readings (:data:`NOISE_READINGS`); each moves contact i by a displacement
``d_i`` (rad of theta) per step, independent per contact and per step:

- ``literal``: d = noise, i.e. 0.0167 rad on theta (the headline of our tables);
- ``gradient``: the noise is added to the gradient *before* the runner's gain, d = gain * noise;
- ``turn``: theta as a fraction of a turn, d = 2 pi * noise (sigma 0.105 rad);
- ``perimeter``: the contact coordinate as a fraction of the perimeter: the contact slides
  ``perimeter * noise`` along the outline, and d is the change of its polar angle.

``noise_scale`` multiplies the noise (the sensitivity sweep). The paper's option (2), a corrective
action "computed using the predictor module itself", is the ``predictor`` action: contacts move
down the gradient of the predictor's failure expectation with respect to theta (chain rule through
eps_FC(theta) and eps_MC(theta)), a step of at most :data:`PREDICTOR_STEP` rad.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.errors import GraspError, UnknownNameError
from controllers.grasp.predictor import FAILURE_THRESHOLD, FSPredictor, network_input
from controllers.grasp.qlearning import EPS_FLOOR, N_BINS
from controllers.grasp.run_folder import TRAIN_HINT
from controllers.grasp.state import ControlState, ControlState3D
from controllers.grasp.trials import GAIN
from controllers.grasp.wrench import fc_gradient, mc_gradient

#: Pre-image action of section 4.3: noise standard deviation and bound, in the unit of the reading.
NOISE_SIGMA = 0.0167
NOISE_BOUND = 0.05
#: How the noise becomes a contact displacement (see the module docstring).
NOISE_READINGS: dict[str, str] = {
    "literal": "0.0167 rad on theta",
    "gradient": "noise added to the gradient before the gain (gain x 0.0167 rad on theta)",
    "turn": "theta as a fraction of a turn (2 pi x 0.0167 = 0.105 rad)",
    "perimeter": "theta as a fraction of the perimeter (0.0167 of the outline's length)",
}
#: The paper's action (1), noise, and its option (2), descent on the predictor's output.
ACTIONS: tuple[str, ...] = ("noise", "predictor")
#: Largest contact displacement per step of the ``predictor`` action (rad): the noise bound of the
#: ``turn`` reading, our choice (the paper gives none).
PREDICTOR_STEP = 2.0 * np.pi * NOISE_BOUND
#: Model files in a model directory: F/S predictors trained on the nine paper objects (Table 2
#: (c)), on the five-object subset (Table 2 (d)), and on random convex polygons (the general one).
PI_MODEL_FILE = "pi_predictor_nine.json"
PI_SUBSET_MODEL_FILE = "pi_predictor_five.json"
PI_GENERAL_MODEL_FILE = "pi_predictor_general.json"


def preimage_noise(
    rng: np.random.Generator, shape: tuple[int, ...], scale: float = 1.0
) -> NDArray[np.float64]:
    """Zero-mean gaussian noise, sigma 0.0167, clipped to [-0.05, 0.05] (section 4.3), times
    ``scale``."""
    return scale * np.clip(rng.normal(0.0, NOISE_SIGMA, size=shape), -NOISE_BOUND, NOISE_BOUND)


def noise_displacement(
    reading: str, noise: NDArray[np.float64], state: ControlState, gain: float
) -> NDArray[np.float64]:
    """Contact displacement (rad of theta, (T, n)) that ``noise`` means under ``reading``."""
    if reading == "literal":
        return noise
    if reading == "gradient":
        return gain * noise
    if reading == "turn":
        return 2.0 * np.pi * noise
    if reading == "perimeter":
        if state.batch is None:
            raise GraspError("the perimeter reading needs the polygons (ControlState.batch)")
        idx = state.object_index
        arc = state.batch.arc_of(idx, state.batch.locate(idx, state.theta))
        moved = state.batch.theta_at_arc(idx, arc + state.batch.perimeter[idx][:, None] * noise)
        return np.angle(np.exp(1j * (moved - state.theta)))
    raise UnknownNameError("noise reading", reading, list(NOISE_READINGS))


def failure_gradient(predictor: FSPredictor, state: ControlState) -> NDArray[np.float64]:
    """d(failure expectation)/d theta, (T, n): the network's input gradient, times the derivative
    of Eq. 14's scaling (0 where it is floored or capped), times the exact gradients of eps_FC and
    eps_MC (Eq. 6 and Eq. 3 with the MC model). Imports torch (for its autograd) when first
    called: the default noise action never needs it."""
    import torch

    x = torch.from_numpy(network_input(state.eps_fc, state.eps_mc)).requires_grad_(True)
    h = torch.tanh(0.5 * (x @ torch.from_numpy(predictor.w1).T + torch.from_numpy(predictor.b1)))
    y = torch.tanh(0.5 * (h @ torch.from_numpy(predictor.w2).T + torch.from_numpy(predictor.b2)))
    (dx,) = torch.autograd.grad(y.sum(), x)
    dx = dx.numpy().astype(float)  # (T, 2): d f / d x_FC, d f / d x_MC
    eps = np.stack([state.eps_fc, state.eps_mc], axis=1)
    live = (eps > EPS_FLOOR) & (eps < EPS_FLOOR * 10.0 ** ((N_BINS - 1) / 14.5))
    dx_deps = np.where(live, 1.0 / (np.log(10.0) * np.maximum(eps, EPS_FLOOR)), 0.0)
    w = dx * dx_deps
    return w[:, :1] * fc_gradient(state.theta) + w[:, 1:] * mc_gradient(state.frames, state.theta)


@dataclass
class PreImaging:
    """PI composer: the knowledge-based gradient plus the pre-image action where failure is
    predicted (section 4.3)."""

    predictor: FSPredictor
    gain: float = GAIN  #: the runner's gain, to turn a displacement into a gradient term
    reading: str = "literal"  #: how the noise enters theta (:data:`NOISE_READINGS`)
    noise_scale: float = 1.0  #: multiplies the paper's noise (sensitivity sweep)
    action: str = "noise"  #: "noise" (the paper's option 1) or "predictor" (option 2)
    threshold: float = FAILURE_THRESHOLD  #: failure is predicted when the output exceeds this
    baseline: KnowledgeBased = field(default_factory=KnowledgeBased)
    name: str = "pi"
    _triggered: NDArray[np.int64] = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.reading not in NOISE_READINGS:
            raise UnknownNameError("noise reading", self.reading, list(NOISE_READINGS))
        if self.action not in ACTIONS:
            raise UnknownNameError("pre-image action", self.action, list(ACTIONS))
        if not (np.isfinite(self.gain) and self.gain > 0.0):
            raise GraspError(f"the gain must be a positive number, got {self.gain}")

    def begin(self, n_trials: int, rng: np.random.Generator) -> None:
        self.baseline.begin(n_trials, rng)
        self._triggered = np.zeros(n_trials, dtype=np.int64)

    def displacement(self, state: ControlState, rng: np.random.Generator) -> NDArray[np.float64]:
        """The pre-image action's contact displacement (rad), for every trial."""
        if self.action == "predictor":
            g = failure_gradient(self.predictor, state)
            big = np.abs(g).max(axis=1, keepdims=True)
            return -PREDICTOR_STEP * np.divide(g, big, out=np.zeros_like(g), where=big > 0.0)
        noise = preimage_noise(rng, state.theta.shape, self.noise_scale)
        return noise_displacement(self.reading, noise, state, self.gain)

    def gradient(self, state: ControlState, rng: np.random.Generator) -> NDArray[np.float64]:
        """The KB gradient, minus the pre-image displacement / gain where failure is predicted.
        With 3-D contacts (:class:`~controllers.grasp.state.ControlState3D`, gradients (T, 2n))
        the displacement moves theta as in the plane and leaves the heights to moment closure."""
        grad = self.baseline.gradient(state, rng)
        if isinstance(state, ControlState3D) and self.action == "predictor":
            raise GraspError("the predictor-gradient pre-image action is planar only; use noise")
        extra = self.displacement(state, rng)
        if extra.shape != grad.shape:  # 3-D: no displacement of the heights
            extra = np.concatenate([extra, np.zeros_like(extra)], axis=1)
        out = self.predictor.failure_expectation(state.eps_fc, state.eps_mc)
        fail = (out > self.threshold) & state.active
        self._triggered += fail
        return grad - np.where(fail[:, None], extra / self.gain, 0.0)

    def end(self, state: ControlState, success: NDArray[np.bool_]) -> None:
        self.baseline.end(state, success)

    @property
    def triggered_steps(self) -> NDArray[np.int64]:
        """Per trial of the last batch, the number of steps the pre-image action was applied."""
        return self._triggered


def load_pi_composer(
    model_dir: Path, file_name: str = PI_MODEL_FILE, gain: float = GAIN, **settings
) -> PreImaging:
    """The PI composer whose predictor ``reproduce`` saved in ``model_dir``, with the settings
    (reading, threshold) saved beside its weights; ``settings`` (:class:`PreImaging` fields)
    override them."""
    hint = f": {TRAIN_HINT}"
    path = Path(model_dir) / file_name
    pred = FSPredictor.load(path, train_hint=hint)
    saved = FSPredictor.load_meta(path).get("settings", {})
    known = {k: saved[k] for k in ("reading", "threshold", "noise_scale", "action") if k in saved}
    return PreImaging(pred, gain=gain, **{**known, **settings})
