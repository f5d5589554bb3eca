"""Wait for Block (interactive mode; section 5.2, Select/Model: "The user starts the cycle by
selecting the object to be grasped; this selection is done directly on the overhead image, by
clicking on the object image"): the overhead camera looks at the table, the user is shown the
image, and the state waits for a click on a block the vision can model. A click on the table,
outside the image, on the arm, or on a block the vision refuses is refused with its reason and
the state waits on; nothing moves meanwhile (the world is frozen: no physics step while
waiting). A cycle after a failed one first lets go of the block, backs the hand off and parks
the arm, so that the camera sees the table (Select/Model's guard)."""

from __future__ import annotations

import contextlib

import numpy as np

from controllers.deliver.carry import retreat
from controllers.errors import ReachError
from controllers.hand.grip import release
from controllers.planning.cspace import CollisionChecker
from fsm.context import Episode
from fsm.episode_queries import top_to_clear
from fsm.perception import on_table, perceive
from fsm.recovery import park_arm
from fsm.states import State, Step
from fsm.user_protocol import WAITING_FOR_BLOCK, ClickedBlock, Pixel, UserChannel
from vision import NotABlockError, Selection, VisionError

#: The arm counts as parked when every joint is within this (rad) of its parked posture.
PARKED_TOLERANCE = 1e-2


def user_of(ep: Episode) -> UserChannel:
    """The episode's user; the wait states are entered only in interactive mode."""
    if ep.user is None:
        raise RuntimeError("a wait state was entered in an episode without a user")
    return ep.user


def wait_for_block(ep: Episode) -> Step:
    """Wait for Block: the overhead image to the user, then the user's clicks until one lands on
    a block the vision models; hand over to Select/Model with that view and block, or to Done
    when the run ends while waiting."""
    user = user_of(ep)
    world = ep.world
    readied = _ready_after_failure(ep)
    if ep.parked_arm is None:
        ep.parked_arm = world.arm_qpos().copy()
    selection = perceive(world, on_image=lambda rgb: user.show_view(rgb, WAITING_FOR_BLOCK))
    log = ep.recorder.log_transition
    here = State.WAIT_FOR_BLOCK.value
    log(here, here, f"{readied}waiting for the user's click on a block in the overhead image")
    while True:
        pixel = user.next_click(WAITING_FOR_BLOCK)
        if pixel is None:
            return Step(State.DONE, "the run was ended while waiting for a block")
        taken = block_at(ep, selection, pixel)
        if isinstance(taken, str):
            user.refuse(taken)
            log(here, here, f"click at pixel {list(pixel)} refused: {taken}")
            continue
        ep.clicked = taken
        name = selection.names[taken.index]
        model = taken.model
        user.accept(
            f"{name}: {model.n_edges} edges, modelled from the click at pixel {list(pixel)}",
            model.pixel_contour,
        )
        return Step(State.SELECT_MODEL, f"the user clicked pixel {list(pixel)}: {name}")


def block_at(ep: Episode, selection: Selection, pixel: Pixel) -> ClickedBlock | str:
    """The block under ``pixel`` of ``selection`` with the vision's model of it, or why the click
    is refused: not on a block ("no block there"), on a block off the table, or on a block the
    vision cannot model (the reason Select/Model would fail with, "polygon not modelled")."""
    try:
        index = selection.index_at_pixel(pixel)
    except NotABlockError as e:
        return f"no block there: click on a block ({str(e).split('; ')[0]})"
    name = selection.names[index]
    if name is None:
        return f"no block there: click on a block (pixel {list(pixel)} is not on a known block)"
    if not on_table(ep.world, selection, index):
        return f"{name} is not on the table: click on a block on the table"
    try:
        model = selection.model(index)
    except VisionError as e:
        return f"polygon not modelled: {e}; click another block"
    return ClickedBlock(selection, index, model, (int(pixel[0]), int(pixel[1])))


def _ready_after_failure(ep: Episode) -> str:
    """After a failed cycle, the hand lets go of what it holds, backs off and the arm parks
    (:func:`fsm.recovery.park_arm`); returns what was done, for the log ("" when the arm is
    parked already). A motion that cannot be made is skipped: the camera then sees the arm
    where it stands."""
    world = ep.world
    last = ep.cycles[-1] if ep.cycles else None
    if last is None or last.success or ep.parked_arm is None:
        return ""
    if np.allclose(world.arm_qpos(), ep.parked_arm, atol=PARKED_TOLERANCE):
        return ""
    done = []
    if ep.grip is not None:
        release(world, ep.grip)
        ep.grip = None
        done.append("the hand let go")
    with contextlib.suppress(ReachError):
        clear_top = top_to_clear(ep) if ep.target is not None else None
        retreat(world, CollisionChecker(world), clear_top=clear_top)
        done.append("backed off")
    done.append(park_arm(ep))
    return f"after the failed cycle {', '.join(done)}; "
