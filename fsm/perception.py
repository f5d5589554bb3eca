"""Select/Model's perception bookkeeping (section 5.2, Select/Model): the overhead view
segmented into blocks, which block a cycle picks, the picked block's model taken into the
episode, the other blocks' footprints, and the place point of the cycle."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from controllers.hand.finger_geometry import PerceivedPrism
from controllers.planning.belief import planning_model
from controllers.planning.belief_world import BeliefWorld, modelled_block, outline_block
from controllers.preshape.palm_candidates import robot_base_xy
from controllers.reach.coarse import ReachTarget
from fsm.context import PLACE_BY_SCENE, PLACE_BY_TASK, PLACE_BY_USER, Episode, EpisodeOptions
from fsm.layout import ASKED_CLEARANCE, free_slot, place_is_free
from fsm.recorder_protocol import VisionView
from fsm.states import Failure, TaskFailedError
from hand_sim.geometry import point_in_convex_polygon
from hand_sim.scene_spec import BlockSpec
from hand_sim.world import World
from vision import ObjectModel, Selection, VisionError, analyze

#: Name prefix of a seen block without a label (``unlabelled_3``: block 3 of the view).
UNLABELLED = "unlabelled_"


def perceive(
    world: BeliefWorld,
    on_image: Callable[[NDArray[np.uint8]], None] | None = None,
    *,
    check_camera: bool = True,
) -> Selection:
    """Look through the overhead camera (:meth:`BeliefWorld.look`: the simulated camera's image,
    the calibrated camera's geometry) and segment the view. The blocks are named after the
    robot's labels (:attr:`BeliefWorld.labels`: the task's layout, then where it last saw or put
    each block), the nearest within 3 cm, as an operator's labels would; the shapes and poses
    come from the image. ``on_image`` receives the image as soon as it is taken, before the
    segmentation (the interactive page shows it). ``check_camera``: the camera's calibration is
    checked against the table in the same view first (``BeliefWorld.look``)."""
    obs = world.look(check=check_camera)
    if on_image is not None:
        on_image(obs.rgb)
    return analyze(obs, world.labels)


def seen_blocks(
    world: BeliefWorld, selection: Selection, name: str, model: ObjectModel
) -> list[BlockSpec]:
    """The blocks the view ``selection`` shows on the table, as the robot's belief holds them
    (:meth:`BeliefWorld.see`): the picked one (``name``) as ``model``, every other modelled one
    as its polygon, one the vision cannot model as the hull of its top face's pixels grown by
    :data:`OBSTACLE_MARGIN`; each extruded from the table to its seen top. A region inside the
    picked block's outline (a fragment of its own view) is left out, and so is one that is a
    modelled block's side face (:func:`side_face`)."""
    table_z = world.scene.table.height
    out = [modelled_block(name, model.polygon, model.centroid[:2], model.yaw, model.height)]
    index = selection.index_of_model(model)
    if index is None:
        index = selection.index_near(model.centroid)
    others, prisms = _others_modelled(world, selection, index, model)
    for i, seen in others.items():
        label = selection.names[i] or f"{UNLABELLED}{i}"
        if isinstance(seen, ObjectModel):
            xy = seen.centroid[:2]
            out.append(modelled_block(label, seen.polygon, xy, seen.yaw, seen.height))
        elif not side_face(selection, i, prisms):
            outline = obstacle_footprint(selection, i)
            if outline is not None:
                out.append(outline_block(label, outline, selection.blocks[i].z_top - table_z))
    return out


def _others_modelled(
    world: World, selection: Selection, index: int, picked: ObjectModel
) -> tuple[dict[int, ObjectModel | VisionError], list[tuple[NDArray[np.float64], float]]]:
    """The regions of ``selection`` on the table other than ``index`` (the picked block, modelled
    as ``picked``) and outside its outline, in the view's order, each with its model or why the
    vision refused it; and the prisms (world footprint, top z) of the picked and the modelled
    blocks."""
    centres = selection.block_centres()
    others: dict[int, ObjectModel | VisionError] = {}
    prisms = [(picked.world_vertices, float(picked.centroid[2]))]
    for i in range(len(selection.blocks)):
        if i == index or not on_table(world, selection, i):
            continue
        if point_in_convex_polygon(centres[i][:2], picked.world_vertices):
            continue  # a fragment of the picked block's own view
        try:
            seen = others[i] = selection.model(i)
            prisms.append((seen.world_vertices, float(seen.centroid[2])))
        except VisionError as e:
            others[i] = e
    return others, prisms


#: A region the vision cannot model whose points (from the depth image) lie within this
#: distance (m) of a modelled block's prism is that block's side face, seen in perspective at
#: the image's edge, not a block of its own: three times the depth's noise under the
#: ``sensing`` perturbation (1 mm), over five pixels on the table. Set before any run:
#: docs/findings.md, "A side face is its block".
SIDE_FACE_TOLERANCE = 0.003
#: ...for at least this share of the region's points.
SIDE_FACE_SHARE = 0.9


def side_face(
    selection: Selection, index: int, prisms: list[tuple[NDArray[np.float64], float]]
) -> bool:
    """Whether region ``index`` of ``selection`` is a side face of one of ``prisms`` (world
    footprint vertices (k, 2), CCW, and top z; each standing on the table): its pixels' points,
    from the depth image, lie within :data:`SIDE_FACE_TOLERANCE` of the prism, at least
    :data:`SIDE_FACE_SHARE` of them."""
    v, u = np.nonzero(selection.blocks[index].top_mask)
    if u.size == 0:
        return False
    obs = selection.observation
    g = obs.geometry
    depth = obs.depth[v, u].astype(float)
    points = g.position + g.rays(np.column_stack([u, v]).astype(float)) * depth[:, None]
    points = points[np.isfinite(points).all(axis=1)]
    if len(points) == 0:
        return False
    for vertices, top in prisms:
        edges = np.roll(vertices, -1, axis=0) - vertices
        normals = np.column_stack([edges[:, 1], -edges[:, 0]])  # outward of a CCW polygon
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        outside = np.einsum("nkj,kj->nk", points[:, None, :2] - vertices[None], normals).max(1)
        near = (outside <= SIDE_FACE_TOLERANCE) & (points[:, 2] <= top + SIDE_FACE_TOLERANCE)
        if near.mean() >= SIDE_FACE_SHARE:
            return True
    return False


def adopt_model(ep: Episode, name: str, model: ObjectModel) -> None:
    """Take ``model`` as the picked block's (named ``name``): the robot's belief holds the
    blocks of the view it came from (:func:`seen_blocks`), the reach target, the perceived prism
    the fingers keep clear of, and the planning model the arm's paths avoid (built from that
    belief: every obstacle is a block the camera saw, never a simulated body)."""
    world = ep.world
    world.see(seen_blocks(world, ep.selection, name, model))
    ep.model = model
    ep.target = ReachTarget.from_object_model(model)
    ep.prism = PerceivedPrism.of(ep.target, world.scene.table.height)
    ep.planning = planning_model(
        world, name, ep.target.polygon, ep.target.yaw, ep.target.position_xy, ep.target.top_z
    )


def log_view(ep: Episode, model: ObjectModel) -> None:
    """Record the overhead view Select/Model looked at and the picked block's model in it."""
    ep.recorder.log_vision(
        VisionView(
            ep.selection.observation.rgb,
            ep.selection.observation.geometry.K,
            ep.selection.observation.geometry.cam_to_world,
            model.world_vertices,
            model.pixel_contour,
            float(model.centroid[2]),
        )
    )


def on_table(world: World, selection: Selection, index: int) -> bool:
    """Whether block ``index`` of ``selection`` has its centre over the table."""
    centre = selection.block_centres()[index][:2]
    return bool(world.scene.table.contains(centre[None], margin=0.0))


def choose_blocks(
    world: World,
    selection: Selection,
    options: EpisodeOptions,
    cycle: int,
    delivered: list[str],
) -> list[int]:
    """Indices (in ``selection``) of the blocks cycle ``cycle`` may pick, in the order to try
    them: the first cycle's one block as ``options`` ask (a pixel, a name, or the scene's
    target); in later cycles the remaining blocks on the table (not in ``delivered``), nearest
    the arm's base first (one that cannot be modelled gives way to the next). Raises
    LookupError when none is left."""
    sel = selection
    if cycle == 0 and options.pick_pixel is not None:
        return [sel.index_at_pixel(options.pick_pixel)]
    if cycle == 0:
        return [sel.index_of_name(options.pick or world.scene.target)]
    remaining = [
        i
        for i, name in enumerate(sel.names)
        if name is not None and name not in delivered and on_table(world, sel, i)
    ]
    if not remaining:
        raise LookupError("no block left")
    centres = sel.block_centres()[:, :2]
    base = np.asarray(robot_base_xy(world))
    return sorted(remaining, key=lambda i: float(np.linalg.norm(centres[i] - base)))


@dataclass(frozen=True)
class PlaceChoice:
    """A cycle's place point: the one asked for (None when nothing was asked: the later cycles of
    ``--cycles``), who chose the point to use (``fsm.context.PLACE_BY_*``) and that point."""

    asked: NDArray[np.float64] | None
    chosen_by: str
    point: NDArray[np.float64]


def place_for_cycle(
    world: World,
    options: EpisodeOptions,
    cycle: int,
    footprints: list[NDArray[np.float64]],
    radius: float,
    place_reach: tuple[float, float],
) -> PlaceChoice:
    """This cycle's place point for a block of circumradius ``radius`` (m). The first cycle's is
    the one asked for (``--place`` / ``--place-pixel``, else the scene's); it must be clear of the
    other blocks' ``footprints``, or, with ``--place-fallback nearest``, the nearest free slot is
    used instead. Later cycles choose their own: the free slot nearest the first place point,
    within ``place_reach`` (m) of the arm's base. Raises :class:`TaskFailedError` when there is
    none."""
    scene = world.scene
    first = np.asarray(options.place if options.place is not None else scene.place, dtype=float)
    reach = (robot_base_xy(world), *place_reach)
    if cycle == 0:
        by = PLACE_BY_SCENE if options.place is None else PLACE_BY_USER
        if place_is_free(first, radius, footprints, scene.table, ASKED_CLEARANCE):
            return PlaceChoice(first, by, first)
        occupied = f"place point {first.round(3).tolist()} is occupied by another block"
        slot = None
        if options.place_fallback == "nearest":
            slot = free_slot(first, radius, footprints, scene.table, reach)
        if slot is None:
            hint = (
                "; no free slot near it either"
                if options.place_fallback == "nearest"
                else " (--place-fallback nearest would deliver to the nearest free slot)"
            )
            raise TaskFailedError(Failure.PLACE_UNREACHABLE, occupied + hint)
        return PlaceChoice(first, by, slot)
    slot = free_slot(first, radius, footprints, scene.table, reach)
    if slot is None:
        raise TaskFailedError(Failure.PLACE_UNREACHABLE, "no free place slot left on the table")
    return PlaceChoice(None, PLACE_BY_TASK, slot)


#: A block Select/Model cannot model stands in the way as the convex hull of its top face's
#: pixels grown by this margin (m) on every side.
OBSTACLE_MARGIN = 0.01


def obstacle_footprint(
    selection: Selection, index: int, margin: float = OBSTACLE_MARGIN
) -> NDArray[np.float64] | None:
    """World footprint (k, 2) of block ``index`` of ``selection`` as an obstacle, without its
    polygon: the convex hull of its top face's pixels cast onto the top's plane, grown by
    ``margin`` (m) (eight offsets of every hull point, hulled again, so that a region of one
    pixel or one pixel wide still gives an area). None when the region has no pixel."""
    region = selection.blocks[index]
    v, u = np.nonzero(region.top_mask)
    if u.size == 0:
        return None
    g = selection.observation.geometry
    pixels = np.unique(np.column_stack([u, v]).astype(np.float32), axis=0)
    hull = cv2.convexHull(pixels).reshape(-1, 2) if len(pixels) >= 3 else pixels
    xy = g.pixel_to_plane(hull.astype(float), region.z_top)[:, :2]
    angles = np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False)
    ring = margin * np.column_stack([np.cos(angles), np.sin(angles)])
    grown = (xy[:, None, :] + ring[None]).reshape(-1, 2).astype(np.float32)
    return cv2.convexHull(grown).reshape(-1, 2).astype(float)


def other_footprints(
    world: World, selection: Selection, index: int, picked: ObjectModel
) -> tuple[list[NDArray[np.float64]], list[str]]:
    """World footprints of the blocks of ``selection`` on the table other than ``index`` (the
    picked block, modelled as ``picked``), as perceived, and why each block that could not be
    modelled was not: such a block counts as an obstacle by :func:`obstacle_footprint`, unless
    it is a modelled block's side face (:func:`side_face`)."""
    out = []
    unmodelled = []
    others, prisms = _others_modelled(world, selection, index, picked)
    for i, seen in others.items():
        if isinstance(seen, ObjectModel):
            out.append(seen.world_vertices)
        elif not side_face(selection, i, prisms):
            unmodelled.append(str(seen))
            footprint = obstacle_footprint(selection, i)
            if footprint is not None:
                out.append(footprint)
    return out, unmodelled
