"""The other approach under ``--approach auto`` (section 5.2: "The path computed determines
whether a top or lateral grasp will be executed"): Coarse Reach takes the shorter of the two
paths, and the paper's choice also weighs whether a grasp is reachable at the end of it. Where
the top approach's grasp proves unreachable there (Posture Control's retries and every regrasp
spent, or a fingertip held off its contact after them), the hand lets go, the arm parks, the
camera models the block again and Coarse Reach plans the lateral approach, which had a path
too, instead of the episode failing."""

from __future__ import annotations

from fsm.context import Episode
from fsm.handlers.look_again import release_and_look
from fsm.states import Failure, State, Step

#: The failures that say a grasp is not reachable at the approach's end (the grasp's contacts
#: out of the hand's reach, or its fingertips held off them), after which ``auto`` may take
#: the other approach.
UNREACHABLE = (Failure.CONTACT_UNREACHABLE, Failure.FINGERS_CANNOT_REACH)


def other_approach_left(ep: Episode, failure: Failure) -> str | None:
    """The approach ``auto`` takes next when the grasp at the end of the one taken is
    unreachable (``failure`` one of :data:`UNREACHABLE`): the lateral one after a top grasp,
    when Coarse Reach found a path for it too; None otherwise (an approach forced on the
    command line, a lateral grasp, the approach taken after a switch, another failure)."""
    coarse = ep.coarse
    if ep.options.approach != "auto" or coarse is None or failure not in UNREACHABLE:
        return None
    if coarse.approach != "top":  # after the switch Coarse Reach's plan is the lateral one
        return None
    lateral = coarse.candidates.get("lateral")
    return "lateral" if lateral is not None and lateral.found else None


def take_other_approach(ep: Episode, approach: str, failure: Failure, detail: str) -> Step:
    """Give up the approach taken (its grasp unreachable at its end: ``failure``, ``detail``),
    let go, park, look again (:func:`fsm.handlers.look_again.release_and_look`) and go back to
    Coarse Reach for ``approach``, its regrasp and posture-retry counts starting afresh. The
    summary's ``approach_given_up`` says which approach was given up and why."""
    given_up = ep.coarse.approach
    parked, moved = release_and_look(ep, detail, failure)
    ep.closed_approaches += (given_up,)
    record = ep.record
    record.approach_given_up = f"{given_up}: {failure.value}: {detail}"
    record.regrasps = record.posture_retries = 0
    ep.synthesis = ep.contacts = ep.reach = ep.grip = None
    ep.regrasp_failure = None
    return Step(
        State.COARSE_REACH,
        f"{given_up} grasp unreachable at its end ({failure.value}: {detail}): released, "
        f"{parked}; seen again {moved * 1000:.0f} mm from where it was modelled: the "
        f"{approach} approach next (auto)",
    )
