"""The pre-imaging (PI) grasp controller (section 4.3, Figure 8).

Baseline: the knowledge-based composer (section 3.6.1). Whenever the F/S predictor expects failure
in a trial's current state, the pre-image action adds zero-mean gaussian noise (sigma = 0.0167 rad,
clipped to +-0.05 rad) to that trial's control gradient.

How the noise enters theta: the trial runner moves contacts by ``theta -= gain * gradient``. The
paper adds the noise "to the current control gradient" but does not say what gain turns that
gradient into a contact displacement. We write the displacement as ``noise_gain * noise``
(independently per contact and per step) by adding ``noise_gain * noise / gain`` to the gradient.
``noise_gain = 1`` is the literal reading (sigma 0.0167 rad on theta); with our gain it leaves
~5 % failures, because the noise cannot carry a contact over a vertex out of the failure
attractors of the triangles within 300 steps. We use ``PREIMAGE_NOISE_GAIN = 6`` (sigma 0.1 rad,
bound 0.3 rad); ``reproduce`` reports the sensitivity to this choice (docs/learning.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.predictor import FSPredictor
from controllers.grasp.run_folder import TRAIN_HINT
from controllers.grasp.state import ControlState
from controllers.grasp.trials import GAIN

#: Pre-image action of section 4.3: noise standard deviation and bound (rad).
NOISE_SIGMA = 0.0167
NOISE_BOUND = 0.05
#: Displacement per unit of pre-image noise (rad/rad); our choice, the paper gives no gain.
PREIMAGE_NOISE_GAIN = 6.0
#: Model files in a model directory: predictor trained on all nine objects (Table 2 (c)) and on
#: the five-object subset (Table 2 (d)).
PI_MODEL_FILE = "pi_predictor.json"
PI_SUBSET_MODEL_FILE = "pi_predictor_five.json"


def preimage_noise(rng: np.random.Generator, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """Zero-mean gaussian noise, sigma 0.0167 rad, clipped to [-0.05, 0.05] rad (section 4.3)."""
    return np.clip(rng.normal(0.0, NOISE_SIGMA, size=shape), -NOISE_BOUND, NOISE_BOUND)


@dataclass
class PreImaging:
    """PI composer: the knowledge-based gradient plus the pre-image action where failure is
    predicted (section 4.3)."""

    predictor: FSPredictor
    gain: float = GAIN  #: the runner's gain, to turn the noise into a gradient term
    noise_gain: float = PREIMAGE_NOISE_GAIN  #: contact displacement per unit noise
    baseline: KnowledgeBased = field(default_factory=KnowledgeBased)
    name: str = "pi"
    _triggered: NDArray[np.int64] = field(default=None, init=False, repr=False)

    def begin(self, n_trials: int, rng: np.random.Generator) -> None:
        self.baseline.begin(n_trials, rng)
        self._triggered = np.zeros(n_trials, dtype=np.int64)

    def gradient(self, state: ControlState, rng: np.random.Generator) -> NDArray[np.float64]:
        grad = self.baseline.gradient(state, rng)
        noise = preimage_noise(rng, grad.shape)
        fail = self.predictor.predicts_failure(state.eps_fc, state.eps_mc) & state.active
        self._triggered += fail
        return grad + np.where(fail[:, None], noise * (self.noise_gain / self.gain), 0.0)

    def end(self, state: ControlState, success: NDArray[np.bool_]) -> None:
        self.baseline.end(state, success)

    @property
    def triggered_steps(self) -> NDArray[np.int64]:
        """Per trial of the last batch, the number of steps the pre-image action was applied."""
        return self._triggered


def load_pi_composer(
    model_dir: Path, file_name: str = PI_MODEL_FILE, gain: float = GAIN
) -> PreImaging:
    """The PI composer whose predictor ``reproduce`` saved in ``model_dir``."""
    hint = f": {TRAIN_HINT}"
    return PreImaging(FSPredictor.load(Path(model_dir) / file_name, train_hint=hint), gain=gain)
