"""The 3-D grasp controller of a lateral grasp: contacts on the arcs a lateral hand can take, at
the heights its fingers take (section 3.4 in 3-D, docs/task_cycle.md "The lateral grasp").

A lateral hand comes in beside the block with its finger row horizontal and its thumb below
it: the hand's shape, not the controller, sets each finger's height on the block (the reach
test slides each contact up or down its face to where the finger can press it,
:func:`controllers.hand.reachability.check_reach`). So the contacts' heights are not the
controller's to move, as they are in a top grasp
(:class:`~controllers.grasp.synthesis3d.GraspSynthesis3D`, where moment closure moves them within a
band and the task sets their common height): they are given (:meth:`LateralSynthesis3D.set_heights`,
from the pre-shape's and each reach test's heights) and held; the controller moves the contact
coordinates theta, each kept on its arc and the pads apart exactly as the planar lateral grasp
(:func:`controllers.grasp.synthesis.keep_contacts`).

What the heights change: eps_MC (Eq. 10 with m_x, m_y, moments about the contacts' mean height,
:func:`controllers.grasp.trials3d.residual_about_mean_height`), which the pre-imaging
composer's failure predictor reads (section 4), and S_G, scored in 3-D (Eq. 13, 6-D wrenches)
with the task of the block hanging in the hand under its weight
(:func:`controllers.grasp.prism3d.physical_tasks`, stage "hang"). The theta gradients are the
planar ones (FC on the Gaussian sphere and MC in theta do not see the heights,
:mod:`controllers.grasp.trials3d`), so with all heights equal the contacts move exactly as the
planar lateral grasp's (tested).

The task cycle runs it only with ``fsm.config.TaskConfig.lateral_grasp_3d`` (off by default): at
the heights a lateral hand's fingers take on single_rectangle, its S_G is 0.99-2.24, above
Eq. 13's 0.4 (docs/task_cycle.md, "The lateral grasp in 3-D").
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.composition import Composer
from controllers.grasp.errors import GraspError
from controllers.grasp.polygon import Polygon, wrap_angle
from controllers.grasp.prism3d import physical_tasks
from controllers.grasp.score3d import GraspScore3D, grasp_score_3d
from controllers.grasp.synthesis import keep_contacts
from controllers.grasp.synthesis3d import GraspSynthesis3D
from controllers.grasp.trials import GAIN, MAX_STEPS
from controllers.grasp.trials3d import HeightBand

#: The physical test's stage whose task a lateral grasp is scored with: the weight alone.
WEIGHT_STAGE = "hang"


class LateralSynthesis3D(GraspSynthesis3D):
    """A composite grasp controller on the prism of ``polygon`` and ``height`` whose contact
    ``i`` stays on its counter-clockwise arc ``arcs[i]`` (rad) at its given height (m above the
    centre of mass, kept in ``band``, the heights a lateral hand's contacts may slide in).

    ``load`` (m*g over the unit contact force) is the task S_G is scored with (the weight,
    :data:`WEIGHT_STAGE`); None scores the null task as the top grasp does. ``min_separation``
    and ``separation_offset`` (the polygon's unit) keep the pads apart as in
    :class:`~controllers.grasp.synthesis.GraspSynthesis`."""

    def __init__(
        self,
        polygon: Polygon,
        height: float,
        band: HeightBand,
        composer: Composer,
        theta_initial: ArrayLike,
        heights_initial: ArrayLike,
        rng: np.random.Generator,
        *,
        arcs: ArrayLike,
        gain: float = GAIN,
        max_steps: int = MAX_STEPS,
        min_separation: float = 0.0,
        separation_offset: float = 0.0,
        load: float | None = None,
    ) -> None:
        n = np.size(theta_initial)
        if np.shape(arcs) != (n, 2):
            raise GraspError(
                f"arcs must be one (lo, hi) interval per contact, shape ({n}, 2); "
                f"got shape {np.shape(arcs)}"
            )
        self.arcs = np.asarray(arcs, dtype=float).copy()
        self.min_separation = float(min_separation)
        self.separation_offset = float(separation_offset)
        self.task = None if load is None else physical_tasks(load, n)[WEIGHT_STAGE]
        # no task shift of the heights (load=None): the hand's shape sets them
        super().__init__(
            polygon,
            height,
            band,
            composer,
            theta_initial,
            heights_initial,
            rng,
            gain=gain,
            max_steps=max_steps,
        )
        self._separate = self._keep
        self._theta = self._keep(wrap_angle(np.asarray(theta_initial, float).reshape(1, -1)))
        self._state = self._evaluate()

    def _keep(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """``theta`` (1, n) projected where a lateral hand's contacts may be: pads apart, each
        on its arc (:func:`~controllers.grasp.synthesis.keep_contacts`, as the planar grasp)."""
        return keep_contacts(
            self.polygon, theta[0], self.min_separation, self.separation_offset, self.arcs
        )[None]

    def _move(self, delta: NDArray[np.float64]) -> float:
        """Move theta by the first half of ``delta`` (1, 2n); the heights are held."""
        n = self._theta.shape[1]
        theta = self._keep(wrap_angle(self._theta + delta[:, :n]))
        moved = float(np.abs(wrap_angle(theta - self._theta)).max())
        self._theta = theta
        return moved

    def score_at(self, theta: ArrayLike) -> GraspScore3D:
        """S_G in 3-D (Eq. 13, 6-D wrenches, the weight's task) of contacts ``theta`` (n,) at
        the current heights."""
        th = np.asarray(theta, dtype=float).reshape(1, -1)
        f = self._batch.locate(self._index, th, self._z)
        return grasp_score_3d(f.point[0], f.normal[0], self.task)

    def score(self) -> GraspScore3D:
        """S_G in 3-D (Eq. 13, 6-D wrenches, the weight's task) of the current contacts."""
        return self.score_at(self._theta[0])

    def stop_at(self, theta: ArrayLike) -> None:
        """End the run at contacts ``theta`` (earlier contacts of this run, e.g. the last the
        hand reached): they become the current contacts and the run is done, not converged."""
        self._theta = np.asarray(theta, dtype=float).reshape(1, -1).copy()
        self._state = self._evaluate()
        self.stopped = True
