"""Grasp trials with 3-D contacts on prisms (section 3.6.2's trials with section 3.4's phi).

The same procedure as :mod:`controllers.grasp.trials`: n contacts drawn at random, moved by
``x <- x - gain * gradient`` until no coordinate moves more than 0.0005 rad in a step or for at
most 300 steps, then scored with S_G in 3-D (:mod:`controllers.grasp.score3d`, 6-D wrenches).

The coordinates of a side contact are theta (the planar contact coordinate, Appendix B) and
its height z above the centre of mass, which is the paper's face coordinate r_phi on a side
face (Eq. 9; docs/grasp.md, "The 3-D model"). The controllers (section 3.4 in 3-D):
- force closure on the Gaussian sphere, the sphere of normals: a contact sits at (theta, phi_0)
  with phi_0 its face normal's elevation, 0 on every side face whatever its height; so FC moves
  theta exactly as the planar FC (Eq. 5-7) and never a height;
- moment closure with the true face forces and the 6-D residual (Eq. 10 with m_x, m_y): along
  theta (a contact sliding along its face at its height) only m_z changes, so the convex MC
  gradient in theta is the planar one (Eq. 11-12); along r_phi the moment
  m = r_theta e_phi - r_phi e_theta (Eq. 9) is linear, eps_MC is exactly quadratic in each
  height, and the height step is a Newton step towards the per-contact minimizer
  (:func:`height_gradient`).

Frame and scale: each prism is built on its **unit-moment polygon** (the planar trials' frame,
section 3.4), its height scaled by the same factor; the origin is the centre of mass. So a grasp
whose contacts all sit at the centre of mass's height is scored and moved exactly as the planar
trials would (tested), and a tall block's m_x, m_y may exceed 1: the tipping the planar model
does not see.

Where the contacts may be: on the side faces, within a :class:`HeightBand` (a hand reaches a
band of heights; the default band is the whole side). After every step the contacts are put
back into the band (a projected gradient descent, as the planar ``min_separation``): heights
are clipped to the band. Top contacts are scored by
S_G (``controllers.grasp score``) but not synthesized: a top grasp's fingers press the sides.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp import wrench
from controllers.grasp.composition import Composer
from controllers.grasp.errors import GraspError
from controllers.grasp.polygon import ContactFrames, Polygon, wrap_angle
from controllers.grasp.polygon_batch import PolygonBatch
from controllers.grasp.prism import ContactFrames3D, face_axes
from controllers.grasp.score3d import GraspScore3D, grasp_score_3d
from controllers.grasp.state import ControlState3D
from controllers.grasp.synthesis import separate_contacts
from controllers.grasp.trials import DescentSettings, TrialOutcomes, descend
from controllers.grasp.wrench3d import mc_residual


@dataclass(frozen=True)
class HeightBand:
    """Heights (m above the base, the polygon's unit) the contacts may take on the side faces."""

    low: float
    high: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.low) and np.isfinite(self.high) and self.low >= 0.0):
            raise GraspError(f"a height band is two finite heights >= 0, got {self}")
        if self.low > self.high:
            raise GraspError(
                f"a height band's low ({self.low:g}) is above its high ({self.high:g})"
            )

    @classmethod
    def below_top(cls, height: float, shallowest: float, deepest: float) -> HeightBand:
        """The band from ``deepest`` to ``shallowest`` below the top of a ``height`` prism."""
        if not 0.0 <= shallowest <= deepest <= height:
            raise GraspError(
                f"depths below the top must satisfy 0 <= {shallowest:g} <= {deepest:g} <= "
                f"the height {height:g}"
            )
        return cls(height - deepest, height - shallowest)


@dataclass(frozen=True)
class PrismBatch:
    """Prisms on unit-moment polygons (module docstring), for vectorized trials.

    ``half_height`` and the band's ``z_low``, ``z_high`` are in the unit-moment frame, z measured
    from the centre of mass."""

    polygons: PolygonBatch
    scale: NDArray[np.float64]  #: (P,) each polygon's largest moment: length unit / unit-moment
    half_height: NDArray[np.float64]  #: (P,)
    z_low: NDArray[np.float64]  #: (P,)
    z_high: NDArray[np.float64]  #: (P,)

    @classmethod
    def of(
        cls,
        polygons: Sequence[Polygon],
        heights: Sequence[float],
        bands: Sequence[HeightBand | None] | None = None,
    ) -> PrismBatch:
        if len(heights) != len(polygons):
            raise GraspError(f"{len(polygons)} polygons but {len(heights)} heights")
        bands = [None] * len(polygons) if bands is None else list(bands)
        scale = np.array([p.max_moment for p in polygons], dtype=float)
        h = np.asarray(heights, dtype=float)
        if not np.all(np.isfinite(h) & (h > 0.0)):
            raise GraspError(f"prism heights must be positive numbers, got {list(heights)}")
        low = np.array([0.0 if b is None else b.low for b in bands])
        high = np.array([hh if b is None else b.high for b, hh in zip(bands, h, strict=True)])
        if np.any(high > h + 1e-12):
            raise GraspError("a height band reaches above its prism's top")
        return cls(
            PolygonBatch.of(polygons),
            scale,
            0.5 * h / scale,
            (low - 0.5 * h) / scale,
            (high - 0.5 * h) / scale,
        )

    def locate(
        self, index: NDArray[np.int64], theta: NDArray[np.float64], z: NDArray[np.float64]
    ) -> ContactFrames3D:
        """Side contacts at polar angles theta and heights z (unit-moment, from the CoM)."""
        pb = self.polygons
        return side_frames(pb.locate(index, theta), z)

    def planar(self, index: NDArray[np.int64], theta: NDArray[np.float64]) -> ContactFrames:
        return self.polygons.locate(index, theta)

    def into_band(self, index: NDArray[np.int64], z: NDArray[np.float64]) -> NDArray[np.float64]:
        """Heights clipped into each prism's band."""
        return np.clip(z, self.z_low[index][:, None], self.z_high[index][:, None])


def side_frames(planar: ContactFrames, z: NDArray[np.float64]) -> ContactFrames3D:
    """3-D frames of contacts on the side faces: the planar contacts raised to heights z."""
    point = np.concatenate([planar.point, z[..., None]], axis=-1)
    zero = np.zeros_like(z)
    normal = np.concatenate([planar.normal, zero[..., None]], axis=-1)
    theta = np.arctan2(planar.point[..., 1], planar.point[..., 0])
    return ContactFrames3D(
        face=planar.edge,
        point=point,
        normal=normal,
        theta=theta,
        phi=np.arctan2(z, np.hypot(planar.point[..., 0], planar.point[..., 1])),
        normal_theta=planar.normal_angle,
        normal_phi=zero,
        offset=planar.offset,
        surface=np.stack([planar.surface, z], axis=-1),
    )


def planar_part(task: ArrayLike | None) -> NDArray[np.float64] | None:
    """(t_fx, t_fy, t_mz) of a 6-D task; None stays None."""
    if task is None:
        return None
    t = np.asarray(task, dtype=float)
    return t[..., [0, 1, 5]]


def residual_about_mean_height(
    frames: ContactFrames3D, task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """The MC residual rho = t - (1/n) sum w_i (Eq. 2, 6-D) with moments about c, the point on
    the vertical axis at the contacts' mean height (the task, given about the centre of mass,
    moved there: rho_m - c x rho_f), shape (T, 6)."""
    rho = mc_residual(frames, task)
    centre = np.zeros((rho.shape[0], 3))
    centre[:, 2] = frames.point[..., 2].mean(-1)
    return np.concatenate([rho[:, :3], rho[:, 3:] - np.cross(centre, rho[:, :3])], axis=1)


def height_gradient(frames: ContactFrames3D, task: ArrayLike | None = None) -> NDArray[np.float64]:
    """The MC height step's direction, (T, n).

    Moments are taken about c, the point on the vertical axis at the contacts' mean height (the
    task, given about the centre of mass, moved there: t_m - c x t_f). About c the moment of a
    force imbalance the unit normal forces leave (the S_G program balances it with its N_i) is
    no reason to move a height; about the centre of mass it would spread the contacts apart.
    With c held, d eps_MC / d r_phi,k = (2/n) rho_m . e_theta,k (Eq. 3 with
    dm/dr_phi = -e_theta, Eq. 9); dividing by its curvature 2 |e_theta|^2 / n^2 = 2 / n^2 gives
    n rho_m . e_theta,k = r_phi,k - r_phi,k*: a step of ``gain`` moves each height that
    fraction of the way to its minimizer (a damped Newton step)."""
    n = frames.point.shape[-2]
    rho_m = residual_about_mean_height(frames, task)[:, 3:]
    e_theta = face_axes(frames.normal_theta, frames.normal_phi)[1]
    return n * np.einsum("td,tnd->tn", rho_m, e_theta)


def control_state_3d(
    batch: PrismBatch,
    index: NDArray[np.int64],
    theta: NDArray[np.float64],
    z: NDArray[np.float64],
    step: int,
    active: NDArray[np.bool_],
    task: ArrayLike | None = None,
) -> ControlState3D:
    """Both controllers' errors and gradients (theta, then height) at (theta, z) (module
    docstring). eps_FC includes the task's f_z, which no side contact changes; eps_MC takes
    moments about the contacts' mean height (:func:`residual_about_mean_height`), so contacts
    at one height have the planar eps_MC and the learned composers' inputs keep their meaning."""
    planar = batch.planar(index, theta)
    frames = side_frames(planar, z)
    t2 = planar_part(task)
    fz = 0.0 if task is None else np.asarray(task, dtype=float)[..., 2]
    zero = np.zeros_like(z)
    return ControlState3D(
        step=step,
        theta=theta,
        z=z,
        frames=frames,
        eps_fc=wrench.eps_fc(theta, t2) + fz**2,
        eps_mc=(residual_about_mean_height(frames, task) ** 2).sum(-1),
        grad_fc=np.concatenate([wrench.fc_gradient_convex(theta, t2), zero], axis=1),
        grad_mc=np.concatenate(
            [wrench.mc_gradient_convex(planar, theta, t2), height_gradient(frames, task)], axis=1
        ),
        active=active,
        object_index=index,
        batch=batch.polygons,
    )


@dataclass(frozen=True, kw_only=True)
class TrialBatch3D(TrialOutcomes):
    """Results of T 3-D trials (angles in rad; points (T, n, 3) in the unit-moment CoM frame)."""

    object_index: NDArray[np.int64]
    theta_initial: NDArray[np.float64]
    z_initial: NDArray[np.float64]  #: heights above the CoM, unit-moment frame
    theta_final: NDArray[np.float64]
    z_final: NDArray[np.float64]
    points: NDArray[np.float64]
    normals: NDArray[np.float64]


def random_contacts_3d(
    rng: np.random.Generator, batch: PrismBatch, index: NDArray[np.int64], n_contacts: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Initial contacts: theta uniform on [0, 2 pi) (one (T, n) draw, as the planar trials),
    then heights uniform in the band (a second draw)."""
    theta = rng.uniform(0.0, 2.0 * np.pi, size=(index.shape[0], n_contacts))
    u = rng.uniform(0.0, 1.0, size=theta.shape)
    lo, hi = batch.z_low[index][:, None], batch.z_high[index][:, None]
    return theta, lo + u * (hi - lo)


def score_contacts_3d(frames: ContactFrames3D, task: ArrayLike | None = None) -> list[GraspScore3D]:
    """S_G in 3-D (Eq. 13 with 6-D wrenches, the round friction cone) of each trial."""
    t = (
        None
        if task is None
        else np.broadcast_to(np.asarray(task, float), (frames.theta.shape[0], 6))
    )
    return [
        grasp_score_3d(frames.point[i], frames.normal[i], None if t is None else t[i])
        for i in range(frames.theta.shape[0])
    ]


def advance(
    batch: PrismBatch,
    index: NDArray[np.int64],
    theta: NDArray[np.float64],
    z: NDArray[np.float64],
    delta: NDArray[np.float64],
    active: NDArray[np.bool_],
    separate: Callable[[NDArray[np.float64]], NDArray[np.float64]],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """One control step: the active trials' coordinates moved by ``delta`` (T, 2n: theta then
    height), theta wrapped and the pads kept apart (``separate``), heights put back in the band.
    Returns (theta, z, moved): moved is each trial's largest change (rad of theta, or height in
    the unit-moment frame: a length compared as an arc at unit distance)."""
    k_n = theta.shape[1]
    d = np.where(active[:, None], delta, 0.0)
    new_theta = separate(wrap_angle(theta + d[:, :k_n]))
    new_z = batch.into_band(index, z + d[:, k_n:])
    moved = np.maximum(
        np.abs(wrap_angle(new_theta - theta)).max(axis=1), np.abs(new_z - z).max(axis=1)
    )
    return new_theta, new_z, moved


def pad_spacing(
    batch: PrismBatch, index: NDArray[np.int64], min_separation: float, offset: float
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The projection that keeps each trial's pads ``min_separation`` apart (the polygons' own
    unit; :func:`~controllers.grasp.synthesis.separate_contacts` on theta); the identity for 0."""

    def separate(th: NDArray[np.float64]) -> NDArray[np.float64]:
        if min_separation <= 0.0:
            return th
        out = th.copy()
        for i, k in enumerate(index):
            unit = batch.polygons.polygons[k]
            out[i] = separate_contacts(
                unit, th[i], min_separation / batch.scale[k], offset / batch.scale[k]
            )
        return out

    return separate


def run_trials_3d(
    batch: PrismBatch,
    object_index: ArrayLike,
    composer: Composer,
    rng: np.random.Generator,
    settings: DescentSettings | None = None,
    *,
    initial: tuple[ArrayLike, ArrayLike] | None = None,
    min_separation: float = 0.0,
    separation_offset: float = 0.0,
) -> TrialBatch3D:
    """Run ``len(object_index)`` 3-D trials at once on ``batch``'s prisms (module docstring).

    ``rng`` draws the initial contacts (unless ``initial`` = (theta, z), z the heights above the
    centre of mass in the unit-moment frame, is given) and feeds the composer. The composer's
    gradients are (T, 2n), theta then height. ``min_separation`` > 0 keeps the pads apart
    after every step as the planar :class:`~controllers.grasp.synthesis.GraspSynthesis` does
    (:func:`~controllers.grasp.synthesis.separate_contacts` on theta, lengths in the polygons'
    own unit; one trial at a time, for a robot's few trials). ``settings`` says how many
    contacts, steps, the gain and the task (default :class:`DescentSettings`). The same seed
    gives the same result."""
    settings = settings or DescentSettings()
    idx = np.asarray(object_index, dtype=np.int64)
    n = idx.shape[0]
    if initial is None:
        theta, z = random_contacts_3d(rng, batch, idx, settings.n_contacts)
    else:
        theta = np.array(initial[0], dtype=float).reshape(n, -1)
        z = np.array(initial[1], dtype=float).reshape(n, -1)
    separate = pad_spacing(batch, idx, min_separation, separation_offset)
    theta = separate(wrap_angle(theta))
    z = batch.into_band(idx, z)
    theta0, z0 = theta.copy(), z.copy()
    coords = {"theta": theta, "z": z}

    def evaluate(step: int, active: NDArray[np.bool_]) -> ControlState3D:
        return control_state_3d(
            batch, idx, coords["theta"], coords["z"], step, active, settings.task
        )

    def move(delta: NDArray[np.float64], active: NDArray[np.bool_]) -> NDArray[np.float64]:
        coords["theta"], coords["z"], moved = advance(
            batch, idx, coords["theta"], coords["z"], delta, active, separate
        )
        return moved

    run = descend(composer, rng, n, settings.max_steps, settings.gain, evaluate, move)
    state, steps, converged = run.state, run.steps, run.converged
    theta, z = coords["theta"], coords["z"]
    scores = score_contacts_3d(state.frames, settings.task)
    success = np.array([s.success for s in scores])
    composer.end(state, success)
    return TrialBatch3D(
        object_index=idx,
        theta_initial=theta0,
        z_initial=z0,
        theta_final=theta,
        z_final=z,
        points=state.frames.point,
        normals=state.frames.normal,
        steps=steps,
        converged=converged,
        eps_fc=state.eps_fc,
        eps_mc=state.eps_mc,
        s_g=np.array([s.s_g for s in scores]),
        feasible=np.array([s.feasible for s in scores]),
        success=success,
    )
