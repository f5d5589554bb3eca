"""Can the hand take these contacts? The reachability criterion of section 5.2 ("Wrench Closure":
"the reachability criterion was extended to mark as unreachable configurations in which finger
links penetrates the object"), over the assignments of contacts to fingers that
:mod:`controllers.hand.finger_assignment` ranks.

The grasp controller moves virtual contacts on a polygon and knows nothing of fingers. Before a
set of contacts is accepted, :func:`check_reach` asks, in this order:
1. do the pads fit: no two contacts closer than :data:`MIN_PAD_SPACING` (two 8.5 mm pads side by
   side, plus a margin);
2. can each fingertip get there: hand inverse kinematics (mink, arm held) puts every fingertip
   site within :data:`CONTACT_TOLERANCE` of its contact point;
3. with the pad, not the side or back of the fingertip: the pad normal within
   :data:`MAX_PAD_ANGLE` of the face's inward normal, the flexion axis not within
   :data:`MAX_PAD_SIDEWAYS` of the face normal, the contact on the palmar half
   (:data:`MIN_PAD_PALMAR`), where the touch sensor feels it;
4. without a finger link inside the block: no link deeper than :data:`MAX_LINK_PENETRATION` in
   the perceived prism.
The first failure is the reason given. The block is the perceived one throughout.

The perceived prism and the finger measures the test uses (clearance, link penetration, pad
normals, fingertip positions) live in :mod:`controllers.hand.finger_geometry`; they are re-exported
here, as is :data:`controllers.hand.finger_samples.PAD_NORMAL_LOCAL`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.hand.finger_assignment import (
    BOTTOM_MARGIN,
    TOP_MARGIN,
    FingerContacts,
    ranked_assignments,
)
from controllers.hand.finger_geometry import (
    PerceivedPrism,
    finger_palmar,
    finger_sideways,
    link_penetration,
    pad_normals,
)
from controllers.hand.finger_samples import Criteria, FingerSamples
from controllers.hand.finger_span import FingerSpans
from controllers.posture.kinematic_scratch import kinematic_scratch
from controllers.posture.solver import solve_posture
from controllers.reach.coarse import ReachTarget
from hand_sim import robot
from hand_sim.indices import RobotIndices
from hand_sim.world import World

#: Smallest distance (m) between the centres of two fingertip pads on their contacts (a pad's
#: centre is one pad radius out from its contact along the face normal): two 8.5 mm pads need
#: 17 mm; the rest is room for the finger links beside them. Contacts on faces at an angle may
#: be closer than contacts side by side on one face.
MIN_PAD_SPACING = 0.019
#: Extra spacing (m) the grasp controller keeps between contacts beyond :data:`MIN_PAD_SPACING`,
#: so that contacts it returns are not on the reach test's limit.
SEPARATION_MARGIN = 0.002
#: Smallest distance (m) between two contacts the grasp controller may return.
CONTACT_SEPARATION = MIN_PAD_SPACING + SEPARATION_MARGIN
#: A fingertip reaches its contact when its tip site ends this close (m) to the contact point.
CONTACT_TOLERANCE = 0.002
#: Largest angle (rad) between a fingertip's pad normal and the face's inward normal (the pad
#: normal is taken at the tip site, 30 deg from the palmar normal towards the tip), and the
#: largest component of the face normal along the fingertip's sideways axis: beyond either, the
#: side of the fingertip, not its pad, would touch.
MAX_PAD_ANGLE = np.deg2rad(65.0)
MAX_PAD_SIDEWAYS = 0.8
#: The touch sensor covers the palmar half of the distal link (models/hand.xml); a contact on the
#: rounded end of the fingertip is felt only if it lies on that half too: the direction from the
#: link's axis into the face must have at least this palmar component (the contact 1.7 mm into
#: the palmar half). The pad-angle test alone lets a contact at the end of the tip slip onto the
#: back of it, where the squeeze, regulated on touch, cannot feel it.
MIN_PAD_PALMAR = 0.2
#: Deepest a finger link may reach into the perceived block (m): the soft pad's compliance.
MAX_LINK_PENETRATION = 0.0015
#: Hand IK iterations of the reachability check.
IK_ITERATIONS = 250
#: The fingers must reach this far (m) into the block past each contact point: a squeeze is a
#: position servo target inside the surface, so a finger that can only just touch cannot grip.
SQUEEZE_REACH = 0.006


@dataclass(frozen=True, eq=False)
class HandReach:
    """Verdict of :func:`check_reach` for contacts in finger order (ff, mf, rf, th)."""

    reachable: bool
    reason: str  #: "" when reachable, else what stands in the way, naming the finger(s)
    hand_q: NDArray[np.float64]  #: (16,) the hand IK solution (arm held)
    tip_error: NDArray[np.float64]  #: (4,) m
    pad_angle: NDArray[np.float64]  #: (4,) rad between pad normal and inward face normal
    penetration: float  #: deepest finger link inside the perceived block (m, >= 0)
    min_spacing: float  #: closest pair of pad centres on their contacts (m)
    heights: NDArray[np.float64] | None = None  #: (4,) contact heights (m) the fingers took
    #: the criteria's worst value as a share of its limit (tip error, pad angle, sideways, link
    #: penetration; pad spacing left out): below 1 every finger passes, lower is more margin
    load: float = np.inf


def grip_targets(
    points: ArrayLike, normals: ArrayLike, depth: float = SQUEEZE_REACH
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Fingertip targets ``depth`` inside the surface at each contact and the matching pad-centre
    targets (one pad radius out along the normal from the fingertip target), (4, 3) each."""
    p, n = np.asarray(points, dtype=float), np.asarray(normals, dtype=float)
    tips = p - depth * n
    return tips, tips + robot.PAD_RADIUS * n


#: A sampled finger posture is an IK start for a contact when its fingertip lies this close (m)
#: to the contact (its vertical line, for sliding contacts).
SAMPLE_TOLERANCE = 0.003


def _sampled_start(
    model: mujoco.MjModel,
    qpos: NDArray[np.float64],
    samples: FingerSamples,
    points: NDArray[np.float64],
    normals: NDArray[np.float64],
    prism: PerceivedPrism,
    heights: tuple[float, float],
    squeeze: float,
    idle: int | None = None,
) -> NDArray[np.float64]:
    """``qpos`` with each finger's joints replaced by the sample that takes its contact best,
    where a sample does (not the ``idle`` finger's); ``heights`` is the range the contacts may
    slide in."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    palm = model.body(robot.hand_name(robot.PALM_BODY)).id
    p0, R0 = data.xpos[palm].copy(), data.xmat[palm].reshape(3, 3).copy()
    criteria = Criteria(
        SAMPLE_TOLERANCE,
        MAX_PAD_ANGLE,
        MAX_PAD_SIDEWAYS,
        MIN_PAD_PALMAR,
        MAX_LINK_PENETRATION,
        squeeze,
    )
    out = qpos.copy()
    adr = RobotIndices.of(model).finger_qpos
    # sliding contacts prefer the palm's height: opposed fingers then press at one height
    prefer = float(p0[2])
    for f in range(len(robot.FINGERS)):
        if f == idle:
            continue
        q, _ = samples.best(
            f, p0, R0, points[f], normals[f], heights, prism.signed_distance, criteria, prefer
        )
        if q is not None:
            out[adr[f]] = q
    return out


def _beyond_span(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    qpos: NDArray[np.float64],
    tips: NDArray[np.float64],
) -> bool:
    """True when a fingertip target of ``tips`` (4, 3) lies beyond its finger's span
    (:class:`controllers.hand.finger_span.FingerSpans`) from configuration ``qpos``: no hand posture
    brings that fingertip within :data:`CONTACT_TOLERANCE` of it. ``data`` (of ``model``) is
    left at ``qpos``, its kinematics computed."""
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    return bool(FingerSpans.of(model, data).out_of_reach(tips, CONTACT_TOLERANCE).any())


def check_reach(
    world: World,
    prism: PerceivedPrism,
    points: ArrayLike,
    normals: ArrayLike,
    *,
    qpos: ArrayLike | None = None,
    model: mujoco.MjModel | None = None,
    check_spacing: bool = True,
    slide: bool = False,
    samples: FingerSamples | None = None,
    squeeze: float = SQUEEZE_REACH,
    give_up: bool = False,
    span_test: bool = False,
    idle: int | None = None,
) -> HandReach:
    """Can the fingers (ff, mf, rf, th) take the contacts ``points`` (4, 3) with outward face
    ``normals`` (4, 3), the arm held at ``qpos``'s posture (default: the world's state now)? The
    fingertips must reach ``squeeze`` (default :data:`SQUEEZE_REACH`) past each contact, pads facing
    it. ``check_spacing=False`` leaves out the pad-spacing test (the pad centres on their contacts,
    at the heights taken, :data:`MIN_PAD_SPACING` apart; the task cycle applies it to the
    controller's final contacts only). With ``slide`` each contact may move up or down its face (a
    planar contact is a vertical line on the prism's face) between :data:`BOTTOM_MARGIN` above the
    prism's bottom and :data:`TOP_MARGIN` below its top; the heights taken are in the verdict's
    ``heights``. With ``samples`` and ``slide`` each finger's IK starts from the sampled posture
    that takes its contact best (:meth:`FingerSamples.best`) where one does, instead of from the
    hand's present posture: a global search the local IK refines. (Without ``slide`` a contact's
    height range is a single height, which no sampled fingertip meets exactly, so the samples are
    not searched.) ``give_up``: the IK stops as soon as a fingertip cannot reach
    (``solve_posture``'s ``give_up``); an unreachable verdict's ``hand_q``, ``tip_error`` and
    ``load`` are then those of the shorter run (the verdict is the same). ``span_test``: without
    ``slide``, when a fingertip target lies beyond its finger's span (:func:`_beyond_span`) neither
    the sampled start nor the IK runs: the verdict (unreachable, as the IK's) is taken at the start
    posture, its ``hand_q``, ``tip_error``, ``load`` and reason those of that posture, for a caller
    that throws unreachable verdicts away. ``idle``: a three-contact grasp's finger that takes no
    contact (its row of ``points`` and ``normals`` is not read): it stays in ``qpos``'s posture and
    only its links' penetration of the block is judged."""
    model = world.model if model is None else model
    p = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    start = np.asarray(world.data.qpos if qpos is None else qpos, dtype=float).copy()
    tips, centres = grip_targets(p, n, squeeze)
    heights = (prism.bottom + BOTTOM_MARGIN, prism.top - TOP_MARGIN)
    # a fingertip target beyond its finger's span is unreachable whatever the IK does: where the
    # caller throws unreachable verdicts away, the verdict is taken from the start posture
    scratch = kinematic_scratch(world, model)
    data = scratch.data
    hopeless = span_test and not slide and _beyond_span(model, data, start, tips)
    if samples is not None and slide and not hopeless:
        start = _sampled_start(model, start, samples, p, n, prism, heights, squeeze, idle)
    sol = solve_posture(
        world,
        tips,
        optimize=False,
        joints="hand",
        tolerance=CONTACT_TOLERANCE,
        reach_iterations=0 if hopeless else IK_ITERATIONS,
        qpos=start,
        model=model,
        pad_centres=centres,
        slide=heights if slide else None,
        give_up=give_up,
        still=() if idle is None else (idle,),
    )
    heights = p[:, 2] if sol.targets is None else sol.targets[:, 2]
    # the pads where they take their contacts: at the heights a sliding contact was taken at
    # (a lateral hand's fingers stacked on one face, a pad's width apart in the plane, are
    # centimetres apart in height)
    centres_at_contact = np.column_stack([p[:, :2], heights]) + robot.PAD_RADIUS * n
    gaps = np.linalg.norm(centres_at_contact[:, None] - centres_at_contact[None, :], axis=-1)
    gaps[np.diag_indices(len(p))] = np.inf
    if idle is not None:
        gaps[idle, :] = gaps[:, idle] = np.inf
    spacing = float(gaps.min())
    data.qpos[:] = start
    data.qpos[scratch.indices.hand_qpos] = sol.hand_q
    mujoco.mj_kinematics(model, data)
    cosines = np.einsum("fd,fd->f", pad_normals(model, data), -n)
    angle = np.arccos(np.clip(cosines, -1.0, 1.0))
    sideways = np.abs(np.einsum("fd,fd->f", finger_sideways(model, data), n))
    palmar = np.einsum("fd,fd->f", finger_palmar(model, data), -n)
    if idle is not None:  # presses nothing: no pad to face a contact
        angle[idle], sideways[idle], palmar[idle] = 0.0, 0.0, 1.0
    depth = link_penetration(model, data, prism)
    deepest = max(depth.values())
    reason = ""
    if check_spacing and spacing < MIN_PAD_SPACING:
        i, j = np.unravel_index(int(np.argmin(gaps)), gaps.shape)
        reason = (
            f"{robot.FINGERS[i]} and {robot.FINGERS[j]} pads would be {spacing * 1000:.0f} mm "
            f"apart on their contacts (two pads need {MIN_PAD_SPACING * 1000:.0f} mm)"
        )
    elif not sol.reachable:
        worst = int(np.argmax(sol.tip_error))
        reason = (
            f"{', '.join(sol.unreachable)} cannot reach (worst: {robot.FINGERS[worst]} "
            f"{sol.tip_error[worst] * 1000:.0f} mm short)"
        )
    elif angle.max() > MAX_PAD_ANGLE or sideways.max() > MAX_PAD_SIDEWAYS:
        worst = int(np.argmax(np.maximum(angle / MAX_PAD_ANGLE, sideways / MAX_PAD_SIDEWAYS)))
        reason = (
            f"{robot.FINGERS[worst]} would touch with the side of its fingertip "
            f"({np.degrees(angle[worst]):.0f} deg from the pad)"
        )
    elif palmar.min() < MIN_PAD_PALMAR:
        worst = int(np.argmin(palmar))
        reason = (
            f"{robot.FINGERS[worst]} would touch with the back of its fingertip, where its "
            f"touch sensor does not reach"
        )
    elif deepest > MAX_LINK_PENETRATION:
        finger = max(depth, key=depth.__getitem__)
        reason = f"{finger} links would penetrate the block by {deepest * 1000:.1f} mm"
    return HandReach(
        reachable=not reason,
        reason=reason,
        hand_q=sol.hand_q,
        tip_error=sol.tip_error,
        pad_angle=angle,
        penetration=max(deepest, 0.0),
        min_spacing=spacing,
        heights=heights.copy(),
        load=float(
            max(
                sol.tip_error.max() / CONTACT_TOLERANCE,
                angle.max() / MAX_PAD_ANGLE,
                sideways.max() / MAX_PAD_SIDEWAYS,
                ((1.0 - palmar) / (1.0 - MIN_PAD_PALMAR)).max(),
                deepest / MAX_LINK_PENETRATION,
            )
        ),
    )


#: Assignments :func:`reachable_contacts` tries, nearest first.
ASSIGNMENTS_TRIED = 6


def reachable_contacts(
    world: World,
    prism: PerceivedPrism,
    target: ReachTarget,
    theta: ArrayLike,
    *,
    model: mujoco.MjModel | None = None,
    check_spacing: bool = True,
    tries: int = ASSIGNMENTS_TRIED,
    qpos: ArrayLike | None = None,
    slide: bool = False,
    samples: FingerSamples | None = None,
    squeeze: float = SQUEEZE_REACH,
    heights: ArrayLike | None = None,
    give_up: bool = False,
    span_test: bool = False,
    idle: int | None = None,
) -> tuple[FingerContacts, HandReach]:
    """The finger-to-contact rule of the task cycle: of the 24 ways to give the four contacts
    to the four fingers, ranked by total squared reach distance from the fingertips (at each
    fingertip's height), the first ``tries`` are checked with :func:`check_reach` and the first
    the hand reaches is taken; when none is, the nearest one with its reason. ``qpos``: judge
    from that configuration instead of the world's. ``slide``: the contacts may move up or down
    their faces (:func:`check_reach`); the contacts returned are at the heights taken.
    ``samples``: start each check's IK from sampled finger postures; ``squeeze``: how far past
    its contact each fingertip must reach (:func:`check_reach`). ``heights`` (n,): world z of
    each contact (a 3-D grasp: a finger takes its contact at the contact's height, not its own).
    ``give_up``: each check stops as soon as it cannot succeed, and the checks after the first
    skip the IK of contacts beyond a finger's span (only the first's reason is returned);
    ``span_test``: the first check does too (:func:`check_reach`). ``idle``: a three-contact
    grasp (three contacts) whose ``idle`` finger takes none
    (:func:`controllers.hand.finger_assignment.ranked_assignments`, :func:`check_reach`)."""
    th = np.asarray(theta, dtype=float)
    model = world.model if model is None else model
    first: tuple[FingerContacts, HandReach] | None = None
    for contacts in ranked_assignments(
        world, prism, target, th, model=model, qpos=qpos, heights=heights, count=tries, idle=idle
    ):
        reach = check_reach(
            world,
            prism,
            contacts.points,
            contacts.normals,
            model=model,
            check_spacing=check_spacing,
            qpos=qpos,
            slide=slide,
            samples=samples,
            squeeze=squeeze,
            give_up=give_up,
            # past the first assignment an unreachable verdict is thrown away
            span_test=span_test or (give_up and first is not None),
            idle=idle,
        )
        if slide and reach.heights is not None:
            points = np.column_stack([contacts.points[:, :2], reach.heights])
            contacts = dataclasses.replace(contacts, points=points)
        if reach.reachable:
            return contacts, reach
        if first is None:
            first = (contacts, reach)
    assert first is not None
    return first
