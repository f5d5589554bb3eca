"""An independent 3-D S_G (Eq. 13) for the tests: each round friction cone replaced by an
inscribed K-facet pyramid, solved as a linear program with scipy's HiGHS (not clarabel), in a
tangent basis of its own (drawn at random, so no choice of the package's is shared).

Contact i's tangential force is T_i = sum_k lam_ik v_ik, lam_ik >= 0, with v_ik the K unit
vectors at angles 2 pi k / K in the contact's tangent plane, and sum_k lam_ik <= mu N_i: T_i lies
in the regular K-gon of circumradius mu N_i inscribed in the cone's circle. The objective uses
sum_k lam_ik for ||T_i||; at the optimum it is the K-gon's gauge g(T_i), and
||T|| <= g(T) <= ||T|| / cos(pi / K).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog


def random_basis(normals: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """An orthonormal tangent basis (n, 2, 3) of each normal, rotated at random about it."""
    nrm = np.asarray(normals, float)
    a = rng.normal(size=nrm.shape)
    t1 = a - np.einsum("ij,ij->i", a, nrm)[:, None] * nrm
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return np.stack([t1, np.cross(nrm, t1)], axis=1)


def pyramid_z(points, normals, task, mu, facets, basis, torsion=None):
    """z = sum N + sum lam of the inscribed-pyramid LP (None when infeasible)."""
    p, nrm = np.asarray(points, float), np.asarray(normals, float)
    n, k = len(p), facets
    ang = 2.0 * np.pi * np.arange(k) / k
    # v[i, j] = cos(ang_j) t_i1 + sin(ang_j) t_i2, shape (n, K, 3)
    cos, sin = np.cos(ang)[None, :, None], np.sin(ang)[None, :, None]
    v = cos * basis[:, None, 0] + sin * basis[:, None, 1]

    def wrench(point, force):  # (..., 3) -> (6, ...) flattened over the leading axes
        return np.concatenate([force, np.cross(point, force)], axis=-1).reshape(-1, 6).T

    cols = [wrench(p, -nrm), wrench(np.broadcast_to(p[:, None], v.shape), v)]
    n_tau = 0
    if torsion is not None:
        cols.append(np.concatenate([np.zeros((3, n)), nrm.T]))
        n_tau = n
    a_eq = np.hstack(cols) / n
    nv = n + n * k + n_tau
    rows = np.zeros((n + 2 * n_tau, nv))
    for i in range(n):
        rows[i, i] = -mu
        rows[i, n + i * k : n + (i + 1) * k] = 1.0
        if n_tau:
            rows[n + i, i] = rows[2 * n + i, i] = -torsion
            rows[n + i, n + n * k + i] = 1.0
            rows[2 * n + i, n + n * k + i] = -1.0
    cost = np.concatenate([np.ones(n + n * k), np.zeros(n_tau)])
    bounds = [(1.0, None)] * n + [(0.0, None)] * (n * k) + [(None, None)] * n_tau
    res = linprog(
        cost,
        A_ub=rows,
        b_ub=np.zeros(len(rows)),
        A_eq=a_eq,
        b_eq=np.asarray(task, float),
        bounds=bounds,
        method="highs",
    )
    return float(res.fun) if res.status == 0 else None
