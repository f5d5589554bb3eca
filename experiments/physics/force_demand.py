"""How much of the hand's own grip a test load needs: a grasp measure at the measured forces.

S_G (Eq. 13, section 3.5) asks for normal forces N_i >= 1 and lets them grow without bound: any
moment a push makes about contacts above the centre of mass can be balanced by squeezing harder,
at a cost. The hand in the physical test does not squeeze harder on demand: its fingers press
with the forces the squeeze left them (measured by the pads). This measure keeps the paper's
contact model (round Coulomb cones, mu; the pads' soft-finger torsion, |tau_i| <= rho N_i) and
bounds each normal force by the one measured, 0 <= N_i <= N_i^0. For each stage k of the test
(the hang, m*g down; then m*g down plus m*g through the centre of mass along +-x, +-y, +-z of
the world) it finds the largest alpha_k such that the contacts resist alpha_k times the stage's
external wrench (force at the centre of mass, no moment):

  maximize alpha  s.t.  sum_i f_i + alpha F_k = 0,  sum_i (p_i x f_i + tau_i n_i) = 0,
  f_i = -N_i n_i + T_i1 t_i1 + T_i2 t_i2,  ||T_i||_2 <= mu N_i,  |tau_i| <= rho N_i,
  0 <= N_i <= N_i^0,  0 <= alpha <= ALPHA_CAP.

The measure is the demand D = 1 / min_k alpha_k: the worst stage's load as a fraction of what
the measured grip can resist (D <= 1: the forces the hand already applies suffice; None when
some stage cannot be resisted at all). Lower predicts a hold, as for S_G. Solved with clarabel's
second-order cones (the friction cones are exact).

What it predicts and what it cannot: docs/findings.md, "Measured-force demand".
"""

from __future__ import annotations

from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.polygon import Polygon
from controllers.grasp.score import solver_settings
from controllers.grasp.score3d import ContactError, check_contacts, tangent_basis, unit_wrenches

#: The pads' sliding friction and torsional coefficient (m), as the hand model's pad geoms
#: (models/hand.xml, class "pad", which take priority over the block's).
PAD_FRICTION = 1.0
PAD_TORSION = 0.004
#: The largest load multiple looked for (a grasp resisting 1000x its test loads is "very safe").
ALPHA_CAP = 1000.0
#: The test's external loads, in units of the block's weight, by stage (world axes).
STAGE_LOADS: dict[str, tuple[float, float, float]] = {
    "hang": (0.0, 0.0, -1.0),
    "+x": (1.0, 0.0, -1.0),
    "-x": (-1.0, 0.0, -1.0),
    "+y": (0.0, 1.0, -1.0),
    "-y": (0.0, -1.0, -1.0),
    "+z": (0.0, 0.0, 0.0),
    "-z": (0.0, 0.0, -2.0),
}


@dataclass(frozen=True)
class ForceDemand:
    """The measure of one grasp: the demand (None when a stage cannot be resisted), the worst
    stage, and every stage's load multiple alpha_k."""

    demand: float | None
    worst_stage: str
    alphas: dict[str, float]


def load_multiple(
    points: ArrayLike,
    normals: ArrayLike,
    max_normal: ArrayLike,
    load: ArrayLike,
    friction: float = PAD_FRICTION,
    torsion: float = PAD_TORSION,
) -> float:
    """The largest alpha (0..ALPHA_CAP) for which contacts at ``points`` (n, 3, m, centre of mass
    frame) with outward unit ``normals`` and normal forces at most ``max_normal`` (n, N) resist
    the force ``alpha * load`` (3, N) applied at the centre of mass (module docstring)."""
    p, nrm, _ = check_contacts(points, normals, None)
    cap = np.asarray(max_normal, dtype=float)
    force = np.asarray(load, dtype=float)
    n = p.shape[0]
    if cap.shape != (n,) or not np.all(np.isfinite(cap)) or np.any(cap < 0):
        raise ContactError(f"max_normal must be {n} finite forces >= 0, got {cap!r}")
    if force.shape != (3,) or not np.all(np.isfinite(force)):
        raise ContactError(f"load must be a finite 3-vector, got {force!r}")
    if not (friction > 0 and torsion >= 0):
        raise ContactError(f"friction must be > 0 and torsion >= 0, got {friction}, {torsion}")
    basis = tangent_basis(nrm)
    # variables: N (n), T1 (n), T2 (n), tau (n), alpha (1)
    iN, i1, i2, it = (np.arange(n) + j * n for j in range(4))
    ia = 4 * n
    nv = 4 * n + 1
    a_eq = np.zeros((6, nv))
    a_eq[:, iN] = unit_wrenches(p, -nrm)
    a_eq[:, i1] = unit_wrenches(p, basis[:, 0])
    a_eq[:, i2] = unit_wrenches(p, basis[:, 1])
    a_eq[3:, it] = nrm.T
    a_eq[:3, ia] = force
    rows, b = [a_eq], [np.zeros(6)]
    eye = np.eye(nv)
    # nonnegative rows, s = b - A x >= 0: N >= 0, cap - N >= 0, rho N -+ tau >= 0, alpha in [0, cap]
    rows += [-eye[iN], eye[iN], -torsion * eye[iN] + eye[it], -torsion * eye[iN] - eye[it]]
    b += [np.zeros(n), cap, np.zeros(n), np.zeros(n)]
    rows += [-eye[[ia]], eye[[ia]]]
    b += [np.zeros(1), np.array([ALPHA_CAP])]
    for i in range(n):  # (mu N_i, T_i1, T_i2) in the second-order cone
        r = np.zeros((3, nv))
        r[0, iN[i]], r[1, i1[i]], r[2, i2[i]] = -friction, -1.0, -1.0
        rows.append(r)
        b.append(np.zeros(3))
    q = np.zeros(nv)
    q[ia] = -1.0
    cones = [clarabel.ZeroConeT(6), clarabel.NonnegativeConeT(4 * n + 2)]
    cones += [clarabel.SecondOrderConeT(3)] * n
    solver = clarabel.DefaultSolver(
        sp.csc_matrix((nv, nv)),
        q,
        sp.csc_matrix(np.vstack(rows)),
        np.concatenate(b),
        cones,
        solver_settings(),
    )
    sol = solver.solve()
    if sol.status not in (clarabel.SolverStatus.Solved, clarabel.SolverStatus.AlmostSolved):
        return 0.0  # alpha = 0 (all forces zero) is always feasible: only a solver failure
    return float(np.clip(np.asarray(sol.x)[ia], 0.0, ALPHA_CAP))


def force_demand(
    points: NDArray[np.float64],
    normals: NDArray[np.float64],
    measured: ArrayLike,
    weight: float,
    block_yaw: float,
    torsion: float = PAD_TORSION,
) -> ForceDemand:
    """The demand of the test's loads on a grasp held with the ``measured`` normal forces (N)
    at ``points``/``normals`` (block centre-of-mass frame, m); ``weight`` = m*g (N), the block
    turned by ``block_yaw`` in the world (the world's loads are turned into its frame);
    ``torsion``: the pads' torsional coefficient (m)."""
    c, s = np.cos(-block_yaw), np.sin(-block_yaw)
    to_block = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    alphas = {
        stage: load_multiple(
            points, normals, measured, weight * (to_block @ np.asarray(d)), torsion=torsion
        )
        if any(d)
        else ALPHA_CAP
        for stage, d in STAGE_LOADS.items()
    }
    worst = min(alphas, key=lambda k: alphas[k])
    a = alphas[worst]
    return ForceDemand(None if a <= 0.0 else 1.0 / a, worst, alphas)


def held_force_demand(
    points: NDArray[np.float64],
    polygon: Polygon,
    measured: ArrayLike,
    weight: float,
    block_yaw: float,
    torsion: float = PAD_TORSION,
) -> ForceDemand:
    """:func:`force_demand` of a held grasp: each contact point (block centre-of-mass frame) put
    on the side face its polar angle meets (as :func:`experiments.physics.measures.grasp_measures`
    does), at its own height, with that face's normal."""
    frames = polygon.locate(np.arctan2(points[:, 1], points[:, 0]))
    p = np.column_stack([frames.point, points[:, 2]])
    n = np.column_stack([frames.normal, np.zeros(len(p))])
    return force_demand(p, n, measured, weight, block_yaw, torsion)
