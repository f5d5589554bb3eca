"""Appendix A: grasp composition as a time-optimal control problem (Pontryagin's maximum principle).

One contact moves on the square while the other stays at beta = -0.46365 rad; the moving contact
follows theta' = -k (alpha dEps_FC/dtheta + (1 - alpha) dEps_WC/dtheta), alpha in [0, 1]. The
Hamiltonian H = -eps_WC + lambda theta' is linear in alpha, so the optimal activation is bang-bang:
alpha = 1 when dH/dalpha = -lambda (dEps_FC - dEps_WC) > 0, else 0. Theta and the costate lambda
(lambda' = dEps_WC/dtheta + lambda (alpha d2Eps_FC + (1 - alpha) d2Eps_WC)) are integrated with
explicit Euler steps from theta(0) = 0, lambda(0) = 5 until theta converges (paper: theta(T) =
3.6052).

Reading of the paper's eps_WC = E + (2 tan(theta) - 1)^2 / 16: the tangent is that of the angle
between the contact and the normal of the face it is on (the contact's moment arm on a unit
square), which is tan(theta) itself on the faces at 0 and pi. Read globally, tan(theta) diverges at
pi/2, in the middle of the face the contact must cross, and the integration blows up. The second
derivative is the exact one of that expression, (8 + 4 (2 tan u - 1) sin 2u) / (16 cos^4 u); the
paper prints 2 (tan u - 1) in place of 4 (2 tan u - 1) (both give the same theta(T)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: Appendix A.3: initial costate, time step and the fixed contact's angle (rad).
LAMBDA_0 = 5.0
DT = 0.01
BETA = -0.46365
THETA_0 = 0.0
#: Controller gain k of Eq. 16 (the paper does not state it; 1 is our choice).
K_GAIN = 1.0
#: theta has converged when a step moves it less than this (rad); our choice.
THETA_TOLERANCE = 1e-7
#: Safety bound on the number of Euler steps.
MAX_STEPS = 100_000
#: Appendix A.3's result.
PAPER_THETA_T = 3.6052


#: Face normals of the square are multiples of this angle; E per face (0, pi/2, pi, 3 pi/2).
FACE_ANGLE = np.pi / 2.0
FACE_E = (1.0, 0.5, 0.0, 0.5)


def face_of(theta):
    """Index 0..3 of the square's face (normal at index * pi/2) that polar angle theta is on."""
    return np.mod(np.round(np.asarray(theta, dtype=float) / FACE_ANGLE), 4).astype(int)


def face_local(theta):
    """Angle from the normal of the contact's face, in [-pi/4, pi/4]."""
    t = np.asarray(theta, dtype=float)
    return t - np.round(t / FACE_ANGLE) * FACE_ANGLE


def face_constant(theta):
    """E of eps_WC: 1 on the face at theta = 0, 0.5 on the faces at pi/2 and 3 pi/2, 0 at pi."""
    return np.array(FACE_E)[face_of(theta)]


def eps_wc(theta):
    """Wrench closure error of the two-contact null grasp of the square (Appendix A.2)."""
    u = face_local(theta)
    return face_constant(theta) + (2.0 * np.tan(u) - 1.0) ** 2 / 16.0


def d_eps_wc(theta):
    """d eps_WC / d theta = (2 tan u - 1) / (4 cos^2 u), u the face-local angle."""
    u = face_local(theta)
    return (2.0 * np.tan(u) - 1.0) / (4.0 * np.cos(u) ** 2)


def d2_eps_wc(theta):
    """d^2 eps_WC / d theta^2 = (8 + 4 (2 tan u - 1) sin 2u) / (16 cos^4 u)."""
    u = face_local(theta)
    return (8.0 + 4.0 * (2.0 * np.tan(u) - 1.0) * np.sin(2.0 * u)) / (16.0 * np.cos(u) ** 4)


def eps_fc(theta, beta: float = BETA):
    """Force closure error with the fixed contact at ``beta`` (Appendix A.2)."""
    return 0.5 * (1.0 + np.cos(theta - beta))


def d_eps_fc(theta, beta: float = BETA):
    return -0.5 * np.sin(theta - beta)


def d2_eps_fc(theta, beta: float = BETA):
    return -0.5 * np.cos(theta - beta)


@dataclass(frozen=True)
class OptimalPath:
    """The time-optimal activation and the path it produces (Figures 17 and 18)."""

    t: NDArray[np.float64]  #: time of each sample (s)
    theta: NDArray[np.float64]  #: moving contact coordinate (rad)
    lam: NDArray[np.float64]  #: costate
    alpha: NDArray[np.float64]  #: activation of the FC controller (0 or 1); last entry repeats
    converged: bool

    @property
    def theta_final(self) -> float:
        return float(self.theta[-1])

    @property
    def switches(self) -> int:
        return int(np.count_nonzero(np.diff(self.alpha)))


def solve_time_optimal(
    lambda_0: float = LAMBDA_0,
    dt: float = DT,
    beta: float = BETA,
    theta_0: float = THETA_0,
    k: float = K_GAIN,
    tol: float = THETA_TOLERANCE,
    max_steps: int = MAX_STEPS,
) -> OptimalPath:
    """Appendix A.2's algorithm: steps 1-5 (choose alpha by the sign of dH/dalpha, Euler steps
    of Eqs. 16 and 17) until theta moves less than ``tol`` in a step."""
    theta, lam = theta_0, lambda_0
    ts, thetas, lams, alphas = [0.0], [theta], [lam], []
    converged = False
    for i in range(max_steps):
        dfc, dwc = d_eps_fc(theta, beta), float(d_eps_wc(theta))
        dh_dalpha = -lam * (dfc - dwc)
        alpha = 1.0 if dh_dalpha > 0.0 else 0.0
        theta_dot = -k * (alpha * dfc + (1.0 - alpha) * dwc)
        d2 = alpha * d2_eps_fc(theta, beta) + (1.0 - alpha) * float(d2_eps_wc(theta))
        lam_dot = dwc + lam * d2
        theta_next = theta + theta_dot * dt
        lam += lam_dot * dt
        alphas.append(alpha)
        ts.append((i + 1) * dt)
        thetas.append(theta_next)
        lams.append(lam)
        step = abs(theta_next - theta)
        theta = theta_next
        if step < tol:
            converged = True
            break
    alphas.append(alphas[-1])
    return OptimalPath(np.array(ts), np.array(thetas), np.array(lams), np.array(alphas), converged)
