"""Composite grasp controllers: the common interface and knowledge-based composition.

A composer turns a :class:`ControlState` into the composite contact gradient
``alpha_FC dEps_FC/dtheta + alpha_MC dEps_MC/dtheta`` (section 3.6.1). Learning composers
(Q-learning, pre-imaging) implement the same hooks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.state import ControlState


class Composer(Protocol):
    """A composition policy, called by the trial runner once per step for all trials at once."""

    name: str

    def begin(self, n_trials: int, rng: np.random.Generator) -> None:
        """A batch of trials starts."""

    def gradient(self, state: ControlState, rng: np.random.Generator) -> NDArray[np.float64]:
        """The composite gradient, shape (T, n)."""
        ...

    def end(self, state: ControlState, success: NDArray[np.bool_]) -> None:
        """The batch ended; ``success`` is each trial's outcome (S_G <= 0.4)."""


def luce_activation(
    eps_fc: NDArray[np.float64], eps_mc: NDArray[np.float64], k_fc: float, k_mc: float, b: float
):
    """Luce's rule (section 3.6.1):
    alpha_FC = e^(k_FC eps_FC + b) / (e^(k_FC eps_FC + b) + e^(k_MC eps_MC - b)).

    Computed as a logistic of the exponent difference so that it never overflows.
    """
    z = (k_fc * eps_fc + b) - (k_mc * eps_mc - b)
    return 0.5 * (1.0 + np.tanh(0.5 * z))


@dataclass
class KnowledgeBased:
    """Knowledge-based heuristic composition (section 3.6.1): k_FC = 4000, b = -10, k_MC = 0.

    FC dominates until eps_FC falls below -2b / k_FC = 0.005, then MC refines moments.
    """

    k_fc: float = 4000.0
    k_mc: float = 0.0
    b: float = -10.0
    name: str = "kb"

    def begin(self, n_trials: int, rng: np.random.Generator) -> None:
        return None

    def activation(self, state: ControlState) -> NDArray[np.float64]:
        return luce_activation(state.eps_fc, state.eps_mc, self.k_fc, self.k_mc, self.b)

    def gradient(self, state: ControlState, rng: np.random.Generator) -> NDArray[np.float64]:
        a = self.activation(state)[:, None]
        return a * state.grad_fc + (1.0 - a) * state.grad_mc

    def end(self, state: ControlState, success: NDArray[np.bool_]) -> None:
        return None
