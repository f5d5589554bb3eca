"""Grasp Object (section 5.2): "drives the fingers from their approach configuration ... to the
virtual finger configuration synthesized by the grasp controller", then squeezes, holds and
releases, all on the simulated hand's joint servos and judged by what it senses of its fingertip
forces (``World.touch``: the servo hand's touch pads; the tendon hand's estimate from its tendon
tensions, :mod:`hand_sim.contact_estimate`).

Each finger moves on its own line in joint space, from a pre-contact posture (fingertip
:data:`PRE_CONTACT` outside its contact, pad facing it) through the contact to a posture
:data:`controllers.hand.reachability.SQUEEZE_REACH` inside the surface: finger f's servo targets are
``q_pre + s_f (q_in - q_pre)`` with its own progress ``s_f``. Closing advances every ``s_f`` until
that finger's pad feels the block (the touch guard: a finger that touches stops, so the first
finger does not shove the block before the others arrive). Squeezing then regulates each finger's
``s_f`` so that its touch force follows its share of the grip force: the normal forces of the S_G
linear programme (Eq. 13) scaled to a mean of ``grip_force``, so the squeeze itself balances. The
same regulation keeps the grip while the arm lifts and carries the block. Releasing moves every
fingertip back out along its contact normal: no finger drags the block sideways.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import lsq_linear

from controllers.errors import ReachError
from controllers.hand.finger_assignment import pressing_fingers
from controllers.hand.finger_geometry import PerceivedPrism, finger_clearance
from controllers.hand.reachability import SQUEEZE_REACH, grip_targets
from controllers.posture.solver import solve_posture
from controllers.timing import CONTROL_PERIOD, control_steps
from hand_sim import robot
from hand_sim.indices import RobotIndices
from hand_sim.world import World

#: Distance (m) of each fingertip outside its contact before closing, and after releasing; a
#: finger whose links would come within PRE_CLEARANCE (m) of the block there starts further out,
#: in steps of PRE_CONTACT_STEP up to MAX_PRE_CONTACT.
PRE_CONTACT = 0.012
PRE_CLEARANCE = 0.003
PRE_CONTACT_STEP = 0.004
MAX_PRE_CONTACT = 0.024
#: Closing speed: progress per second along the pre-contact-to-inside line (1 = the whole line;
#: PRE_CONTACT + SQUEEZE_REACH = 18 mm, so about 18 mm/s at the fingertip).
CLOSE_RATE = 1.0
#: A pad "feels" the block above this normal force (N) (for the tendon hand, whose touch is
#: estimated from its tendon tensions: the least force its tensions allow, ``World.touch_felt``).
TOUCH_THRESHOLD = 0.05
#: Closing gives up when a finger has gone this far past its line's end without touching.
CLOSE_OVERRUN = 0.5
#: Grip force: mean normal force per finger (N) and the regulation gain (progress per N per s).
GRIP_FORCE = 6.0
FORCE_GAIN = 0.5
#: Largest progress of the squeeze (beyond the inside posture, by extrapolation).
MAX_PROGRESS = 2.0
#: The squeeze has settled when every finger's force is within this fraction of its target.
FORCE_TOLERANCE = 0.2
#: ... or within this many newtons of it: a finger asked for a few tenths of a newton (a light
#: finger of a balanced lateral squeeze, :func:`balanced_shares`) is within the touch signal's
#: ripple of its target long before it is within a fifth of it.
FORCE_FLOOR = 0.15
#: Time (s) allowed to close and to squeeze.
CLOSE_TIME = 3.0
SQUEEZE_TIME = 2.0
#: Squeeze shares balanced in 3-D (:func:`balanced_shares`): the least share of the mean force a
#: finger keeps (so that its pad still feels the block), and the weight of the planar shares
#: (the prior) against the 3-D balance.
MIN_SHARE = 0.1
PRIOR_WEIGHT = 0.1
#: Time (s) to open the hand at release, and where each finger ends on its line (progress; a
#: negative one extrapolates outwards beyond the pre-contact posture).
RELEASE_TIME = 0.8
RELEASE_PROGRESS = -0.6


@dataclass
class Grip:
    """The fingers' lines in joint space and their progress; see the module docstring."""

    q_pre: NDArray[np.float64]  #: (16,) pre-contact posture
    q_in: NDArray[np.float64]  #: (16,) posture SQUEEZE_REACH inside the contacts
    forces: NDArray[np.float64]  #: (4,) target normal force per finger (N)
    pre_error: NDArray[np.float64] = field(default_factory=lambda: np.zeros(4))  #: IK, m
    in_error: NDArray[np.float64] = field(default_factory=lambda: np.zeros(4))  #: IK, m
    progress: NDArray[np.float64] = field(default_factory=lambda: np.zeros(4))
    touched: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(4, dtype=bool))
    #: (4, 3) the contacts' outward face normals, world axes: the squeeze regulates the force
    #: into each face (:meth:`hand_sim.world.World.touch`); None: as the hand senses it
    normals: NDArray[np.float64] | None = None

    def targets(self) -> NDArray[np.float64]:
        """(16,) hand servo targets for the current progress."""
        q = self.q_pre.copy()
        for f, sl in enumerate(robot.FINGER_JOINT_SLICES):
            q[sl] = self.q_pre[sl] + self.progress[f] * (self.q_in[sl] - self.q_pre[sl])
        return q

    def regulate(self, world: World, dt: float) -> None:
        """Hold the fingers' servo targets (the grip is a stiffness: the block settles where the
        fingers' forces and friction balance)."""
        world.set_hand_targets(self.targets())


def plan_grip(
    world: World,
    points: ArrayLike,
    normals: ArrayLike,
    force_shares: ArrayLike,
    *,
    grip_force: float = GRIP_FORCE,
    model: mujoco.MjModel | None = None,
    prism: PerceivedPrism | None = None,
    along_normal: bool = False,
    start: ArrayLike | None = None,
    squeeze_reach: float = SQUEEZE_REACH,
    idle: int | None = None,
) -> Grip:
    """The two postures of each finger for contacts ``points`` (4, 3) with outward ``normals``
    (finger order ff, mf, rf, th), arm held where it is now; ``force_shares`` (4,) are the
    relative normal forces (e.g. the S_G LP's), scaled to a mean of ``grip_force`` N.

    With the block's ``prism`` given, a finger whose pre-contact posture would bring any of its
    links within :data:`PRE_CLEARANCE` of the block starts from further out (up to
    :data:`MAX_PRE_CONTACT`): closing then begins with every finger clear of the block.

    With ``along_normal`` each finger's line runs through its inside posture along the joint
    direction ``K^-1 J^T (-n)`` (K the finger's servo gains, J its fingertip Jacobian): the
    servo torques the squeeze adds past contact are then those of a force along the contact's
    inward normal, with no tangential part that friction passes on to the block (a finger row
    held horizontally, as in a lateral grasp, otherwise drags the block up or down as it
    squeezes and tips it). ``start`` (16,): the hand posture the inside posture's IK starts from
    (default the hand's present one), e.g. the one that showed the contacts reachable;
    ``squeeze_reach``: how far (m) inside its contact the inside posture puts each fingertip.
    ``idle``: a three-contact grasp's finger that takes no contact (its rows of ``points``,
    ``normals`` and ``force_shares`` are not read): it keeps its posture in ``start``
    throughout (both its postures that one, its force 0, counted as touching)."""
    p = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    shares = np.asarray(force_shares, dtype=float).copy()
    pressing = pressing_fingers(idle)
    if (
        shares.shape != (4,)
        or not np.all(np.isfinite(shares[pressing]))
        or shares[pressing].min() <= 0
    ):
        raise ReachError(f"force shares must be 4 positive numbers, got {force_shares!r}")
    if idle is not None:
        n = n.copy()
        n[idle] = 0.0  # no squeeze direction: backed_off_hand leaves the finger where it is
        shares[idle] = 0.0
    if not grip_force > 0:
        raise ReachError(f"grip force must be positive, got {grip_force}")
    inside, inside_pads = grip_targets(p, n, squeeze_reach)
    qpos = None
    if start is not None:
        qpos = world.data.qpos.copy()
        qpos[RobotIndices.of(world.model if model is None else model).hand_qpos] = start
    sol_in = solve_posture(
        world,
        inside,
        optimize=False,
        joints="hand",
        model=model,
        pad_centres=inside_pads,
        qpos=qpos,
        still=() if idle is None else (idle,),
    )
    model = world.model if model is None else model
    data_q = world.data.qpos.copy()
    finger_qpos = RobotIndices.of(model).hand_qpos
    data_q[finger_qpos] = sol_in.hand_q
    standoff = np.full(4, PRE_CONTACT)
    while True:
        if along_normal:
            pre_q = backed_off_hand(model, data_q, n, standoff + squeeze_reach)
            data = mujoco.MjData(model)
            data.qpos[:] = data_q
            data.qpos[finger_qpos] = pre_q
            mujoco.mj_kinematics(model, data)
            if prism is None:
                break
            tight = finger_clearance(model, data, prism) < PRE_CLEARANCE
            if not tight.any() or standoff[tight].min() >= MAX_PRE_CONTACT:
                break
            standoff[tight] = np.minimum(standoff[tight] + PRE_CONTACT_STEP, MAX_PRE_CONTACT)
            continue
        pre = p + standoff[:, None] * n
        pre_pads = pre + robot.PAD_RADIUS * n
        sol_pre = solve_posture(
            world,
            pre,
            optimize=False,
            joints="hand",
            model=model,
            pad_centres=pre_pads,
            qpos=data_q,
            still=() if idle is None else (idle,),
        )
        if prism is None:
            break
        data = mujoco.MjData(model)
        data.qpos[:] = data_q
        data.qpos[finger_qpos] = sol_pre.hand_q
        mujoco.mj_kinematics(model, data)
        tight = finger_clearance(model, data, prism) < PRE_CLEARANCE
        if not tight.any() or standoff[tight].min() >= MAX_PRE_CONTACT:
            break
        standoff[tight] = np.minimum(standoff[tight] + PRE_CONTACT_STEP, MAX_PRE_CONTACT)
    forces = grip_force * shares / shares[pressing].mean()
    touched = np.arange(len(robot.FINGERS)) == idle  # the idle finger waits for no touch
    if along_normal:
        return Grip(
            pre_q,
            sol_in.hand_q,
            forces,
            in_error=sol_in.tip_error,
            touched=touched,
            normals=n.copy(),
        )
    return Grip(
        sol_pre.hand_q,
        sol_in.hand_q,
        forces,
        pre_error=sol_pre.tip_error,
        in_error=sol_in.tip_error,
        touched=touched,
        normals=n.copy(),
    )


def backed_off_hand(
    model: mujoco.MjModel, qpos: ArrayLike, normals: ArrayLike, distance: ArrayLike
) -> NDArray[np.float64]:
    """The hand's joints (16,) with each finger moved back from its posture in ``qpos`` along
    its normal-squeeze direction (:func:`normal_squeeze`) until, to first order, its fingertip
    is ``distance`` (m; scalar or (4,)) further out along its contact's outward ``normals``
    (4, 3); within the joint ranges."""
    q = np.asarray(qpos, dtype=float)
    direction, rate = normal_squeeze(model, q, np.asarray(normals, dtype=float))
    back = np.broadcast_to(np.asarray(distance, dtype=float), rate.shape) / rate
    idx = RobotIndices.of(model)
    limits = model.jnt_range[idx.hand_joints]
    hand = q[idx.hand_qpos]
    return np.clip(hand - np.repeat(back, robot.JOINTS_PER_FINGER) * direction, *limits.T)


def normal_squeeze(
    model: mujoco.MjModel, qpos: NDArray[np.float64], normals: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per finger at ``qpos``: the joint direction (16,) ``K^-1 J^T (-n)`` of a pure normal
    squeeze (:func:`plan_grip`) and the rate (4,) at which moving along it drives the fingertip
    into its face (m per unit)."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    idx = RobotIndices.of(model)
    kp = model.actuator_gainprm[idx.hand_ctrl, 0].reshape(idx.finger_dofs.shape)
    jac = np.zeros((3, model.nv))
    direction = np.zeros(idx.finger_dofs.size)
    rate = np.zeros(len(robot.FINGERS))
    for f, site in enumerate(idx.tip_sites):
        mujoco.mj_jacSite(model, data, jac, None, int(site))
        J = jac[:, idx.finger_dofs[f]]
        d = (J.T @ -normals[f]) / kp[f]
        d /= max(float(np.linalg.norm(d)), 1e-12)
        direction[4 * f : 4 * f + 4] = d
        rate[f] = max(float(-normals[f] @ J @ d), 1e-6)
    return direction, rate


def balanced_shares(
    points: ArrayLike,
    normals: ArrayLike,
    prior: ArrayLike,
    *,
    min_share: float = MIN_SHARE,
    prior_weight: float = PRIOR_WEIGHT,
) -> NDArray[np.float64]:
    """Relative normal forces (n,), mean 1, that squeeze the block at contacts ``points`` (n, 3)
    with outward ``normals`` (n, 3) without a net force or moment in 3-D, as near the planar
    shares ``prior`` (n,) as that allows.

    The grasp controller balances the contacts in the block's cross-section (section 5: the
    contacts are planar), so its shares (the S_G LP's normal forces, Eq. 13) leave out the moments
    about horizontal axes that contacts at different heights make: a lateral grasp puts the
    middle finger high and the thumb low on the block, and squeezing them as hard as the other
    two tips the block over. Least squares (``scipy.optimize.lsq_linear``) on the net wrench,
    moments divided by the contacts' RMS distance from their centroid, plus ``prior_weight``
    times the distance to the prior and the mean held at 1, with every share at least
    ``min_share``. Contacts at one height get the prior back when it balances them."""
    p = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    f0 = np.asarray(prior, dtype=float)
    k = len(p)
    if p.shape != (k, 3) or n.shape != (k, 3) or f0.shape != (k,) or k == 0:
        raise ReachError(
            f"points and normals must be (n, 3) and the prior (n,), got "
            f"{p.shape}, {n.shape}, {f0.shape}"
        )
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n)) and np.all(np.isfinite(f0))):
        raise ReachError("points, normals and prior must be finite")
    if not 0.0 <= min_share < 1.0:
        raise ReachError(f"min_share must lie in [0, 1), got {min_share}")
    f0 = f0 / f0.mean() if f0.mean() > 0 else np.ones(k)
    arm = p - p.mean(axis=0)
    scale = max(float(np.sqrt((arm**2).sum(axis=1).mean())), 1e-6)
    wrench = np.vstack([-n.T, -np.cross(arm, n).T / scale])  # (6, n): per unit normal force
    rows = np.vstack([wrench, np.sqrt(prior_weight) * np.eye(k), np.full((1, k), 10.0)])
    rhs = np.concatenate([np.zeros(6), np.sqrt(prior_weight) * f0, [10.0 * k]])
    sol = lsq_linear(rows, rhs, bounds=(min_share, np.inf))
    return sol.x / sol.x.mean()


def move_hand(world: World, q: ArrayLike, duration: float) -> None:
    """Move the hand's servo targets to ``q`` (16,) along a smooth (cosine) profile."""
    q0 = world.hand_targets()
    q1 = np.asarray(q, dtype=float)
    steps = control_steps(world)
    n = max(1, round(duration / CONTROL_PERIOD))
    for k in range(1, n + 1):
        s = 0.5 - 0.5 * np.cos(np.pi * k / n)
        world.set_hand_targets(q0 + s * (q1 - q0))
        world.step(steps)


@dataclass(frozen=True)
class CloseResult:
    """Outcome of :func:`close`: ``touched`` per finger, in order ff, mf, rf, th."""

    all_touched: bool
    touched: tuple[bool, ...]
    seconds: float
    touch: NDArray[np.float64]  #: (4,) N at the end


def close(world: World, grip: Grip, *, max_time: float = CLOSE_TIME) -> CloseResult:
    """Drive every finger from its pre-contact posture towards the block; a finger stops where its
    pad first feels the block (touch guard). Ends when all four touch or one has overrun."""
    steps = control_steps(world)
    t0 = world.time
    rate = CLOSE_RATE * CONTROL_PERIOD
    while world.time - t0 < max_time:
        grip.touched |= world.touch_felt(TOUCH_THRESHOLD)
        if grip.touched.all() or grip.progress.max() > 1.0 + CLOSE_OVERRUN:
            break
        grip.progress = np.where(grip.touched, grip.progress, grip.progress + rate)
        world.set_hand_targets(grip.targets())
        world.step(steps)
    return CloseResult(
        bool(grip.touched.all()),
        tuple(bool(t) for t in grip.touched),
        world.time - t0,
        world.touch(),
    )


@dataclass(frozen=True)
class SqueezeResult:
    """Outcome of :func:`squeeze`: the forces reached against their targets (N)."""

    settled: bool
    touch: NDArray[np.float64]
    target: NDArray[np.float64]
    seconds: float


def squeeze(
    world: World, grip: Grip, *, max_time: float = SQUEEZE_TIME, seek: bool = False
) -> SqueezeResult:
    """Regulate every finger's force into its face (the grip's normals; the tendon hand's
    estimate would otherwise count a pad dragging along the face as pressing) to its own target
    (its share of the grip) until all are within FORCE_TOLERANCE (or FORCE_FLOOR) of it; the
    fingers' servo targets then stay where the squeeze left them (the grip holds as a stiffness
    while the arm lifts and carries). ``seek``: a pressing finger that feels nothing (its face moved
    away as the others pressed) closes again at least at :data:`CLOSE_RATE`, as in
    :func:`close`, rather than at the force loop's rate, which for a light finger of a balanced
    lateral squeeze (a few tenths of a newton) is a few millimetres a second."""
    steps = control_steps(world)
    t0 = world.time
    settled_for = 0
    slack = np.maximum(FORCE_TOLERANCE * grip.forces, FORCE_FLOOR)
    sensed = world.touch(grip.normals)
    while world.time - t0 < max_time:
        rate = FORCE_GAIN * (grip.forces - sensed)
        if seek:
            lost = (grip.forces > 0.0) & (sensed < TOUCH_THRESHOLD)
            rate = np.where(lost, np.maximum(rate, CLOSE_RATE), rate)
        grip.progress = np.clip(grip.progress + rate * CONTROL_PERIOD, 0.0, MAX_PROGRESS)
        world.set_hand_targets(grip.targets())
        world.step(steps)
        sensed = world.touch(grip.normals)  # read once per step: the next error and the test
        settled_for = settled_for + 1 if np.all(np.abs(sensed - grip.forces) <= slack) else 0
        if settled_for >= 5:
            break
    return SqueezeResult(settled_for >= 5, sensed, grip.forces.copy(), world.time - t0)


def release(world: World, grip: Grip, *, duration: float = RELEASE_TIME) -> NDArray[np.float64]:
    """Open the hand: every finger back along its own line past its pre-contact posture (each
    fingertip moves out along its contact normal, to twice the pre-contact distance, so that no
    finger grazes the block when the hand leaves). Returns the touch forces (4,) afterwards."""
    steps = control_steps(world)
    start = grip.progress.copy()
    n = max(1, round(duration / CONTROL_PERIOD))
    for k in range(1, n + 1):
        s = 0.5 - 0.5 * np.cos(np.pi * k / n)
        grip.progress = start + s * (RELEASE_PROGRESS - start)
        world.set_hand_targets(grip.targets())
        world.step(steps)
    return world.touch()
