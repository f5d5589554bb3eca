"""The force and moment closure controllers for 3-D contacts (section 3.4, Eq. 5-12 in full).

A wrench is (f_x, f_y, f_z, m_x, m_y, m_z) and a task a 6-vector ``t`` (default: the null grasp);
:func:`planar_task` lifts a planar task (t_fx, t_fy, t_mz). Contacts are located on a prism by the
ray coordinates (theta, phi) of :mod:`controllers.grasp.prism`. Everything is vectorized over
(T grasps, n >= 2 contacts) as :mod:`controllers.grasp.wrench`, whose scaling conventions (unit
forces, moments of the unit-moment object, the 1/n of Eq. 2) and signs are kept, so that with
every contact at phi = 0 on a side face and a planar task each function here returns the planar
one's values. Gradients come as (T, n, 2) arrays, [..., 0] in theta (or r_theta) and [..., 1] in
phi (or r_phi); minimizers per coordinate as (coordinate*, eps*) pairs of (T, n) arrays.
docs/grasp.md ("The derivations, in short") derives the phi-direction results.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.polygon import wrap_angle
from controllers.grasp.prism import ContactFrames3D, face_axes
from controllers.grasp.wrench import _convex_slope

Pair = tuple[NDArray[np.float64], NDArray[np.float64]]


def planar_task(task: ArrayLike | None) -> NDArray[np.float64] | None:
    """The 6-D task (t_fx, t_fy, 0, 0, 0, t_mz) of a planar task (t_fx, t_fy, t_mz) (shape (3,)
    or (T, 3)); None stays None (the null grasp)."""
    if task is None:
        return None
    t = np.asarray(task, dtype=float)
    z = np.zeros((*t.shape[:-1], 1))
    return np.concatenate([t[..., :2], z, z, z, t[..., 2:3]], axis=-1)


def _task(task: ArrayLike | None, batch: int) -> NDArray[np.float64]:
    if task is None:
        return np.zeros((batch, 6))
    t = np.asarray(task, dtype=float)
    if t.shape[-1] != 6 or not np.all(np.isfinite(t)):
        raise ValueError(
            f"a task wrench is (t_fx, t_fy, t_fz, t_mx, t_my, t_mz), finite; got {task!r} "
            "(planar_task lifts a planar one)"
        )
    return np.broadcast_to(t, (batch, 6))


# --- Force closure (section 3.4.2): unit forces on the Gaussian sphere -------------------------
def fc_directions(theta: NDArray[np.float64], phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """u(theta, phi) = (cos theta cos phi, sin theta cos phi, sin phi), shape (T, n, 3)."""
    c = np.cos(phi)
    return np.stack([c * np.cos(theta), c * np.sin(theta), np.sin(phi)], axis=-1)


def fc_wrenches(theta: NDArray[np.float64], phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """The FC wrench model of section 3.4.2: w = (-u(theta, phi), 0, 0, 0), shape (T, n, 6)."""
    return np.concatenate([-fc_directions(theta, phi), np.zeros((*theta.shape, 3))], axis=-1)


def fc_residual(
    theta: NDArray[np.float64], phi: NDArray[np.float64], task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Force residual rho_f = t_f + (1/n) sum u_i, shape (T, 3) (the brackets of Eq. 5)."""
    t = _task(task, theta.shape[0])
    c = np.cos(phi)
    mean = [(c * np.cos(theta)).mean(-1), (c * np.sin(theta)).mean(-1), np.sin(phi).mean(-1)]
    return t[:, :3] + np.stack(mean, axis=-1)


def eps_fc(
    theta: NDArray[np.float64], phi: NDArray[np.float64], task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Force closure error (Eq. 5 with its f_z term), shape (T,)."""
    return (fc_residual(theta, phi, task) ** 2).sum(-1)


def fc_gradient(
    theta: NDArray[np.float64], phi: NDArray[np.float64], task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Exact gradient (d eps_FC / d theta_k, d eps_FC / d phi_k), shape (T, n, 2).

    theta: Eq. 6, (2/n) cos(phi_k) (rho_y cos theta_k - rho_x sin theta_k).
    phi: (2/n) (rho_z cos phi_k - sin phi_k (rho_x cos theta_k + rho_y sin theta_k)).
    """
    n = theta.shape[-1]
    rho = fc_residual(theta, phi, task)[:, None, :]
    c, s = np.cos(theta), np.sin(theta)
    d_theta = (2.0 / n) * (rho[..., 1] * c - rho[..., 0] * s) * np.cos(phi)
    d_phi = (2.0 / n) * (
        rho[..., 2] * np.cos(phi) - np.sin(phi) * (rho[..., 0] * c + rho[..., 1] * s)
    )
    return np.stack([d_theta, d_phi], axis=-1)


def _fc_others(theta, phi, task):
    """S = rho_f minus contact k's own term u_k / n, shape (T, n, 3)."""
    n = theta.shape[-1]
    return fc_residual(theta, phi, task)[:, None, :] - fc_directions(theta, phi) / n


def fc_minimizer_theta(
    theta: NDArray[np.float64], phi: NDArray[np.float64], task: ArrayLike | None = None
) -> Pair:
    """theta_k* minimizing eps_FC along theta_k (phi_k and the others fixed) and eps_FC* there.

    Eq. 8 with the quadrant: eps_FC = |S + u_k/n|^2 is smallest where the horizontal part of u_k
    points against S: theta_k* = atan2(-S_y, -S_x) (= -atan2(A, B) with Eq. 6's A, B), and
    eps_FC* = (|S_xy| - cos(phi_k)/n)^2 + (S_z + sin(phi_k)/n)^2.
    """
    n = theta.shape[-1]
    S = _fc_others(theta, phi, task)
    theta_star = np.arctan2(-S[..., 1], -S[..., 0])
    eps_star = (np.hypot(S[..., 0], S[..., 1]) - np.cos(phi) / n) ** 2 + (
        S[..., 2] + np.sin(phi) / n
    ) ** 2
    return theta_star, eps_star


def fc_minimizer_phi(
    theta: NDArray[np.float64], phi: NDArray[np.float64], task: ArrayLike | None = None
) -> Pair:
    """phi_k* minimizing eps_FC along phi_k (theta_k and the others fixed) and eps_FC* there.

    Along the meridian great circle of theta_k, u_k = cos(phi) h + sin(phi) z with h the horizontal
    unit vector at theta_k; eps_FC = |S + u_k/n|^2 is smallest where u_k points against the
    projection (P, S_z) of S on that plane (P = S . h): phi_k* = atan2(-S_z, -P) in (-pi, pi]
    (beyond +-pi/2 the minimum lies over the pole), eps_FC* = (hypot(P, S_z) - 1/n)^2 + Q^2 with
    Q = S . (-sin theta_k, cos theta_k, 0) the part of S the meridian cannot reach.
    """
    n = theta.shape[-1]
    S = _fc_others(theta, phi, task)
    c, s = np.cos(theta), np.sin(theta)
    P = S[..., 0] * c + S[..., 1] * s
    Q = S[..., 1] * c - S[..., 0] * s
    phi_star = np.arctan2(-S[..., 2], -P)
    eps_star = (np.hypot(P, S[..., 2]) - 1.0 / n) ** 2 + Q**2
    return phi_star, eps_star


def fc_gradient_convex(
    theta: NDArray[np.float64], phi: NDArray[np.float64], task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Convex FC gradients (Eq. 7 in theta and in phi): 2 (eps_FC - eps_FC*) / (x_k - x_k*) with
    the minimum along each coordinate, shape (T, n, 2)."""
    eps = eps_fc(theta, phi, task)[:, None]
    theta_star, eps_theta = fc_minimizer_theta(theta, phi, task)
    phi_star, eps_phi = fc_minimizer_phi(theta, phi, task)
    return np.stack(
        [
            _convex_slope(eps - eps_theta, wrap_angle(theta - theta_star)),
            _convex_slope(eps - eps_phi, wrap_angle(phi - phi_star)),
        ],
        axis=-1,
    )


# --- Moment closure (section 3.4.3): true face forces, moments linear in (r_theta, r_phi) ------
def mc_moment_axes(frames: ContactFrames3D) -> Pair:
    """(a, b) = (dm/dr_theta, dm/dr_phi) of Eq. 9, shape (T, n, 3) each:
    a = (-sin phi_0 cos theta_0, -sin phi_0 sin theta_0, cos phi_0) = e_phi,
    b = (sin theta_0, -cos theta_0, 0) = -e_theta."""
    _, e_theta, e_phi = face_axes(frames.normal_theta, frames.normal_phi)
    return e_phi, -e_theta


def mc_moments(frames: ContactFrames3D) -> NDArray[np.float64]:
    """m = r_theta a + r_phi b (Eq. 9), = r x f for the unit inward normal force f = -n."""
    a, b = mc_moment_axes(frames)
    return frames.surface[..., 0, None] * a + frames.surface[..., 1, None] * b


def mc_wrenches(frames: ContactFrames3D) -> NDArray[np.float64]:
    """MC wrench model (Eq. 9): the face's inward unit normal force and its moment, (T, n, 6)."""
    return np.concatenate([-frames.normal, mc_moments(frames)], axis=-1)


def mc_residual(frames: ContactFrames3D, task: ArrayLike | None = None) -> NDArray[np.float64]:
    """Wrench residual rho = t - (1/n) sum w_i (Eq. 2 with the MC model), shape (T, 6)."""
    w = mc_wrenches(frames)
    return _task(task, w.shape[0]) - w.mean(axis=1)


def eps_mc(frames: ContactFrames3D, task: ArrayLike | None = None) -> NDArray[np.float64]:
    """Moment closure error (Eq. 10), shape (T,)."""
    return (mc_residual(frames, task) ** 2).sum(-1)


def mc_surface_gradient(
    frames: ContactFrames3D, task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """(d eps_MC / d r_theta_k, d eps_MC / d r_phi_k) = -(2/n) (a . rho_m, b . rho_m) (Eq. 3 with
    G_k = (0, a) and (0, b)), shape (T, n, 2)."""
    n = frames.theta.shape[-1]
    rho_m = mc_residual(frames, task)[:, None, 3:]
    a, b = mc_moment_axes(frames)
    return -(2.0 / n) * np.stack([(rho_m * a).sum(-1), (rho_m * b).sum(-1)], axis=-1)


def mc_moment_derivatives(frames: ContactFrames3D) -> Pair:
    """(dm/dtheta, dm/dphi) of each contact moved on the plane of its face, (T, n, 3) each.

    Side face (u = theta - theta_0, rho_s = r_0 / cos u): r_theta = r_0 tan u and
    r_phi = rho_s tan phi, so dm/dtheta = a r_0 / cos^2 u + b r_0 tan(phi) sin(u) / cos^2 u and
    dm/dphi = b rho_s / cos^2 phi. Top or base face (its frame turns with the contact):
    m = r_phi b(theta) with r_phi = -r_0 cot phi, so dm/dtheta = r_phi (cos theta, sin theta, 0)
    and dm/dphi = b r_0 / sin^2 phi.
    """
    a, b = mc_moment_axes(frames)
    cap = frames.on_cap[..., None]
    theta, phi, r_0 = frames.theta, frames.phi, frames.offset
    u = theta - frames.normal_theta
    sec2 = 1.0 / np.cos(u) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        side_theta = (
            a * (r_0 * sec2)[..., None] + b * (r_0 * np.tan(phi) * np.sin(u) * sec2)[..., None]
        )
        side_phi = b * (r_0 / np.cos(u) / np.cos(phi) ** 2)[..., None]
        radial = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=-1)
        cap_theta = frames.surface[..., 1, None] * radial
        cap_phi = b * (r_0 / np.sin(phi) ** 2)[..., None]
    return np.where(cap, cap_theta, side_theta), np.where(cap, cap_phi, side_phi)


def mc_gradient(frames: ContactFrames3D, task: ArrayLike | None = None) -> NDArray[np.float64]:
    """Exact gradient (d eps_MC / d theta_k, d eps_MC / d phi_k) with each contact on the plane of
    its face (Eq. 3: -(2/n) G_k^T rho, G_k = (0, dm/dx)), shape (T, n, 2)."""
    n = frames.theta.shape[-1]
    rho_m = mc_residual(frames, task)[:, None, 3:]
    dm_theta, dm_phi = mc_moment_derivatives(frames)
    return -(2.0 / n) * np.stack([(rho_m * dm_theta).sum(-1), (rho_m * dm_phi).sum(-1)], axis=-1)


def _mc_others(frames: ContactFrames3D, task: ArrayLike | None):
    """S_k = n t_m - sum_{i != k} m_i, shape (T, n, 3): contact k's moment that would cancel the
    moment residual (n rho_m = S_k - m_k)."""
    n = frames.theta.shape[-1]
    t = _task(task, frames.theta.shape[0])
    m = mc_moments(frames)
    return n * t[:, None, 3:] - (m.sum(axis=1, keepdims=True) - m)


def mc_surface_minimizer(
    frames: ContactFrames3D, task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """(r*_theta, r*_phi) = (a . S_k, b . S_k), the surface coordinates where d eps_MC / d r_theta
    (the r*_theta formula before Eq. 11) and d eps_MC / d r_phi vanish, shape (T, n, 2)."""
    S = _mc_others(frames, task)
    a, b = mc_moment_axes(frames)
    return np.stack([(S * a).sum(-1), (S * b).sum(-1)], axis=-1)


def _eps_keeping(frames: ContactFrames3D, task, axis) -> NDArray[np.float64]:
    """eps_MC at the minimum when contact k's moment moves along the face's other in-plane axis:
    the moment residual keeps only its components along ``axis`` (T, n, 3) and the normal."""
    rho = mc_residual(frames, task)
    n_hat = frames.normal
    rho_m = rho[:, None, 3:]
    # (a, b, n) is orthonormal and m_k _|_ n: |rho_m|^2 = (a.rho)^2 + (b.rho)^2 + (n.rho)^2
    kept = (rho_m * axis).sum(-1) ** 2 + (rho_m * n_hat).sum(-1) ** 2
    return (rho[:, :3] ** 2).sum(-1)[:, None] + kept


def mc_minimizer_theta(frames: ContactFrames3D, task: ArrayLike | None = None) -> Pair:
    """theta_k* and eps_MC* of the theta-direction MC controller (Eq. 11), per contact.

    Side face: theta_k* = theta_0 + atan(r*_theta / r_0), where r_theta = r*_theta (the minimum
    along the face's horizontal, at the contact's height); eps_MC* = eps_MC - (a . rho_m)^2.
    Top/base face: the contact turns about the vertical axis at fixed phi, m_k = r_phi b(theta), and
    eps_MC is smallest where r_phi b points along S_k: theta_k* = atan2(sg S_x, -sg S_y) with
    sg = sign(r_phi), eps_MC* = |rho_f|^2 + ((|S_xy| - |r_phi|)^2 + S_z^2) / n^2.
    """
    n = frames.theta.shape[-1]
    _, b = mc_moment_axes(frames)
    r_star = mc_surface_minimizer(frames, task)
    side_star = frames.normal_theta + np.arctan(r_star[..., 0] / frames.offset)
    side_eps = _eps_keeping(frames, task, b)
    S = _mc_others(frames, task)
    r_phi = frames.surface[..., 1]
    sg = np.sign(r_phi)
    cap_star = np.arctan2(sg * S[..., 0], -sg * S[..., 1])
    rho_f2 = (mc_residual(frames, task)[:, :3] ** 2).sum(-1)[:, None]
    cap_eps = (
        rho_f2 + ((np.hypot(S[..., 0], S[..., 1]) - np.abs(r_phi)) ** 2 + S[..., 2] ** 2) / n**2
    )
    cap = frames.on_cap
    return np.where(cap, cap_star, side_star), np.where(cap, cap_eps, side_eps)


def mc_minimizer_phi(frames: ContactFrames3D, task: ArrayLike | None = None) -> Pair:
    """phi_k* and eps_MC* of the phi-direction MC controller (the phi form of Eq. 11), per contact.

    Moving phi_k at fixed theta_k moves r_phi alone on every face, so the minimum along phi is
    r_phi = r*_phi = b . S_k, eps_MC* = eps_MC - (b . rho_m)^2. Side face: r_phi = rho_s tan phi,
    phi_k* = atan(r*_phi / rho_s) with rho_s = r_0 / cos(theta_k - theta_0) the distance from the
    vertical axis. Top (sg = +1) or base (sg = -1) face: r_phi = -r_0 cot phi,
    phi_k* = atan2(sg r_0, -sg r*_phi) (beyond +-pi/2: past the vertical axis).
    """
    a, _ = mc_moment_axes(frames)
    r_star = mc_surface_minimizer(frames, task)[..., 1]
    rho_s = frames.offset / np.cos(frames.theta - frames.normal_theta)
    side_star = np.arctan(r_star / rho_s)
    sg = np.sign(frames.normal[..., 2])
    cap_star = np.arctan2(sg * frames.offset, -sg * r_star)
    phi_star = np.where(frames.on_cap, cap_star, side_star)
    return phi_star, _eps_keeping(frames, task, a)


def mc_gradient_convex(
    frames: ContactFrames3D, task: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Convex MC gradients (Eq. 12 in theta and its phi form): 2 (eps_MC - eps_MC*) / (x_k - x_k*),
    shape (T, n, 2)."""
    eps = eps_mc(frames, task)[:, None]
    theta_star, eps_theta = mc_minimizer_theta(frames, task)
    phi_star, eps_phi = mc_minimizer_phi(frames, task)
    return np.stack(
        [
            _convex_slope(eps - eps_theta, wrap_angle(frames.theta - theta_star)),
            _convex_slope(eps - eps_phi, wrap_angle(frames.phi - phi_star)),
        ],
        axis=-1,
    )
