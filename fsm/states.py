"""The states of the task cycle and everything about them a reader needs in one place: Figure 14
of the paper (section 5.2) as a table of states, their guards, time budgets, the states each may
hand over to, and the failure reasons each may end the episode with.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class State(Enum):
    """The modules of section 5.2, sequenced by the finite state machine of Figure 14."""

    SELECT_MODEL = "Select/Model"
    COARSE_REACH = "Coarse Reach"
    FINE_REACH = "Fine Reach"
    POSTURE_CONTROL = "Posture Control"
    WRENCH_CLOSURE = "Wrench Closure"
    GRASP_OBJECT = "Grasp Object"
    DELIVER = "Deliver"
    #: interactive mode only (fsm.interactive, section 5.1): the user's click on a block before
    #: Select/Model, and on the delivery point after Grasp Object; the world is frozen meanwhile
    WAIT_FOR_BLOCK = "Wait for Block"
    WAIT_FOR_PLACE = "Wait for Place"
    DONE = "Done"
    FAILED = "Failed"


class Failure(Enum):
    """Why an episode failed: each is named in the summary and printed on exit."""

    NO_BLOCK_AT_PICK = "no block at the pick point"
    POLYGON_NOT_MODELLED = "polygon not modelled"
    NO_COARSE_PATH = "no coarse path"
    FINGERS_CANNOT_REACH = "fingers cannot reach"
    GRASP_NOT_CONVERGED = "grasp controller did not converge"
    CONTACT_UNREACHABLE = "contact unreachable after posture retries"
    SLIPPED_DURING_LIFT = "block slipped during lift"
    DROPPED_IN_TRANSPORT = "block dropped in transport"
    PLACE_UNREACHABLE = "place point unreachable or occupied"
    SET_DOWN_NOT_SENSED = "set-down not sensed"
    SIMULATION_UNSTABLE = "simulation unstable"
    TIME_BUDGET_EXCEEDED = "time budget exceeded"
    NOT_PLACED = "block not placed as asked"  # the physical judgement after the retreat
    INTERRUPTED = "interrupted"
    #: the last resort: an exception no state names (a bug); its one line is the detail
    INTERNAL_ERROR = "internal error"


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


#: Reasons any state can end with (interrupted: Ctrl-C, or the interactive page's stop).
ANY_STATE_FAILURES = (
    Failure.SIMULATION_UNSTABLE,
    Failure.TIME_BUDGET_EXCEEDED,
    Failure.INTERRUPTED,
    Failure.INTERNAL_ERROR,
)
#: Times Wrench Closure may send the machine back to Posture Control before giving up (the paper's
#: "after a number of transitions between both modules"), and Fine Reach <-> Posture Control.
MAX_POSTURE_RETRIES = 4
MAX_FINE_REACH_LOOPS = 2


@dataclass(frozen=True)
class StateSpec:
    """One row of the transition table."""

    state: State
    guard: str  #: what must hold on entry
    budget: float  #: simulated seconds the state may take (0: none passes, it is instantaneous)
    next: tuple[State, ...]  #: states it may hand over to (FAILED always allowed)
    failures: tuple[Failure, ...]  #: reasons it may fail with (plus ANY_STATE_FAILURES)


TRANSITIONS: dict[State, StateSpec] = {
    s.state: s
    for s in (
        StateSpec(
            State.SELECT_MODEL,
            "the arm is parked clear of the table; a block to pick remains",
            1.0,
            (State.COARSE_REACH, State.DONE),
            (Failure.NO_BLOCK_AT_PICK, Failure.POLYGON_NOT_MODELLED, Failure.PLACE_UNREACHABLE),
        ),
        StateSpec(
            State.COARSE_REACH,
            "a perceived polygon, centroid and yaw of the picked block",
            25.0,
            # again, pitched further down, where no grasp at this pitch can set the block down
            (State.FINE_REACH, State.COARSE_REACH),
            # a lateral regrasp's, after looking again, when no palm pose is left
            (Failure.NO_COARSE_PATH, Failure.FINGERS_CANNOT_REACH, Failure.SLIPPED_DURING_LIFT),
        ),
        StateSpec(
            State.FINE_REACH,
            "the hand is near the block in its pre-shape, top or lateral",
            16.0,  # the reach takes 2-5 s; a finger held off adds the regrasp's repositioning
            # back to Coarse Reach: under auto, the other approach
            # (fsm.recovery.other_approach_left)
            (State.POSTURE_CONTROL, State.FINE_REACH, State.COARSE_REACH),
            (Failure.FINGERS_CANNOT_REACH,),
        ),
        StateSpec(
            State.POSTURE_CONTROL,
            "fingertips near the block's surface (after Fine Reach) or contacts to make reachable "
            "(from Wrench Closure)",
            12.0,  # a repositioning: retract, back out, move, pre-shape, approach (up to ~8 s)
            # back to Coarse Reach: under auto, the other approach
            # (fsm.recovery.other_approach_left)
            (State.FINE_REACH, State.WRENCH_CLOSURE, State.COARSE_REACH),
            (Failure.CONTACT_UNREACHABLE,),
        ),
        StateSpec(
            State.WRENCH_CLOSURE,
            "all fingertips near the block's surface",
            0.0,
            (State.POSTURE_CONTROL, State.GRASP_OBJECT),
            (Failure.GRASP_NOT_CONVERGED, Failure.CONTACT_UNREACHABLE),
        ),
        StateSpec(
            State.GRASP_OBJECT,
            "a converged grasp (S_G <= 0.4) whose contacts the hand reaches",
            # closing and squeezing take 3-5 s; a miss adds the regrasp's repositioning (a
            # lateral one's release, retreat and park, fsm.recovery.look_again: up to ~12 s)
            30.0,
            # Wait for Place: interactive mode only (the user's delivery point)
            (State.DELIVER, State.FINE_REACH, State.COARSE_REACH, State.WAIT_FOR_PLACE),
            (Failure.FINGERS_CANNOT_REACH,),
        ),
        StateSpec(
            State.DELIVER,
            "all four pads feel the block at the grip force",
            60.0,
            # Wait for Block: interactive mode only (the next cycle waits for the user's click)
            (State.SELECT_MODEL, State.COARSE_REACH, State.DONE, State.WAIT_FOR_BLOCK),
            (
                Failure.SLIPPED_DURING_LIFT,
                Failure.DROPPED_IN_TRANSPORT,
                Failure.PLACE_UNREACHABLE,
                Failure.SET_DOWN_NOT_SENSED,
                Failure.NOT_PLACED,
            ),
        ),
        StateSpec(
            State.WAIT_FOR_BLOCK,
            "interactive mode; the arm is parked clear of the table (after a failed cycle the "
            "hand first lets go and the arm parks)",
            # the wait itself takes no simulated time (the world is frozen); the park after a
            # failed cycle takes up to ~15 s
            30.0,
            (State.SELECT_MODEL, State.DONE),
            (),
        ),
        StateSpec(
            State.WAIT_FOR_PLACE,
            "interactive mode; the hand holds the block at the grip force, on the table",
            0.0,
            (State.DELIVER,),
            (),
        ),
    )
}


def allowed(current: State, following: State) -> bool:
    """Whether the table lets ``current`` hand over to ``following`` (FAILED always may)."""
    if following is State.FAILED:
        return current in TRANSITIONS
    spec = TRANSITIONS.get(current)
    return spec is not None and following in spec.next


def table_markdown() -> str:
    """The transition table as Markdown (for the README and docs)."""
    rows = [
        "| state | guard on entry | budget (sim s) | next | may fail with |",
        "|---|---|---:|---|---|",
    ]
    for spec in TRANSITIONS.values():
        budget = f"{spec.budget:g}" if spec.budget else "virtual"
        rows.append(
            f"| {spec.state.value} | {spec.guard} | {budget} | "
            f"{', '.join(s.value for s in spec.next)} | "
            f"{'; '.join(f.value for f in spec.failures)} |"
        )
    return "\n".join(rows)
