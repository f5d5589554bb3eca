"""Wrench Closure (section 5.2): the grasp controller moves virtual contacts on the perceived
polygon until it converges, while the hand's reachability of the contacts is checked."""

from __future__ import annotations

import numpy as np

from controllers.fine_reach import project_to_surface
from controllers.grasp.session import GraspSynthesis
from controllers.hand_reach import CONTACT_SEPARATION, MIN_PAD_SPACING, reachable_contacts
from fsm.context import Episode
from fsm.handlers.common import contact_points, reach_query
from fsm.recorder_protocol import SynthesisRecord
from fsm.states import Failure, State, Step, TaskFailedError
from hand_sim import robot


def wrench_closure(ep: Episode) -> Step:
    """Wrench Closure: the grasp controller (kb, ql or pi) moves virtual contacts on the
    perceived polygon from the fingertips' projections until it converges; every
    ``config.reach_check_every`` steps the hand's reachability of the contacts is checked and an
    unreachable set sends the machine back to Posture Control."""
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
            min_separation=CONTACT_SEPARATION,
            separation_offset=robot.PAD_RADIUS,
        )
    syn = ep.synthesis
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
            check_spacing=syn.done,
            slide=query.slide,
            samples=query.samples,
            squeeze=query.squeeze,
            # an unreachable top grasp only needs the verdict (a lateral one keeps its heights)
            give_up=not query.slide,
        )
        ep.contacts, ep.reach = contacts, reach
        if syn.done and reach.min_spacing < MIN_PAD_SPACING:
            raise TaskFailedError(Failure.CONTACT_UNREACHABLE, reach.reason)
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
