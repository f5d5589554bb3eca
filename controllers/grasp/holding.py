"""Normal forces that hold a block against its weight with the most friction to spare: the grasp
force distribution of a 3-D grasp (section 3.5's contact model, with 6-D wrenches).

S_G (Eq. 13, :mod:`controllers.grasp.score3d`) scores where the contacts are; it does not say
how hard each finger should press. A lateral hand presses from different heights (the middle
finger high, the thumb low) on faces that do not oppose one another, so normal forces chosen to
balance the block in its cross-section leave a net force and moment that friction must carry,
beside the weight, once the table no longer does. This programme chooses the normal forces with
the weight in the balance and the friction cones as constraints:

  f_i = N_i (-n_i) + T_i1 t_i1 + T_i2 t_i2,
  sum_i (f_i, (p_i - c) x f_i) = (0, 0, W, 0, 0, 0)   (the contacts carry the weight W at c),
  sum_i N_i = F,   N_min <= N_i <= N_max,   ||T_i||_2 <= mu N_i - lambda,
  maximise lambda

lambda (N) is the friction reserve of the least reserved contact: how much more tangential force
every contact could take before it slides, with the squeeze's total F given. A negative lambda
means no normal forces within the bounds hold the block by the model (the contacts need more
friction than mu gives). The total is given because it is not the programme's to choose: where
the contacts' heights make a moment the normal forces cannot cancel (a thumb pressing below two
fingers on the opposite face), every newton of squeeze costs reserve, and a free total would
squeeze as little as the bounds allow. The cones
are exact second-order cones (clarabel), as in :func:`controllers.grasp.score3d.grasp_score_3d`.
"""

from __future__ import annotations

from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.score import FRICTION, solver_settings
from controllers.grasp.score3d import ContactError, check_contacts, tangent_basis, unit_wrenches


@dataclass(frozen=True)
class HoldingForces:
    """The programme's solution; ``solved`` False (and empty arrays) when clarabel found none."""

    solved: bool
    reserve: float  #: lambda (N), the least friction reserve; -inf when not solved
    normal_forces: NDArray[np.float64]  #: N_i (n,)
    tangential_forces: NDArray[np.float64]  #: (T_i1, T_i2) (n, 2)
    tangents: NDArray[np.float64]  #: (t_i1, t_i2) (n, 2, 3), :func:`tangent_basis`

    @property
    def holds(self) -> bool:
        """Whether every contact keeps some friction in reserve (lambda > 0)."""
        return self.solved and self.reserve > 0.0


def holding_forces(
    points: ArrayLike,
    normals: ArrayLike,
    centre: ArrayLike,
    weight: float,
    *,
    total: float,
    max_force: float,
    min_force: float = 0.0,
    friction: float = FRICTION,
) -> HoldingForces:
    """The normal forces (N) at contacts ``points`` (n, 3; m) with outward unit ``normals``
    (n, 3) that hold a block of ``weight`` (N) whose centre of mass is ``centre`` (3,) with the
    largest friction reserve, ``total`` (N) in all, each between ``min_force`` and ``max_force``
    (see the module docstring). ``solved`` is False where no forces within the bounds balance
    the weight at all (e.g. three contacts on one face and one on another). Raises
    :class:`controllers.grasp.score3d.ContactError` on bad input."""
    p, nrm, _ = check_contacts(points, normals, None)
    c = np.asarray(centre, dtype=float)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ContactError(f"centre must be 3 finite numbers, got {centre!r}")
    for name, value in (("weight", weight), ("max_force", max_force), ("friction", friction)):
        if not (np.isfinite(value) and value > 0):
            raise ContactError(f"{name} must be a positive number, got {value!r}")
    if not (np.isfinite(min_force) and 0.0 <= min_force <= max_force):
        raise ContactError(f"min_force must lie in [0, max_force], got {min_force!r}")
    n = len(p)
    if not (np.isfinite(total) and n * min_force <= total <= n * max_force):
        raise ContactError(
            f"total must lie in [{n} min_force, {n} max_force] = [{n * min_force:g}, "
            f"{n * max_force:g}] N, got {total!r}"
        )
    arm = p - c
    basis = tangent_basis(nrm)
    iN, i1, i2 = (np.arange(n) + j * n for j in range(3))
    il = 3 * n
    nv = 3 * n + 1
    a_eq = np.zeros((6, nv))
    a_eq[:, iN] = unit_wrenches(arm, -nrm)
    a_eq[:, i1] = unit_wrenches(arm, basis[:, 0])
    a_eq[:, i2] = unit_wrenches(arm, basis[:, 1])
    a_eq = np.vstack([a_eq, np.zeros((1, nv))])
    a_eq[6, iN] = 1.0
    rows = [a_eq]
    b = [np.array([0.0, 0.0, weight, 0.0, 0.0, 0.0, total])]
    bounds = np.zeros((2 * n, nv))  # s = N - min >= 0 and max - N >= 0
    bounds[np.arange(n), iN] = -1.0
    bounds[n + np.arange(n), iN] = 1.0
    rows.append(bounds)
    b.append(np.concatenate([np.full(n, -min_force), np.full(n, max_force)]))
    for i in range(n):  # s = (mu N_i - lambda, T_i1, T_i2) in the second-order cone
        r = np.zeros((3, nv))
        r[0, iN[i]] = -friction
        r[0, il] = 1.0
        r[1, i1[i]] = -1.0
        r[2, i2[i]] = -1.0
        rows.append(r)
        b.append(np.zeros(3))
    q = np.zeros(nv)
    q[il] = -1.0
    cones = [clarabel.ZeroConeT(7), clarabel.NonnegativeConeT(2 * n)]
    cones += [clarabel.SecondOrderConeT(3)] * n
    sol = clarabel.DefaultSolver(
        sp.csc_matrix((nv, nv)),
        q,
        sp.csc_matrix(np.vstack(rows)),
        np.concatenate(b),
        cones,
        solver_settings(),
    ).solve()
    if sol.status not in (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved):
        return HoldingForces(False, -np.inf, np.zeros(0), np.zeros((0, 2)), basis)
    x = np.asarray(sol.x)
    return HoldingForces(True, float(x[il]), x[iN].copy(), np.stack([x[i1], x[i2]], axis=1), basis)
