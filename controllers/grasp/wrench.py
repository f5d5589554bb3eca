"""Wrench models, error metrics and gradients of the force and moment closure controllers.

Planar contacts (phi = 0 in the paper's notation): a wrench is (f_x, f_y, m_z) and a task is a
planar wrench ``t`` (default: the null grasp, t = 0). All functions are vectorized: ``theta`` has
shape (T, n) for T grasps of n >= 2 contacts, and a task of shape (3,) or (T, 3).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.polygon import ContactFrames, wrap_angle

#: |theta - theta*| below which the convex gradients (Eq. 7, 12) are taken as 0 (at the minimum).
AT_MINIMUM = 1e-12


def _task(task: ArrayLike | None, batch: int) -> NDArray[np.float64]:
    if task is None:
        return np.zeros((batch, 3))
    t = np.asarray(task, dtype=float)
    if t.shape[-1] != 3 or not np.all(np.isfinite(t)):
        raise ValueError(f"a planar task wrench is (t_fx, t_fy, t_mz), finite; got {task!r}")
    return np.broadcast_to(t, (batch, 3))


# --- Force closure (section 3.4.2) ----------------------------------------------------------
def fc_wrenches(theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """FC wrench model on the unit Gaussian circle: w = (-cos theta, -sin theta, 0)."""
    return np.stack([-np.cos(theta), -np.sin(theta), np.zeros_like(theta)], axis=-1)


def fc_residual(theta: NDArray[np.float64], task: ArrayLike | None = None) -> NDArray[np.float64]:
    """Force residual rho_f = t_f - (1/n) sum w_i, shape (T, 2) (the bracket of Eq. 5)."""
    t = _task(task, theta.shape[0])
    return t[:, :2] + np.stack([np.cos(theta).mean(-1), np.sin(theta).mean(-1)], axis=-1)


def eps_fc(theta: NDArray[np.float64], task: ArrayLike | None = None) -> NDArray[np.float64]:
    """Force closure error (Eq. 5), shape (T,)."""
    rho = fc_residual(theta, task)
    return (rho**2).sum(-1)


def fc_gradient(theta: NDArray[np.float64], task: ArrayLike | None = None) -> NDArray[np.float64]:
    """Exact gradient d eps_FC / d theta_k (Eq. 6), shape (T, n)."""
    n = theta.shape[-1]
    rho = fc_residual(theta, task)
    return (2.0 / n) * (rho[:, None, 1] * np.cos(theta) - rho[:, None, 0] * np.sin(theta))


def fc_minimizer(theta: NDArray[np.float64], task: ArrayLike | None = None):
    """theta_k* minimizing eps_FC with the other contacts fixed (Eq. 8), and eps_FC* there.

    With S = rho_f minus contact k's own term, eps_FC(theta_k) = |S + u(theta_k)/n|^2 is smallest
    when u points against S: theta_k* = atan2(-S_y, -S_x), eps_FC* = (|S| - 1/n)^2.
    """
    n = theta.shape[-1]
    rho = fc_residual(theta, task)
    sx = rho[:, None, 0] - np.cos(theta) / n
    sy = rho[:, None, 1] - np.sin(theta) / n
    theta_star = np.arctan2(-sy, -sx)
    eps_star = (np.hypot(sx, sy) - 1.0 / n) ** 2
    return theta_star, eps_star


def fc_gradient_convex(
    theta: NDArray[np.float64], task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Convex FC gradient (Eq. 7): 2 (eps_FC - eps_FC*) / (theta_k - theta_k*), per contact."""
    theta_star, eps_star = fc_minimizer(theta, task)
    eps = eps_fc(theta, task)[:, None]
    return _convex_slope(eps - eps_star, wrap_angle(theta - theta_star))


# --- Moment closure (section 3.4.3) ---------------------------------------------------------
def mc_wrenches(frames: ContactFrames) -> NDArray[np.float64]:
    """MC wrench model (Eq. 9, phi_0 = 0): the true inward normal force of the facet and its
    moment m_z = r_theta (the surface coordinate), shape (T, n, 3)."""
    return np.concatenate([-frames.normal, frames.surface[..., None]], axis=-1)


def mc_residual(frames: ContactFrames, task: ArrayLike | None = None) -> NDArray[np.float64]:
    """Wrench residual rho = t - (1/n) sum w_i (Eq. 2 with the MC model), shape (T, 3)."""
    w = mc_wrenches(frames)
    return _task(task, w.shape[0]) - w.mean(axis=1)


def eps_mc(frames: ContactFrames, task: ArrayLike | None = None) -> NDArray[np.float64]:
    """Moment closure error (Eq. 10): the sum over wrench components of the squared residual."""
    return (mc_residual(frames, task) ** 2).sum(-1)


def mc_gradient(frames: ContactFrames, theta: NDArray[np.float64], task: ArrayLike | None = None):
    """Exact gradient of eps_MC within each contact's facet (Eq. 3: -(2/n) G_k^T rho), where
    G_k = (0, 0, dm_z/dtheta) and dm_z/dtheta = r_0 / cos^2(theta - theta_n)."""
    n = theta.shape[-1]
    rho_m = mc_residual(frames, task)[:, None, 2]
    dm = frames.offset / np.cos(theta - frames.normal_angle) ** 2
    return -(2.0 / n) * rho_m * dm


def mc_minimizer(frames: ContactFrames, theta: NDArray[np.float64], task: ArrayLike | None = None):
    """theta_k* of Eq. 11 and the error eps_MC* there, per contact.

    r*_k = n t_mz - sum_{i != k} m_zi is the surface coordinate that cancels the moment residual
    (the planar case of the r*_theta formula); theta_k* = theta_n + atan(r*_k / r_0). The force part
    of eps_MC is constant on a facet, so eps_MC* = eps_MC - rho_m^2.
    """
    n = theta.shape[-1]
    t = _task(task, theta.shape[0])
    m = frames.surface
    r_star = n * t[:, None, 2] - (m.sum(-1, keepdims=True) - m)
    theta_star = frames.normal_angle + np.arctan(r_star / frames.offset)
    rho = mc_residual(frames, task)
    eps_star = ((rho[:, :2] ** 2).sum(-1))[:, None] * np.ones_like(theta)
    return theta_star, eps_star


def mc_gradient_convex(
    frames: ContactFrames, theta: NDArray[np.float64], task: ArrayLike | None = None
):
    """Convex MC gradient (Eq. 12): 2 (eps_MC - eps_MC*) / (theta_k - theta_k*), per contact."""
    theta_star, eps_star = mc_minimizer(frames, theta, task)
    eps = eps_mc(frames, task)[:, None]
    return _convex_slope(eps - eps_star, wrap_angle(theta - theta_star))


def _convex_slope(rise: NDArray[np.float64], run: NDArray[np.float64]) -> NDArray[np.float64]:
    """Slope 2 * rise / run of the quadratic through the minimum and the current point."""
    safe = np.abs(run) > AT_MINIMUM
    return np.where(safe, 2.0 * np.maximum(rise, 0.0) / np.where(safe, run, 1.0), 0.0)


def sufficiency(
    wrenches: NDArray[np.float64], task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """The stable grasp sufficiency metric of Eq. 2 for any wrench model, wrenches (T, n, d)."""
    t = np.zeros(wrenches.shape[-1]) if task is None else np.asarray(task, dtype=float)
    rho = t - wrenches.mean(axis=-2)
    return (rho**2).sum(-1)
