"""An independent S_G (Eq. 13) for the grasp core's tests: the same linear program written
with scipy's HiGHS solver over x = [N, T+, T-], not with the package's clarabel formulation."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog


def linprog_score(points, normals, task=None, mu=1.0):
    """Independent S_G with scipy/HiGHS over x = [N, T+, T-]."""
    p, nrm = np.asarray(points, float), np.asarray(normals, float)
    task = np.zeros(3) if task is None else task
    n = len(p)
    tan = np.stack([-nrm[:, 1], nrm[:, 0]], 1)
    cols = []
    for f in (-nrm, tan, -tan):
        cols.append(np.stack([f[:, 0], f[:, 1], p[:, 0] * f[:, 1] - p[:, 1] * f[:, 0]]) / n)
    a_eq = np.hstack(cols)
    a_ub = np.hstack([-mu * np.eye(n), np.eye(n), np.eye(n)])
    res = linprog(
        np.ones(3 * n),
        A_ub=a_ub,
        b_ub=np.zeros(n),
        A_eq=a_eq,
        b_eq=task,
        bounds=[(1, None)] * n + [(0, None)] * (2 * n),
        method="highs",
    )
    return res.fun / n - 1.0 if res.status == 0 else None
