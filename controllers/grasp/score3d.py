"""The grasp evaluation metric S_G in 3-D (section 3.5, Eq. 13, with 6-D wrenches).

For n contacts at points p_i with outward unit normals n_i and a tangent basis (t_i1, t_i2):
  f_i = N_i (-n_i) + T_i1 t_i1 + T_i2 t_i2,  w_i = (f_i, p_i x f_i + tau_i n_i),
  N_i >= 1, ||T_i||_2 <= mu N_i, |tau_i| <= torsion N_i (only when ``torsion`` is given),
  t - (1/n) sum_i w_i = 0,  minimize z = sum_i N_i + ||T_i||_2,  S_G = z / n - 1.
The sign and the 1/n are those of the planar :func:`controllers.grasp.score.grasp_score`: the
mean of the contact wrenches equals the task ``t``, so contacts in one horizontal plane with a
planar task give the planar number.

Solved with clarabel's native second-order cone (``SecondOrderConeT(3)``), twice per contact:
(mu N_i, T_i1, T_i2) is the friction cone and (u_i, T_i1, T_i2) the epigraph of ||T_i||_2 in the
objective. The cone is exact: no linearisation error. An inscribed K-facet pyramid would raise z
(typically by about 1/cos(pi/K) - 1, more for nearly infeasible grasps) and could call a feasible
grasp infeasible; tests/grasp/test_score3d.py brackets this program between two such LPs.

Tangent basis: t_i1 = e_z x n_i / ||e_z x n_i|| (horizontal, the planar code's CCW tangent for a
horizontal normal) and t_i2 = n_i x t_i1 (= +z for a horizontal normal), so (t_i1, t_i2, n_i) is
right-handed. Normals within 1e-6 of +-z use t_i1 = e_x projected off n_i. The cone is round, so
S_G does not depend on this choice; only how T is reported does.

Torsion: an optional soft-finger moment tau_i about the normal, bounded by |tau_i| <= torsion N_i
(a linear model decoupled from the friction cone, as for a pad whose contact patch scales with
the load). It is a moment, not a force, so it is not counted in z: the paper's z sums forces.

Prism contacts and the physical test's task wrenches (:func:`prism_contacts`,
:func:`physical_tasks`, :func:`worst_task_score`) live in :mod:`controllers.grasp.prism3d`.
"""

from __future__ import annotations

from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.errors import GraspError
from controllers.grasp.score import FRICTION, MIN_NORMAL_FORCE, SUCCESS_THRESHOLD, solver_settings

#: A normal is a unit vector when its length is within this of 1.
UNIT_TOLERANCE = 1e-6
#: Normals whose horizontal part is shorter than this use e_x for the first tangent.
VERTICAL_TOLERANCE = 1e-6
#: Largest equilibrium residual and cone violation of an accepted solution.
SOLUTION_TOLERANCE = 1e-6


class ContactError(GraspError, ValueError):
    """Contact points, normals, a task or a friction parameter given to the 3-D metric are bad."""


@dataclass(frozen=True)
class GraspScore3D:
    """S_G of one 3-D contact configuration. ``feasible`` is False (and ``s_g`` is inf) when no
    forces satisfy the constraints: an infeasible grasp is a failure, not an error."""

    feasible: bool
    s_g: float  #: Eq. 13, inf when infeasible
    normal_forces: NDArray[np.float64]  #: N_i, shape (n,) (empty when infeasible)
    tangential_forces: NDArray[np.float64]  #: (T_i1, T_i2), shape (n, 2) (empty when infeasible)
    torsion_moments: NDArray[np.float64]  #: tau_i, shape (n,) (zeros without torsion)
    tangents: NDArray[np.float64]  #: (t_i1, t_i2) of each contact, shape (n, 2, 3)
    status: str  #: clarabel's solver status

    @property
    def success(self) -> bool:
        return self.feasible and self.s_g <= SUCCESS_THRESHOLD


def contact_forces(score: GraspScore3D, normals: ArrayLike) -> NDArray[np.float64]:
    """The forces f_i = N_i (-n_i) + T_i1 t_i1 + T_i2 t_i2 (n, 3) of a feasible ``score``."""
    if not score.feasible:
        return np.zeros((0, 3))
    nrm = np.asarray(normals, dtype=float).reshape(-1, 3)
    t = score.tangential_forces
    return (
        -score.normal_forces[:, None] * nrm
        + t[:, :1] * score.tangents[:, 0]
        + t[:, 1:] * score.tangents[:, 1]
    )


def tangent_basis(normals: ArrayLike) -> NDArray[np.float64]:
    """(t_i1, t_i2) (n, 2, 3) of outward unit ``normals`` (n, 3): t_i1 = e_z x n_i normalised
    (horizontal), or e_x projected off n_i when n_i is within VERTICAL_TOLERANCE of +-z;
    t_i2 = n_i x t_i1. (t_i1, t_i2, n_i) is right-handed and orthonormal."""
    nrm = np.asarray(normals, dtype=float).reshape(-1, 3)
    t1 = np.cross(np.array([0.0, 0.0, 1.0]), nrm)
    length = np.linalg.norm(t1, axis=1)
    vertical = length < VERTICAL_TOLERANCE
    ex = np.array([1.0, 0.0, 0.0])
    t1[vertical] = ex - nrm[vertical] * nrm[vertical, :1]
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    return np.stack([t1, t2], axis=1)


def unit_wrenches(points: NDArray, forces: NDArray) -> NDArray[np.float64]:
    """Wrenches (f, p x f) (6, n) of unit forces ``forces`` (n, 3) at ``points`` (n, 3)."""
    return np.concatenate([forces, np.cross(points, forces)], axis=1).T


def check_contacts(
    points: ArrayLike, normals: ArrayLike, task: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Points (n, 3), unit normals (n, 3) and the task (6,) as float arrays; raises
    :class:`ContactError` naming the problem."""
    arrays = []
    for name, value in (("points", points), ("normals", normals)):
        try:
            a = np.array(value, dtype=float)
        except (TypeError, ValueError) as e:
            raise ContactError(f"contact {name} must be numbers") from e
        if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] < 1:
            raise ContactError(f"contact {name} must have shape (n, 3) with n >= 1, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ContactError(f"contact {name} must be finite (found NaN or inf)")
        arrays.append(a)
    p, nrm = arrays
    if p.shape[0] != nrm.shape[0]:
        raise ContactError(
            f"need as many normals as points, got {p.shape[0]} points and {nrm.shape[0]} normals"
        )
    length = np.linalg.norm(nrm, axis=1)
    bad = np.flatnonzero(np.abs(length - 1.0) > UNIT_TOLERANCE)
    if bad.size:
        raise ContactError(
            f"normals must be unit vectors: normal {int(bad[0])} has length {length[bad[0]]:g}"
        )
    if task is None:
        t = np.zeros(6)
    else:
        try:
            t = np.array(task, dtype=float)
        except (TypeError, ValueError) as e:
            raise ContactError("the task wrench must be 6 numbers") from e
        if t.shape != (6,):
            raise ContactError(
                f"the task wrench must have shape (6,) (f_x, f_y, f_z, m_x, m_y, m_z), "
                f"got {t.shape}"
            )
        if not np.all(np.isfinite(t)):
            raise ContactError("the task wrench must be finite (found NaN or inf)")
    return p, nrm, t


def _check_coefficient(name: str, value: float | None, allow_none: bool) -> None:
    if value is None and allow_none:
        return
    ok = isinstance(value, int | float | np.floating | np.integer) and np.isfinite(value)
    if not ok or value < 0.0:
        raise ContactError(f"{name} must be a finite number >= 0, got {value!r}")


def grasp_score_3d(
    points: ArrayLike,
    normals: ArrayLike,
    task: ArrayLike | None = None,
    friction: float = FRICTION,
    torsion: float | None = None,
) -> GraspScore3D:
    """S_G (Eq. 13) of contacts at ``points`` (n, 3) with outward unit ``normals`` (n, 3).

    ``task`` is the 6-D wrench (f_x, f_y, f_z, m_x, m_y, m_z) the mean contact wrench must equal
    (default: the null grasp); lengths in the unit-moment frame of section 3.4 (see
    :mod:`controllers.grasp.prism3d`). ``friction`` is mu of the round Coulomb cone
    ||T_i||_2 <= mu N_i; ``torsion`` (None: point contacts with friction) bounds a soft-finger
    moment about each normal, |tau_i| <= torsion N_i.

    Program over x = [N, T1, T2, u, tau], in clarabel's form b - A x in K: 6 equality rows
    (ZeroCone), N_i - 1 >= 0 and torsion N_i -+ tau_i >= 0 (NonnegativeCone), then per contact
    (mu N_i, T_i1, T_i2) and (u_i, T_i1, T_i2) in SecondOrderConeT(3), written as the rows
    -A x with b = 0. Minimises sum N + sum u. Raises :class:`ContactError` on bad input.
    """
    p, nrm, t = check_contacts(points, normals, task)
    _check_coefficient("friction", friction, allow_none=False)
    _check_coefficient("torsion", torsion, allow_none=True)
    n = p.shape[0]
    basis = tangent_basis(nrm)
    use_tau = torsion is not None
    k = 5 if use_tau else 4  # variable blocks: N, T1, T2, u (, tau)
    iN, i1, i2, iu, it = (np.arange(n) + j * n for j in range(5))
    nv = k * n

    a_eq = np.zeros((6, nv))
    a_eq[:, iN] = unit_wrenches(p, -nrm) / n
    a_eq[:, i1] = unit_wrenches(p, basis[:, 0]) / n
    a_eq[:, i2] = unit_wrenches(p, basis[:, 1]) / n
    if use_tau:
        a_eq[3:, it] = nrm.T / n

    rows, b = [a_eq], [t]
    lower = np.zeros((n, nv))
    lower[np.arange(n), iN] = -1.0  # s = N - 1 >= 0
    rows.append(lower)
    b.append(-MIN_NORMAL_FORCE * np.ones(n))
    if use_tau:
        for sign in (1.0, -1.0):  # s = torsion N -+ tau >= 0
            r = np.zeros((n, nv))
            r[np.arange(n), iN] = -torsion
            r[np.arange(n), it] = sign
            rows.append(r)
            b.append(np.zeros(n))
    for i in range(n):
        for head, scale in ((iN[i], friction), (iu[i], 1.0)):  # s = (head, T1, T2) in SOC
            r = np.zeros((3, nv))
            r[0, head] = -scale
            r[1, i1[i]] = -1.0
            r[2, i2[i]] = -1.0
            rows.append(r)
            b.append(np.zeros(3))
    a = sp.csc_matrix(np.vstack(rows))
    q = np.zeros(nv)
    q[iN] = 1.0
    q[iu] = 1.0
    n_nonneg = 3 * n if use_tau else n
    cones = [clarabel.ZeroConeT(6), clarabel.NonnegativeConeT(n_nonneg)]
    cones += [clarabel.SecondOrderConeT(3)] * (2 * n)
    solver = clarabel.DefaultSolver(
        sp.csc_matrix((nv, nv)), q, a, np.concatenate(b), cones, solver_settings()
    )
    sol = solver.solve()
    status = str(sol.status).rsplit(".", 1)[-1]
    x = np.asarray(sol.x)
    ok = sol.status in (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved)
    if ok:
        tang = np.stack([x[i1], x[i2]], axis=1)
        big = max(1.0, float(np.abs(x).max()))
        ok = (
            np.abs(a_eq @ x - t).max() < SOLUTION_TOLERANCE * big
            and np.all(x[iN] >= MIN_NORMAL_FORCE - SOLUTION_TOLERANCE)
            and np.all(np.linalg.norm(tang, axis=1) <= friction * x[iN] + SOLUTION_TOLERANCE * big)
        )
    if not ok:
        return GraspScore3D(
            False, float("inf"), np.zeros(0), np.zeros((0, 2)), np.zeros(0), basis, status
        )
    z = float(x[iN].sum() + np.linalg.norm(tang, axis=1).sum())
    tau = x[it].copy() if use_tau else np.zeros(n)
    return GraspScore3D(True, z / n - 1.0, x[iN].copy(), tang, tau, basis, status)
