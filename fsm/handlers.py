"""One function per state of the task cycle (section 5.2): each calls into ``vision`` and
``controllers``, updates the :class:`~fsm.context.Episode` and returns the next state with the
reason for the transition, or raises :class:`TaskFailedError` with a named reason."""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import mujoco
import numpy as np

from controllers.cspace import CollisionChecker
from controllers.errors import ReachError
from controllers.fine_reach import (
    GRASP_DEPTH,
    SurfaceTargets,
    contact_targets,
    fine_reach,
    project_to_surface,
)
from controllers.finger_samples import FingerSamples
from controllers.grasp.score import grasp_score
from controllers.grasp.session import GraspSynthesis, separate_contacts
from controllers.grip import (
    CONTROL_PERIOD,
    GRIP_FORCE,
    PRE_CONTACT,
    backed_off_hand,
    balanced_shares,
    close,
    move_hand,
    plan_grip,
    release,
    squeeze,
)
from controllers.hand_reach import (
    MIN_PAD_SPACING,
    PAD_NORMAL_LOCAL,
    SQUEEZE_REACH,
    PerceivedPrism,
    fingertips_at,
    grip_targets,
    reachable_contacts,
)
from controllers.planning_model import PERCEIVED_GEOM, planning_model
from controllers.posture import (
    SERVO_CORRECTIONS,
    SETTLE_TIME,
    HandIndices,
    apply_posture,
    solve_posture,
)
from controllers.reach import (
    APPROACHES,
    LATERAL_DEPTH,
    ReachTarget,
    execute_path,
    plan_arm_path,
    plan_coarse_reach,
    plan_delivery,
)
from controllers.transport import (
    carry,
    held_load,
    lift,
    lower_until_supported,
    move_palm,
    retreat,
)
from fsm.context import Episode
from fsm.judge import judge
from fsm.layout import ASKED_CLEARANCE, free_slot, place_is_free
from fsm.states import MAX_FINE_REACH_LOOPS, MAX_POSTURE_RETRIES, Failure, State
from hand_sim import robot
from hand_sim.blocks import WOOD_DENSITY
from hand_sim.contacts import robot_contacts
from hand_sim.geometry import place_polygon, point_in_convex_polygon
from vision import Observation, VisionError, analyze, overhead_camera
from vision.errors import NotABlockError

#: Fine Reach leaves each fingertip this far (m) outside its surface point; Wrench Closure then
#: works from their projections.
FINE_REACH_STANDOFF = 0.008
#: Fine Reach counts as reached with every fingertip this close (m) to its target; beyond
#: FINE_REACH_GIVE_UP the fingers cannot reach the block at all.
FINE_REACH_TOLERANCE = 0.006
FINE_REACH_GIVE_UP = 0.03
#: Posture Control after Fine Reach: fingertips may drift this far (m) before Fine Reach repeats.
POSTURE_DRIFT = 0.005
#: Wrench Closure checks the contacts' reachability every this many controller steps and at the
#: end (the paper: "until convergence, or until the reachability criterion is no longer
#: satisfied").
REACH_CHECK_EVERY = 10
#: The grasp controller keeps its contacts this much (m) further apart than two pads need.
SEPARATION_MARGIN = 0.002
#: Fingers retract this far (m) from the block before the arm changes posture or the hand
#: pre-shapes for the grasp.
RETRACT = 0.015
RETRACT_TRIES = 3
#: Posture Control changes the arm's posture backed out by this much (m) along the approach axis,
#: each straight move out and in taking BACKOFF_TIME (s): the fingers stay clear of the block.
BACKOFF = 0.08
BACKOFF_TIME = 0.8
#: Clearance (m) of the harmonic path between the backed-out postures.
REPOSITION_CLEARANCE = 0.0
#: Times (s) of the hand's moves.
RETRACT_TIME = 0.4
PRESHAPE_TIME = 0.6
ARM_MOVE_TIME = 1.0
#: The held load must be at least this share of the perceived block's weight after the lift, and
#: during the carry (wrist sensor), else the block slipped / was dropped.
MIN_HELD_SHARE = 0.5
#: Pads that carry at least this share of the grip's mean force count for the lift's slip check
#: in a lateral grasp.
CARRYING_SHARE = 0.5
#: A carried block counts as dropped when, over DROP_WINDOW control periods, fewer than two pads
#: feel it; after the carry, at rest, the wrist sensor must still show MIN_HELD_SHARE of its
#: weight. (The wrist's load while the arm moves is not a drop sensor: the accelerometer at the
#: wrist does not see the hand's rotational accelerations, and on clutter5's third block the
#: estimate of a 0.5 N block fell below 0.15 N over 0.3 s while all four pads held it at 2-5 N.)
DROP_WINDOW = 15
#: Place slots a later cycle tries when the hand cannot set its block down at the first.
MAX_PLACE_SLOTS = 4
#: Time (s) the hand holds still after the carry before the wrist sensor weighs the load.
WEIGH_TIME = 0.3
#: Gravity (m/s^2) for the perceived block's expected weight.
G = 9.81


class TaskFailedError(Exception):
    """A state ends the episode: ``failure`` names the reason, ``detail`` says more."""

    def __init__(self, failure: Failure, detail: str = "") -> None:
        super().__init__(f"{failure.value}: {detail}" if detail else failure.value)
        self.failure = failure
        self.detail = detail


@dataclass(frozen=True)
class Step:
    """A state's result: the next state and why."""

    next: State
    reason: str


Handler = Callable[[Episode], Step]


# --- Select/Model -------------------------------------------------------------------------------
def perceive(ep: Episode) -> None:
    """Render the overhead view and segment it (the scene names label the regions, as a
    simulator's object labels would; the shapes and poses come from the image)."""
    world = ep.world
    with overhead_camera(world) as cam:
        obs = Observation.capture(cam)
    names = {b.name: world.block_pose(b.name)[0][:2] for b in world.scene.blocks}
    ep.selection = analyze(obs, names)


def _on_table(ep: Episode, index: int) -> bool:
    centre = ep.selection.block_centres()[index][:2]
    return bool(ep.world.scene.table.contains(centre[None], margin=0.0))


def _choose_block(ep: Episode) -> int:
    """Index (in the selection) of the block this cycle picks."""
    sel = ep.selection
    opts = ep.options
    if ep.cycle == 0 and opts.pick_pixel is not None:
        return sel.index_at_pixel(opts.pick_pixel)
    if ep.cycle == 0:
        return sel.index_of_name(opts.pick or ep.world.scene.target)
    # later cycles: the remaining block nearest the place point is cleared first
    remaining = [
        i
        for i, name in enumerate(sel.names)
        if name is not None and name not in ep.delivered and _on_table(ep, i)
    ]
    if not remaining:
        raise LookupError("no block left")
    centres = sel.block_centres()[:, :2]
    base = np.asarray(robot_base_xy(ep))
    return min(remaining, key=lambda i: float(np.linalg.norm(centres[i] - base)))


def robot_base_xy(ep: Episode) -> tuple[float, float]:
    body = ep.world.model.body(robot.arm_name("arm_base")).id
    x, y = ep.world.data.xpos[body][:2]
    return float(x), float(y)


#: Horizontal distances (m) from the arm's base a place slot may lie at.
PLACE_REACH = (0.35, 0.95)


def _place_for_cycle(ep: Episode, footprints: list[np.ndarray], radius: float) -> np.ndarray:
    """This cycle's place point: the asked one first, then free slots near it."""
    scene = ep.world.scene
    first = np.asarray(ep.options.place if ep.options.place is not None else scene.place)
    if ep.cycle == 0:
        if not place_is_free(first, radius, footprints, scene.table, ASKED_CLEARANCE):
            raise TaskFailedError(
                Failure.PLACE_UNREACHABLE,
                f"place point {first.round(3).tolist()} is occupied by another block",
            )
        return first
    reach = (robot_base_xy(ep), *PLACE_REACH)
    slot = free_slot(first, radius, footprints, scene.table, reach)
    if slot is None:
        raise TaskFailedError(Failure.PLACE_UNREACHABLE, "no free place slot left on the table")
    return slot


def _other_footprints(ep: Episode, index: int) -> list[np.ndarray]:
    """World footprints of the other blocks on the table as perceived (a block whose polygon
    cannot be extracted counts by its convex region of pixels on the table plane)."""
    out = []
    g = ep.selection.observation.geometry
    picked = ep.model.world_vertices
    centres = ep.selection.block_centres()[:, :2]
    for i, region in enumerate(ep.selection.blocks):
        if i == index or not _on_table(ep, i):
            continue
        if point_in_convex_polygon(centres[i], picked):
            continue  # a fragment of the picked block's own view
        try:
            out.append(ep.selection.model(i).world_vertices)
        except VisionError:
            v, u = np.nonzero(region.top_mask)
            pixels = np.column_stack([u, v]).astype(np.float32)
            hull = cv2.convexHull(pixels).reshape(-1, 2)
            out.append(np.array([g.pixel_to_plane(p, region.z_top)[:2] for p in hull]))
    return out


def select_model(ep: Episode) -> Step:
    """Select/Model: the picked block's polygon, centroid and yaw from the overhead image."""
    record = ep.new_cycle()
    perceive(ep)
    try:
        index = _choose_block(ep)
    except LookupError:
        return Step(State.DONE, "no block left to pick")
    except NotABlockError as e:
        raise TaskFailedError(Failure.NO_BLOCK_AT_PICK, str(e)) from e
    except VisionError as e:
        raise TaskFailedError(Failure.NO_BLOCK_AT_PICK, str(e)) from e
    try:
        model = ep.selection.model(index)
    except VisionError as e:
        raise TaskFailedError(Failure.POLYGON_NOT_MODELLED, str(e)) from e
    name = ep.selection.names[index]
    if name is None:
        raise TaskFailedError(Failure.NO_BLOCK_AT_PICK, "the selected region is not a block")
    record.block = name
    ep.model = model
    world = ep.world
    table_z = world.scene.table.height
    ep.target = ReachTarget.from_object_model(model)
    ep.prism = PerceivedPrism.of(ep.target, table_z)
    ep.planning = planning_model(
        world, name, ep.target.polygon, ep.target.yaw, ep.target.position_xy, ep.target.top_z
    )
    ep.expected_load = model.polygon.area * model.height * WOOD_DENSITY * G
    record.polygon = model.polygon.vertices.round(5).tolist()
    truth = world.scene.block(name)
    true_pos = world.block_pose(name)[0]
    record.polygon_error = {
        "centroid_mm": float(np.linalg.norm(model.centroid[:2] - true_pos[:2]) * 1000),
        "area_percent": float(
            abs(model.polygon.area - truth.polygon.area) / truth.polygon.area * 100
        ),
        "edges": float(model.n_edges),
        "true_edges": float(truth.polygon.n_edges),
    }
    # the place point must be clear of every other perceived block
    footprints = _other_footprints(ep, index)
    radius = float(np.linalg.norm(model.polygon.vertices, axis=1).max())
    ep.place = _place_for_cycle(ep, footprints, radius)
    ep.place_footprints, ep.place_radius = footprints, radius
    record.place = (float(ep.place[0]), float(ep.place[1]))
    ep.others_before = {
        b.name: world.block_pose(b.name)[0] for b in world.scene.blocks if b.name != name
    }
    if ep.recorder is not None:
        ep.recorder.set_target(name)
        ep.recorder.log_vision(
            ep.selection.observation.rgb,
            ep.selection.observation.geometry.K,
            ep.selection.observation.geometry.cam_to_world,
            model.world_vertices,
            model.pixel_contour,
            float(model.centroid[2]),
        )
    return Step(
        State.COARSE_REACH,
        f"picked {name}: {model.n_edges} edges, centroid "
        f"({model.centroid[0]:.3f}, {model.centroid[1]:.3f}) m, "
        f"yaw {np.degrees(model.yaw):.0f} deg; "
        f"place at ({ep.place[0]:.3f}, {ep.place[1]:.3f})",
    )


# --- Coarse Reach -------------------------------------------------------------------------------
def coarse_reach(ep: Episode) -> Step:
    """Coarse Reach: a harmonic path in the arm's c-space to above (top) or beside (lateral)
    the perceived block; the path determines the approach unless one is forced."""
    approaches = APPROACHES if ep.options.approach == "auto" else (ep.options.approach,)
    plan = plan_coarse_reach(ep.world, ep.target, approaches=approaches, model=ep.planning)
    if not plan.found:
        raise TaskFailedError(Failure.NO_COARSE_PATH, plan.reason)
    ep.coarse = plan
    ep.record.approach = plan.approach
    run = execute_path(ep.world, plan.path.path, hand_q=plan.hand_q)
    touched = ", ".join(f"{a}-{b}" for a, b in run.contacts) or "nothing"
    lengths = ", ".join(f"{a} {p.length:.2f} rad" for a, p in plan.candidates.items() if p.found)
    preshape = ""
    if plan.approach == "lateral":
        done = _lateral_preshape(ep)
        preshape = "; " + (done or "no pinch pre-shape (none is approached without collision)")
    return Step(
        State.FINE_REACH,
        f"{plan.approach} approach (paths: {lengths}); touched {touched} on the way{preshape}",
    )


def _palm_pose_search(
    ep: Episode,
    poses: list[PalmPose],
    theta_of,
    *,
    reachable_only: bool,
    skip: int = 0,
):
    """Search the palm ``poses`` (:func:`_lateral_poses`, :func:`_top_poses`) group by group (a
    lateral grasp's palm nearest the block first: the fingers on the far contacts keep room to
    squeeze; at the limit of their reach they push the block along instead) for one from which
    the hand reaches the contacts ``theta_of(pose)`` (the hand IK starting from sampled finger
    postures) and that it approaches without collision (:func:`_approach_plan`); of several in
    one group, the one with the lowest ``HandReach.load``. Without ``reachable_only``, when none
    reaches, the lowest load that approaches. ``skip`` passes over that many acceptable poses
    first (a regrasp tries the next). Returns (qpos, contacts, label, load, approach plan) or
    None."""
    world = ep.world
    hand_adr = HandIndices.of(world.model).finger_qpos.ravel()
    tried = []
    for _, group in itertools.groupby(poses, key=lambda pose: pose.group):
        found = []
        for pose in group:
            contacts, reach = reachable_contacts(
                world,
                ep.prism,
                ep.target,
                theta_of(pose),
                model=ep.planning,
                qpos=pose.qpos,
                tries=LATERAL_TRIES,
                check_spacing=False,
                slide=_slides(ep),
                samples=_finger_samples(ep),
                squeeze=_squeeze_reach(ep),
            )
            qpos = pose.qpos.copy()
            qpos[hand_adr] = reach.hand_q
            found.append((reach.load, qpos, contacts, pose.label))
        found.sort(key=lambda c: c[0])
        for load, qpos, contacts, label in found:
            if load >= 1.0:
                break
            plan = _approach_plan(ep, qpos, contacts)
            if plan is not None:
                if skip == 0:
                    return qpos, contacts, label, load, plan
                skip -= 1
        tried += [c for c in found if c[0] >= 1.0]
    if reachable_only:
        return None
    for load, qpos, contacts, label in sorted(tried, key=lambda c: c[0]):
        plan = _approach_plan(ep, qpos, contacts)
        if plan is not None:
            if skip == 0:
                return qpos, contacts, label, load, plan
            skip -= 1
    return None


#: Side contacts stay this far (m) inside the block's extent along the approach axis.
SIDE_INSET = 0.004


def _side_contacts(ep: Episode, tips: np.ndarray) -> np.ndarray:
    """Contact coordinates (polar angles on the perceived polygon) where lines from the
    approach axis across it, through each fingertip of ``tips`` (4, 3), meet the block's outline
    on the fingertip's side: the side faces a lateral pinch closes on. (The nearest surface point
    of a fingertip in front of the block's near corner is on the near face, where the palm
    pushes against nothing.) A fingertip before or beyond the block along the axis takes the
    block's first or last SIDE_INSET."""
    centre = np.asarray(ep.target.position_xy)
    axis = centre - np.asarray(robot_base_xy(ep))
    axis /= np.linalg.norm(axis)
    across = np.array([-axis[1], axis[0]])
    foot = ep.target.footprint()
    depth = (foot - centre) @ axis
    lo, hi = depth.min() + SIDE_INSET, depth.max() - SIDE_INSET
    edges = np.roll(foot, -1, axis=0) - foot
    theta = np.empty(len(tips))
    for f, tip in enumerate(tips[:, :2]):
        d = float(np.clip((tip - centre) @ axis, lo, hi))
        side = 1.0 if (tip - centre) @ across >= 0.0 else -1.0
        origin, ray = centre + d * axis, side * across
        # the ray leaves the convex outline through exactly one edge
        best = np.inf
        for a, e in zip(foot, edges, strict=True):
            m = np.column_stack([ray, -e])
            if abs(np.linalg.det(m)) < 1e-12:
                continue
            t, u = np.linalg.solve(m, a - origin)
            if t > 0.0 and -1e-9 <= u <= 1.0 + 1e-9:
                best = min(best, t)
        local = origin + best * ray - centre
        theta[f] = np.arctan2(local[1], local[0]) - ep.target.yaw
    return np.mod(theta + np.pi, 2 * np.pi) - np.pi


def _lateral_preshape(ep: Episode, skip: int = 0) -> str | None:
    """The lateral pre-shape: the palm pose beside the block from which the hand best reaches
    the surface points nearest the fingertips of :data:`LATERAL_PINCH` there (kept a pad spacing
    apart; :func:`_palm_pose_search`); the hand pre-shapes outside those points and the palm moves
    there along its approach axis (``skip``: the next pose, :func:`_palm_pose_search`). Returns what
    was done, for the log, or None when no pose is approached without collision."""

    def pinch_contacts(pose: PalmPose) -> np.ndarray:
        tips = fingertips_at(ep.planning, pose.qpos)
        return separate_contacts(
            ep.target.polygon,
            _side_contacts(ep, tips),
            MIN_PAD_SPACING + SEPARATION_MARGIN,
            robot.PAD_RADIUS,
        )

    found = _palm_pose_search(
        ep, _lateral_poses(ep), pinch_contacts, reachable_only=False, skip=skip
    )
    if found is None:
        return None
    _, _, label, load, plan = found
    _approach(ep, *plan)
    return f"pinch pre-shape, {label} (reach load {load:.2f})"


#: Fingertip distances (m) outside the contacts of the hand postures a new arm posture may be
#: approached with, tried in order (a block standing at an angle to the approach axis needs the
#: fingers wider open); at the posture the fingers then close to PRE_CONTACT.
APPROACH_STANDOFFS = (PRE_CONTACT, 0.02, 0.03)


def _approach_plan(ep: Episode, qpos: np.ndarray, contacts) -> tuple[np.ndarray, ...] | None:
    """The arm posture of ``qpos``, a hand posture whose straight approach to it along the palm's
    axis clears the perceived block (:func:`_approach_clear`; the fingertips
    :data:`APPROACH_STANDOFFS` outside their contacts) and the hand's pre-contact posture there
    (PRE_CONTACT outside); None when no approach clears. ``qpos``'s hand takes ``contacts``
    (:func:`_squeeze_reach` inside); the fingers back off from it along their squeeze directions
    (:func:`controllers.grip.backed_off_hand`)."""
    m = ep.world.model
    arm_q = qpos[[m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.ARM_JOINTS]]

    def hand_at(standoff: float) -> np.ndarray:
        # back from the posture that takes the contacts, along the fingers' squeeze directions
        # (a finger reaching round a corner cannot hold its pad facing a point further out)
        return backed_off_hand(ep.planning, qpos, contacts.normals, standoff + _squeeze_reach(ep))

    hand_pre = hand_at(PRE_CONTACT)
    for standoff in APPROACH_STANDOFFS:
        wide = hand_pre if standoff == PRE_CONTACT else hand_at(standoff)
        if _approach_clear(ep, arm_q, wide):
            return arm_q, wide, hand_pre
    return None


def _approach(ep: Episode, arm_q: np.ndarray, wide: np.ndarray, hand_pre: np.ndarray) -> None:
    """:func:`_reposition` with the hand at ``wide``, then the fingers close to ``hand_pre``."""
    _reposition(ep, arm_q, wide)
    if not np.array_equal(wide, hand_pre):
        move_hand(ep.world, hand_pre, PRESHAPE_TIME)


#: The straight approach of a new posture (the last BACKOFF of it) must keep the hand this far
#: (m) from the perceived block and everything else, checked every APPROACH_STEP (m).
APPROACH_CLEARANCE = 0.003
APPROACH_STEP = 0.01


def _approach_clear(ep: Episode, arm_q: np.ndarray, hand_q: np.ndarray) -> bool:
    """Whether the palm's straight approach to ``arm_q`` along the coarse reach's approach axis
    over BACKOFF (as :func:`_reposition` makes it), the hand held at ``hand_q``, stays
    APPROACH_CLEARANCE clear of the perceived world."""
    checker = CollisionChecker(
        ep.world, model=ep.planning, hand_q=hand_q, clearance=APPROACH_CLEARANCE
    )
    p, R = checker.palm_pose(arm_q)
    axis = ep.coarse.goal.palm_rotation[:, 2]  # the approach _reposition takes
    q = np.asarray(arm_q, dtype=float)
    if checker.collides(q):
        return False
    for back in np.arange(APPROACH_STEP, BACKOFF + 1e-9, APPROACH_STEP):
        ik = checker.solve_ik(p - back * axis, R, q)
        if not ik.found or checker.collides(ik.q):
            return False
        q = ik.q
    return True


# --- Fine Reach ---------------------------------------------------------------------------------
def fine_reach_state(ep: Episode) -> Step:
    """Fine Reach: harmonic fields bring each fingertip near its projection on the perceived
    block's surface (a touch guard stops a finger that arrives early)."""
    world = ep.world
    # each fingertip's contact coordinate (its polar angle about the perceived centroid,
    # Appendix B), the contacts kept a pad spacing apart: three fingers projected onto one small
    # face would crowd each other
    tips = world.fingertip_positions()
    local = tips[:, :2] - np.asarray(ep.target.position_xy)
    theta = np.arctan2(local[:, 1], local[:, 0]) - ep.target.yaw
    theta = separate_contacts(
        ep.target.polygon, theta, MIN_PAD_SPACING + SEPARATION_MARGIN, robot.PAD_RADIUS
    )
    spread = contact_targets(ep.target, theta)
    z = np.clip(tips[:, 2], world.scene.table.height + 0.02, ep.target.top_z - GRASP_DEPTH)
    targets = SurfaceTargets(
        np.column_stack([spread.points[:, :2], z]), spread.normals, spread.theta
    )
    result = fine_reach(
        world,
        ep.target_name,
        targets,
        seen=ep.target,
        tolerance=FINE_REACH_TOLERANCE,
        standoff=FINE_REACH_STANDOFF,
        model=ep.planning,
        touchable=PERCEIVED_GEOM,
    )
    worst = float(result.tip_error.max())
    if not result.reached and worst > FINE_REACH_GIVE_UP:
        finger = robot.FINGERS[int(np.argmax(result.tip_error))]
        raise TaskFailedError(
            Failure.FINGERS_CANNOT_REACH,
            f"{finger} stayed {worst * 1000:.0f} mm from its surface point",
        )
    ep.posture_mode = "hold"
    return Step(
        State.POSTURE_CONTROL,
        f"fingertips {np.round(result.tip_error * 1000, 1).tolist()} mm from their targets"
        + (
            f", stopped on touch: {', '.join(result.stopped_on_touch)}"
            if result.stopped_on_touch
            else ""
        ),
    )


# --- Posture Control ----------------------------------------------------------------------------
def _retract(ep: Episode) -> None:
    """Move every fingertip RETRACT straight out from the perceived block's nearest face, and
    again, each time RETRACT further (up to RETRACT_TRIES times in all), while any finger still
    touches the block: a finger left on it (a thumb's middle link pressed on a face, say) would
    drag it, or wedge it against the palm and lift it, when the palm backs away."""
    world = ep.world
    body = world.block_body_id(ep.target_name)
    for k in range(RETRACT_TRIES):
        tips = world.fingertip_positions()
        out = project_to_surface(ep.target, tips, table_z=world.scene.table.height)
        sol = solve_posture(
            world,
            tips + (k + 1) * RETRACT * out.normals,
            optimize=False,
            joints="hand",
            model=ep.planning,
            avoid_collisions=True,
            touchable=PERCEIVED_GEOM,
        )
        move_hand(world, sol.hand_q, RETRACT_TIME)
        if not any(c.finger in robot.FINGERS for c in robot_contacts(world, body)):
            return


def _move_arm_and_hand(ep: Episode, arm_q: np.ndarray, hand_q: np.ndarray) -> None:
    world = ep.world
    a0, h0 = world.arm_targets(), world.hand_targets()
    steps = max(1, round(0.02 / world.model.opt.timestep))
    n = max(1, round(ARM_MOVE_TIME / 0.02))
    for k in range(1, n + 1):
        s = 0.5 - 0.5 * np.cos(np.pi * k / n)
        world.set_arm_targets(a0 + s * (arm_q - a0))
        world.set_hand_targets(h0 + s * (hand_q - h0))
        world.step(steps)
    world.step(round(0.3 / world.model.opt.timestep))


def _reposition(ep: Episode, arm_q: np.ndarray, hand_q: np.ndarray) -> None:
    """Take the arm and hand to a new posture near the block without sweeping a finger through
    it: retract the fingers, back the palm out along the approach by BACKOFF, move the arm to the
    new posture backed out likewise (on a harmonic path), shape the hand there, and approach in a
    straight line."""
    world = ep.world
    checker = CollisionChecker(world, model=ep.planning)
    _retract(ep)
    # out and back in along the coarse reach's approach (straight up for a top grasp, along the
    # arm's radius for a lateral one), whatever tilt Posture Control gave the palm: the fingers
    # then slide along the block's faces, not into them
    axis = ep.coarse.goal.palm_rotation[:, 2]
    move_palm(world, checker, -BACKOFF * axis, BACKOFF_TIME)
    p_new, R_new = checker.palm_pose(arm_q)
    raised = checker.solve_ik(p_new - BACKOFF * axis, R_new, arm_q)
    if not raised.found:
        raise ReachError("the new arm posture cannot be approached along the hand's axis")
    # the arm moves on a collision-free harmonic path (the hand keeps its retracted shape)
    mover = CollisionChecker(
        world, model=ep.planning, hand_q=world.hand_qpos(), clearance=REPOSITION_CLEARANCE
    )
    path = plan_arm_path(mover, world.arm_qpos(), raised.q)
    if path.found:
        execute_path(world, path.path, settle=0.2)
    else:  # e.g. the backed-out hand already grazes a neighbour: straight there, in joint space
        _move_arm_and_hand(ep, raised.q, world.hand_targets())
    move_hand(world, hand_q, PRESHAPE_TIME)  # then opens, clear of the block
    move_palm(world, checker, BACKOFF * axis, BACKOFF_TIME)
    if not _slides(ep):
        return
    # lateral: the arm lags its targets and its servos sag under the hand's weight, which moves
    # a horizontal finger row off its faces: let it settle and take out the steady-state error,
    # as apply_posture does (a top grasp's fingers close from above and do not need it; it costs
    # 1.5 s of simulated time)
    settle = round(SETTLE_TIME / world.model.opt.timestep)
    world.step(settle)
    for _ in range(SERVO_CORRECTIONS):
        world.set_arm_targets(world.arm_targets() + arm_q - world.arm_qpos())
        world.step(settle)


def posture_control(ep: Episode) -> Step:
    """Posture Control (Grupen & Souccar, ref. [16]): the arm and hand reconfigure to maximise
    the hand's manipulability, holding the fingertips (after Fine Reach) or bringing the current
    virtual contacts within the fingers' reach (from Wrench Closure), never touching anything
    but the block's surface with the pads (collision avoidance in the perceived world)."""
    world = ep.world
    if ep.posture_mode == "hold":
        sol = solve_posture(
            world,
            model=ep.planning,
            avoid_collisions=True,
            touchable=PERCEIVED_GEOM,
        )
        before = world.fingertip_positions()
        if sol.reachable:
            apply_posture(world, sol)
        drift = float(np.linalg.norm(world.fingertip_positions() - before, axis=1).max())
        gain = sol.log_manipulability_end - sol.log_manipulability_start
        if drift > POSTURE_DRIFT and ep.record.fine_reach_loops < MAX_FINE_REACH_LOOPS:
            ep.record.fine_reach_loops += 1
            return Step(State.FINE_REACH, f"fingertips drifted {drift * 1000:.1f} mm")
        return Step(
            State.WRENCH_CLOSURE,
            f"manipulability log M +{gain:.2f}, tips held within {drift * 1000:.1f} mm",
        )
    # contacts mode: make the virtual contacts reachable, trying the wrist roll in steps
    if ep.record.posture_retries > MAX_POSTURE_RETRIES:
        return _regrasp_or_fail(ep)
    found = _reachable_posture(ep)
    if found is None:
        if ep.record.posture_retries >= MAX_POSTURE_RETRIES:
            return _regrasp_or_fail(ep)
        return Step(State.WRENCH_CLOSURE, "no arm posture reaches the contacts yet")
    qpos, contacts, label, plan = found
    ep.contacts = contacts
    if plan is None and _slides(ep):
        plan = _approach_plan(ep, qpos, contacts)
    if plan is not None:
        _approach(ep, *plan)
    else:
        m = world.model
        arm_q = qpos[[m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.ARM_JOINTS]]
        pre, pre_pads = grip_targets(contacts.points, contacts.normals, -PRE_CONTACT)
        hand_pre = solve_posture(
            world,
            pre,
            optimize=False,
            joints="hand",
            model=ep.planning,
            pad_centres=pre_pads,
            qpos=qpos,
        ).hand_q
        _reposition(ep, arm_q, hand_pre)
    return Step(
        State.WRENCH_CLOSURE,
        f"arm reconfigured (search from {label}) so that the contacts are within reach",
    )


#: Wrist-roll offsets (rad) Posture Control starts its search from, in order: the arm's own
#: differential IK finds the nearest posture, which may keep a finger on the wrong side.
ROLL_SEEDS = tuple(np.deg2rad([0, 45, -45, 90, -90, 180]))
#: Posture Control may tilt the palm's approach axis this far (rad) from the coarse reach's, per
#: approach: a hand tilted further grips a block standing on the table at an angle.
MAX_PALM_TILT = {"top": np.deg2rad(12.0), "lateral": np.deg2rad(35.0)}


def _regrasp_or_fail(
    ep: Episode, reason: str | None = None, failure: Failure = Failure.CONTACT_UNREACHABLE
) -> Step:
    """After MAX_POSTURE_RETRIES the contacts stay out of reach (or, from Grasp Object, a finger
    missed the block as the hand closed): start again from Fine Reach with
    the hand turned (top grasp: the wrist rolled by the next of REGRASP_ROLLS) or moved (lateral:
    the pinch pre-shape at the next palm pose beside the block, :func:`_lateral_preshape`), so
    the grasp controller starts from other contacts; after MAX_REGRASPS, fail with ``failure``
    and the reason."""
    record = ep.record
    if reason is None:
        reason = ep.reach.reason if ep.reach is not None else "unreachable"
    if record.regrasps >= MAX_REGRASPS:
        raise TaskFailedError(
            failure,
            f"after {MAX_REGRASPS} regrasps and {record.posture_retries} posture retries: {reason}",
        )
    if _slides(ep):
        # lateral: the pinch pre-shape at the next palm pose beside the block
        record.regrasps += 1
        done = _lateral_preshape(ep, skip=record.regrasps)
        if done is None:
            raise TaskFailedError(
                Failure.CONTACT_UNREACHABLE, f"{reason}; no other palm pose to regrasp from"
            )
        record.posture_retries = 0
        ep.synthesis = ep.contacts = ep.reach = None
        return Step(State.FINE_REACH, f"regrasp ({reason}): {done}")
    world = ep.world
    checker = CollisionChecker(world, model=ep.planning)
    arm_now = world.arm_targets()
    # back to the coarse reach's goal (the hand hovering in its pre-shape), turned or moved
    p, R = ep.coarse.goal.palm_position, ep.coarse.goal.palm_rotation
    seed = arm_now.copy()
    roll = REGRASP_ROLLS[record.regrasps]
    c, s = np.cos(roll), np.sin(roll)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    goal_p, goal_R = p, turn @ R
    seed[-1] += roll
    how = f"wrist turned {np.degrees(roll):+.0f} deg"
    ik = checker.solve_ik(goal_p - BACKOFF * goal_R[:, 2], goal_R, seed)
    record.regrasps += 1
    if not ik.found:  # the other way round
        goal_R = goal_R @ np.diag([-1.0, -1.0, 1.0])
        seed[-1] += np.pi if seed[-1] < 0 else -np.pi
        ik = checker.solve_ik(goal_p - BACKOFF * goal_R[:, 2], goal_R, seed)
    if not ik.found:
        raise TaskFailedError(Failure.CONTACT_UNREACHABLE, f"{reason}; cannot regrasp ({how})")
    back = checker.solve_ik(goal_p, goal_R, ik.q)
    _reposition(ep, back.q if back.found else ik.q, np.asarray(ep.coarse.hand_q))
    record.posture_retries = 0
    ep.synthesis = ep.contacts = ep.reach = None
    return Step(State.FINE_REACH, f"regrasp ({reason}) with the {how}")


#: Regrasps after the contacts stay out of reach, and how a top grasp's hand is turned for each.
#: Four, not two: over random scenes 0-29 (pi) the third and fourth regrasps delivered the three
#: episodes whose contacts stayed out of reach after two (two hexagons, a pentagon; 27 -> 30 of 30
#: on those seeds, at 100-190 s of wall time each).
MAX_REGRASPS = 4
REGRASP_ROLLS = (np.pi / 4, -np.pi / 4, np.pi / 2, -np.pi / 2)


def _palm_tilt(ep: Episode, arm_q: np.ndarray) -> float:
    """Angle (rad) between the palm's approach axis at ``arm_q`` and the coarse reach's."""
    checker = CollisionChecker(ep.world, model=ep.planning)
    _, R = checker.palm_pose(arm_q)
    goal = ep.coarse.goal.palm_rotation[:, 2]
    return float(np.arccos(np.clip(R[:, 2] @ goal, -1.0, 1.0)))


def _posture_seeds(ep: Episode) -> list[tuple[str, np.ndarray]]:
    """Start configurations of a top grasp's Posture Control search, with a label: the wrist
    roll in steps (the arm's differential IK finds the nearest posture, which may keep a finger
    on the wrong side of the block)."""
    world = ep.world
    m = world.model
    roll_j = m.joint(robot.qualified("wrist_roll")).id
    roll_adr = m.jnt_qposadr[roll_j]
    lo, hi = m.jnt_range[roll_j]
    seeds = []
    for roll in ROLL_SEEDS:
        seed = world.data.qpos.copy()
        seed[roll_adr] = np.clip(seed[roll_adr] + roll, lo, hi)
        seeds.append((f"wrist roll {np.degrees(roll):+.0f} deg", seed))
    return seeds


@dataclass(frozen=True)
class PalmPose:
    """A palm pose a Posture Control search tries (:func:`_palm_pose_search`): the
    configuration (qpos), its group (poses are tried group by group, in order: a lateral pose's
    palm-block distance in m, a top pose's 0 where the palm is and 1 shifted) and a label."""

    qpos: np.ndarray
    group: float
    label: str


def _lateral_poses(ep: Episode) -> list[PalmPose]:
    """Palm poses beside the perceived block: the approach axis horizontal and radial (the arm
    has five joints), hand y up as the coarse reach put it, turned LATERAL_ROLLS about the axis,
    the palm face LATERAL_GAPS from the block's nearest point along the axis, at the coarse
    reach's height, LATERAL_SHIFTS aside; in order of the gap."""
    world = ep.world
    m = world.model
    hand_adr = HandIndices.of(m).finger_qpos.ravel()
    checker = CollisionChecker(world, model=ep.planning)
    arm_adr = [m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.ARM_JOINTS]
    q_arm = world.data.qpos[arm_adr]
    base = np.asarray(robot_base_xy(ep))
    centre = np.array([*ep.target.position_xy, ep.target.top_z - LATERAL_DEPTH])
    axis = np.array([*(centre[:2] - base), 0.0])
    axis /= np.linalg.norm(axis)
    up = np.array([0.0, 0.0, np.sign(ep.coarse.goal.palm_rotation[2, 1]) or 1.0])
    near = float(((ep.target.footprint() - centre[:2]) @ axis[:2]).min())
    poses = []
    for gap in LATERAL_GAPS:
        for roll in LATERAL_ROLLS:
            for shift in LATERAL_SHIFTS:
                palm = centre + (near - gap) * axis + shift * np.cross(up, axis)
                # the approach axis through the shifted palm is radial, as the arm has it
                radial = np.array([*(palm[:2] - base), 0.0])
                radial /= np.linalg.norm(radial)
                y = np.cos(roll) * up + np.sin(roll) * np.cross(up, radial)
                rot = np.column_stack([np.cross(y, radial), y, radial])
                arm = checker.solve_ik(palm, rot, q_arm)
                if not arm.found:
                    continue
                qpos = world.data.qpos.copy()
                qpos[arm_adr] = arm.q
                qpos[hand_adr] = np.asarray(LATERAL_PINCH)
                label = (
                    f"palm {gap * 100:.1f} cm from the block, {shift * 100:+.1f} cm aside, "
                    f"rolled {np.degrees(roll):+.0f} deg"
                )
                poses.append(PalmPose(qpos, gap, label))
    return poses


#: A lateral pinch of the hand (ff, mf, rf, th; abduction, MCP, PIP, DIP, rad):
#: ``benchmarks.hand_reachability``'s best lateral grasp of the rectangle (S_G 0.002; 3000 hand
#: samples, seed 0): first and middle finger on one long face, ring finger and thumb on the other.
LATERAL_PINCH = (
    -0.61, 1.56, 0.87, 0.14,
    -0.69, 0.48, 1.53, 0.32,
    0.64, 1.05, 1.31, 0.18,
    -0.82, 0.55, 0.61, 1.15,
)  # fmt: skip
#: Lateral palm poses (:func:`_lateral_poses`): the approach axis horizontal and radial, the palm
#: face LATERAL_GAPS (m) from the perceived block's nearest point along it, at the coarse reach's
#: height (LATERAL_DEPTH below the top), LATERAL_SHIFTS (m) aside and hand y turned LATERAL_ROLLS
#: (rad) from vertical about the approach axis (a roll moves the middle finger and the thumb off
#: the block's centre line, towards the faces they take).
LATERAL_GAPS = (0.03, 0.035, 0.04)
LATERAL_ROLLS = tuple(np.deg2rad([0.0, 10.0, -10.0]))
LATERAL_SHIFTS = (0.0, -0.008, 0.008)


def _slides(ep: Episode) -> bool:
    """Whether the contacts may slide up and down their faces: in a lateral grasp the finger row
    is horizontal and the thumb below it, so the hand's shape, not a depth below the top, sets
    each finger's height on the block (a top grasp keeps its fingers at the depth they reached)."""
    return ep.coarse is not None and ep.coarse.approach == "lateral"


def _finger_samples(ep: Episode) -> FingerSamples:
    """Sampled finger postures, IK starts for a palm-pose search (drawn once an episode)."""
    if ep.finger_samples is None:
        ep.finger_samples = FingerSamples.draw(pad_normal_local=PAD_NORMAL_LOCAL)
    return ep.finger_samples


def _samples(ep: Episode) -> FingerSamples | None:
    """The sampled finger postures lateral reachability starts from."""
    return _finger_samples(ep) if _slides(ep) else None


#: How far (m) past its contact a lateral grasp's fingertip must reach (SQUEEZE_REACH for a top
#: grasp). A lateral squeeze runs along each finger's normal-squeeze direction, past the inside
#: posture by extrapolation (controllers.grip.plan_grip, along_normal), so the reach only has to
#: show that the pad gets into the face. Chosen by looking at the result: on single_rectangle
#: --approach lateral --controller kb, seeds 0-9, 8 of 10 delivered with 4 mm, 5 of 10 with
#: SQUEEZE_REACH's 6 mm (the fingers on the far contacts cannot reach 6 mm into the face).
LATERAL_SQUEEZE_REACH = 0.004


def _squeeze_reach(ep: Episode) -> float:
    """How far past its contact each fingertip must reach in this cycle's grasp."""
    return LATERAL_SQUEEZE_REACH if _slides(ep) else SQUEEZE_REACH


#: Assignments of contacts to fingers a lateral Posture Control search checks per palm pose.
LATERAL_TRIES = 2


def _posture_among(ep: Episode, poses: list[PalmPose]):
    """A palm pose of ``poses`` from which the hand reaches the current contacts
    (:func:`_palm_pose_search`): (qpos, contacts, label, approach plan) or None."""
    theta = ep.synthesis.theta
    found = _palm_pose_search(ep, poses, lambda pose: theta, reachable_only=True)
    return None if found is None else (*found[:3], found[4])


def _reachable_posture(ep: Episode):
    """An arm and hand configuration (qpos) from which the current contacts are reachable, with
    the contacts given to the fingers, the search's label and the approach plan
    (:func:`_approach_plan`, None when the arm's own IK found the posture); None if none is.
    A top grasp first follows the arm's IK from wrist-roll seeds, then, when that finds nothing,
    searches :func:`_top_poses` with sampled finger postures as IK starts. Over random scenes
    0-29 (3-5 blocks, pi) the palm-pose search took the episodes delivered from 25 to 26."""
    if _slides(ep):
        return _posture_among(ep, _lateral_poses(ep))
    found = _roll_seed_posture(ep)
    if found is not None:
        return (*found, None)
    # the arm's differential IK from the roll seeds found nothing: search palm poses above the
    # block, the fingers' IK starting from sampled postures (as a lateral grasp does)
    return _posture_among(ep, _top_poses(ep))


#: A top grasp's palm poses (:func:`_top_poses`): the hand turned about the vertical through the
#: perceived block's centroid by TOP_ROLLS (rad) from where it is, and moved TOP_SHIFT (m) along
#: the world's x and y.
TOP_ROLLS = tuple(np.deg2rad(np.arange(0.0, 360.0, 30.0)))
TOP_SHIFT = 0.008


def _top_poses(ep: Episode) -> list[PalmPose]:
    """Palm poses above the perceived block for a top grasp's Posture Control: the palm level
    (the coarse reach's orientation) at its present height, turned TOP_ROLLS about the vertical
    through the block's centroid, first where it is (``group`` 0), then TOP_SHIFT aside (``group``
    1); the hand in its present shape."""
    world = ep.world
    m = world.model
    checker = CollisionChecker(world, model=ep.planning)
    arm_adr = [m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.ARM_JOINTS]
    roll_j = m.joint(robot.qualified("wrist_roll")).id
    lo, hi = m.jnt_range[roll_j]
    q_arm = world.data.qpos[arm_adr]
    p, _ = checker.palm_pose(q_arm)
    R0 = ep.coarse.goal.palm_rotation
    centre = np.asarray(ep.target.position_xy, dtype=float)
    shifts = [(0, np.zeros(2))] + [
        (1, TOP_SHIFT * np.array(d)) for d in ((1, 0), (-1, 0), (0, 1), (0, -1))
    ]
    poses = []
    for gap, shift in shifts:
        for roll in TOP_ROLLS:
            c, s = np.cos(roll), np.sin(roll)
            turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            palm = p.copy()
            palm[:2] = centre + turn[:2, :2] @ (p[:2] - centre) + shift
            seed = q_arm.copy()
            seed[-1] = np.mod(seed[-1] + roll - lo, 2 * np.pi) + lo
            if seed[-1] > hi:
                seed[-1] -= 2 * np.pi
            arm = checker.solve_ik(palm, turn @ R0, seed)
            if not arm.found:
                continue
            qpos = world.data.qpos.copy()
            qpos[arm_adr] = arm.q
            label = f"palm turned {np.degrees(roll):+.0f} deg about the block" + (
                f", moved {shift[0] * 1000:+.0f}, {shift[1] * 1000:+.0f} mm" if gap else ""
            )
            poses.append(PalmPose(qpos, float(gap), label))
    return poses


def _roll_seed_posture(ep: Episode):
    """A top grasp's first search: the arm and hand IK from each of :func:`_posture_seeds`."""
    world = ep.world
    m = world.model
    arm_adr = [m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.ARM_JOINTS]
    hand_adr = HandIndices.of(m).finger_qpos.ravel()
    for label, seed in _posture_seeds(ep):
        contacts, _ = reachable_contacts(
            world,
            ep.prism,
            ep.target,
            ep.synthesis.theta,
            model=ep.planning,
            qpos=seed,
            tries=1,
        )
        tips, centres = grip_targets(contacts.points, contacts.normals)
        sol = solve_posture(
            world,
            tips,
            joints="arm+hand",
            model=ep.planning,
            avoid_collisions=True,
            touchable=PERCEIVED_GEOM,
            fingers_may_touch=True,
            pad_centres=centres,
            qpos=seed,
        )
        if not sol.reachable:
            continue
        if _palm_tilt(ep, sol.arm_q) > MAX_PALM_TILT[ep.coarse.approach]:
            continue
        qpos = seed.copy()
        qpos[arm_adr] = sol.arm_q
        qpos[hand_adr] = sol.hand_q
        contacts, reach = reachable_contacts(
            world,
            ep.prism,
            ep.target,
            ep.synthesis.theta,
            model=ep.planning,
            qpos=qpos,
            check_spacing=False,
        )
        if reach.reachable:
            return qpos, contacts, label
    return None


# --- Wrench Closure -----------------------------------------------------------------------------
def wrench_closure(ep: Episode) -> Step:
    """Wrench Closure: the grasp controller (kb, ql or pi) moves virtual contacts on the
    perceived polygon from the fingertips' projections until it converges; every
    REACH_CHECK_EVERY steps the hand's reachability of the contacts is checked and an unreachable
    set sends the machine back to Posture Control."""
    world = ep.world
    table_z = world.scene.table.height
    record = ep.record
    if ep.synthesis is None:
        start = project_to_surface(ep.target, world.fingertip_positions(), table_z=table_z)
        ep.synthesis = GraspSynthesis(
            ep.target.polygon,
            ep.composer,
            start.theta,
            ep.rng,
            min_separation=MIN_PAD_SPACING + SEPARATION_MARGIN,
            separation_offset=robot.PAD_RADIUS,
        )
    syn = ep.synthesis
    while True:
        if not syn.done:
            step = syn.step()
            record.synthesis_steps = syn.steps
            if ep.recorder is not None:
                fc_world = _contact_points(ep, syn.theta)
                ep.recorder.log_synthesis(
                    step.step, step.eps_fc, step.eps_mc, step.predicted_failure, fc_world
                )
            if syn.steps % REACH_CHECK_EVERY and not syn.done:
                continue
        contacts, reach = reachable_contacts(
            world,
            ep.prism,
            ep.target,
            syn.theta,
            model=ep.planning,
            check_spacing=syn.done,
            slide=_slides(ep),
            samples=_samples(ep),
            squeeze=_squeeze_reach(ep),
        )
        ep.contacts, ep.reach = contacts, reach
        if syn.done and reach.min_spacing < MIN_PAD_SPACING:
            raise TaskFailedError(Failure.CONTACT_UNREACHABLE, reach.reason)
        if ep.recorder is not None:
            ep.recorder.log_reachability(record.posture_retries, reach.reachable, reach.reason)
        if not reach.reachable:
            record.reach_reasons.append(reach.reason)
            record.posture_retries += 1
            ep.posture_mode = "contacts"
            return Step(State.POSTURE_CONTROL, f"step {syn.steps}: {reach.reason}")
        if syn.done:
            break
    score = syn.finish()
    record.converged = syn.converged
    record.s_g = float(score.s_g) if score.feasible else None
    record.contacts = ep.contacts.points.round(5).tolist()
    record.contact_theta = ep.contacts.theta.round(5).tolist()
    if not syn.converged:
        raise TaskFailedError(
            Failure.GRASP_NOT_CONVERGED, f"contacts still moving after {syn.steps} steps"
        )
    if not score.success:
        what = f"S_G {score.s_g:.3f} > 0.4" if score.feasible else "no feasible grasp (S_G LP)"
        raise TaskFailedError(Failure.GRASP_NOT_CONVERGED, f"converged to a weak grasp: {what}")
    return Step(
        State.GRASP_OBJECT,
        f"converged in {syn.steps} steps, S_G {score.s_g:.3f}, reachable "
        f"(pads {np.degrees(ep.reach.pad_angle).round(0).tolist()} deg off their faces)",
    )


#: A lateral pre-shape moves the fingertips to their pre-contact positions along straight lines
#: in PRESHAPE_WAYPOINTS steps, each a hand IK with collision avoidance.
PRESHAPE_WAYPOINTS = 10
PRESHAPE_IK_ITERATIONS = 40


def _preshape(ep: Episode, q_pre: np.ndarray) -> None:
    """Pre-shape the hand to ``q_pre`` for closing. In a lateral grasp the middle finger and the
    thumb reach round the block's near corners, and a straight line in joint space from where
    the fingers retracted to cuts through a corner: there the fingertips and pad centres move
    along straight lines to where ``q_pre`` puts them, through PRESHAPE_WAYPOINTS hand IK
    solutions that keep every link clear of the perceived block (collision avoidance), and the
    hand then settles on ``q_pre``."""
    world = ep.world
    if _slides(ep):
        m = ep.planning
        tip_sites = [m.site(robot.qualified(s)).id for s in robot.FINGERTIP_SITES]
        pad_sites = [m.site(robot.qualified(s)).id for s in robot.PAD_CENTRE_SITES]
        hand_adr = HandIndices.of(m).finger_qpos.ravel()
        data = mujoco.MjData(m)
        data.qpos[:] = world.data.qpos
        data.qpos[hand_adr] = q_pre
        mujoco.mj_kinematics(m, data)
        tips1, pads1 = data.site_xpos[tip_sites].copy(), data.site_xpos[pad_sites].copy()
        qpos = world.data.qpos.copy()
        qpos[hand_adr] = world.hand_targets()
        data.qpos[:] = qpos
        mujoco.mj_kinematics(m, data)
        tips0, pads0 = data.site_xpos[tip_sites].copy(), data.site_xpos[pad_sites].copy()
        for k in range(1, PRESHAPE_WAYPOINTS + 1):
            s = k / PRESHAPE_WAYPOINTS
            sol = solve_posture(
                world,
                tips0 + s * (tips1 - tips0),
                optimize=False,
                joints="hand",
                model=m,
                avoid_collisions=True,
                pad_centres=pads0 + s * (pads1 - pads0),
                qpos=qpos,
                reach_iterations=PRESHAPE_IK_ITERATIONS,
            )
            qpos[hand_adr] = sol.hand_q
            move_hand(world, sol.hand_q, PRESHAPE_TIME / PRESHAPE_WAYPOINTS)
    move_hand(world, q_pre, PRESHAPE_TIME)


def _contact_points(ep: Episode, theta: np.ndarray) -> np.ndarray:
    """World points (n, 3) of contacts ``theta`` on the perceived polygon, at the top's height
    less 3 cm (for drawing)."""
    frames = ep.target.polygon.locate(theta)
    xy = place_polygon(frames.point, ep.target.position_xy, ep.target.yaw)
    return np.column_stack([xy, np.full(len(xy), ep.target.top_z - 0.03)])


# --- Grasp Object -------------------------------------------------------------------------------
def grasp_object(ep: Episode) -> Step:
    """Grasp Object: the fingers go from their approach posture to the synthesized contacts,
    each stopping when its pad feels the block, then squeeze to the grip force."""
    world = ep.world
    contacts = ep.contacts
    unit = ep.target.polygon.unit_moment()
    frames = unit.locate(contacts.theta)
    shares = grasp_score(frames.point, frames.normal).normal_forces
    grip_force = GRIP_FORCE
    if _slides(ep):
        # the fingers' heights differ (the middle finger high, the thumb low): squeeze without
        # tipping the block, no finger harder than GRIP_FORCE
        shares = balanced_shares(contacts.points, contacts.normals, shares)
        grip_force = GRIP_FORCE * float(shares.mean() / shares.max())
    _retract(ep)
    world.step(round(0.2 / world.model.opt.timestep))
    ep.empty_hand_force = world.wrist_wrench()[0]
    ep.grip = plan_grip(
        world,
        contacts.points,
        contacts.normals,
        shares,
        grip_force=grip_force,
        model=ep.planning,
        prism=ep.prism,
        along_normal=_slides(ep),
        # lateral: from the posture the reachability check found (a local IK from the retracted
        # hand may turn a pad that reaches round a corner onto its side)
        start=ep.reach.hand_q if _slides(ep) else None,
        squeeze_reach=_squeeze_reach(ep),
    )
    _preshape(ep, ep.grip.q_pre)
    closing = close(world, ep.grip)
    if not closing.all_touched:
        missing = [f for f, t in zip(robot.FINGERS, closing.touched, strict=True) if not t]
        # open to the approach posture and regrasp (the fingers that touched only stopped there)
        move_hand(world, ep.grip.q_pre, PRESHAPE_TIME)
        return _regrasp_or_fail(
            ep, f"{', '.join(missing)} did not touch the block", Failure.FINGERS_CANNOT_REACH
        )
    result = squeeze(world, ep.grip)
    ep.record.grip_forces = result.touch.round(3).tolist()
    ep.record.grip_target = result.target.round(3).tolist()
    if not result.settled:
        weak = [
            f"{f} {t:.1f} N"
            for f, t, g in zip(robot.FINGERS, result.touch, result.target, strict=True)
            if t < 0.5 * g
        ]
        move_hand(world, ep.grip.q_pre, PRESHAPE_TIME)  # open, and regrasp
        return _regrasp_or_fail(
            ep,
            f"the squeeze did not reach the grip force ({', '.join(weak) or 'unsettled'} of "
            f"{result.target.mean():.1f} N)",
            Failure.FINGERS_CANNOT_REACH,
        )
    return Step(
        State.DELIVER,
        f"all four pads touch; squeezed to {np.round(result.touch, 1).tolist()} N "
        f"(mean target {result.target.mean():.1f} N)",
    )


# --- Deliver ------------------------------------------------------------------------------------
class _DroppedError(Exception):
    pass


def deliver(ep: Episode) -> Step:
    """Deliver: lift, carry along a harmonic path planned with the block in the hand, lower
    until the table takes the weight (wrist sensor), release along the contact normals, retreat;
    then judge the placement physically."""
    world = ep.world
    name = ep.target_name
    record = ep.record
    checker = CollisionChecker(world)
    table_z = world.scene.table.height
    half = 0.5 * world.scene.block(name).height  # to measure clearance (judging only)
    log = ep.recorder.log_transition if ep.recorder is not None else (lambda *a, **k: None)

    def clearance_now(w) -> float:
        return float(w.block_pose(name)[0][2] - half - table_z)

    lifted = lift(world, checker, name, ep.grip)
    record.lift_height = float(lifted.block_rise)
    record.lift_slip = float(lifted.slip)
    record.lift_clearance = max(record.lift_clearance, clearance_now(world))
    load = held_load(world, ep.empty_hand_force)
    lost = world.touch() <= 0.0
    if _slides(ep):
        # a balanced lateral squeeze holds with two opposed pads; the others only touch lightly
        # (balanced_shares) and may let go as the block settles in the grip
        lost &= ep.grip.forces >= CARRYING_SHARE * ep.grip.forces.mean()
    if load < MIN_HELD_SHARE * ep.expected_load or lost.sum() > 1:
        raise TaskFailedError(
            Failure.SLIPPED_DURING_LIFT,
            f"the hand holds {load:.2f} N of an expected {ep.expected_load:.2f} N; "
            f"touch {np.round(world.touch(), 2).tolist()} N",
        )
    log(
        State.DELIVER.value,
        State.DELIVER.value,
        f"lifted: block rose {lifted.block_rise * 100:.1f} cm",
    )
    plan = plan_delivery(world, name, ep.place, block_height=ep.model.height)
    tried = [np.asarray(ep.place, dtype=float)]
    # a place the user did not ask for (a later cycle's slot, or the scene's place point) may be
    # free for the block but not for the hand around it: take the next free slot
    chosen = ep.cycle > 0 or (ep.options.place is None and ep.options.place_pixel is None)
    while not plan.found and chosen and len(tried) < MAX_PLACE_SLOTS:
        taken = [t + 0.001 * np.array([[1.0, 0.0], [-0.5, 0.87], [-0.5, -0.87]]) for t in tried]
        slot = free_slot(
            tried[0],
            ep.place_radius,
            [*ep.place_footprints, *taken],
            world.scene.table,
            (robot_base_xy(ep), PLACE_REACH[0], PLACE_REACH[1]),
        )
        if slot is None:
            break
        log(
            State.DELIVER.value,
            State.DELIVER.value,
            f"place slot {tried[-1].round(3).tolist()}: {plan.reason}; trying "
            f"{slot.round(3).tolist()}",
        )
        ep.place = slot
        record.place = (float(slot[0]), float(slot[1]))
        tried.append(slot)
        plan = plan_delivery(world, name, ep.place, block_height=ep.model.height)
    if not plan.found:
        raise TaskFailedError(Failure.PLACE_UNREACHABLE, plan.reason)

    lost: deque[bool] = deque(maxlen=DROP_WINDOW)

    def watch(w) -> None:
        """Sensed, not judged: the pads (the wrist is weighed at rest, after the carry)."""
        record.lift_clearance = max(record.lift_clearance, clearance_now(w))
        lost.append(int((w.touch() > 0.0).sum()) < 2)
        if len(lost) == DROP_WINDOW and all(lost):
            raise _DroppedError

    try:
        carry(world, plan.path, ep.grip, on_period=watch)
    except _DroppedError as e:
        raise TaskFailedError(
            Failure.DROPPED_IN_TRANSPORT,
            f"fewer than two pads have felt the block since t = "
            f"{world.time - DROP_WINDOW * CONTROL_PERIOD:.2f} s",
        ) from e
    world.step(round(WEIGH_TIME / world.model.opt.timestep))
    load = held_load(world, ep.empty_hand_force)
    if load < MIN_HELD_SHARE * ep.expected_load:
        raise TaskFailedError(
            Failure.DROPPED_IN_TRANSPORT,
            f"after the carry the hand holds {load:.2f} N of an expected "
            f"{ep.expected_load:.2f} N (wrist sensor, at rest)",
        )
    log(State.DELIVER.value, State.DELIVER.value, "carried to the place point; lowering")
    down = lower_until_supported(world, checker, ep.grip, ep.empty_hand_force)
    if not down.supported:
        raise TaskFailedError(
            Failure.SET_DOWN_NOT_SENSED,
            f"lowered {down.lowered * 100:.1f} cm; the hand still holds {down.load_after:.2f} N",
        )
    release(world, ep.grip)
    retreat(world, checker)
    world.step(round(0.5 / world.model.opt.timestep))
    verdict = judge(world, name, ep.place, record.lift_clearance, ep.others_before)
    record.judgement = {
        "place_error_mm": verdict.place_error_mm,
        "tilt_deg": verdict.tilt_deg,
        "speed_m_s": verdict.speed,
        "spin_rad_s": verdict.spin,
        "lift_clearance_m": verdict.lift_clearance,
        "finger_contact": verdict.finger_contact,
        "palm_distance_m": verdict.palm_distance,
        "other_blocks_moved_m": verdict.other_motion,
        "final_position": verdict.final_position.round(5).tolist(),
        "final_quat_wxyz": verdict.final_quat.round(5).tolist(),
        "reasons": list(verdict.reasons),
    }
    if not verdict.success:
        raise TaskFailedError(Failure.NOT_PLACED, "; ".join(verdict.reasons))
    record.success = True
    ep.delivered.append(name)
    summary = (
        f"{name} placed {verdict.place_error_mm:.1f} mm from the place point, "
        f"tilt {verdict.tilt_deg:.1f} deg"
    )
    cycles = ep.options.cycles
    if cycles is None or len(ep.cycles) < cycles:
        ep.cycle += 1
        return Step(State.SELECT_MODEL, summary + "; next block")
    return Step(State.DONE, summary)


HANDLERS: dict[State, Handler] = {
    State.SELECT_MODEL: select_model,
    State.COARSE_REACH: coarse_reach,
    State.FINE_REACH: fine_reach_state,
    State.POSTURE_CONTROL: posture_control,
    State.WRENCH_CLOSURE: wrench_closure,
    State.GRASP_OBJECT: grasp_object,
    State.DELIVER: deliver,
}
