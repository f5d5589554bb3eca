"""Wait for Place (interactive mode; section 5.2, Deliver: "At this point, the user is prompted to
enter a delivery point to which the object should be moved. Again, this selection is done
directly on the overhead image"): after Grasp Object the hand holds the block at the grip force
on the table; the overhead camera shows the table as it is now and the state waits for a click
on a point the block can be set down at. The world is frozen meanwhile (no physics step), so the
hand holds the block as Grasp Object left it however long the user takes.

A click is taken with the task cycle's own checks of a place point: on the table with the block's
circumradius to spare (``fsm.run --place``'s check), within the arm's placing reach
(``TaskConfig.place_reach``), clear of every other block as Select/Model perceived them
(:func:`fsm.layout.place_is_free`, the clearance a point asked for needs), and a set-down the
hand can make there holding the block as it does (Deliver's planner without the transit:
:func:`controllers.deliver.plan.plan_delivery`). A click that fails one is refused with the
reason; the block stays held and the state waits on."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.deliver.plan import plan_delivery
from controllers.preshape.palm_candidates import robot_base_xy
from fsm.context import PLACE_BY_USER, Episode
from fsm.handlers.wait_for_block import user_of
from fsm.layout import ASKED_CLEARANCE, place_is_free
from fsm.states import Failure, State, Step, TaskFailedError
from fsm.user_protocol import WAITING_FOR_PLACE, Pixel
from vision import CameraGeometry


def wait_for_place(ep: Episode) -> Step:
    """Wait for Place: the overhead image to the user, then the user's clicks until one is a
    place point the block can be set down at; hand over to Deliver with it. The run ending
    meanwhile fails the cycle as interrupted (its files are written; the hand still holds the
    block)."""
    user = user_of(ep)
    world = ep.world
    obs = world.look()  # the camera's image, read with the camera's calibrated geometry
    user.show_view(obs.rgb, WAITING_FOR_PLACE)
    log = ep.recorder.log_transition
    here = State.WAIT_FOR_PLACE.value
    log(here, here, f"holding {ep.target_name}; waiting for the user's click on a place point")
    while True:
        pixel = user.next_click(WAITING_FOR_PLACE)
        if pixel is None:
            raise TaskFailedError(
                Failure.INTERRUPTED,
                f"the run was ended while the hand held {ep.target_name}, waiting for a place "
                "point",
            )
        point = place_at(obs.geometry, pixel, world.scene.table.height)
        problem = place_problem(ep, point)
        if problem:
            user.refuse(f"{problem}; {ep.target_name} stays in the hand: click another point")
            log(here, here, f"click at pixel {list(pixel)} refused: {problem}")
            continue
        record = ep.record
        record.place_asked = (float(point[0]), float(point[1]))
        record.place_chosen_by = PLACE_BY_USER
        ep.use_place(point)
        where = f"({point[0]:.3f}, {point[1]:.3f})"
        user.accept(f"{ep.target_name} goes to {where} m")
        return Step(State.DELIVER, f"the user clicked pixel {list(pixel)}: place at {where} (user)")


def place_at(geometry: CameraGeometry, pixel: Pixel, table_z: float) -> NDArray[np.float64]:
    """The table point (world x, y) seen at ``pixel``: the pixel's ray met with the plane of the
    table top (as ``fsm.run --place-pixel`` reads a pixel)."""
    point = geometry.pixel_to_plane(np.asarray(pixel, dtype=float), table_z)
    return np.asarray(point[:2], dtype=float)


def place_problem(ep: Episode, point: NDArray[np.float64]) -> str:
    """Why the held block cannot be set down at ``point`` (world x, y), or "" when it can: off
    the table, out of the arm's reach, occupied by another block (as perceived), or no set-down
    posture for the hand holding it as it does."""
    world = ep.world
    table = world.scene.table
    radius = ep.place_radius
    where = f"({point[0]:.3f}, {point[1]:.3f})"
    if not place_is_free(point, radius, [], table):  # the table alone: the block fits on it
        return (
            f"off the table: {where} m leaves no room for the block on the table top "
            f"({table.size_xy[0]:.2f} x {table.size_xy[1]:.2f} m)"
        )
    base = np.asarray(robot_base_xy(world))
    d = float(np.linalg.norm(point - base))
    lo, hi = ep.config.place_reach
    if not lo <= d <= hi:
        return (
            f"out of reach: {where} m is {d:.2f} m from the arm's waist axis; the arm places "
            f"within {lo:.2f}-{hi:.2f} m"
        )
    if not place_is_free(point, radius, ep.place_footprints, table, ASKED_CLEARANCE):
        return f"occupied: {where} m is taken by {_nearest_block(ep, point)}"
    plan = plan_delivery(
        world,
        ep.target_name,
        point,
        block_height=ep.model.height,
        nearer=True,
        with_transit=False,
        check_lift=False,
    )
    if not plan.found:
        return f"no set-down there for the hand as it holds the block: {plan.reason}"
    return ""


def _nearest_block(ep: Episode, point: NDArray[np.float64]) -> str:
    """The name of the other block (as Select/Model saw them) nearest ``point``."""
    selection = ep.selection
    if selection is None or not selection.blocks:
        return "another block"
    centres = selection.block_centres()[:, :2]
    order = np.argsort(np.linalg.norm(centres - point, axis=1))
    for i in order:
        name = selection.names[int(i)]
        if name is not None and name != ep.target_name:
            return name
    return "another block"
