"""One grasp controller run on one polygon, a step at a time (section 5.2, "Wrench Closure").

:func:`controllers.grasp.trials.run_trials` runs many trials to convergence at once; a robot needs
the opposite: one grasp, whose virtual contacts it can inspect after every step (are they still
reachable by the hand?), pause while the arm changes posture, and resume. A
:class:`GraspSynthesis` does that with the same controller step as the trials
(``theta <- theta - gain * gradient`` of a :class:`~controllers.grasp.composition.Composer`,
the same convergence test and step limit, section 3.6.2), so a synthesis run to the end gives the
same contacts as ``run_trials`` from the same initial contacts and generator.

One addition the robot needs and the paper's point contacts do not: ``min_separation``. A
fingertip is a pad of finite size, and two contacts closer than two pads cannot both be taken;
with ``min_separation`` > 0 every step is followed by a projection that keeps the pads' centres
(``separation_offset`` outside the contacts) that far apart, pushing close contacts apart along
the outline (:func:`separate_contacts`): a projected gradient descent on the same objective.
With 0 (the default) the controller is the paper's.

A second one, for a hand that cannot take every face: ``arcs``, one counter-clockwise interval of
contact coordinates per contact, to which each step's contacts are projected (a lateral hand's
pads take only the faces beside its approach axis,
``controllers.preshape.palm_candidates.lateral_arcs``). Without it every contact may go anywhere on
the outline, as in the paper.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.composition import Composer
from controllers.grasp.errors import GraspError
from controllers.grasp.polygon import Polygon, wrap_angle
from controllers.grasp.score import GraspScore, grasp_score
from controllers.grasp.state import ControlState, ControlState3D
from controllers.grasp.trials import (
    CONVERGENCE_STEP,
    GAIN,
    MAX_STEPS,
    PolygonBatch,
    control_state,
)

#: Passes of :func:`separate_contacts` at most.
SEPARATION_PASSES = 30
#: Alternations of the pad separation and the arc projection (``GraspSynthesis(arcs=...)``).
ARC_PASSES = 3


def separate_contacts(
    polygon: Polygon, theta: ArrayLike, min_distance: float, offset: float = 0.0
) -> NDArray[np.float64]:
    """Contact coordinates ``theta`` (n,) moved so that the points ``offset`` outside each
    contact along its normal (a round fingertip's centre, for ``offset`` = its radius) are at
    least ``min_distance`` apart (polygon units). Close pairs are pushed apart along the
    outline, each contact by half the shortfall (an arc of length s at distance r from the
    centroid spans at most s / r radians)."""
    th = np.asarray(theta, dtype=float).copy()
    n = len(th)
    for _ in range(SEPARATION_PASSES):
        frames = polygon.locate(th)
        p = frames.point + offset * frames.normal
        r = np.maximum(np.linalg.norm(frames.point, axis=1), 1e-12)
        moved = False
        for i in range(n):
            for j in range(i + 1, n):
                d = float(np.linalg.norm(p[i] - p[j]))
                if d >= min_distance:
                    continue
                sign = 1.0 if wrap_angle(th[j] - th[i]) >= 0 else -1.0
                need = 0.5 * (min_distance - d) * 1.05
                th[i] -= sign * need / r[i]
                th[j] += sign * need / r[j]
                moved = True
        th = wrap_angle(th)
        if not moved:
            break
    return th


@dataclass(frozen=True)
class SynthesisStep:
    """What one controller step did. Angles in radians (contact coordinate theta, Appendix B)."""

    step: int  #: 1 for the first step
    theta: NDArray[np.float64]  #: (n,) contacts after the step
    eps_fc: float  #: Eq. 5 before the step
    eps_mc: float  #: Eq. 10 before the step
    predicted_failure: bool | None  #: the F/S predictor's verdict before the step (PI only)
    moved: float  #: largest contact displacement of the step (rad)


def clamp_to_arcs(theta: ArrayLike, arcs: ArrayLike) -> NDArray[np.float64]:
    """Each contact coordinate ``theta[i]`` (rad) moved to the nearer end of its
    counter-clockwise interval ``arcs[i] = (lo, hi)`` when outside it."""
    th = np.asarray(theta, dtype=float)
    a = np.asarray(arcs, dtype=float).reshape(-1, 2)
    two_pi = 2.0 * np.pi
    span = np.mod(a[:, 1] - a[:, 0], two_pi)
    rel = np.mod(th - a[:, 0], two_pi)
    outside = rel > span
    nearer_hi = rel - span < two_pi - rel
    out = np.where(outside, np.where(nearer_hi, a[:, 1], a[:, 0]), th)
    return wrap_angle(out)


def keep_contacts(
    polygon: Polygon,
    theta: ArrayLike,
    min_distance: float,
    offset: float = 0.0,
    arcs: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Contact coordinates ``theta`` projected where the contacts may be: pads apart
    (:func:`separate_contacts`, when ``min_distance`` > 0), then each on its arc
    (:func:`clamp_to_arcs`, when ``arcs`` are given), alternated :data:`ARC_PASSES` times (the
    arc wins where both cannot hold: the reach test judges pads at different heights apart in
    3-D)."""
    th = np.asarray(theta, dtype=float)
    for _ in range(ARC_PASSES if arcs is not None else 1):
        if min_distance > 0:
            th = separate_contacts(polygon, th, min_distance, offset)
        if arcs is not None:
            th = clamp_to_arcs(th, arcs)
    return th


class SteppedSynthesis(ABC):
    """What the planar and the 3-D syntheses share: one grasp controller run a step at a time
    (``theta <- theta - gain * gradient`` of the composer, the convergence test and step limit of
    the trials). A subclass sets ``composer``, ``rng``, ``gain``, ``max_steps``, ``_theta``
    (1, n) and ``_state`` and implements :meth:`_move` and :meth:`_evaluate`."""

    composer: Composer
    rng: np.random.Generator
    gain: float
    max_steps: int
    steps: int = 0
    converged: bool = False
    _theta: NDArray[np.float64]
    _state: ControlState | ControlState3D

    @abstractmethod
    def _move(self, delta: NDArray[np.float64]) -> float:
        """Add ``delta`` (1, coordinates) to the contacts, keep them where they may be; return
        the largest move."""

    @abstractmethod
    def _evaluate(self) -> ControlState | ControlState3D:
        """The controllers' state at the current contacts."""

    def _active(self) -> NDArray[np.bool_]:
        return np.array([not self.done])

    #: the run was stopped at earlier contacts (:meth:`GraspSynthesis.stop_at`)
    stopped: bool = False

    @property
    def done(self) -> bool:
        """The controller converged, used up its steps or was stopped."""
        return self.converged or self.stopped or self.steps >= self.max_steps

    @property
    def theta(self) -> NDArray[np.float64]:
        """(n,) current contact coordinates (rad)."""
        return self._theta[0].copy()

    @property
    def eps_fc(self) -> float:
        return float(self._state.eps_fc[0])

    @property
    def eps_mc(self) -> float:
        return float(self._state.eps_mc[0])

    def predicts_failure(self) -> bool | None:
        """The composer's F/S predictor (section 4.2) on the current state; None without one."""
        predictor = getattr(self.composer, "predictor", None)
        if predictor is None:
            return None
        return bool(predictor.predicts_failure(self._state.eps_fc, self._state.eps_mc)[0])

    def step(self) -> SynthesisStep:
        """One control step (raises :class:`GraspError` once :attr:`done`)."""
        if self.done:
            raise GraspError("the grasp controller has already finished")
        before = self._state
        predicted = self.predicts_failure()
        grad = self.composer.gradient(before, self.rng)
        moved = self._move(-self.gain * grad)
        self.steps += 1
        self.converged = moved <= CONVERGENCE_STEP
        self._state = self._evaluate()
        return SynthesisStep(
            step=self.steps,
            theta=self.theta,
            eps_fc=float(before.eps_fc[0]),
            eps_mc=float(before.eps_mc[0]),
            predicted_failure=predicted,
            moved=moved,
        )


class GraspSynthesis(SteppedSynthesis):
    """A composite grasp controller acting on ``polygon`` from contacts ``theta_initial``.

    ``composer`` is any :class:`Composer` (``kb``, ``ql``, ``pi``); ``rng`` feeds its exploration
    or pre-image noise. Call :meth:`step` until :attr:`done`; :attr:`converged` tells whether the
    contacts stopped moving (no contact moved more than 0.0005 rad) before the step limit.
    """

    def __init__(
        self,
        polygon: Polygon,
        composer: Composer,
        theta_initial: ArrayLike,
        rng: np.random.Generator,
        *,
        gain: float = GAIN,
        max_steps: int = MAX_STEPS,
        task: ArrayLike | None = None,
        min_separation: float = 0.0,
        separation_offset: float = 0.0,
        arcs: ArrayLike | None = None,
    ) -> None:
        theta = np.asarray(theta_initial, dtype=float).reshape(1, -1)
        if arcs is not None and np.shape(arcs) != (theta.shape[1], 2):
            raise GraspError(
                f"arcs must be one (lo, hi) interval per contact, shape ({theta.shape[1]}, 2); "
                f"got shape {np.shape(arcs)}"
            )
        if theta.shape[1] < 2 or not np.all(np.isfinite(theta)):
            raise GraspError(
                f"need at least 2 finite initial contact angles, got {theta_initial!r}"
            )
        if not (np.isfinite(gain) and gain > 0):
            raise GraspError(f"gain must be a positive number, got {gain}")
        if max_steps < 1:
            raise GraspError(f"max_steps must be >= 1, got {max_steps}")
        self.polygon = polygon
        self.composer = composer
        self.rng = rng
        self.gain = float(gain)
        self.max_steps = int(max_steps)
        self.task = task
        self.min_separation = float(min_separation)
        self.separation_offset = float(separation_offset)
        self.arcs = None if arcs is None else np.asarray(arcs, dtype=float).copy()
        self._batch = PolygonBatch.of([polygon])
        self._index = np.zeros(1, dtype=np.int64)
        self._theta = self._keep(wrap_angle(theta))
        self.steps = 0
        self.converged = False
        self.composer.begin(1, rng)
        self._state = self._evaluate()

    def _keep(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """``theta`` (1, n) projected where the contacts may be (:func:`keep_contacts`)."""
        return keep_contacts(
            self.polygon, theta[0], self.min_separation, self.separation_offset, self.arcs
        )[None]

    def _move(self, delta: NDArray[np.float64]) -> float:
        theta = self._keep(wrap_angle(self._theta + delta))
        moved = float(np.abs(wrap_angle(theta - self._theta)).max())
        self._theta = theta
        return moved

    def _evaluate(self) -> ControlState:
        return control_state(
            self._batch, self._index, self._theta, self.steps, self._active(), self.task
        )

    def score(self) -> GraspScore:
        """S_G (Eq. 13) of the current contacts on the unit-moment polygon."""
        frames = self._batch.locate(self._index, self._theta)
        return grasp_score(frames.point[0], frames.normal[0], self.task)

    def score_at(self, theta: ArrayLike) -> GraspScore:
        """S_G (Eq. 13) of contacts ``theta`` (n,) on the unit-moment polygon."""
        th = np.asarray(theta, dtype=float).reshape(1, -1)
        frames = self._batch.locate(self._index, th)
        return grasp_score(frames.point[0], frames.normal[0], self.task)

    def stop_at(self, theta: ArrayLike) -> None:
        """End the run at contacts ``theta`` (earlier contacts of this run, e.g. the last a hand
        reached): they become the current contacts and the run is done, not converged."""
        self._theta = np.asarray(theta, dtype=float).reshape(1, -1).copy()
        self._state = self._evaluate()
        self.stopped = True

    def finish(self) -> GraspScore:
        """Tell the composer the run ended (learning composers update on it) and score it."""
        score = self.score()
        self.composer.end(self._state, np.array([score.success]))
        return score
