"""The grasp evaluation metric S_G (section 3.5, Eq. 13), solved as a linear program with clarabel.

For n contacts with normal force N_i (inward) and tangential force T_i (along the CCW tangent):
  N_i >= 1, |T_i| <= mu N_i (mu = 1), t - (1/n) sum w_i(N_i, T_i) = 0,
  minimize z = sum_i N_i + |T_i|, and S_G = z / n - 1. ``S_G <= 0.4`` is a success.
|T_i| is the epigraph variable u_i >= +-T_i, so the problem is an LP over x = [N, T, u].
"""

from __future__ import annotations

from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

#: Threshold of section 3.5: grasps with S_G <= 0.4 are good.
SUCCESS_THRESHOLD = 0.4
#: Coulomb friction coefficient of the metric (section 3.5: mu <= 1).
FRICTION = 1.0
#: Smallest normal force (section 3.5: ||N|| >= 1).
MIN_NORMAL_FORCE = 1.0


def opposition_floor(n: int) -> float:
    """Eq. 13's least S_G for ``n`` contacts of which one opposes the other ``n - 1`` across
    parallel faces (a lateral hand's thumb against its fingers): every normal force is at least
    1 (section 3.5), so the one pushes ``n - 1`` and ``z = 2 (n - 1)``, ``S_G = (n - 2) / n``
    (0 for a pinch, 1/3 for three contacts, 1/2 for four). Balanced as the hand's kinematics
    allow, such a grasp still scores this much above a grasp whose contacts share the load."""
    if n < 2:
        raise ValueError(f"an opposition takes at least two contacts, got {n}")
    return (n - 2) / n


@dataclass(frozen=True)
class GraspScore:
    """S_G of one contact configuration. ``feasible`` is False (and ``s_g`` is inf) when no forces
    satisfy the constraints: an infeasible grasp is a failure, not an error."""

    feasible: bool
    s_g: float  #: Eq. 13, inf when infeasible
    normal_forces: NDArray[np.float64]  #: N_i (empty when infeasible)
    tangential_forces: NDArray[np.float64]  #: T_i (empty when infeasible)
    status: str  #: clarabel's solver status

    @property
    def success(self) -> bool:
        return self.feasible and self.s_g <= SUCCESS_THRESHOLD


def solver_settings() -> clarabel.DefaultSettings:
    """clarabel's default settings, silent."""
    s = clarabel.DefaultSettings()
    s.verbose = False
    return s


def dense_to_csc(matrix: NDArray[np.float64]) -> sp.csc_matrix:
    """``scipy.sparse.csc_matrix(matrix)`` (the nonzeros, column by column, rows in order),
    built from the nonzeros' indices directly: the same arrays, without the detour through
    COO that costs as much as the small linear programs of Eq. 13 themselves."""
    cols, rows = np.nonzero(matrix.T)
    indptr = np.zeros(matrix.shape[1] + 1, dtype=np.int32)
    np.cumsum(np.bincount(cols, minlength=matrix.shape[1]), out=indptr[1:])
    return sp.csc_matrix((matrix.T[cols, rows], rows.astype(np.int32), indptr), shape=matrix.shape)


def grasp_score(
    points: ArrayLike,
    normals: ArrayLike,
    task: ArrayLike | None = None,
    friction: float = FRICTION,
) -> GraspScore:
    """S_G (Eq. 13) of contacts at ``points`` (n, 2) with outward unit ``normals`` (n, 2).

    Points are in the object frame of the unit-moment polygon (section 3.4), so forces and
    moments share a scale. ``task`` is the planar wrench (t_fx, t_fy, t_mz), default null grasp.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    nrm = np.asarray(normals, dtype=float).reshape(-1, 2)
    n = p.shape[0]
    if nrm.shape[0] != n or n < 1:
        raise ValueError(
            f"need as many normals as points, got {n} points and {nrm.shape[0]} normals"
        )
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(nrm))):
        raise ValueError("contact points and normals must be finite")
    t = np.zeros(3) if task is None else np.asarray(task, dtype=float).reshape(3)
    tangent = np.stack([-nrm[:, 1], nrm[:, 0]], axis=1)
    # Wrench of unit N (force -normal) and unit T (force +tangent): (f_x, f_y, p x f).
    fn, ft = -nrm, tangent
    wn = np.stack([fn[:, 0], fn[:, 1], p[:, 0] * fn[:, 1] - p[:, 1] * fn[:, 0]])
    wt = np.stack([ft[:, 0], ft[:, 1], p[:, 0] * ft[:, 1] - p[:, 1] * ft[:, 0]])
    eye, zero = np.eye(n), np.zeros((n, n))
    a_eq = np.hstack([wn / n, wt / n, np.zeros((3, n))])
    a_ineq = np.vstack(
        [
            np.hstack([-eye, zero, zero]),  # N >= 1
            np.hstack([zero, eye, -eye]),  # T <= u
            np.hstack([zero, -eye, -eye]),  # -T <= u
            np.hstack([-friction * eye, zero, eye]),  # u <= mu N
        ]
    )
    a = dense_to_csc(np.vstack([a_eq, a_ineq]))
    b = np.concatenate([t, -MIN_NORMAL_FORCE * np.ones(n), np.zeros(3 * n)])
    q = np.concatenate([np.ones(n), np.zeros(n), np.ones(n)])
    cones = [clarabel.ZeroConeT(3), clarabel.NonnegativeConeT(4 * n)]
    solver = clarabel.DefaultSolver(
        sp.csc_matrix((3 * n, 3 * n)), q, a, b, cones, solver_settings()
    )
    sol = solver.solve()
    status = str(sol.status).rsplit(".", 1)[-1]
    x = np.asarray(sol.x)
    ok = sol.status in (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved)
    if ok:
        residual = np.abs(a_eq @ x - t).max()
        ok = residual < 1e-6 and np.all(x[:n] >= MIN_NORMAL_FORCE - 1e-6)
    if not ok:
        empty = np.zeros(0)
        return GraspScore(False, float("inf"), empty, empty, status)
    z = float(x[:n].sum() + np.abs(x[n : 2 * n]).sum())
    return GraspScore(True, z / n - 1.0, x[:n].copy(), x[n : 2 * n].copy(), status)
