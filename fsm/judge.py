"""Is the block really placed? The physical judgement of one delivery, from the simulation's
true state after the hand has retreated; nothing is read back from a commanded target.

A delivery succeeds when the block is within :data:`PLACE_TOLERANCE` of the place point
(horizontally), upright (tilt under :data:`MAX_TILT_DEG`), at rest (under :data:`MAX_SPEED` and
:data:`MAX_SPIN`), was lifted at least :data:`MIN_LIFT` clear of the table while carried, no finger
touches it and the palm is at least :data:`MIN_PALM_DISTANCE` away, and no other block moved more
than :data:`MAX_OTHER_MOTION`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from hand_sim import robot
from hand_sim.contacts import robot_contacts
from hand_sim.world import World

PLACE_TOLERANCE = 0.02  #: m
MAX_TILT_DEG = 10.0
MAX_SPEED = 0.01  #: m/s
MAX_SPIN = 0.5  #: rad/s
MIN_LIFT = 0.05  #: m, block bottom above the table during the carry
MIN_PALM_DISTANCE = 0.05  #: m, palm (any palm geom) to the block
MAX_OTHER_MOTION = 0.01  #: m


def tilt_degrees(quat: ArrayLike) -> float:
    """Angle (deg) between a body's z axis and the world's z axis, from its (w, x, y, z)
    quaternion."""
    _, x, y, _ = np.asarray(quat, dtype=float)
    cos_tilt = 1.0 - 2.0 * (x * x + y * y)
    return float(np.degrees(np.arccos(np.clip(cos_tilt, -1.0, 1.0))))


def block_velocity(world: World, name: str) -> tuple[float, float]:
    """Linear (m/s) and angular (rad/s) speed of block ``name``."""
    m = world.model
    body = world.block_body_id(name)
    dof = m.jnt_dofadr[m.body_jntadr[body]]
    v = world.data.qvel[dof : dof + 6]
    return float(np.linalg.norm(v[:3])), float(np.linalg.norm(v[3:]))


def palm_distance(world: World, name: str) -> float:
    """Smallest distance (m) between the palm's geoms and block ``name``'s."""
    m, d = world.model, world.data
    palm = m.body(robot.hand_name(robot.PALM_BODY)).id
    block = world.block_body_id(name)
    palm_geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] == palm and m.geom_contype[g]]
    block_geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] == block]
    best = np.inf
    fromto = np.zeros(6)
    for a in palm_geoms:
        for b in block_geoms:
            best = min(best, mujoco.mj_geomDistance(m, d, a, b, 1.0, fromto))
    return float(best)


@dataclass(frozen=True)
class Judgement:
    """The physical verdict of one delivery, with every measured quantity."""

    success: bool
    reasons: tuple[str, ...]  #: what failed, empty on success
    place_error_mm: float
    tilt_deg: float
    speed: float  #: m/s
    spin: float  #: rad/s
    lift_clearance: float  #: m, highest block bottom above the table during the carry
    finger_contact: bool
    palm_distance: float  #: m
    other_motion: dict[str, float]  #: m, each other block's horizontal displacement
    final_position: NDArray[np.float64]  #: (3,)
    final_quat: NDArray[np.float64]  #: (4,) w, x, y, z


def judge(
    world: World,
    block: str,
    place: ArrayLike,
    lift_clearance: float,
    others_before: dict[str, NDArray[np.float64]],
) -> Judgement:
    """Judge the delivery of ``block`` to ``place`` (x, y) now; ``lift_clearance`` is the highest
    block-bottom-above-table height measured during the carry, ``others_before`` every other
    block's position (3,) before the cycle began."""
    pos, quat = world.block_pose(block)
    err = float(np.linalg.norm(pos[:2] - np.asarray(place, dtype=float)))
    tilt = tilt_degrees(quat)
    speed, spin = block_velocity(world, block)
    touching = any(
        c.finger in robot.FINGERS for c in robot_contacts(world, world.block_body_id(block))
    )
    palm = palm_distance(world, block)
    moved = {
        name: float(np.linalg.norm(world.block_pose(name)[0][:2] - p[:2]))
        for name, p in others_before.items()
    }
    reasons = []
    if err > PLACE_TOLERANCE:
        reasons.append(f"{err * 1000:.0f} mm from the place point (> {PLACE_TOLERANCE * 1000:.0f})")
    if tilt >= MAX_TILT_DEG:
        reasons.append(f"tilted {tilt:.1f} deg (>= {MAX_TILT_DEG:g})")
    if speed >= MAX_SPEED or spin >= MAX_SPIN:
        reasons.append(f"not at rest ({speed * 100:.1f} cm/s, {spin:.2f} rad/s)")
    if lift_clearance < MIN_LIFT:
        reasons.append(
            f"lifted only {lift_clearance * 100:.1f} cm clear of the table (< {MIN_LIFT * 100:g})"
        )
    if touching:
        reasons.append("a finger still touches it")
    if palm < MIN_PALM_DISTANCE:
        reasons.append(f"palm {palm * 100:.1f} cm from it (< {MIN_PALM_DISTANCE * 100:g})")
    for name, d in moved.items():
        if d > MAX_OTHER_MOTION:
            reasons.append(f"block {name!r} moved {d * 1000:.0f} mm")
    return Judgement(
        success=not reasons,
        reasons=tuple(reasons),
        place_error_mm=err * 1000.0,
        tilt_deg=tilt,
        speed=speed,
        spin=spin,
        lift_clearance=float(lift_clearance),
        finger_contact=touching,
        palm_distance=palm,
        other_motion=moved,
        final_position=pos,
        final_quat=quat,
    )


def block_at_failure(world: World, block: str, start: ArrayLike) -> dict[str, Any]:
    """Where block ``block`` is when its cycle fails, judged from the simulation's true state
    (for the summary and the bench; no state reads it): its tilt (deg), its horizontal distance
    (mm) from ``start`` (its true position when Select/Model saw it), and ``knocked_over``
    when the tilt is at least :data:`MAX_TILT_DEG` (fallen, or leaning on the hand)."""
    pos, quat = world.block_pose(block)
    tilt = tilt_degrees(quat)
    moved = float(np.linalg.norm(pos[:2] - np.asarray(start, dtype=float)[:2]))
    return {
        "tilt_deg": round(tilt, 1),
        "moved_mm": round(moved * 1000.0, 1),
        "knocked_over": bool(tilt >= MAX_TILT_DEG),
    }


def block_state_text(state: dict[str, Any] | None, block: str | None) -> str:
    """The judged state of a failed cycle's block in words ("" when there is none)."""
    if not state or block is None:
        return ""
    how = "knocked over" if state["knocked_over"] else "upright"
    return (
        f"{block} {how} (judged: tilted {state['tilt_deg']:.0f} deg, "
        f"{state['moved_mm']:.0f} mm from where it stood)"
    )


# --- the summary's judged fields: the simulation's truth, read by no state ---------------------
def seen_against_truth(
    world: World, block: str, centroid_xy: ArrayLike, area: float, edges: int
) -> tuple[list[float], dict[str, float]]:
    """Block ``block``'s true position now (the cycle's ``block_start``) and how far the model
    the camera made of it (its top's ``centroid_xy``, ``area`` m^2, ``edges``) is from its true
    footprint (``polygon_error``), from the simulated ``world``."""
    truth = world.scene.block(block)
    pos = world.block_pose(block)[0]
    error = {
        "centroid_mm": float(np.linalg.norm(np.asarray(centroid_xy)[:2] - pos[:2]) * 1000),
        "area_percent": float(abs(area - truth.polygon.area) / truth.polygon.area * 100),
        "edges": float(edges),
        "true_edges": float(truth.polygon.n_edges),
    }
    return [float(v) for v in pos], error


def other_blocks_now(world: World, block: str) -> dict[str, NDArray[np.float64]]:
    """Every block but ``block`` where the simulated ``world`` has it now (for
    :func:`judge`'s ``others_before``)."""
    return {b.name: world.block_pose(b.name)[0] for b in world.scene.blocks if b.name != block}


def block_height_now(world: World, block: str) -> float:
    """World z (m) of block ``block``'s centre in the simulated ``world``."""
    return float(world.block_pose(block)[0][2])


def block_clearance_now(world: World, block: str) -> float:
    """How far (m) block ``block``'s bottom is above the table in the simulated ``world``."""
    half = 0.5 * world.scene.block(block).height
    return block_height_now(world, block) - half - world.scene.table.height


def block_tilt_now(world: World, block: str) -> float:
    """Tilt (deg) of block ``block`` in the simulated ``world``."""
    return tilt_degrees(world.block_pose(block)[1])
