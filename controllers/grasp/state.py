"""The grasp state the composite controllers see at one control step (section 3.6)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.polygon import ContactFrames
from controllers.grasp.polygon_batch import PolygonBatch


@dataclass(frozen=True)
class ControlState:
    """Everything a composer needs at one step, for T trials of n contacts at once.

    ``grad_fc`` and ``grad_mc`` are the convex FC and MC gradients (Eq. 7 and 12); ``active``
    marks trials that have not converged yet (finished trials are not moved).
    """

    step: int
    theta: NDArray[np.float64]  #: (T, n) contact coordinates
    frames: ContactFrames  #: (T, n) contact geometry on the true polygon
    eps_fc: NDArray[np.float64]  #: (T,) Eq. 5
    eps_mc: NDArray[np.float64]  #: (T,) Eq. 10
    grad_fc: NDArray[np.float64]  #: (T, n) Eq. 7
    grad_mc: NDArray[np.float64]  #: (T, n) Eq. 12
    active: NDArray[np.bool_]  #: (T,)
    object_index: NDArray[np.int64]  #: (T,) which polygon each trial grasps
    batch: PolygonBatch | None = None  #: the polygons (unit-moment), for geometry-aware composers
