"""Step 1 of the physical study, planar or 3-D: the grasp controller's contacts for one grasp.

- ``planar`` (the paper's controllers with phi = 0): a
  :class:`~controllers.grasp.synthesis.GraspSynthesis` from four contacts uniform in theta, with
  the task cycle's pad spacing; the hand then takes each contact at its fingertip's height;
- ``3d`` (:mod:`controllers.grasp.trials3d`): the same composer on the 3-D controllers, over
  theta and the contacts' heights, within the band of heights a top grasp reaches
  (:data:`TOP_GRASP_DEPTHS`); the initial heights are drawn uniform in the band after the same
  theta draw; the pad spacing as in the planar synthesis (after every step); then the physical
  test's task wrenches set the contacts' common height (:mod:`controllers.grasp.task_height`).
  The hand takes each contact at its own height; when it cannot, the next-best common heights
  (:data:`HEIGHT_TRIES` in all, :data:`HEIGHT_GAP` apart) are tried in turn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.composition import Composer
from controllers.grasp.polygon import Polygon
from controllers.grasp.synthesis import GraspSynthesis
from controllers.grasp.synthesis3d import GraspSynthesis3D
from controllers.grasp.task_height import HEIGHT_GAP, HEIGHT_TRIES
from controllers.grasp.trials3d import HeightBand
from controllers.hand.reachability import CONTACT_SEPARATION
from controllers.reach.fine import GRASP_DEPTH, TOP_GRASP_DEPTHS
from hand_sim import robot

#: Grasp models of the study (and of ``--model``).
MODELS: tuple[str, ...] = ("planar", "3d")


@dataclass(frozen=True)
class Synthesis:
    """The controller's final contacts: polar angles (rad) and, in 3-D, heights above the
    block's centre of mass (m); its S_G (None when infeasible), steps and convergence."""

    theta: NDArray[np.float64]
    heights: NDArray[np.float64] | None
    s_g: float | None
    steps: int
    converged: bool
    #: 3-D: the contact heights (m above the centre of mass) to try in turn, ``heights`` first
    height_options: tuple[NDArray[np.float64], ...] = ()


def grasp_depths(model: str) -> tuple[float, ...]:
    """Depths below the top (m) the hand's seed postures are pre-shaped at for ``model``."""
    return (GRASP_DEPTH,) if model == "planar" else TOP_GRASP_DEPTHS


def top_grasp_band(height: float) -> HeightBand:
    """:data:`TOP_GRASP_DEPTHS` as a band of heights above the base of a ``height`` block."""
    return HeightBand.below_top(height, *TOP_GRASP_DEPTHS)


def synthesize(
    model: str,
    polygon: Polygon,
    height: float,
    composer: Composer,
    theta_initial: list[float],
    rng: np.random.Generator,
    *,
    load: float,
    yaw: float,
    height_tries: int = HEIGHT_TRIES,
    heights_initial: NDArray[np.float64] | None = None,
) -> Synthesis:
    """Run the ``model``'s controller (module docstring) from ``theta_initial``. In 3-D the
    contacts' common height is then set by the physical test's tasks
    (the first of :func:`controllers.grasp.task_height.ranked_shifts`, ``load`` = m*g over the
    grip force per finger, ``yaw`` = the world x axis's angle in the block's frame) and up to
    ``height_tries`` common heights are offered, best first. ``heights_initial`` (3-D; m above
    the centre of mass, kept in the band): the contacts' initial heights (default: uniform in the
    band, drawn from ``rng``)."""
    if model == "planar":
        syn = GraspSynthesis(
            polygon,
            composer,
            theta_initial,
            rng,
            min_separation=CONTACT_SEPARATION,
            separation_offset=robot.PAD_RADIUS,
        )
        while not syn.done:
            syn.step()
        score = syn.finish()
        s_g = float(score.s_g) if score.feasible else None
        return Synthesis(syn.theta, None, s_g, syn.steps, bool(syn.converged))
    band = top_grasp_band(height)
    low, high = band.low - 0.5 * height, band.high - 0.5 * height
    if heights_initial is None:
        u = rng.uniform(0.0, 1.0, size=len(theta_initial))
        initial = band.low - 0.5 * height + u * (band.high - band.low)
    else:
        initial = np.clip(np.asarray(heights_initial, dtype=float), low, high)
    syn3 = GraspSynthesis3D(
        polygon,
        height,
        band,
        composer,
        theta_initial,
        initial,
        rng,
        min_separation=CONTACT_SEPARATION,
        separation_offset=robot.PAD_RADIUS,
        load=load,
        yaw=yaw,
    )
    while not syn3.done:
        syn3.step()
    score3 = syn3.finish()
    s_g = float(score3.s_g) if score3.feasible else None
    options = tuple(syn3.height_options(height_tries, HEIGHT_GAP))
    return Synthesis(syn3.theta, syn3.heights, s_g, syn3.steps, bool(syn3.converged), options)
