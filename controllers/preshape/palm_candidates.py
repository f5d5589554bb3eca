"""Candidate palm poses and IK seeds for Posture Control's search (section 5.2, Posture
Control: the arm reconfigures so that the virtual contacts come within the fingers' reach).

Each generator takes the world, the planning model and the perceived block explicitly and
returns configurations to start from; :mod:`controllers.preshape.palm_search` searches them:
- :func:`lateral_poses`: palm poses beside the block (a lateral grasp), with a pinch pre-shape;
- :func:`top_poses`: palm poses above the block, turned about it and shifted (a top grasp);
- :func:`roll_seeds`: the present configuration with the wrist rolled in steps (a top grasp's
  first search, the arm's own IK from each);
- :func:`lateral_arcs`: the stretches of the outline a lateral hand's pads can face;
- :func:`face_arcs`: each contact's own face, less an inset at its ends;
- :func:`side_contacts`: the side-face contacts a lateral pinch closes on.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from controllers.grasp.polygon import Polygon
from controllers.planning.cspace import CollisionChecker
from controllers.reach.coarse import (
    LATERAL_DEPTH,
    PITCH_TOLERANCE,
    ReachTarget,
    axis_pitch,
    lateral_frame,
)
from hand_sim import robot
from hand_sim.geometry import place_polygon
from hand_sim.world import World

#: The wrist roll (rad) between neighbouring lateral palm poses about the approach axis.
LATERAL_ROLL_STEP = float(np.deg2rad(10.0))


@dataclass(frozen=True)
class PalmPoseParams:
    """The palm poses Posture Control's search tries, and its limits."""

    #: A lateral pinch of the hand (ff, mf, rf, th; abduction, MCP, PIP, DIP, rad):
    #: ``benchmarks.hand_reachability``'s best lateral grasp of the rectangle (S_G 0.002; 3000
    #: hand samples, seed 0): first and middle finger on one long face, ring finger and thumb on
    #: the other.
    lateral_pinch: tuple[float, ...] = (
        -0.61, 1.56, 0.87, 0.14,
        -0.69, 0.48, 1.53, 0.32,
        0.64, 1.05, 1.31, 0.18,
        -0.82, 0.55, 0.61, 1.15,
    )  # fmt: skip
    #: Lateral palm poses (:func:`lateral_poses`): the approach axis horizontal and radial, the
    #: palm face ``lateral_gaps`` (m) from the perceived block's nearest point along it, at the
    #: coarse reach's height (LATERAL_DEPTH below the top), ``lateral_shifts`` (m) aside and hand
    #: y turned ``lateral_rolls`` (rad) from vertical about the approach axis (a roll moves the
    #: middle finger and the thumb off the block's centre line, towards the faces they take).
    lateral_gaps: tuple[float, ...] = (0.03, 0.035, 0.04)
    lateral_rolls: tuple[float, ...] = (0.0, LATERAL_ROLL_STEP, -LATERAL_ROLL_STEP)
    #: Wrist rolls (rad) a lateral pre-shape's sampled contacts are searched at where none is
    #: taken at ``lateral_rolls``: the hand upside down (180, 170 deg: the thumb on the other
    #: side of the block) and its finger row vertical (+-90 deg). Each is searched with its
    #: neighbours +-LATERAL_ROLL_STEP afterwards.
    #: Chosen by the best sampled S_G at ten rolls: docs/findings.md, "More wrist rolls".
    lateral_more_rolls: tuple[float, ...] = tuple(np.deg2rad([180.0, 170.0, 90.0, -90.0]))
    lateral_shifts: tuple[float, ...] = (0.0, -0.008, 0.008)
    #: The palm poses a lateral pre-shape searches for contacts among the sampled finger
    #: postures (:mod:`controllers.preshape.lateral_grasp`): gaps (m) and shifts (m) as above, with
    #: the same rolls. Wider than the pinch's: that search is cheap where no finger posture fits (no
    #: hand IK runs there), and ``benchmarks.hand_reachability`` finds the hand's lateral grasps
    #: with the palm 3-30 mm from the block and the block up to 3 cm aside.
    lateral_sampled_gaps: tuple[float, ...] = (0.015, 0.02, 0.025, 0.03, 0.035, 0.04)
    lateral_sampled_shifts: tuple[float, ...] = (0.0, -0.008, 0.008, -0.016, 0.016, -0.024, 0.024)
    #: Side contacts stay this far (m) inside the block's extent along the approach axis, and
    #: inside the ends of the side arcs (:func:`lateral_arcs`).
    side_inset: float = 0.004
    #: A lateral hand's pads take only faces whose outward normal is turned at most
    #: ``lateral_face_away`` (rad) away from the palm, or ``lateral_face_palmward`` towards it,
    #: from the horizontal across the approach axis (:func:`lateral_arcs`). The pinch's fingers
    #: curl from the palm round the block's sides, so their pads face across and back towards
    #: the palm: a face turned away from the palm (the block narrowing beyond its widest part) is
    #: taken with the pad, a face turned towards the palm needs a pad facing forward, which a
    #: curled finger has not.
    #: Chosen by the reach test's pad angles: docs/findings.md, "Faces a lateral pad takes".
    lateral_face_away: float = float(np.deg2rad(45.0))
    lateral_face_palmward: float = float(np.deg2rad(15.0))
    #: Assignments of contacts to fingers a lateral Posture Control search checks per palm pose
    #: (the top grasp's search over :func:`top_poses` checks as many).
    pose_tries: int = 2
    #: A top grasp's palm poses (:func:`top_poses`): the hand turned about the vertical through
    #: the perceived block's centroid by ``top_rolls`` (rad) from where it is, and moved
    #: ``top_shift`` (m) along the world's x and y.
    top_rolls: tuple[float, ...] = tuple(np.deg2rad(np.arange(0.0, 360.0, 30.0)))
    top_shift: float = 0.008
    #: Wrist-roll offsets (rad) Posture Control starts its search from, in order: the arm's own
    #: differential IK finds the nearest posture, which may keep a finger on the wrong side.
    roll_seeds: tuple[float, ...] = tuple(np.deg2rad([0, 45, -45, 90, -90, 180]))
    #: Posture Control may tilt the palm's approach axis this far (rad) from the coarse reach's,
    #: per approach: a hand tilted further grips a block standing on the table at an angle.
    max_palm_tilt_top: float = float(np.deg2rad(12.0))
    max_palm_tilt_lateral: float = float(np.deg2rad(35.0))

    def max_palm_tilt(self, approach: str) -> float:
        """The largest palm tilt (rad) for ``approach`` ("top" or "lateral")."""
        return {"top": self.max_palm_tilt_top, "lateral": self.max_palm_tilt_lateral}[approach]


DEFAULT_PALM_POSE = PalmPoseParams()


@dataclass(frozen=True, eq=False)
class PoseSetting:
    """Where palm poses are sought: the world as it is now, the planning model (the perceived
    block in place of the simulated one), the perceived target, and the palm rotation at the
    coarse reach's goal (``coarse_rotation``, 3x3); ``arm_q``, the arm joints the poses' IK
    starts from (default the arm's present ones; e.g. the coarse goal's, before the arm is
    there)."""

    world: World
    planning: mujoco.MjModel
    target: ReachTarget
    coarse_rotation: NDArray[np.float64]
    arm_q: NDArray[np.float64] | None = None

    def arm_start(self) -> tuple[NDArray[np.int64], CollisionChecker, NDArray[np.float64]]:
        """The arm's qpos addresses, a collision checker on the planning model, and the joint
        angles the IK starts from (``arm_q``, else the arm's present ones)."""
        arm_adr = robot.arm_qpos_addresses(self.world.model)
        checker = CollisionChecker(self.world, model=self.planning)
        start = self.world.data.qpos[arm_adr] if self.arm_q is None else self.arm_q
        return arm_adr, checker, np.array(start, dtype=float)


@dataclass(frozen=True, eq=False)
class PalmPose:
    """A palm pose a Posture Control search tries
    (:func:`controllers.preshape.palm_search.search_poses`): the configuration (qpos), its group
    (poses are tried group by group, in order: a lateral pose's palm-block distance in m, a top
    pose's 0 where the palm is and 1 shifted) and a label."""

    qpos: NDArray[np.float64]
    group: float
    label: str


def robot_base_xy(world: World) -> tuple[float, float]:
    """World (x, y) of the arm's base."""
    body = world.model.body(robot.arm_name("arm_base")).id
    x, y = world.data.xpos[body][:2]
    return float(x), float(y)


def approach_origin(
    base_xy: ArrayLike, target: ReachTarget, coarse_rotation: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Where a lateral hand's approach axis comes from in the table plane, for
    :func:`lateral_arcs` and :func:`side_contacts`: the arm's base (``base_xy``) when the
    coarse reach's palm (``coarse_rotation``, approach axis = its z column) faces the block from
    the base's side, else the base mirrored through the block's centre (a palm beyond the
    block, facing back towards the base: :func:`controllers.reach.coarse.plan_coarse_reach`)."""
    base = np.asarray(base_xy, dtype=float)
    if from_base_side(base, target, coarse_rotation):
        return base
    return 2.0 * np.asarray(target.position_xy, dtype=float) - base


def from_base_side(base_xy: ArrayLike, target: ReachTarget, rotation: NDArray[np.float64]) -> bool:
    """Whether a lateral palm of ``rotation`` (approach axis = its z column) faces the block
    from the arm base's side (False: from its far side, facing back towards the base)."""
    centre = np.asarray(target.position_xy, dtype=float)
    return float(rotation[:2, 2] @ (centre - np.asarray(base_xy, dtype=float))) >= 0.0


def turn_about_vertical(angle: float) -> NDArray[np.float64]:
    """Rotation by ``angle`` (rad) about the vertical."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def lateral_poses(
    where: PoseSetting,
    params: PalmPoseParams = DEFAULT_PALM_POSE,
    arcs: NDArray[np.float64] | None = None,
    *,
    sampled: bool = False,
    hand: NDArray[np.float64] | None = None,
) -> list[PalmPose]:
    """Palm poses beside the perceived block: the approach axis radial (the arm has five joints;
    from the base's side of the block, or from its far side where the coarse reach's is) and
    horizontal, or pitched down as the coarse reach's (``coarse_rotation``, its goal palm
    rotation; :data:`controllers.reach.coarse.LATERAL_TILTS`), hand y up as the coarse reach put it,
    turned ``lateral_rolls`` about the axis, the palm face ``lateral_gaps`` from the block's
    nearest point along the axis (which passes LATERAL_DEPTH below the top of the block's
    vertical axis), ``lateral_shifts`` aside; in order of the gap. A pitched palm's face is
    kept at least its gap clear of the block along its own axis (:func:`palm_plate_depth`): its
    upper edge meets the block's top edge before its centre line meets the side. The hand
    takes the pinch pre-shape.

    With ``arcs`` (:func:`lateral_arcs`) the gaps are counted from where the side faces the
    fingers can take begin (less ``side_inset``), when that lies beyond the nearest point: a
    block with a corner towards the arm (a pentagon's, 2.2 cm before its side faces) otherwise
    leaves its side faces beyond the fingers' reach. ``sampled``: the gaps and shifts of the
    sampled-contact search (``lateral_sampled_gaps``, ``lateral_sampled_shifts``); ``hand``:
    the hand's posture instead of the pinch (the one that took a sampled pre-shape's contacts)."""
    world, target, coarse_rotation = where.world, where.target, where.coarse_rotation
    hand_adr = robot.hand_qpos_addresses(world.model)
    arm_adr, checker, q_arm = where.arm_start()
    base = np.asarray(robot_base_xy(world))
    centre = np.array([*target.position_xy, target.top_z - LATERAL_DEPTH])
    # from the base's side, or (-1) from the block's far side facing back towards the base
    side = 1.0 if from_base_side(base, target, coarse_rotation) else -1.0
    axis = side * np.array([*(centre[:2] - base), 0.0])
    axis /= np.linalg.norm(axis)
    up = np.array([0.0, 0.0, np.sign(coarse_rotation[2, 1]) or 1.0])
    # the coarse reach's pitch of the approach axis below the horizontal (0 but where the arm
    # reaches a lateral goal only pitched, controllers.reach.coarse.LATERAL_TILTS)
    tilt = axis_pitch(coarse_rotation)
    near = float(((target.footprint() - centre[:2]) @ axis[:2]).min())
    if arcs is not None:
        ends = place_polygon(
            target.polygon.locate(np.ravel(arcs)).point, target.position_xy, target.yaw
        )
        near = max(near, float(((ends - centre[:2]) @ axis[:2]).min()) - params.side_inset)
    gaps = params.lateral_sampled_gaps if sampled else params.lateral_gaps
    half_face = palm_half_face(where.planning)
    shifts = params.lateral_sampled_shifts if sampled else params.lateral_shifts
    poses = []
    for gap in gaps:
        for roll in params.lateral_rolls:
            for shift in shifts:
                # the palm (near - gap) from the block along the (pitched) approach axis
                palm = centre + (near - gap) * lateral_frame(axis, tilt)[:, 2]
                palm += shift * np.cross(up, axis)
                # the approach axis through the shifted palm is radial, as the arm has it
                radial = side * np.array([*(palm[:2] - base), 0.0])
                radial /= np.linalg.norm(radial)
                rot = lateral_frame(radial, tilt, roll)
                if up[2] < 0:  # hand y down: the coarse reach's frame turned about the axis
                    rot = rot @ np.diag([-1.0, -1.0, 1.0])
                if tilt > PITCH_TOLERANCE:
                    # a pitched face meets the block's top edge first: back it out along its
                    # own (radial) axis until the face itself is ``gap`` clear
                    clear = palm_plate_depth(target, palm, rot, half_face)
                    palm -= max(0.0, gap - clear) * rot[:, 2]
                arm = checker.solve_ik(palm, rot, q_arm)
                if not arm.found:
                    continue
                qpos = world.data.qpos.copy()
                qpos[arm_adr] = arm.q
                qpos[hand_adr] = np.asarray(params.lateral_pinch if hand is None else hand)
                label = (
                    f"palm {gap * 100:.1f} cm from the block, {shift * 100:+.1f} cm aside, "
                    f"rolled {np.degrees(roll):+.0f} deg"
                )
                poses.append(PalmPose(qpos, gap, label))
    return poses


#: How far below its top (m) :func:`palm_plate_depth` takes a block to reach: any block of the
#: scenes (the table stops the palm before a taller one's foot would matter).
BLOCK_DEPTH_BOUND = 0.5


def palm_half_face(model: mujoco.MjModel) -> tuple[float, float]:
    """Half the palm's face (m, along hand x and y): its collision box in ``model``."""
    size = model.geom_size[model.geom(robot.hand_name("palm_collision")).id]
    return float(size[0]), float(size[1])


def palm_plate_depth(
    target: ReachTarget,
    origin: NDArray[np.float64],
    frame: NDArray[np.float64],
    half_face: tuple[float, float],
) -> float:
    """How far (m) along ``frame``'s approach axis (its z column) from ``origin`` the palm's face
    (``half_face`` about the axis, :func:`palm_half_face`; hand x and y as ``frame`` has them) first
    meets the perceived block (the convex hull of its footprint, from its top face down): the least
    ``z . (p - origin)`` over the block's points ``p`` in the face's shadow along the axis, a linear
    programme; ``inf`` when the shadow misses the block. A palm facing a vertical side level meets
    the nearest point of the side; a palm pitched down meets the block's top edge with its upper
    edge, further out than its centre's line does."""
    hull = ConvexHull(target.footprint())
    x, y, z = frame[:, 0], frame[:, 1], frame[:, 2]
    a, b = half_face
    rows = [np.append(eq[:2], 0.0) for eq in hull.equations]
    bounds = [-eq[2] for eq in hull.equations]
    for axis, half in ((x, a), (y, b)):
        rows += [axis, -axis]
        bounds += [half + axis @ origin, half - axis @ origin]
    lp = linprog(
        z,
        A_ub=np.array(rows),
        b_ub=np.array(bounds),
        bounds=[(None, None), (None, None), (target.top_z - BLOCK_DEPTH_BOUND, target.top_z)],
        method="highs",
    )
    return float(z @ (lp.x - origin)) if lp.status == 0 else float("inf")


def top_poses(where: PoseSetting, params: PalmPoseParams = DEFAULT_PALM_POSE) -> list[PalmPose]:
    """Palm poses above the perceived block for a top grasp's Posture Control: the palm level
    (the coarse reach's orientation, ``coarse_rotation``) at its present height, turned
    ``top_rolls`` about the vertical through the block's centroid, first where it is (``group``
    0), then ``top_shift`` aside (``group`` 1); the hand in its present shape."""
    world, target, coarse_rotation = where.world, where.target, where.coarse_rotation
    m = world.model
    lo, hi = m.jnt_range[m.joint(robot.qualified("wrist_roll")).id]
    arm_adr, checker, q_arm = where.arm_start()
    p, _ = checker.palm_pose(q_arm)
    centre = np.asarray(target.position_xy, dtype=float)
    shifts = [(0, np.zeros(2))] + [
        (1, params.top_shift * np.array(d)) for d in ((1, 0), (-1, 0), (0, 1), (0, -1))
    ]
    poses = []
    for gap, shift in shifts:
        for roll in params.top_rolls:
            turn = turn_about_vertical(roll)
            palm = p.copy()
            palm[:2] = centre + turn[:2, :2] @ (p[:2] - centre) + shift
            seed = q_arm.copy()
            seed[-1] = np.mod(seed[-1] + roll - lo, 2 * np.pi) + lo
            if seed[-1] > hi:
                seed[-1] -= 2 * np.pi
            arm = checker.solve_ik(palm, turn @ coarse_rotation, seed)
            if not arm.found:
                continue
            qpos = world.data.qpos.copy()
            qpos[arm_adr] = arm.q
            label = f"palm turned {np.degrees(roll):+.0f} deg about the block" + (
                f", moved {shift[0] * 1000:+.0f}, {shift[1] * 1000:+.0f} mm" if gap else ""
            )
            poses.append(PalmPose(qpos, float(gap), label))
    return poses


def roll_seeds(
    world: World, params: PalmPoseParams = DEFAULT_PALM_POSE
) -> list[tuple[str, NDArray[np.float64]]]:
    """Start configurations of a top grasp's Posture Control search, with a label: the world's
    configuration with the wrist rolled by each of ``roll_seeds`` (within its range; the arm's
    differential IK finds the nearest posture, which may keep a finger on the wrong side of the
    block)."""
    m = world.model
    roll_j = m.joint(robot.qualified("wrist_roll")).id
    roll_adr = m.jnt_qposadr[roll_j]
    lo, hi = m.jnt_range[roll_j]
    seeds = []
    for roll in params.roll_seeds:
        seed = world.data.qpos.copy()
        seed[roll_adr] = np.clip(seed[roll_adr] + roll, lo, hi)
        seeds.append((f"wrist roll {np.degrees(roll):+.0f} deg", seed))
    return seeds


def _approach_frame(
    target: ReachTarget, base_xy: tuple[float, float]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The block's centre (world xy), the horizontal approach axis (from the arm's base
    through the centre) and the direction across it to its left, unit vectors."""
    centre = np.asarray(target.position_xy, dtype=float)
    axis = centre - np.asarray(base_xy, dtype=float)
    axis /= np.linalg.norm(axis)
    return centre, axis, np.array([-axis[1], axis[0]])


def lateral_arcs(
    target: ReachTarget,
    base_xy: tuple[float, float],
    params: PalmPoseParams = DEFAULT_PALM_POSE,
) -> NDArray[np.float64]:
    """The stretches of the perceived block's outline a lateral hand's pads can face, one per
    side of the approach axis (row 0 left, row 1 right), as contact-coordinate intervals
    ``(lo, hi)`` (rad, counter-clockwise from lo to hi on the perceived polygon). A side's arc
    is the chain of edges whose outward normal is turned from the horizontal across the axis on
    that side at most ``params.lateral_face_away`` away from the palm and
    ``params.lateral_face_palmward`` towards it (one chain: the polygon is convex), or, when no
    edge is, the edges nearest that; its ends ``params.side_inset`` (m) in from the chain's end
    vertices.

    Section 5.2's reachability criterion, for the hand's shape in a lateral grasp: the finger
    row is horizontal and the pads close across the approach axis, so a face turned towards the
    palm (a pentagon's or a triangle's near faces when a corner points at the arm) or far away
    from it is pressed with the side of a fingertip. The grasp controller keeps its contacts on
    these arcs (``GraspSynthesis(arcs=...)``)."""
    _, axis, across = _approach_frame(target, base_xy)
    c, s = np.cos(target.yaw), np.sin(target.yaw)

    def to_object(d: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])

    axis_obj, across_obj = to_object(axis), to_object(across)
    poly = target.polygon
    v = poly.vertices
    normals = np.column_stack([np.cos(poly.normal_angle), np.sin(poly.normal_angle)])
    k = len(v)
    inset = params.side_inset
    arcs = np.empty((2, 2))
    for row, side in enumerate((1.0, -1.0)):
        # each edge's turn from the across direction, positive away from the palm
        turn = np.arctan2(normals @ axis_obj, normals @ (side * across_obj))
        outside = np.maximum(turn - params.lateral_face_away, -params.lateral_face_palmward - turn)
        good = outside <= 0.0
        if not good.any():
            good = outside <= outside.min() + 1e-9
        # the chain's first edge: a good edge whose predecessor is not
        first = next(j for j in range(k) if good[j] and not good[j - 1]) if not good.all() else 0
        last = first
        while good[(last + 1) % k] and (last + 1) % k != first:
            last = (last + 1) % k
        start, end = v[first], v[(last + 1) % k]
        e_start = v[(first + 1) % k] - start
        e_end = end - v[last]
        length = sum(
            float(np.linalg.norm(v[(j + 1) % k] - v[j]))
            for j in (np.arange(first, first + ((last - first) % k) + 1) % k)
        )
        step = min(inset, 0.25 * length)
        start = start + step * e_start / np.linalg.norm(e_start)
        end = end - step * e_end / np.linalg.norm(e_end)
        arcs[row] = poly.theta_of(start), poly.theta_of(end)
    return arcs


def side_contacts(
    target: ReachTarget,
    base_xy: tuple[float, float],
    tips: NDArray[np.float64],
    inset: float = DEFAULT_PALM_POSE.side_inset,
    arcs: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Contact coordinates (polar angles on the perceived polygon) where lines from the
    approach axis (from the arm's base at ``base_xy`` through the block's centre) across it,
    through each fingertip of ``tips`` (4, 3), meet the block's outline on the fingertip's
    side: the side faces a lateral pinch closes on. (The nearest surface point of a fingertip in
    front of the block's near corner is on the near face, where the palm pushes against
    nothing.) A fingertip before or beyond the block along the axis takes the block's first or
    last ``inset`` (m); with ``arcs`` (:func:`lateral_arcs`), the first or last point of its
    side's arc."""
    centre, axis, across = _approach_frame(target, base_xy)
    foot = target.footprint()
    depth = (foot - centre) @ axis
    extent = {1.0: (depth.min() + inset, depth.max() - inset)}
    extent[-1.0] = extent[1.0]
    if arcs is not None:
        for row, side in enumerate((1.0, -1.0)):
            ends = place_polygon(
                target.polygon.locate(arcs[row]).point, target.position_xy, target.yaw
            )
            d_ends = (ends - centre) @ axis
            extent[side] = (float(d_ends.min()), float(d_ends.max()))
    edges = np.roll(foot, -1, axis=0) - foot
    theta = np.empty(len(tips))
    for f, tip in enumerate(tips[:, :2]):
        side = 1.0 if (tip - centre) @ across >= 0.0 else -1.0
        lo, hi = extent[side]
        d = float(np.clip((tip - centre) @ axis, lo, hi))
        origin, ray = centre + d * axis, side * across
        # the ray leaves the convex outline through exactly one edge
        best = np.inf
        for a, e in zip(foot, edges, strict=True):
            mat = np.column_stack([ray, -e])
            if abs(np.linalg.det(mat)) < 1e-12:
                continue
            t, u = np.linalg.solve(mat, a - origin)
            if t > 0.0 and -1e-9 <= u <= 1.0 + 1e-9:
                best = min(best, t)
        local = origin + best * ray - centre
        theta[f] = np.arctan2(local[1], local[0]) - target.yaw
    return np.mod(theta + np.pi, 2 * np.pi) - np.pi


def face_arcs(polygon: Polygon, theta: NDArray[np.float64], inset: float) -> NDArray[np.float64]:
    """Each contact's own face as a contact-coordinate interval ``(lo, hi)`` (rad,
    counter-clockwise), its ends ``inset`` (m; at most a quarter of the face) in from the
    face's vertices: where a lateral grasp whose contacts were chosen among the hand's sampled
    postures (:mod:`controllers.preshape.lateral_grasp`) keeps each finger."""
    v = polygon.vertices
    edges = polygon.locate(np.asarray(theta, dtype=float)).edge
    out = np.empty((len(edges), 2))
    for i, k in enumerate(edges):
        a, b = v[k], v[(k + 1) % len(v)]
        length = float(np.linalg.norm(b - a))
        step = min(inset, 0.25 * length) * (b - a) / length
        out[i] = polygon.theta_of(a + step), polygon.theta_of(b - step)
    return out
