"""Select/Model (section 5.2): the picked block's polygon, centroid and yaw from the overhead
image, its planning model, and the cycle's place point."""

from __future__ import annotations

import numpy as np

from fsm.context import CycleRecord, Episode
from fsm.judge import other_blocks_now, seen_against_truth
from fsm.perception import (
    adopt_model,
    choose_blocks,
    log_view,
    other_footprints,
    perceive,
    place_for_cycle,
)
from fsm.states import Failure, State, Step, TaskFailedError
from hand_sim.blocks import WOOD_DENSITY
from hand_sim.robot import STANDARD_GRAVITY
from vision import VisionError


def select_model(ep: Episode) -> Step:
    """Select/Model: the picked block's polygon, centroid and yaw from the overhead image."""
    record = ep.new_cycle()
    world = ep.world
    if ep.parked_arm is None:
        ep.parked_arm = world.arm_qpos().copy()
    clicked, ep.clicked = ep.clicked, None
    check = ep.config.closed_loop.camera_check
    ep.selection = perceive(world, check_camera=check) if clicked is None else clicked.selection
    camera = world.last_check
    if camera is not None and camera.corrected:
        record.camera_recalibrated = {
            "shift_mm": round(camera.shift * 1000.0, 2),
            "turn_deg": round(float(np.degrees(camera.turn)), 3),
        }
    try:
        candidates = (
            choose_blocks(world, ep.selection, ep.options, ep.cycle, ep.delivered)
            if clicked is None
            else [clicked.index]  # interactive: the block clicked, in the view clicked on
        )
    except LookupError:
        return Step(State.DONE, "no block left to pick")
    except VisionError as e:  # NotABlockError among them
        raise TaskFailedError(Failure.NO_BLOCK_AT_PICK, str(e)) from e
    reasons = []
    for index in candidates:
        try:
            model = ep.selection.model(index)
            break
        except VisionError as e:
            reasons.append(str(e))
    else:
        raise TaskFailedError(Failure.POLYGON_NOT_MODELLED, "; ".join(reasons))
    record.skipped_not_modelled = reasons
    name = ep.selection.names[index]
    if name is None:
        raise TaskFailedError(Failure.NO_BLOCK_AT_PICK, "the selected region is not a block")
    record.block = name
    adopt_model(ep, name, model)
    ep.expected_load = model.polygon.area * model.height * WOOD_DENSITY * STANDARD_GRAVITY
    record.polygon = model.polygon.vertices.round(5).tolist()
    # judged, for the summary: the block's true position and the model's error against it
    record.block_start, record.polygon_error = seen_against_truth(
        ep.simulated, name, model.centroid, model.polygon.area, model.n_edges
    )
    # the place point must be clear of every other perceived block
    footprints, unmodelled = other_footprints(world, ep.selection, index, model)
    record.obstacles_not_modelled = unmodelled
    radius = float(np.linalg.norm(model.polygon.vertices, axis=1).max())
    if ep.user is not None:  # interactive: the user clicks the place point after Grasp Object
        ep.place_footprints, ep.place_radius = footprints, radius
        ep.place = None
    else:
        reach = ep.config.place_reach
        choice = place_for_cycle(world, ep.options, ep.cycle, footprints, radius, reach)
        ep.place_footprints, ep.place_radius = footprints, radius
        if choice.asked is not None:
            record.place_asked = (float(choice.asked[0]), float(choice.asked[1]))
        record.place_chosen_by = choice.chosen_by
        ep.use_place(choice.point)
    ep.others_before = other_blocks_now(ep.simulated, name)  # for the judge
    ep.recorder.set_target(name)
    log_view(ep, model)
    return Step(
        State.COARSE_REACH,
        f"picked {name}: {model.n_edges} edges, centroid "
        f"({model.centroid[0]:.3f}, {model.centroid[1]:.3f}) m, "
        f"yaw {np.degrees(model.yaw):.0f} deg; {place_text(record)}",
    )


def place_text(record: CycleRecord) -> str:
    """The cycle's place point for the transition log: where it goes, who chose it, and the point
    asked for when it differs (``--place-fallback nearest``)."""
    used = record.place_used
    if used is None:
        return "the place point is the user's click after Grasp Object"
    text = f"place at ({used[0]:.3f}, {used[1]:.3f}) ({record.place_chosen_by})"
    if record.delivered_elsewhere and record.place_asked is not None:
        asked = record.place_asked
        text += (
            f", elsewhere than the place point asked for ({asked[0]:.3f}, {asked[1]:.3f}): "
            f"{record.place_moved_mm:.0f} mm away"
        )
    return text
