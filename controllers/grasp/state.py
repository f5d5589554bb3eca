"""The grasp state the composite controllers see at one control step (section 3.6)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.polygon import ContactFrames
from controllers.grasp.polygon_batch import PolygonBatch
from controllers.grasp.prism import ContactFrames3D


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

    @property
    def coordinates(self) -> NDArray[np.float64]:
        """(T, n) the coordinates the controllers move: theta."""
        return self.theta


@dataclass(frozen=True)
class ControlState3D:
    """The same for 3-D contacts on the side faces of prisms (section 3.4 in 3-D,
    :mod:`controllers.grasp.trials3d`): the controllers move the coordinates
    (theta_1..theta_n, z_1..z_n), z the height above the centre of mass (the face coordinate
    r_phi of Eq. 9), so every gradient is (T, 2n), theta first.
    Composers written for :class:`ControlState` (they weigh ``grad_fc`` against ``grad_mc``
    from ``eps_fc`` and ``eps_mc``) work on it unchanged."""

    step: int
    theta: NDArray[np.float64]  #: (T, n) contact coordinates (polar angles, Appendix B)
    z: NDArray[np.float64]  #: (T, n) heights above the centre of mass (unit-moment frame)
    frames: ContactFrames3D  #: (T, n) contact geometry on the unit-moment prisms
    eps_fc: NDArray[np.float64]  #: (T,) Eq. 5 with its f_z term
    eps_mc: NDArray[np.float64]  #: (T,) Eq. 10 with m_x, m_y
    grad_fc: NDArray[np.float64]  #: (T, 2n) Eq. 7 in theta, then 0 (heights)
    grad_mc: NDArray[np.float64]  #: (T, 2n) Eq. 12 in theta, then the height step
    active: NDArray[np.bool_]  #: (T,)
    object_index: NDArray[np.int64]  #: (T,)
    batch: PolygonBatch | None = None  #: the prisms' unit-moment cross-sections

    @property
    def coordinates(self) -> NDArray[np.float64]:
        """(T, 2n) the coordinates the controllers move: theta then z."""
        return np.concatenate([self.theta, self.z], axis=1)
