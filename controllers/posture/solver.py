"""Posture control (section 5.2, after Grupen & Souccar's posture controller, ref. [16] of the
paper): keep the fingertips where they are while reconfiguring the arm and hand to maximise the
hand's manipulability, with mink's differential IK (one position-only FrameTask per fingertip,
joint limits as ConfigurationLimit).

The manipulability measure ``M`` and its mink task are in :mod:`controllers.posture.manipulability`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mink
import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.errors import PostureError
from controllers.posture.ik_progress import ReachProgress
from controllers.posture.kinematic_scratch import kinematic_scratch
from controllers.posture.manipulability import ManipulabilityTask, log_manipulability
from controllers.posture.reduced_ik import ReducedStep
from controllers.timing import SERVO_SETTLE_TIME
from hand_sim import robot
from hand_sim.indices import RobotIndices
from hand_sim.world import World

#: Fingertip position tolerance (m) for a target to count as reached / held.
TIP_TOLERANCE = 1e-3
#: Differential-IK integration step (s), QP solver and Levenberg-Marquardt damping.
IK_DT = 0.05
QP_SOLVER = "daqp"
IK_DAMPING = 1e-3
#: Fingertip-only IK steps after each manipulability step, to pull the tips back on target.
TIP_RECOVERY_STEPS = 3
#: Fingertip FrameTask cost and Levenberg-Marquardt damping (mink FrameTask, position only).
TIP_COST = 1.0
#: Cost of the pad-centre targets that turn each pad towards its surface (see solve_posture).
PAD_CENTRE_COST = 0.3
#: The pad-centre targets have settled when their summed error shrinks less than this per
#: iteration (m).
PAD_SETTLED = 1e-5
TIP_LM_DAMPING = 1e-3
#: Iterations: reaching the fingertip targets, then optimising the posture.
REACH_ITERATIONS = 300
POSTURE_ITERATIONS = 150
#: Stop optimising when M improved by less than this over POSTURE_WINDOW iterations.
POSTURE_MIN_GAIN = 1e-3
POSTURE_WINDOW = 20
#: Which joints posture control may move.
JOINT_SETS: tuple[str, ...] = ("arm+hand", "hand")
#: Collision avoidance (mink CollisionAvoidanceLimit) between the robot's geoms and the
#: environment's (table, blocks): the distance kept (m), the distance at which the limit engages
#: (m) and its gain. Without it, moving the arm to hold the fingertips sweeps the palm through
#: the block it is about to grasp.
AVOID_DISTANCE = 0.003
AVOID_DETECTION = 0.03
AVOID_GAIN = 0.85
#: The palm keeps this much further (m) from the blocks: under the hand's weight the arm's servos
#: sag by a few millimetres, and a palm planned 3 mm above a block's top presses on it.
PALM_DISTANCE = 0.003
#: How far (m) the iterates may come inside an avoided distance before a step is refused.
CLEARANCE_SLACK = 0.001
#: Distance (m) a pad keeps from the block it may touch when it must not press into it
#: (``pads_press=False``): 0, touching allowed.
PAD_PRESS_LIMIT = 0.0


@dataclass(frozen=True, eq=False)
class PostureResult:
    """Result of :func:`solve_posture`. ``reachable`` is False when some fingertip target could
    not be brought within ``TIP_TOLERANCE``; ``unreachable`` names those fingers."""

    reachable: bool
    arm_q: NDArray[np.float64]  #: (5,) arm joints
    hand_q: NDArray[np.float64]  #: (16,) hand joints
    tip_error: NDArray[np.float64]  #: (4,) fingertip distance to target (m)
    log_manipulability_start: float
    log_manipulability_end: float
    iterations: int
    unreachable: tuple[str, ...]
    #: (k, 21) arm (5) and hand (16) joints of the IK's iterates, start to end: a path that keeps
    #: the solver's limits (collision avoidance included) all along, for apply_posture to follow.
    path: NDArray[np.float64] | None = None
    #: (4, 3) the fingertip targets at the end: the given ones, or with ``slide`` the heights
    #: the fingertips slid to
    targets: NDArray[np.float64] | None = None


def avoidance_groups(
    model: mujoco.MjModel,
    touchable: str | None = None,
    *,
    fingers_may_touch: bool = False,
    pads_press: bool = True,
) -> list[tuple[list[tuple[list[int], list[int]]], float]]:
    """Geom groups for collision avoidance, each with its distance to keep (m): every colliding
    robot geom against every colliding geom that is not the robot's (table top, blocks; not the
    floor the robot stands on), the palm from further (:data:`PALM_DISTANCE`). The fingertip pads
    may touch the geom named ``touchable`` (the block to grasp), and with ``fingers_may_touch``
    every finger link may (a grasp wraps the block; whether a link would press into it is for
    :mod:`controllers.hand.reachability` to judge). Without ``pads_press`` the pads may touch that
    geom but not press into it (:data:`PAD_PRESS_LIMIT`): holding the fingertip sites alone
    leaves each finger free to turn about its tip, and the turn swings the pad into the face
    (clutter3: 5-9 mm in). A posture move that starts with a pad pressed in further than
    :data:`CLEARANCE_SLACK` then makes no step at all."""
    active = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    pads = {model.geom(robot.hand_name(f"{f}_pad")).id for f in robot.FINGERS}
    palm = model.body(robot.hand_name(robot.PALM_BODY)).id
    robot_geoms, env_geoms = [], []
    for g in np.flatnonzero(active):
        name = model.body(model.geom_bodyid[g]).name
        if name.startswith(robot.ARM_PREFIX):
            robot_geoms.append(int(g))
        elif model.geom_type[g] != mujoco.mjtGeom.mjGEOM_PLANE:
            env_geoms.append(int(g))
    palm_geoms = [g for g in robot_geoms if model.geom_bodyid[g] == palm]
    others = [g for g in robot_geoms if g not in palm_geoms]
    target = model.geom(touchable).id if touchable is not None else -1
    rest = [g for g in env_geoms if g != target]
    near = [(others, rest)]
    if target >= 0:
        hand = {
            g for g in others if model.body(model.geom_bodyid[g]).name.startswith(robot.HAND_PREFIX)
        }
        allowed = hand if fingers_may_touch else pads
        near.append(([g for g in others if g not in allowed], [target]))
    groups = [(near, AVOID_DISTANCE), ([(palm_geoms, env_geoms)], PALM_DISTANCE)]
    if target >= 0 and not pads_press:
        groups.append(([(sorted(pads), [target])], PAD_PRESS_LIMIT))
    return groups


def avoidance_limits(
    model: mujoco.MjModel,
    touchable: str | None = None,
    *,
    fingers_may_touch: bool = False,
    pads_press: bool = True,
) -> list[mink.CollisionAvoidanceLimit]:
    """mink's collision-avoidance limits of :func:`avoidance_groups` (same arguments): each
    group's distance kept with gain :data:`AVOID_GAIN`, engaging :data:`AVOID_DETECTION`
    further out."""
    return [
        mink.CollisionAvoidanceLimit(
            model,
            pairs,
            gain=AVOID_GAIN,
            minimum_distance_from_collisions=distance,
            collision_detection_distance=distance + AVOID_DETECTION,
        )
        for pairs, distance in avoidance_groups(
            model, touchable, fingers_may_touch=fingers_may_touch, pads_press=pads_press
        )
    ]


def mink_velocity(
    cfg: mink.Configuration,
    tasks: list[mink.Task],
    limits: list[mink.Limit],
    constraints: list[mink.Task],
) -> NDArray[np.float64]:
    """mink's differential-IK step of ``tasks`` (posture control's step, damping and solver):
    the joint velocity; raises ``mink.NoSolutionFound`` when the program has no solution."""
    return mink.solve_ik(
        cfg,
        tasks,
        IK_DT,
        QP_SOLVER,
        damping=IK_DAMPING,
        limits=limits,
        constraints=constraints,
    )


def moving_dofs(model: mujoco.MjModel, frozen: list[int]) -> NDArray[np.int64]:
    """The degrees of freedom of ``model`` not in ``frozen``, in order."""
    return np.array(sorted(set(range(model.nv)).difference(frozen)), dtype=np.int64)


def _point_tasks(
    sites: tuple[str, ...], points: NDArray[np.float64], cost: float
) -> list[mink.FrameTask]:
    """Position-only mink tasks putting each of ``sites`` on its row of ``points``."""
    tasks = []
    for site, p in zip(sites, points, strict=True):
        task = mink.FrameTask(
            robot.qualified(site),
            "site",
            position_cost=cost,
            orientation_cost=0.0,
            lm_damping=TIP_LM_DAMPING,
        )
        task.set_target(mink.SE3.from_translation(p))
        tasks.append(task)
    return tasks


def _frozen_dofs(model: mujoco.MjModel, idx: RobotIndices, joints: str) -> list[int]:
    movable = set(idx.finger_dofs.ravel().tolist())
    if joints == "arm+hand":
        movable |= set(idx.arm_dofs.tolist())
    return [d for d in range(model.nv) if d not in movable]


def solve_posture(
    world: World,
    targets: ArrayLike | None = None,
    *,
    optimize: bool = True,
    joints: str = "arm+hand",
    tolerance: float = TIP_TOLERANCE,
    reach_iterations: int = REACH_ITERATIONS,
    posture_iterations: int = POSTURE_ITERATIONS,
    qpos: ArrayLike | None = None,
    model: mujoco.MjModel | None = None,
    avoid_collisions: bool = False,
    touchable: str | None = None,
    fingers_may_touch: bool = False,
    pads_press: bool = True,
    pad_centres: ArrayLike | None = None,
    slide: tuple[float, float] | None = None,
    give_up: bool = False,
    still: tuple[int, ...] = (),
) -> PostureResult:
    """Kinematic posture control from the world's current state, or from ``qpos`` (the world is not
    changed). First the fingertips are brought to ``targets`` (4, 3) (default: where they are now);
    if a target stays farther than ``tolerance`` the result is ``reachable=False``. Then, if
    ``optimize``, the manipulability task raises ``M`` while the fingertip tasks hold the tips; a
    step that would let a fingertip drift beyond ``tolerance`` is refused. ``joints`` is
    ``"arm+hand"`` (posture control) or ``"hand"`` (fingers only); other joints are frozen.
    ``model`` replaces the world's model (same state layout; e.g. the planning model holding the
    perceived target, :mod:`controllers.planning.belief`). ``avoid_collisions`` keeps every robot
    geom :data:`AVOID_DISTANCE` from the table and the blocks (mink's collision avoidance limit),
    except that the fingertip pads may touch (and, kinematically, press into, unless ``pads_press``
    is False) the geom named ``touchable``. ``pad_centres`` (4, 3), if given, are targets of the
    centres of the fingertips' rounded ends (:data:`robot.PAD_CENTRE_SITES`) at a lower cost: with a
    fingertip target on a surface point and its pad centre one pad radius out along the surface
    normal, the pad, not the side or the end of the finger, faces the surface (position-only IK
    leaves each finger one redundant degree of freedom, its pad's orientation). ``slide`` = (lowest,
    highest) world z (m) lets each fingertip target slide vertically within that range while the
    fingertips are brought to their targets: a contact on a prism's vertical face is planar (section
    5), a vertical line, so only the target's horizontal position is held and its height follows the
    fingertip's. ``give_up``: stop as soon as the targets cannot be reached
    (:class:`controllers.posture.ik_progress.ReachProgress`), for a caller that discards unreachable
    results (their joints then differ from those of a full run). ``still``: fingers held as they are
    (a three-contact grasp's idle finger): their joints frozen, their targets where they are.
    """
    if joints not in JOINT_SETS:
        raise PostureError(f"unknown joint set {joints!r}; valid: {', '.join(JOINT_SETS)}")
    model = world.model if model is None else model
    scratch = kinematic_scratch(world, model)
    idx = scratch.indices
    cfg = scratch.configuration
    start = world.data.qpos if qpos is None else np.asarray(qpos, dtype=float)
    if start.shape != (model.nq,) or not np.all(np.isfinite(start)):
        raise PostureError(f"qpos must be {model.nq} finite numbers, got shape {start.shape}")
    cfg.update(start.copy())
    goal = (
        cfg.data.site_xpos[idx.tip_sites].copy()
        if targets is None
        else np.asarray(targets, dtype=float)
    )
    if goal.shape != (len(robot.FINGERS), 3) or not np.all(np.isfinite(goal)):
        raise PostureError(f"fingertip targets must be a finite (4, 3) array, got {goal.shape}")
    held = list(still)
    pad_sites = np.array([model.site(robot.qualified(s)).id for s in robot.PAD_CENTRE_SITES])
    if held:
        goal = goal.copy()
        goal[held] = cfg.data.site_xpos[idx.tip_sites[held]]
    tips = _point_tasks(robot.FINGERTIP_SITES, goal, TIP_COST)
    pads = []
    if pad_centres is not None:
        centres = np.array(pad_centres, dtype=float)
        if centres.shape != goal.shape or not np.all(np.isfinite(centres)):
            raise PostureError(f"pad centres must be a finite (4, 3) array, got {centres.shape}")
        if held:
            centres[held] = cfg.data.site_xpos[pad_sites[held]]
        pads = _point_tasks(robot.PAD_CENTRE_SITES, centres, PAD_CENTRE_COST)
    tips_and_pads = tips + pads
    if slide is not None:
        lo_z, hi_z = float(slide[0]), float(slide[1])
        if not (np.isfinite(lo_z) and np.isfinite(hi_z) and lo_z <= hi_z):
            raise PostureError(f"slide must be a finite (low, high) height range, got {slide!r}")
        goal = goal.copy()
        pad_rise = centres[:, 2] - goal[:, 2] if pads else np.zeros(len(goal))

    def follow_heights() -> None:
        """Slide the targets' heights to the fingertips' (within ``slide``)."""
        goal[:, 2] = np.clip(cfg.data.site_xpos[idx.tip_sites][:, 2], lo_z, hi_z)
        goal[held, 2] = cfg.data.site_xpos[idx.tip_sites[held], 2]  # where they are held
        for task, target in zip(tips, goal, strict=True):
            task.set_target(mink.SE3.from_translation(target))
        for k, task in enumerate(pads):
            centres[k, 2] = goal[k, 2] + pad_rise[k]
            task.set_target(mink.SE3.from_translation(centres[k]))

    avoidance = (
        avoidance_limits(
            model, touchable, fingers_may_touch=fingers_may_touch, pads_press=pads_press
        )
        if avoid_collisions
        else []
    )
    limits: list[mink.Limit] = [scratch.limit, *avoidance]
    fromto = np.zeros(6)

    def clear() -> bool:
        """Every avoided pair at least its distance apart (less CLEARANCE_SLACK): the limits
        act on velocities only, to first order, and the iterates can creep past them."""
        for limit in avoidance:
            floor = limit.minimum_distance_from_collisions - CLEARANCE_SLACK
            for g1, g2 in limit.geom_id_pairs:
                if mujoco.mj_geomDistance(model, cfg.data, g1, g2, floor + 1e-3, fromto) < floor:
                    return False
        return True

    frozen = _frozen_dofs(model, idx, joints) + [int(d) for f in held for d in idx.finger_dofs[f]]
    constraints = [mink.DofFreezingTask(model, dof_indices=frozen)] if frozen else []

    def tip_error() -> NDArray[np.float64]:
        return np.linalg.norm(cfg.data.site_xpos[idx.tip_sites] - goal, axis=1)

    # the fingertip (and pad-centre) steps, most of an episode's IK, on the moving joints only
    reduced = ReducedStep(
        model,
        tips_and_pads,
        moving_dofs(model, frozen),
        limits,
        damping=IK_DAMPING,
        solver=QP_SOLVER,
    )

    def ik_step(tasks: list[mink.Task]) -> bool:
        """One damped differential-IK step of ``tasks`` within the limits, integrated in place;
        False when the QP has no solution (the limits contradict each other, e.g. a start
        already inside an avoided distance): the configuration is then left as it is."""
        if tasks is tips_and_pads:
            v = reduced.velocity(cfg, IK_DT)
            if v is None:
                return False
            cfg.integrate_inplace(v, IK_DT)
            return True
        try:
            v = mink_velocity(cfg, tasks, limits, constraints)
        except mink.NoSolutionFound:
            return False
        cfg.integrate_inplace(v, IK_DT)
        return True

    arm_adr = idx.arm_qpos
    hand_adr = idx.hand_qpos

    def snapshot() -> NDArray[np.float64]:
        return np.concatenate([cfg.q[arm_adr], cfg.q[hand_adr]])

    path = [snapshot()]
    m_start = log_manipulability(model, cfg.data, idx)
    iterations = 0

    def pad_error() -> float:
        if not pads:
            return 0.0
        return float(np.linalg.norm(cfg.data.site_xpos[pad_sites] - centres, axis=1).sum())

    last_pad = np.inf
    progress = ReachProgress(tolerance, reach_iterations) if give_up else None
    for _ in range(reach_iterations):
        if slide is not None:
            follow_heights()
        now_pad = pad_error()
        if tip_error().max() < 0.5 * tolerance and last_pad - now_pad < PAD_SETTLED:
            break
        if progress is not None and progress.hopeless(float(tip_error().max())):
            break
        last_pad = now_pad
        if not ik_step(tips_and_pads):
            break
        path.append(snapshot())
        iterations += 1
    if slide is not None:
        follow_heights()
    err = tip_error()
    if err.max() < tolerance and optimize:
        manip = ManipulabilityTask(model)
        history = [log_manipulability(model, cfg.data, idx)]
        for _ in range(posture_iterations):
            q_before = cfg.q.copy()
            solved = ik_step([*tips_and_pads, manip])
            # let the fingertip tasks alone pull the tips back onto their targets
            for _ in range(TIP_RECOVERY_STEPS):
                solved = solved and ik_step(tips_and_pads)
            iterations += 1
            if not solved:
                cfg.update(q_before)
                break
            value = log_manipulability(model, cfg.data, idx)
            if tip_error().max() > 0.5 * tolerance or not value > history[-1] or not clear():
                cfg.update(q_before)
                break
            history.append(value)
            path.append(snapshot())
            if (
                len(history) > POSTURE_WINDOW
                and history[-1] - history[-1 - POSTURE_WINDOW] < POSTURE_MIN_GAIN
            ):
                break
        err = tip_error()
    arm_q = cfg.q[idx.arm_qpos]
    hand_q = cfg.q[idx.hand_qpos]
    unreachable = tuple(f for f, e in zip(robot.FINGERS, err, strict=True) if e >= tolerance)
    return PostureResult(
        reachable=not unreachable,
        arm_q=arm_q.copy(),
        hand_q=hand_q.copy(),
        tip_error=err,
        log_manipulability_start=m_start,
        log_manipulability_end=log_manipulability(model, cfg.data, idx),
        iterations=iterations,
        unreachable=unreachable,
        path=np.array(path),
        targets=goal.copy(),
    )


#: Time (s) over which servo targets move to a new posture (then they settle for
#: :data:`controllers.timing.SERVO_SETTLE_TIME`).
MOVE_TIME = 1.0
#: A pad pressing on something with more than this (N) is in contact (see :func:`apply_posture`).
CONTACT_FORCE = 0.05
#: Steady-state servo error corrections after a move (see :func:`apply_posture`).
SERVO_CORRECTIONS = 2


def apply_posture(
    world: World,
    result: PostureResult,
    *,
    move_time: float = MOVE_TIME,
    settle: float = SERVO_SETTLE_TIME,
    corrections: int = SERVO_CORRECTIONS,
) -> NDArray[np.float64]:
    """Move the arm and hand servos to ``result``'s posture over ``move_time`` s along the IK's own
    path of iterates (which kept the solver's limits, collision avoidance included, at every
    step; a straight line in joint space between two collision-free postures need not), let them
    settle, and return the fingertip positions (4, 3) the simulation then has.

    Position servos sag under gravity (the fingers' servos are soft); ``corrections`` times the
    remaining steady-state joint error is added to the servo targets and the servos settle again,
    except for a finger the hand senses pressing on something (``World.pads_pressing``): its
    error is the contact's doing, and correcting it would push harder.
    """
    start = np.concatenate([world.arm_targets(), world.hand_targets()])
    goal = np.concatenate([result.arm_q, result.hand_q])
    waypoints = (
        np.vstack([start, goal])
        if result.path is None
        else np.vstack([start, result.path[1:], goal])
    )
    seg = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    dt = world.model.opt.timestep
    n = max(1, round(move_time / dt))
    chunk = 10
    n_arm = len(result.arm_q)
    for k in range(0, n, chunk):
        s = min(1.0, (k + chunk) / n) * arc[-1]
        q = np.array([np.interp(s, arc, waypoints[:, j]) for j in range(waypoints.shape[1])])
        world.set_arm_targets(q[:n_arm])
        world.set_hand_targets(q[n_arm:])
        world.step(chunk)
    world.step(max(0, round(settle / dt)))
    for _ in range(corrections):
        world.set_arm_targets(world.arm_targets() + result.arm_q - world.arm_qpos())
        free = np.repeat(~world.pads_pressing(CONTACT_FORCE), robot.JOINTS_PER_FINGER)
        error = np.where(free, result.hand_q - world.hand_qpos(), 0.0)
        world.set_hand_targets(world.hand_targets() + error)
        world.step(max(0, round(settle / dt)))
    return world.fingertip_positions()
