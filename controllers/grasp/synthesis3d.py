"""One 3-D grasp controller run on one prism, a step at a time (the robot's Wrench Closure with
contacts that have heights).

The 3-D counterpart of :class:`controllers.grasp.synthesis.GraspSynthesis`, with the same
interface (``step``, ``done``, ``converged``, ``theta``, ``finish``) plus ``heights``: the
controller step of :func:`controllers.grasp.trials3d.run_trials_3d` (theta and height, in a band
of heights, the pads kept apart after every step). When it finishes, the contacts' common height
is set by the task (the first of :func:`controllers.grasp.task_height.ranked_shifts`) when a
``load`` is given; :meth:`GraspSynthesis3D.height_options` gives the next-best common heights
for a hand that cannot take the contacts at the best one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.composition import Composer
from controllers.grasp.errors import GraspError
from controllers.grasp.polygon import Polygon
from controllers.grasp.score3d import GraspScore3D, grasp_score_3d
from controllers.grasp.state import ControlState3D
from controllers.grasp.synthesis import SteppedSynthesis, SynthesisStep
from controllers.grasp.task_height import TaskShift, ranked_shifts, spread_shifts
from controllers.grasp.trials import GAIN, MAX_STEPS
from controllers.grasp.trials3d import (
    HeightBand,
    PrismBatch,
    advance,
    control_state_3d,
    pad_spacing,
)


class GraspSynthesis3D(SteppedSynthesis):
    """A composite grasp controller on the prism of ``polygon`` (its own unit, centroid at the
    origin) and ``height``, contacts at polar angles ``theta_initial`` and heights
    ``heights_initial`` above the centre of mass (the polygon's unit), kept in ``band``.

    ``load`` (m*g over the unit contact force) and ``yaw`` (the world x axis in the polygon's
    frame) describe the task that sets the common height when the run ends; None leaves it.
    """

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
        gain: float = GAIN,
        max_steps: int = MAX_STEPS,
        min_separation: float = 0.0,
        separation_offset: float = 0.0,
        load: float | None = None,
        yaw: float = 0.0,
    ) -> None:
        theta = np.asarray(theta_initial, dtype=float).reshape(1, -1)
        z = np.asarray(heights_initial, dtype=float).reshape(1, -1)
        if theta.shape[1] < 2 or theta.shape != z.shape:
            raise GraspError(
                f"need at least 2 contacts with one height each, got {theta.shape[1]} angles "
                f"and {z.shape[1]} heights"
            )
        if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(z))):
            raise GraspError("initial contacts must be finite")
        if not (np.isfinite(gain) and gain > 0) or max_steps < 1:
            raise GraspError(f"gain must be > 0 and max_steps >= 1, got {gain}, {max_steps}")
        self.polygon = polygon
        self.composer = composer
        self.rng = rng
        self.gain = float(gain)
        self.max_steps = int(max_steps)
        self.load = load
        self.yaw = float(yaw)
        self._batch = PrismBatch.of([polygon], [height], [band])
        self._index = np.zeros(1, dtype=np.int64)
        self._scale = float(self._batch.scale[0])
        self._separate = pad_spacing(self._batch, self._index, min_separation, separation_offset)
        self._theta = self._separate(theta)
        self._z = self._batch.into_band(self._index, z / self._scale)
        self.steps = 0
        self.converged = False
        self.composer.begin(1, rng)
        self._state = self._evaluate()
        self._shifts: list[TaskShift] = []
        self._unshifted: NDArray[np.float64] | None = None  # heights before the task's shift

    def _evaluate(self) -> ControlState3D:
        return control_state_3d(
            self._batch, self._index, self._theta, self._z, self.steps, self._active()
        )

    def _move(self, delta: NDArray[np.float64]) -> float:
        self._theta, self._z, moved = advance(
            self._batch,
            self._index,
            self._theta,
            self._z,
            delta,
            np.ones(1, dtype=bool),
            self._separate,
        )
        return float(moved[0])

    @property
    def heights(self) -> NDArray[np.float64]:
        """(n,) current contact heights above the centre of mass (the polygon's unit)."""
        return self._z[0] * self._scale

    def score(self) -> GraspScore3D:
        """S_G in 3-D (Eq. 13, 6-D wrenches, the null grasp) of the current contacts."""
        f = self._state.frames
        return grasp_score_3d(f.point[0], f.normal[0])

    def step(self) -> SynthesisStep:
        """One control step; the step that ends the run (converged or the step limit) also sets
        the common height by the task (when a load is given), so that :attr:`theta` and
        :attr:`heights` are final once :attr:`done`."""
        out = super().step()
        if self.done and self.load is not None:
            f = self._state.frames
            lo, hi = self._batch.z_low[0], self._batch.z_high[0]
            self._shifts = ranked_shifts(f.point[0], f.normal[0], lo, hi, self.load, self.yaw)
            self._unshifted = self._z[0].copy()
            self._z = self._z + self._shifts[0].shift
            self._state = self._evaluate()
        return out

    def set_heights(self, heights: ArrayLike) -> None:
        """The contacts' heights (n,) (m above the centre of mass), e.g. those the fingers took
        in a reach test or one of :meth:`height_options`, clipped to the band; the controllers'
        state follows."""
        z = np.asarray(heights, dtype=float).reshape(1, -1)
        if z.shape != self._theta.shape or not np.all(np.isfinite(z)):
            raise GraspError(f"need {self._theta.shape[1]} finite heights, got {heights!r}")
        self._z = self._batch.into_band(self._index, z / self._scale)
        self._state = self._evaluate()

    def height_options(self, tries: int, min_gap: float) -> list[NDArray[np.float64]]:
        """Contact heights (n,) above the centre of mass (the polygon's unit) to try in turn,
        best first: the task's common height (:attr:`heights`), then the next-best common shifts
        by the worst-task S_G (:func:`~controllers.grasp.task_height.spread_shifts`), at most
        ``tries`` in all, each at least ``min_gap`` (the polygon's unit) from the others. Only
        :attr:`heights` before the run ends or without a task."""
        if self._unshifted is None:
            return [self.heights]
        kept = spread_shifts(self._shifts, tries, min_gap / self._scale)
        return [(self._unshifted + t.shift) * self._scale for t in kept]

    def finish(self) -> GraspScore3D:
        """Tell the composer the run ended (learning composers update on it) and score it."""
        score = self.score()
        self.composer.end(self._state, np.array([score.success]))
        return score
