"""Fingertip contact forces of the tendon-driven Utah/MIT hand estimated from what the real hand
sensed: its 16 joint angles and 32 tendon tensions (Jacobsen et al., "Design of the Utah/M.I.T.
Dextrous Hand", ICRA 1986; "The Utah/MIT Dextrous Hand: Work in Progress", IJRR 3(4), 1984). The
real hand had no fingertip force sensors; the model's touch pads stay as the ground truth this
estimate is checked against (tests/hand_sim/test_contact_estimate.py, docs/models.md).

Per finger (four joints, :data:`hand_sim.robot.HAND_JOINTS` order), with every quantity read at
the state the sensors sampled:

1. Joint torques from the tension sensors, tau = r (T_flex - T_ext)
   (:func:`hand_sim.tendon_drive.joint_torques`).
2. The torque the finger needs without a contact: its dynamics from the sensed angles,
   M(q) qddot + bias (MuJoCo's mass matrix times the joint accelerations, which the real
   controller would get by differentiating its angle sensors, plus ``qfrc_bias``: gravity, the
   velocity terms and the arm's motion coupled into the finger), the joints' viscous damping
   d qdot, and the tendons' Coulomb friction -F s, s the direction each joint last slid in
   (:class:`FrictionMemory`: a joint stopped by its PD loop or by a contact stays at the edge of
   its stiction band, its friction still opposing the motion that brought it there). The rest is
   the torque an external force makes: tau_ext = tau - M qddot - bias - d qdot - F s.
3. That torque as a force at the pad: tau_ext = J^T f, J the (3, 4) translational Jacobian of the
   contact point over the finger's joints, so f = (J J^T + lambda^2 I)^-1 J tau_ext (least
   squares, four torques for three force components, with the small ridge :data:`RIDGE`). The
   contact point is first the fingertip site, then the point of the pad's rounded end that faces
   along f (pad centre + pad radius * f/|f|), and f is solved again there (one refinement: the
   contact moves over the pad and the lever arms with it). A joint within :data:`LIMIT_MARGIN`
   of a range limit is left out: its mechanical stop's torque is not sensed.
4. The normal force reported is |f| (f is along the pad's normal at that point). Given the
   contacts' outward face normals n (``normals``: the grasp's own, from the perceived block),
   the contact point is instead the point of the pad facing the face (pad centre - pad radius *
   n), and the normal force reported is f's component into the face, max(0, -f . n): a finger
   that presses and drags along the face (a squeeze that curls the fingers pushes the pads down
   the faces) has a tangential force that |f| counts as pressing.

A joint that is not sliding holds its friction at any value in [-F, F] (stiction), and the
memory's sign can be wrong (an overshoot, a load that reversed): the estimate cannot see it. It
reports how far that unknown friction can move |f| (``uncertainty``: the fit's column norms times
F over the stuck joints) and, asked for it (``least=True``), the **least** pad force the sensed
torques allow: the smallest |f| of the fit over every stuck joint's friction in [-F, F] (each
stuck joint's external torque in a band of +-F about its value without friction, the sliding
joints' exact), a bounded least-squares problem (``scipy.optimize.lsq_linear``). It is 0 when
friction alone can hold the finger where it is, and above 0 only when no friction the joints
can have explains the tensions without a contact; the guards take a new touch where it exceeds
:data:`DETECTION_THRESHOLD` (``World.touch_felt``). Everything is numpy on a compiled MuJoCo
model and its data; no global state (the friction memory belongs to its World).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import lsq_linear

from hand_sim import robot
from hand_sim.tendon_drive import TendonLayout, joint_torques

#: A joint moving faster than this (rad/s) is sliding: its friction is -F sign(qdot), and it
#: keeps that sign once the joint sticks (:class:`FrictionMemory`).
MOVING_SPEED = 0.02
#: A joint within this angle (rad) of a range limit may be held by its mechanical stop, whose
#: torque no sensor reads: its equation is left out of the fit.
LIMIT_MARGIN = 0.01
#: Ridge (m) of the least-squares fit: a finger's joints barely see a force along a nearly
#: straight or a fully curled finger (a lever of a few millimetres), and an unregularized fit
#: turns a few hundredths of a newton-metre of torque error into tens of newtons there.
RIDGE = 0.003
#: The least estimated pad force (N) the tendon hand's guards take for contact: a held contact is
#: kept above it (``World.touch_floor``); a new touch is taken where the least force the tensions
#: allow (``ContactEstimate.least``) exceeds it (``World.touch_felt``). A freely moving finger
#: reads below it (tested).
DETECTION_THRESHOLD = 0.5


@dataclass
class FrictionMemory:
    """The direction (-1, 0, +1 per joint, 16) each joint last slid in: a joint stopped by its PD
    loop or by a contact stays at the edge of its stiction band, its friction still -F times that
    direction, until it slides the other way. 0 until the joint first moves."""

    direction: NDArray[np.float64] = field(default_factory=lambda: np.zeros(len(robot.HAND_JOINTS)))

    def update(self, qdot: NDArray[np.float64]) -> None:
        """Note the joints sliding now (|qdot| > :data:`MOVING_SPEED`)."""
        moving = np.abs(qdot) > MOVING_SPEED
        self.direction = np.where(moving, np.sign(qdot), self.direction)

    def reset(self) -> None:
        """Forget every direction (a hand at rest that has not moved)."""
        self.direction = np.zeros_like(self.direction)


@dataclass(frozen=True)
class ContactEstimate:
    """Estimated contact force at each fingertip, order ff, mf, rf, th."""

    #: (4,) N, the pad's normal force: |f|, or f's component into the face given its normal
    normal: NDArray[np.float64]
    force: NDArray[np.float64]  #: (4, 3) N, force the finger exerts, world axes
    external_torque: NDArray[np.float64]  #: (16,) N m, tau_ext per joint
    point: NDArray[np.float64]  #: (4, 3) m, the contact point the force was solved at
    at_limit: NDArray[np.bool_]  #: (16,) joints left out of the fit (at a range limit)
    #: (4,) N: how far the stuck joints' unknown friction (up to F each) can move |f|
    uncertainty: NDArray[np.float64]
    #: (4,) N: the least |f| the sensed torques allow, each stuck joint's friction anywhere in
    #: [-F, F] (:func:`least_force`); None unless asked for (``estimate(least=True)``)
    least: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class ContactEstimator:
    """Where a hand's joints, tendons and pad sites are in a compiled model, and the estimate
    from them (module docstring)."""

    layout: TendonLayout
    finger_dofs: NDArray[np.int_]  #: (4, 4) dof addresses, one row per finger
    tip_sites: NDArray[np.int_]  #: (4,) fingertip site ids
    pad_centres: NDArray[np.int_]  #: (4,) pad centre site ids
    damping: NDArray[np.float64]  #: (16,) joint damping (N m s/rad)
    friction: NDArray[np.float64]  #: (16,) joint Coulomb friction (N m)
    joint_range: NDArray[np.float64]  #: (16, 2) joint ranges (rad)
    pad_radius: float = robot.PAD_RADIUS
    #: the fit's ridge term lambda^2 I (step 3)
    _ridge: NDArray[np.float64] = field(default_factory=lambda: RIDGE**2 * np.eye(3), repr=False)

    @classmethod
    def for_model(cls, model: mujoco.MjModel, prefix: str = "") -> ContactEstimator:
        """The estimator of the tendon hand whose names carry ``prefix`` in ``model``."""
        layout = TendonLayout.from_model(model, prefix)

        def site(name: str) -> int:
            i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, prefix + name)
            if i < 0:
                raise ValueError(f"the model has no site named {prefix + name!r}")
            return i

        dofs = np.asarray(layout.dof_adr)
        joints = [
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, prefix + j) for j in layout.joints
        ]
        return cls(
            layout=layout,
            finger_dofs=dofs.reshape(len(robot.FINGERS), robot.JOINTS_PER_FINGER),
            tip_sites=np.array([site(f"{f}_tip") for f in robot.FINGERS]),
            pad_centres=np.array([site(f"{f}_pad_centre") for f in robot.FINGERS]),
            damping=model.dof_damping[dofs].copy(),
            friction=model.dof_frictionloss[dofs].copy(),
            joint_range=model.jnt_range[joints].copy(),
        )

    def external_torque(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        sliding: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """(16,) joint torques (N m) not explained by the finger's own dynamics (steps 1-2);
        ``sliding``: each joint's last sliding direction (:class:`FrictionMemory`; default: the
        present velocity's sign where the joint slides, else no friction)."""
        dofs = self.layout.dof_adr
        tau = joint_torques(*self.layout.tensions(data), self.layout.radius)
        qdot = data.qvel[dofs]
        if sliding is None:
            sliding = np.where(np.abs(qdot) > MOVING_SPEED, np.sign(qdot), 0.0)
        inertial = np.zeros(len(data.qvel))
        mujoco.mj_mulM(model, data, inertial, data.qacc)
        return (
            tau
            - inertial[dofs]
            - data.qfrc_bias[dofs]
            - self.damping * qdot
            - self.friction * sliding
        )

    def estimate(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        sliding: NDArray[np.float64] | None = None,
        *,
        least: bool = False,
        normals: NDArray[np.float64] | None = None,
    ) -> ContactEstimate:
        """The estimated pad forces in ``data``'s present state (kinematics and sensors must be
        current, as after ``mj_step`` or ``mj_forward``); ``sliding`` as in
        :meth:`external_torque`; ``least``: also the least force the torques allow (module
        docstring); ``normals`` (4, 3): the contacts' outward face normals, world axes, to
        report each force's component into its face (step 4)."""
        qdot = data.qvel[self.layout.dof_adr]
        if sliding is None:
            sliding = np.where(np.abs(qdot) > MOVING_SPEED, np.sign(qdot), 0.0)
        tau_ext = self.external_torque(model, data, sliding)
        q = data.qpos[self.layout.qpos_adr]
        lo, hi = self.joint_range.T
        at_limit = (q < lo + LIMIT_MARGIN) | (q > hi - LIMIT_MARGIN)
        n = len(robot.FINGERS)
        per = robot.JOINTS_PER_FINGER
        stuck_friction = np.where(np.abs(qdot) > MOVING_SPEED, 0.0, self.friction)
        faces = None if normals is None else np.asarray(normals, dtype=float)
        if at_limit.any():
            force, point, solvers = self._fit_each(model, data, tau_ext, at_limit, faces)
        else:
            force, point, solvers = self._fit_all(model, data, tau_ext, faces)
        uncertainty = np.zeros(n)
        lows = np.zeros(n) if least else None
        for f in range(n):
            rows = slice(per * f, per * (f + 1))
            keep = ~at_limit[rows]
            solver = solvers[f]
            band = stuck_friction[rows][keep]
            uncertainty[f] = float(np.linalg.norm(solver, axis=0) @ band)
            if lows is not None:
                # the stuck joints' torques without the memory's friction, +- F about that
                centre = tau_ext[rows][keep] + band * sliding[rows][keep]
                lows[f] = (
                    least_force(solver, centre, band)
                    if faces is None
                    else least_pressing(-faces[f] @ solver, centre, band)
                )
        pressing = np.linalg.norm(force, axis=1)
        if normals is not None:
            pressing = np.maximum(0.0, -np.einsum("ij,ij->i", force, normals))
        return ContactEstimate(
            normal=pressing,
            force=force,
            external_torque=tau_ext,
            point=point,
            at_limit=at_limit,
            uncertainty=uncertainty,
            least=lows,
        )

    def _start_points(self, data: mujoco.MjData, faces: NDArray[np.float64] | None) -> NDArray:
        """(4, 3) first contact points (step 3): the tip sites, or the pad points facing the
        faces."""
        if faces is None:
            return data.site_xpos[self.tip_sites].copy()
        return data.site_xpos[self.pad_centres] - self.pad_radius * faces

    def _fit_all(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        tau_ext: NDArray[np.float64],
        faces: NDArray[np.float64] | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Step 3 for the four fingers at once, none at a joint limit: forces (4, 3), points
        (4, 3) and fits (4, 3, 4), the same numbers as :meth:`_fit_each` to the bit (tested)."""
        n, per = len(robot.FINGERS), robot.JOINTS_PER_FINGER
        jac = np.zeros((3, model.nv))
        A = np.empty((n, per, 3))
        bodies = model.site_bodyid[self.tip_sites]
        centres = data.site_xpos[self.pad_centres]
        tau = tau_ext.reshape(n, per)
        point = self._start_points(data, faces)
        active = np.ones(n, dtype=bool)
        force = np.zeros((n, 3))
        solvers = np.zeros((n, 3, per))
        for _ in range(2):
            idx = np.flatnonzero(active)
            for f in idx:
                mujoco.mj_jac(model, data, jac, None, point[f], int(bodies[f]))
                A[f] = jac[:, self.finger_dofs[f]].T
            At = np.swapaxes(A[idx], 1, 2)
            solvers[idx] = np.linalg.solve(At @ A[idx] + self._ridge, At)
            size = np.zeros(n)
            for f in idx:  # matrix-vector products and norms one by one: the same rounding
                force[f] = solvers[f] @ tau[f]
                size[f] = float(np.linalg.norm(force[f]))
            if faces is not None:  # at a face the point is known: one solve
                break
            active &= size >= 1e-9
            if not active.any():
                break
            point[active] = centres[active] + self.pad_radius * force[active] / size[active, None]
        return force, point, solvers

    def _fit_each(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        tau_ext: NDArray[np.float64],
        at_limit: NDArray[np.bool_],
        faces: NDArray[np.float64] | None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], list[NDArray[np.float64]]]:
        """Step 3 finger by finger, the joints at a limit left out: forces (4, 3), points
        (4, 3) and each finger's fit (3, k)."""
        n, per = len(robot.FINGERS), robot.JOINTS_PER_FINGER
        jac = np.zeros((3, model.nv))
        force = np.zeros((n, 3))
        point = self._start_points(data, faces)
        solvers = []
        for f in range(n):
            rows = slice(per * f, per * (f + 1))
            keep = ~at_limit[rows]
            body = int(model.site_bodyid[self.tip_sites[f]])
            centre = data.site_xpos[self.pad_centres[f]]
            p = point[f]
            fv = np.zeros(3)
            solver = np.zeros((3, int(keep.sum())))
            for _ in range(2):
                mujoco.mj_jac(model, data, jac, None, p, body)
                A = jac[:, self.finger_dofs[f]].T[keep]
                solver = np.linalg.solve(A.T @ A + self._ridge, A.T)
                fv = solver @ tau_ext[rows][keep]
                size = float(np.linalg.norm(fv))
                if size < 1e-9 or faces is not None:  # at a face the point is known: one solve
                    break
                p = centre + self.pad_radius * fv / size
            force[f], point[f] = fv, p
            solvers.append(solver)
        return force, point, solvers


def least_force(
    solver: NDArray[np.float64], centre: NDArray[np.float64], band: NDArray[np.float64]
) -> float:
    """min |solver tau| over the torques tau with |tau_j - centre_j| <= band_j: the least force
    (N) the fit ``solver`` (3, k) gives for joint torques known only within a band (a stuck
    joint's friction, anywhere in [-F, F]); a joint with band 0 is fixed at its centre. 0 when
    the box holds a torque the fit maps to no force (e.g. torques friction alone explains)."""
    free = band > 0
    fixed = solver[:, ~free] @ centre[~free]
    if not free.any():
        return float(np.linalg.norm(fixed))
    lo, hi = centre[free] - band[free], centre[free] + band[free]
    found = lsq_linear(solver[:, free], -fixed, bounds=(lo, hi), method="bvls")
    return float(np.linalg.norm(solver[:, free] @ found.x + fixed))


def least_pressing(
    into: NDArray[np.float64], centre: NDArray[np.float64], band: NDArray[np.float64]
) -> float:
    """min over the torques tau with |tau_j - centre_j| <= band_j of ``into`` . tau, floored at
    0: the least force into a face (N) that the fit's row ``into`` (k,) (the face's inward normal
    times the fit) gives for joint torques known only within a band. Linear, so each joint sits
    at the end of its band that lowers it: into . centre - |into| . band."""
    return max(0.0, float(into @ centre - np.abs(into) @ band))
