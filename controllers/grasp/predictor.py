"""The failure/success (F/S) predictor of the pre-imaging controller (section 4.3).

A 2-3-1 network of bipolar sigmoid units, f(x) = 2 / (1 + e^-x) - 1 (outputs in (-1, 1)), trained
by backpropagation on the states visited by the knowledge-based controller: every state of a trial
carries that trial's label. Output +1 means failure expected, -1 success (Figure 11a plots failure
expectation). Success states are subsampled so both classes are equally represented (footnote 5).
Weights are saved as JSON (small, and byte-for-byte reproducible). The trained predictor is
evaluated in numpy (float32, as trained), so a controller that only uses it does not import
torch; the network and its training are in :mod:`controllers.grasp.predictor_training`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.errors import GraspError, ModelNotTrainedError
from controllers.grasp.qlearning import EPS_FLOOR, LOG_SCALE, N_BINS, scaled_error
from graspsim_base.files import write_text

#: Network shape of section 4.3: two state inputs, three hidden units, one output.
N_INPUTS, N_HIDDEN, N_OUTPUTS = 2, 3, 1
#: Training length of section 4.3: 10 epochs of 90 knowledge-based trials (10 per object).
PREDICTOR_EPOCHS = 10
TRIALS_PER_OBJECT = 10
#: Backpropagation settings (the paper gives none; our choice): plain SGD on the mean squared
#: error, this learning rate and mini-batch, this many passes over the balanced set at the end
#: of each epoch. The set is drawn from all states visited so far ("a fraction of all visited
#: states", section 4.3); ``reproduce`` reports PI (c) with that epoch's states only beside it.
#: Chosen between the two readings: docs/findings.md, "F/S predictor's training set".
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


def bipolar_sigmoid(x: NDArray[np.float32]) -> NDArray[np.float32]:
    """The bipolar sigmoid 2 / (1 + e^-x) - 1 = tanh(x / 2) (section 4.3), in float32 as the
    network was trained (torch's float32 result to within 1e-6; over 2 million random states of
    each shipped predictor, the same sign everywhere)."""
    one = np.float32(1.0)
    return (np.float32(2.0) / (one + np.exp(-x, dtype=np.float32)) - one).astype(np.float32)


@dataclass(frozen=True)
class FSPredictor:
    """Trained F/S predictor weights (numpy copies, float32) and how to evaluate them."""

    w1: NDArray[np.float32]  #: (3, 2)
    b1: NDArray[np.float32]  #: (3,)
    w2: NDArray[np.float32]  #: (1, 3)
    b2: NDArray[np.float32]  #: (1,)

    def failure_expectation(self, eps_fc: ArrayLike, eps_mc: ArrayLike) -> NDArray[np.float32]:
        """Network output in (-1, 1) for each state; > 0 predicts failure."""
        x = network_input(eps_fc, eps_mc)
        h = bipolar_sigmoid(x @ self.w1.T + self.b1)
        y = bipolar_sigmoid(h @ self.w2.T + self.b2)
        return y[..., 0]

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
