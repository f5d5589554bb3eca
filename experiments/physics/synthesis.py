"""Step 1 of the physical study, planar or 3-D: the grasp controller's contacts for one grasp.

- ``planar`` (the paper's controllers with phi = 0): a
  :class:`~controllers.grasp.session.GraspSynthesis` from four contacts uniform in theta, with
  the task cycle's pad spacing; the hand then takes each contact at its fingertip's height;
- ``3d`` (:mod:`controllers.grasp.trials3d`): the same composer on the 3-D controllers, over
  theta and the contacts' heights, within the band of heights a top grasp reaches
  (:data:`TOP_GRASP_DEPTHS`); the initial heights are drawn uniform in the band after the same
  theta draw; the pad spacing as in the planar synthesis (after every step); then the physical
  test's task wrenches set the contacts' common height (:mod:`controllers.grasp.task_height`).
  The hand takes each contact at its own height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.fine_reach import GRASP_DEPTH
from controllers.grasp.composition import Composer
from controllers.grasp.polygon import Polygon
from controllers.grasp.score3d import grasp_score_3d
from controllers.grasp.session import GraspSynthesis
from controllers.grasp.task_height import task_shift
from controllers.grasp.trials3d import HeightBand, PrismBatch, run_trials_3d
from controllers.hand_reach import CONTACT_SEPARATION
from hand_sim import robot

#: Grasp models of the study (and of ``--model``).
MODELS: tuple[str, ...] = ("planar", "3d")
#: Depths (m below the block's top) a top grasp's contacts may take in the 3-D model: from the
#: task cycle's grasp depth (a contact nearer the top edge is pressed by the side of the
#: fingertip) to 6 cm. The 6 cm was chosen by looking at physical results: a probe placing
#: KB's planar contacts at one depth on the square, pentagon, hexagon and rectangle (12 grasps
#: each, seed 0) held 15 of 48 at 4 cm, 38 at 6 cm and 34 at 7 cm (docs/grasp3d_physics.md).
TOP_GRASP_DEPTHS = (GRASP_DEPTH, 0.06)


@dataclass(frozen=True)
class Synthesis:
    """The controller's final contacts: polar angles (rad) and, in 3-D, heights above the
    block's centre of mass (m); its S_G (None when infeasible), steps and convergence."""

    theta: NDArray[np.float64]
    heights: NDArray[np.float64] | None
    s_g: float | None
    steps: int
    converged: bool


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
) -> Synthesis:
    """Run the ``model``'s controller (module docstring) from ``theta_initial``. In 3-D the
    contacts' common height is then set by the physical test's tasks
    (:func:`controllers.grasp.task_height.task_shift`, ``load`` = m*g over the grip force per
    finger, ``yaw`` = the world x axis's angle in the block's frame)."""
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
    batch = PrismBatch.of([polygon], [height], [top_grasp_band(height)])
    theta0 = np.asarray(theta_initial, dtype=float)[None]
    lo, hi = batch.z_low[0], batch.z_high[0]
    z0 = lo + rng.uniform(0.0, 1.0, size=theta0.shape) * (hi - lo)
    out = run_trials_3d(
        batch,
        np.zeros(1, dtype=np.int64),
        composer,
        rng,
        initial=(theta0, z0),
        min_separation=CONTACT_SEPARATION,
        separation_offset=robot.PAD_RADIUS,
    )
    theta = out.theta_final[0]
    one = np.zeros(1, dtype=np.int64)
    frames = batch.locate(one, theta[None], out.z_final[0][None])
    shift = task_shift(frames.point[0], frames.normal[0], lo, hi, load, yaw).shift
    z = out.z_final[0] + shift
    frames = batch.locate(one, theta[None], z[None])
    score = grasp_score_3d(frames.point[0], frames.normal[0])
    s_g = float(score.s_g) if score.feasible else None
    heights = z * polygon.max_moment
    return Synthesis(theta, heights, s_g, int(out.steps[0]), bool(out.converged[0]))
