"""Wrench Closure (section 5.2): the grasp controller moves virtual contacts on the perceived
polygon until it converges, while the hand's reachability of the contacts is checked."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.score import SUCCESS_THRESHOLD
from controllers.grasp.synthesis import GraspSynthesis
from controllers.grasp.synthesis3d import GraspSynthesis3D
from controllers.grasp.trials3d import HeightBand
from controllers.hand.grip import GRIP_FORCE
from controllers.hand.reachability import (
    CONTACT_SEPARATION,
    MIN_PAD_SPACING,
    reachable_contacts,
)
from controllers.reach.fine import MIN_CONTACT_HEIGHT, TOP_GRASP_DEPTHS, project_to_surface
from fsm.context import Episode
from fsm.episode_queries import (
    contact_arcs,
    contact_points,
    is_lateral,
    reach_query,
    reach_start,
    sampled_preshape,
)
from fsm.recorder_protocol import SynthesisRecord
from fsm.states import Failure, State, Step, TaskFailedError
from hand_sim import robot


def synthesis_for(
    ep: Episode, theta: NDArray[np.float64], tips_z: NDArray[np.float64]
) -> GraspSynthesis | GraspSynthesis3D:
    """This cycle's grasp controller from contacts ``theta``: planar, or, with ``--model 3d``
    on a block tall enough for the band, 3-D from the contacts' heights ``tips_z`` (world).
    A top grasp's heights move in the band :data:`~controllers.reach.fine.TOP_GRASP_DEPTHS`
    below the top and above the table margin, the common height set by the task (the perceived
    weight over the grip force; the pushes along the world's axes). A lateral grasp is planar,
    its contacts kept on their arcs (the side arcs, or a sampled pre-shape's own faces)."""
    separation = {"min_separation": CONTACT_SEPARATION, "separation_offset": robot.PAD_RADIUS}
    height = ep.prism.top - ep.prism.bottom
    low = max(height - TOP_GRASP_DEPTHS[1], MIN_CONTACT_HEIGHT)
    high = height - TOP_GRASP_DEPTHS[0]
    com_z = ep.prism.centre_z
    if is_lateral(ep):
        # a lateral hand takes only the faces beside its approach axis: each contact stays on
        # its side's arc
        arcs = contact_arcs(ep, np.asarray(theta, dtype=float))
        return GraspSynthesis(
            ep.target.polygon, ep.composer, theta, ep.rng, arcs=arcs, **separation
        )
    if ep.options.grasp_model != "3d" or low > high:
        return GraspSynthesis(ep.target.polygon, ep.composer, theta, ep.rng, **separation)
    return GraspSynthesis3D(
        ep.target.polygon,
        height,
        HeightBand(low, high),
        ep.composer,
        theta,
        np.asarray(tips_z, dtype=float) - com_z,
        ep.rng,
        load=ep.expected_load / GRIP_FORCE,
        yaw=-ep.target.yaw,
        **separation,
    )


def wrench_closure(ep: Episode) -> Step:
    """Wrench Closure: the grasp controller (kb, ql or pi) moves virtual contacts on the
    perceived polygon from the fingertips' projections until it converges; every
    ``config.reach_check_every`` steps the hand's reachability of the contacts is checked and an
    unreachable set sends the machine back to Posture Control. A lateral grasp whose contacts
    still move when the step budget ends is taken there when the hand reaches them and they
    pass the gate (as it stops at the last reachable contacts); any other is not converged."""
    world = ep.world
    table_z = world.scene.table.height
    record = ep.record
    if ep.synthesis is None:
        tips = world.fingertip_positions()
        start = project_to_surface(ep.target, tips, table_z=table_z).theta
        start_z = tips[:, 2]
        if is_lateral(ep) and ep.preshape_contacts is not None:
            # a lateral grasp starts from the pre-shape's contacts, which the hand reaches, at
            # the heights its fingers took there
            pressing = ep.preshape_contacts.pressing  # a three-contact grasp's three
            start = ep.preshape_contacts.theta[pressing].copy()
            start_z = ep.preshape_contacts.points[pressing, 2].copy()
        ep.synthesis = synthesis_for(ep, start, start_z)
        ep.last_reachable = None
        if is_lateral(ep):
            _remember_if_reachable(ep)
    syn = ep.synthesis
    stopped = ""
    while True:
        if not syn.done:
            step = syn.step()
            record.synthesis_steps = syn.steps
            ep.recorder.log_synthesis(
                SynthesisRecord(
                    step.step,
                    step.eps_fc,
                    step.eps_mc,
                    step.predicted_failure,
                    contact_points(ep, syn.theta),
                )
            )
            if syn.steps % ep.config.reach_check_every and not syn.done:
                continue
        query = reach_query(ep)
        contacts, reach = reachable_contacts(
            world,
            query.prism,
            query.target,
            syn.theta,
            model=query.planning,
            qpos=reach_start(ep),
            check_spacing=syn.done,
            slide=query.slide,
            samples=query.samples,
            squeeze=query.squeeze,
            heights=query.heights,
            # an unreachable top grasp only needs the verdict (a lateral one keeps its heights)
            give_up=not query.slide,
            idle=query.idle,
        )
        ep.contacts, ep.reach = contacts, reach
        if syn.done and reach.min_spacing < MIN_PAD_SPACING:
            raise TaskFailedError(Failure.CONTACT_UNREACHABLE, reach.reason)
        ep.recorder.log_reachability(record.posture_retries, reach.reachable, reach.reason)
        if reach.reachable and is_lateral(ep):
            ep.last_reachable = (syn.theta, contacts, reach, syn.steps)
        if not reach.reachable and _last_reachable_grasp(ep):
            theta, ep.contacts, ep.reach, at = ep.last_reachable
            stopped = (
                f"; stopped at step {at}'s contacts, the last the hand reached (at step "
                f"{syn.steps}: {reach.reason})"
            )
            syn.stop_at(theta)
            break
        if not reach.reachable:
            ep.last_reachable = None  # Posture Control may move the arm
            record.reach_reasons.append(reach.reason)
            record.posture_retries += 1
            ep.posture_mode = "contacts"
            return Step(State.POSTURE_CONTROL, f"step {syn.steps}: {reach.reason}")
        if syn.done:
            break
    score = syn.finish()
    gate = _gate(ep)
    # the final contacts (at their heights in 3-D) with their S_G (3-D S_G in 3-D)
    ep.recorder.log_synthesis(
        SynthesisRecord(
            syn.steps,
            syn.eps_fc,
            syn.eps_mc,
            None,
            contact_points(ep, syn.theta),
            float(score.s_g) if score.feasible else None,
        )
    )
    record.converged = syn.converged
    record.s_g = float(score.s_g) if score.feasible else None
    pressing = ep.contacts.pressing  # the fingers that take a contact, in finger order
    record.contacts = ep.contacts.points[pressing].round(5).tolist()
    record.contact_theta = ep.contacts.theta[pressing].round(5).tolist()
    record.contact_fingers = [robot.FINGERS[f] for f in pressing]
    passes = score.feasible and score.s_g <= gate
    if not syn.converged and not syn.stopped:
        if not (is_lateral(ep) and passes):
            raise TaskFailedError(
                Failure.GRASP_NOT_CONVERGED, f"contacts still moving after {syn.steps} steps"
            )
        # a lateral grasp stops where its step budget ends when the hand reaches those
        # contacts (just checked) and they pass the gate, as it stops at the last reachable ones
        stopped = f"; its contacts still moved at the step budget, and these pass S_G <= {gate:.2f}"
    if not passes:
        what = f"S_G {score.s_g:.3f} > {gate:g}" if score.feasible else "no feasible grasp (S_G LP)"
        raise TaskFailedError(Failure.GRASP_NOT_CONVERGED, f"converged to a weak grasp: {what}")
    return Step(
        State.GRASP_OBJECT,
        ("converged" if syn.converged else "stopped")
        + f" in {syn.steps} steps, S_G {score.s_g:.3f}, reachable "
        f"(pads {np.degrees(ep.reach.pad_angle).round(0).tolist()} deg off their faces)" + stopped,
    )


def _remember_if_reachable(ep: Episode) -> None:
    """A lateral grasp's starting contacts, kept as the last reachable ones when the hand
    reaches them (``ep.last_reachable``). After a sampled pre-shape, its own contacts: the
    planar controller's start keeps the pads a pad spacing apart in the plane, which moves
    fingers stacked on one face (apart in height) by up to 0.6 rad of contact coordinate, to
    contacts the hand does not reach (single_square, single_trapezoid)."""
    syn = ep.synthesis
    query = reach_query(ep)
    shaped = ep.preshape_contacts
    theta = shaped.theta[shaped.pressing] if sampled_preshape(ep) else syn.theta
    contacts, reach = reachable_contacts(
        ep.world,
        query.prism,
        query.target,
        theta,
        model=query.planning,
        qpos=reach_start(ep),
        check_spacing=False,
        slide=query.slide,
        samples=query.samples,
        squeeze=query.squeeze,
        heights=query.heights,
        idle=query.idle,
    )
    if reach.reachable:
        ep.last_reachable = (theta, contacts, reach, syn.steps)


def _last_reachable_grasp(ep: Episode) -> bool:
    """Whether a lateral grasp whose controller's contacts have left the hand's reach may stop
    at the last contacts the hand reached: they pass S_G (Eq. 13) and their pads fit. A lateral
    hand reaches only a few centimetres of each side face (the 5-joint arm cannot turn it), so
    a grasp the controller would still improve is taken where the hand can make it, rather
    than lost to Posture Control's search."""
    if ep.last_reachable is None or not is_lateral(ep):
        return False
    theta, _, reach, _ = ep.last_reachable
    score = ep.synthesis.score_at(theta)
    return score.feasible and score.s_g <= _gate(ep) and reach.min_spacing >= MIN_PAD_SPACING


def _gate(ep: Episode) -> float:
    """The S_G a grasp must reach (Eq. 13): 0.4, or a lateral grasp's gate for its number of
    contacts (:meth:`fsm.config.TaskConfig.lateral_gate_for`: counted from the thumb's
    opposition by default)."""
    if not is_lateral(ep):
        return SUCCESS_THRESHOLD
    return ep.config.lateral_gate_for(len(ep.synthesis.theta))
