"""Grasp trials (section 3.6.2, "Trial Description"), vectorized over many trials at once.

Each trial places n contacts at random (uniform in the contact coordinate theta), then lets a
composer move them by ``theta <- theta - gain * gradient`` until no contact moves more than
0.0005 rad in a step, or for at most 300 steps. The final configuration is scored with S_G.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.composition import Composer
from controllers.grasp.errors import TrialSettingsError
from controllers.grasp.polygon import Polygon, wrap_angle
from controllers.grasp.polygon_batch import PolygonBatch
from controllers.grasp.score import GraspScore, grasp_score
from controllers.grasp.state import ControlState
from controllers.grasp.wrench import eps_fc, eps_mc, fc_gradient_convex, mc_gradient_convex

#: Maximum control steps per trial (section 3.6.2).
MAX_STEPS = 300
#: A trial has converged when no contact moved more than this in the last step (rad).
CONVERGENCE_STEP = 5e-4
#: Contacts per trial (four-fingered grasps).
N_CONTACTS = 4
#: Step size of the gradient descent on theta (rad per unit gradient; the paper gives none). In
#: the MC phase a step shrinks the angular error by about GAIN * r_0^2, r_0 = 1 / tan(pi / k) on a
#: unit-moment regular k-gon, so 0.25 keeps the MC descent stable up to octagons.
#: Chosen for that stability: docs/findings.md, "Control gain".
GAIN = 0.25


def control_state(
    batch: PolygonBatch,
    object_index: NDArray[np.int64],
    theta: NDArray[np.float64],
    step: int,
    active: NDArray[np.bool_],
    task: ArrayLike | None = None,
) -> ControlState:
    """Evaluate both controllers' errors and convex gradients at ``theta``."""
    frames = batch.locate(object_index, theta)
    return ControlState(
        step=step,
        theta=theta,
        frames=frames,
        eps_fc=eps_fc(theta, task),
        eps_mc=eps_mc(frames, task),
        grad_fc=fc_gradient_convex(theta, task),
        grad_mc=mc_gradient_convex(frames, theta, task),
        active=active,
        object_index=object_index,
        batch=batch,
    )


@dataclass(frozen=True, kw_only=True)
class TrialOutcomes:
    """What a batch of T trials reports per trial, planar or 3-D (section 4.1): the descent's
    steps and convergence, the final eps_FC and eps_MC, S_G (Eq. 13; inf when infeasible), and
    success (converged to S_G <= the threshold)."""

    steps: NDArray[np.int64]
    converged: NDArray[np.bool_]
    eps_fc: NDArray[np.float64]
    eps_mc: NDArray[np.float64]
    s_g: NDArray[np.float64]
    feasible: NDArray[np.bool_]
    success: NDArray[np.bool_]

    @property
    def failure_rate(self) -> float:
        return float(1.0 - self.success.mean())


@dataclass(frozen=True, kw_only=True)
class TrialBatch(TrialOutcomes):
    """Results of T planar trials. Angles in radians.

    ``states`` (when recorded) holds (eps_FC, eps_MC) before each step and after the last one,
    shape (T, MAX_STEPS + 1, 2), NaN past the end of each trial.
    """

    object_index: NDArray[np.int64]
    theta_initial: NDArray[np.float64]
    theta_final: NDArray[np.float64]
    points: NDArray[np.float64]  #: (T, n, 2) final contact points, unit-moment object frame
    states: NDArray[np.float64] | None = field(default=None, repr=False)

    def subset(self, mask: NDArray[np.bool_]) -> TrialBatch:
        """The trials selected by a boolean (or index) ``mask`` over the batch."""
        return TrialBatch(
            **{
                name: None if value is None else value[mask]
                for name, value in ((f, getattr(self, f)) for f in self.__dataclass_fields__)
            }
        )


def random_contacts(
    rng: np.random.Generator, n_trials: int, n_contacts: int
) -> NDArray[np.float64]:
    """Initial contact coordinates, uniform on [0, 2 pi)."""
    return rng.uniform(0.0, 2.0 * np.pi, size=(n_trials, n_contacts))


def score_contacts(
    batch: PolygonBatch,
    object_index: NDArray[np.int64],
    theta: NDArray[np.float64],
    task: ArrayLike | None = None,
) -> list[GraspScore]:
    """S_G of each configuration (one LP per trial)."""
    frames = batch.locate(object_index, theta)
    t = None if task is None else np.broadcast_to(np.asarray(task, float), (theta.shape[0], 3))
    return [
        grasp_score(frames.point[i], frames.normal[i], None if t is None else t[i])
        for i in range(theta.shape[0])
    ]


@dataclass(frozen=True)
class Descent:
    """Where :func:`descend` left a batch of trials: the last state and, per trial, its steps
    and whether it converged."""

    state: Any
    steps: NDArray[np.int64]
    converged: NDArray[np.bool_]


@dataclass(frozen=True)
class DescentSettings:
    """How a batch of trials descends (section 3.6.2): contacts per grasp, the step budget, the
    gain of ``theta <- theta - gain * gradient`` and the task wrench (None: no task term).
    Refuses settings that cannot run."""

    n_contacts: int = N_CONTACTS
    max_steps: int = MAX_STEPS
    gain: float = GAIN
    task: ArrayLike | None = None

    def __post_init__(self) -> None:
        if self.n_contacts < 2:
            raise TrialSettingsError(f"a grasp needs at least 2 contacts, got {self.n_contacts}")
        if self.max_steps < 1:
            raise TrialSettingsError(f"max_steps must be >= 1, got {self.max_steps}")


def descend(
    composer: Composer,
    rng: np.random.Generator,
    n_trials: int,
    max_steps: int,
    gain: float,
    evaluate: Callable[[int, NDArray[np.bool_]], Any],
    move: Callable[[NDArray[np.float64], NDArray[np.bool_]], NDArray[np.float64]],
    before_step: Callable[[int, Any, NDArray[np.bool_]], None] | None = None,
) -> Descent:
    """The trials' gradient descent (section 3.6.2), whatever the contacts' coordinates:
    ``evaluate(step, active)`` gives the controllers' state, ``move(-gain * gradient, active)``
    moves the active trials' contacts and returns each trial's largest move; a trial converges
    when that is at most :data:`CONVERGENCE_STEP`, or stops at ``max_steps``."""
    active = np.ones(n_trials, dtype=bool)
    steps = np.zeros(n_trials, dtype=np.int64)
    converged = np.zeros(n_trials, dtype=bool)
    composer.begin(n_trials, rng)
    state = evaluate(0, active.copy())
    for k in range(max_steps):
        if before_step is not None:
            before_step(k, state, active)
        moved = move(-gain * composer.gradient(state, rng), active)
        steps[active] = k + 1
        done = active & (moved <= CONVERGENCE_STEP)
        converged |= done
        active = active & ~done
        state = evaluate(k + 1, active.copy())
        if not active.any():
            break
    return Descent(state, steps, converged)


def run_trials(
    polygons: Sequence[Polygon],
    object_index: ArrayLike,
    composer: Composer,
    rng: np.random.Generator,
    *,
    n_contacts: int = N_CONTACTS,
    max_steps: int = MAX_STEPS,
    gain: float = GAIN,
    task: ArrayLike | None = None,
    theta_initial: ArrayLike | None = None,
    record_states: bool = False,
    batch: PolygonBatch | None = None,
) -> TrialBatch:
    """Run ``len(object_index)`` trials at once; trial i grasps ``polygons[object_index[i]]``.

    ``rng`` draws the initial contacts (unless ``theta_initial`` is given) and is passed to the
    composer (exploration, pre-image noise). The same seed gives the same result.
    """
    DescentSettings(n_contacts, max_steps, gain, task)
    batch = batch or PolygonBatch.of(polygons)
    idx = np.asarray(object_index, dtype=np.int64)
    n_trials = idx.shape[0]
    if theta_initial is None:
        theta = random_contacts(rng, n_trials, n_contacts)
    else:
        theta = np.array(theta_initial, dtype=float).reshape(n_trials, -1)
    theta0 = theta.copy()
    states = np.full((n_trials, max_steps + 1, 2), np.nan) if record_states else None
    coords = {"theta": theta}

    def evaluate(step: int, active: NDArray[np.bool_]) -> ControlState:
        return control_state(batch, idx, coords["theta"], step, active, task)

    def move(delta: NDArray[np.float64], active: NDArray[np.bool_]) -> NDArray[np.float64]:
        d = np.where(active[:, None], delta, 0.0)
        coords["theta"] = wrap_angle(coords["theta"] + d)
        return np.abs(d).max(axis=1)

    def record(k: int, state: ControlState, active: NDArray[np.bool_]) -> None:
        if states is not None:
            states[active, k, 0] = state.eps_fc[active]
            states[active, k, 1] = state.eps_mc[active]

    run = descend(composer, rng, n_trials, max_steps, gain, evaluate, move, record)
    state, steps, converged, theta = run.state, run.steps, run.converged, coords["theta"]
    if states is not None:
        rows = np.arange(n_trials)
        states[rows, steps, 0] = state.eps_fc
        states[rows, steps, 1] = state.eps_mc
    scores = score_contacts(batch, idx, theta, task)
    s_g = np.array([s.s_g for s in scores])
    feasible = np.array([s.feasible for s in scores])
    success = np.array([s.success for s in scores])
    composer.end(state, success)
    return TrialBatch(
        object_index=idx,
        theta_initial=theta0,
        theta_final=theta,
        points=state.frames.point,
        steps=steps,
        converged=converged,
        eps_fc=state.eps_fc,
        eps_mc=state.eps_mc,
        s_g=s_g,
        feasible=feasible,
        success=success,
        states=states,
    )


def trial_summary(result: TrialBatch, seconds: float | None = None) -> dict:
    """Failure rate, mean S_G over feasible grasps, mean steps (and trials/s) of a batch."""
    feasible = result.s_g[result.feasible]
    out = {
        "trials": int(result.success.size),
        "failure_rate": result.failure_rate,
        "mean_s_g": float(feasible.mean()) if feasible.size else float("nan"),
        "infeasible": int((~result.feasible).sum()),
        "mean_steps": float(result.steps.mean()),
        "converged": float(result.converged.mean()),
    }
    if seconds is not None:
        out["seconds"] = seconds
        out["trials_per_s"] = result.success.size / seconds if seconds > 0 else float("inf")
    return out
