"""mink's differential-IK step for site frame tasks, solved on the joints that move.

:func:`mink.solve_ik` builds its quadratic program over every degree of freedom of the model (the
arm's 5, the hand's 16 and 6 per free block) and holds the joints that must not move with equality
constraints (:class:`mink.DofFreezingTask`); each :class:`mink.FrameTask` adds a 6-row Jacobian over
all of them. Posture control (section 5.2, :mod:`controllers.posture.solver`) runs tens of thousands
of such steps in an episode's searches, most of them with the arm frozen and only position targets
on sites. :class:`ReducedStep` solves the same program with the frozen joints eliminated:

    min_dq  1/2 dq^T H dq + c^T dq   s.t.  G dq <= h,   dq_frozen = 0

where, for frame tasks k with cost vector w_k, gain g_k, error e_k (mink's body twist
log(T_bt)) and Jacobian J_k = -jlog(T_tb) Ad(T_fw) J_site,

    H = sum_k (w_k J_k)^T (w_k J_k) + (damping + sum_k lm_k |w_k g_k e_k|^2) I,
    c = sum_k (w_k J_k)^T (w_k g_k e_k),

the configuration limits (mink's :class:`~mink.ConfigurationLimit`: gain times each joint's
distance to its limits) and any other mink limits as rows of G (their own
``compute_qp_inequalities``). Setting dq_frozen = 0 leaves the program on the moving joints'
columns: the same minimiser, found by the same solver (daqp, called directly, the moving
joints' limits as its simple bounds) on a smaller problem. Rows of a task with zero cost, and
constraint rows with no moving joint, drop out; such a constraint row with h < 0 (a frozen
joint beyond its limit) makes the program infeasible, as it makes mink's. The numbers agree with
mink's to rounding (tests/controllers/test_reduced_ik.py), not to the bit.
"""

from __future__ import annotations

from collections.abc import Sequence

import daqp
import mink
import mujoco
import numpy as np
from mink.lie import _lie_ops_c as lie_ops
from numpy.typing import NDArray

#: daqp's "no bound" (what qpsolvers passes for a missing one).
NO_BOUND = 1e30


class ReducedStep:
    """The differential-IK step of site ``tasks`` (:class:`mink.FrameTask` on sites, their
    targets read at each step) moving only the degrees of freedom ``free`` of ``model``, within
    ``limits`` (:class:`mink.Limit`); ``damping`` is mink's global Levenberg-Marquardt damping and
    ``solver`` the QP solver mink would use (this step is written for daqp's interface)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        tasks: Sequence[mink.FrameTask],
        free: NDArray[np.int64],
        limits: Sequence[mink.Limit],
        *,
        damping: float,
        solver: str,
    ) -> None:
        self.model = model
        self.tasks = list(tasks)
        self.free = np.asarray(free, dtype=np.int64)
        self.limits = list(limits)
        self.damping = float(damping)
        if solver != "daqp":
            raise ValueError(f"ReducedStep solves with daqp, not {solver!r}")
        self._sites = np.array([model.site(t.frame_name).id for t in self.tasks], dtype=int)
        for task in self.tasks:
            if task.frame_type != "site":
                raise ValueError(f"ReducedStep takes site frame tasks, got a {task.frame_type}")
            if np.any(task.cost[3:] != 0.0):
                raise ValueError("ReducedStep takes position-only frame tasks")
        k = len(self.tasks)
        cost = np.array([t.cost[:3] for t in self.tasks])
        self._neg_cost = -cost[:, :, None]
        self._cost_gain = -cost * np.array([[t.gain] for t in self.tasks])
        self._lm_rows = np.repeat([t.lm_damping for t in self.tasks], 3)
        self._errors = np.empty((k, 3))
        self._jacobian_ops = np.empty((k, 3, 6))
        self._jac = np.empty((k, 6, model.nv))
        self._per_site = [
            (task, int(site), self._jac[i, :3], self._jac[i, 3:])
            for i, (task, site) in enumerate(zip(self.tasks, self._sites, strict=True))
        ]
        configuration = [lim for lim in self.limits if isinstance(lim, mink.ConfigurationLimit)]
        if (
            len(configuration) != 1
            or configuration[0].projection_matrix is None
            or len(configuration[0]._ball_qposadr) > 0
        ):
            raise ValueError("ReducedStep needs one ConfigurationLimit on hinge or slide joints")
        limit = configuration[0]
        self.others = [lim for lim in self.limits if lim is not limit]
        dofs = np.asarray(limit.indices, dtype=np.int64)
        joints = model.dof_jntid[dofs]
        qpos = model.jnt_qposadr[joints] + dofs - model.jnt_dofadr[joints]
        column = {int(d): i for i, d in enumerate(self.free)}
        moves = np.array([int(d) in column for d in dofs], dtype=bool)
        self._limit_gain = limit.gain
        self._frozen_qpos = qpos[~moves]
        self._frozen_upper = limit.upper[self._frozen_qpos]
        self._frozen_lower = limit.lower[self._frozen_qpos]
        self._moving_qpos = qpos[moves]
        self._moving_upper = limit.upper[self._moving_qpos]
        self._moving_lower = limit.lower[self._moving_qpos]
        self._moving_column = np.array([column[int(d)] for d in dofs[moves]], dtype=int)
        self._ub = np.full(len(self.free), NO_BOUND)
        self._lb = np.full(len(self.free), -NO_BOUND)
        self._no_rows = np.zeros((0, len(self.free)))
        self._box_sense = np.zeros(len(self.free), dtype=np.intc)

    def objective(self, cfg: mink.Configuration) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(H, c) of the program on the free joints at ``cfg`` (see the module docstring)."""
        model, data = self.model, cfg.data
        site_xmat, site_xpos = data.site_xmat, data.site_xpos
        ops, errors = self._jacobian_ops, self._errors
        for i, (task, site, jacp, jacr) in enumerate(self._per_site):
            xmat = site_xmat[site]
            frame = lie_ops.xmat_xpos_to_wxyz_xyz(xmat, site_xpos[site])
            target = task.transform_target_to_world.wxyz_xyz
            errors[i] = lie_ops.se3_rminus(target, frame)[:3]
            jlog = lie_ops.se3_jlog(lie_ops.se3_inverse_multiply(target, frame))
            np.matmul(jlog[:3], lie_ops.se3_rotation_adjoint_from_xmat(xmat), out=ops[i])
            mujoco.mj_jacSite(model, data, jacp, jacr, site)
        # weighted rows: cost * (-jlog Ad J_site) and cost * (-gain * error), position rows only
        W = np.matmul(self._neg_cost * ops, self._jac[:, :, self.free]).reshape(-1, len(self.free))
        weighted_error = self._cost_gain * errors
        mu = float(self._lm_rows @ (weighted_error * weighted_error).ravel())
        H = W.T @ W
        H.flat[:: len(self.free) + 1] += self.damping + mu
        c = -(weighted_error.ravel() @ W)
        return H, c

    def bounds(
        self, cfg: mink.Configuration, dt: float
    ) -> (
        tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.intc]]
        | None
    ):
        """daqp's constraint rows A (m, n_free), their upper and lower bounds (n_free + m,) and
        kinds: first the free joints' own bounds (mink's :class:`~mink.ConfigurationLimit`: gain
        times the distance to each limit), then the other limits' rows ``A dq <= b``; None when a
        limit on the frozen joints alone cannot hold (the program is infeasible)."""
        q = cfg.q
        frozen = q[self._frozen_qpos]
        if (frozen > self._frozen_upper).any() or (frozen < self._frozen_lower).any():
            return None
        moving = q[self._moving_qpos]
        rows, upper, lower = [self._no_rows], [self._ub], [self._lb]
        self._ub[self._moving_column] = self._limit_gain * (self._moving_upper - moving)
        self._lb[self._moving_column] = -(self._limit_gain * (moving - self._moving_lower))
        for limit in self.others:
            inequality = limit.compute_qp_inequalities(cfg, dt)
            if inequality.inactive:
                continue
            G = inequality.G[:, self.free]
            acts = (G != 0.0).any(axis=1)
            h = inequality.h
            if not acts.all():
                if (h[~acts] < 0.0).any():
                    return None
                G, h = G[acts], h[acts]
            rows.append(G)
            upper.append(h)
            lower.append(np.full(len(h), -NO_BOUND))
        if len(rows) == 1:
            return self._no_rows, self._ub, self._lb, self._box_sense
        A = np.vstack(rows)
        return A, np.concatenate(upper), np.concatenate(lower), self._sense(len(A))

    def _sense(self, rows: int) -> NDArray[np.intc]:
        """daqp's constraint kinds (0: an inequality) for the free joints' bounds and ``rows``
        more."""
        return np.zeros(len(self.free) + rows, dtype=np.intc)

    def velocity(self, cfg: mink.Configuration, dt: float) -> NDArray[np.float64] | None:
        """The joint velocity (model.nv,) of one step of duration ``dt`` (zero on the frozen
        joints), or None when the program has no solution (mink's ``NoSolutionFound``)."""
        constraints = self.bounds(cfg, dt)
        if constraints is None:
            return None
        A, upper, lower, sense = constraints
        H, c = self.objective(cfg)
        x, _, exitflag, _ = daqp.solve(H, c, A, upper, lower, sense)
        if exitflag <= 0:
            return None
        v = np.zeros(self.model.nv)
        v[self.free] = x / dt
        return v
