"""One module per state of the task cycle (section 5.2, Figure 14): each handler calls into
``vision`` and ``controllers``, updates the :class:`~fsm.context.Episode` and returns the next
state with the reason for the transition (a :class:`Step`), or raises
:class:`TaskFailedError` with a named reason. :data:`HANDLERS` maps each state to its
handler (:mod:`fsm.machine` runs them); the two wait states are entered only in interactive
mode (:mod:`fsm.user_protocol`). What the states share lives beside this package:
:mod:`fsm.episode_queries` (the episode's view of the controllers' inputs),
:mod:`fsm.lateral_preshape` (the lateral pre-shape search's inputs and result) and
:mod:`fsm.recovery` (the regrasp, looking again, the other approach)."""

from __future__ import annotations

from collections.abc import Callable

from fsm.context import Episode
from fsm.handlers.coarse_reach import coarse_reach
from fsm.handlers.deliver import deliver
from fsm.handlers.fine_reach import fine_reach_state
from fsm.handlers.grasp_object import grasp_object
from fsm.handlers.posture_control import posture_control
from fsm.handlers.select_model import select_model
from fsm.handlers.wait_for_block import wait_for_block
from fsm.handlers.wait_for_place import wait_for_place
from fsm.handlers.wrench_closure import wrench_closure
from fsm.states import State, Step, TaskFailedError

Handler = Callable[[Episode], Step]

HANDLERS: dict[State, Handler] = {
    State.SELECT_MODEL: select_model,
    State.COARSE_REACH: coarse_reach,
    State.FINE_REACH: fine_reach_state,
    State.POSTURE_CONTROL: posture_control,
    State.WRENCH_CLOSURE: wrench_closure,
    State.GRASP_OBJECT: grasp_object,
    State.DELIVER: deliver,
    State.WAIT_FOR_BLOCK: wait_for_block,
    State.WAIT_FOR_PLACE: wait_for_place,
}

__all__ = [
    "HANDLERS",
    "Handler",
    "Step",
    "TaskFailedError",
    "coarse_reach",
    "deliver",
    "fine_reach_state",
    "grasp_object",
    "posture_control",
    "select_model",
    "wait_for_block",
    "wait_for_place",
    "wrench_closure",
]
