"""Contacts on a prism and the physical test's task wrenches, for the 3-D S_G (section 3.5,
Eq. 13, in :mod:`controllers.grasp.score3d`).

Frame: the prism is a convex :class:`Polygon` extruded from its base (z = 0) to ``height``; the
object frame has its origin at the centre of mass (the polygon's centroid at height / 2, for a
uniform prism), axes those of the polygon, z up. A force through the centre of mass then has no
moment, so the physical tasks are pure forces.

Units: lengths are the polygon's; ``unit_moment=True`` scales every length (outline, contact
heights, height) by 1 / ``polygon.max_moment``, the planar code's unit-moment frame (section
3.4: a unit normal force on a side face exerts at most a unit m_z). The same factor scales the
vertical lengths, so a tall prism's m_x, m_y can exceed 1: that is the tipping the planar metric
does not see. Forces are in units of the unit contact force, the smallest normal force of the
program (N_i >= 1): e.g. the grip's average squeeze per finger when the hand shares the LP's
normal forces. Physical tasks are pure forces at the origin, so their S_G does not depend on
the length unit at all (every moment row is homogeneous in the lengths).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.errors import PolygonError
from controllers.grasp.polygon import Polygon
from controllers.grasp.score import FRICTION
from controllers.grasp.score3d import ContactError, GraspScore3D, check_contacts, grasp_score_3d

#: Contacts may lie this far (relative to the polygon's size) outside a face and still count.
FACE_TOLERANCE = 1e-9
#: Names of the physical test's stages, in its order: the block hanging in the hand, then an
#: extra m*g through the centre of mass along each world axis (experiments/physics/study.py).
PHYSICAL_STAGES = ("hang", "+x", "-x", "+y", "-y", "+z", "-z")


def _finite_array(name: str, value: ArrayLike, ndim: int) -> NDArray[np.float64]:
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise PolygonError(f"{name} must be numbers") from e
    if a.ndim == 0 and ndim == 1:
        a = a.reshape(1)
    if a.ndim != ndim:
        raise PolygonError(f"{name} must be a {ndim}-D array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise PolygonError(f"{name} must be finite (found NaN or inf)")
    return a


def prism_contacts(
    polygon: Polygon,
    theta: ArrayLike,
    z: ArrayLike,
    height: float,
    top: ArrayLike | None = None,
    unit_moment: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Points and outward unit normals (m + k, 3) of contacts on a prism, centre-of-mass frame.

    Side contacts: polar angles ``theta`` (m,) about the centroid (the planar contact coordinate,
    Appendix B) at heights ``z`` (m,) above the base, 0 <= z <= height; their normals are the
    side faces' (horizontal). Top contacts: ``top`` (k, 2) points of the top face in the
    polygon's frame, normal +z. The side contacts come first. With ``unit_moment`` every length
    is scaled by 1 / polygon.max_moment (the frame of section 3.4). Raises
    :class:`PolygonError` naming the bad value.
    """
    if not isinstance(polygon, Polygon):
        raise PolygonError(f"polygon must be a Polygon, got {type(polygon).__name__}")
    th = _finite_array("theta", theta, 1)
    zz = _finite_array("z", z, 1)
    if th.shape != zz.shape:
        raise PolygonError(f"theta and z must have the same shape, got {th.shape} and {zz.shape}")
    h = float(_finite_array("height", [height], 1)[0])
    if h <= 0.0:
        raise PolygonError(f"prism height must be positive, got {h:g}")
    tol = FACE_TOLERANCE * max(h, polygon.diameter)
    out = np.flatnonzero((zz < -tol) | (zz > h + tol))
    if out.size:
        i = int(out[0])
        raise PolygonError(f"contact {i} at z = {zz[i]:g} is off the sides (0 <= z <= {h:g})")
    frames = polygon.locate(th)
    side_p = np.concatenate([frames.point, (zz - 0.5 * h)[:, None]], axis=1)
    side_n = np.concatenate([frames.normal, np.zeros((th.size, 1))], axis=1)
    if top is None:
        tp = np.zeros((0, 2))
    else:
        tp = _finite_array("top", top, 2)
        if tp.shape[1] != 2:
            raise PolygonError(f"top contacts must have shape (k, 2), got {tp.shape}")
        normals2 = np.stack([np.cos(polygon.normal_angle), np.sin(polygon.normal_angle)], axis=1)
        excess = tp @ normals2.T - polygon.offset[None, :]
        outside = np.flatnonzero(excess.max(axis=1) > FACE_TOLERANCE * polygon.diameter)
        if outside.size:
            i = int(outside[0])
            raise PolygonError(
                f"top contact {i} at ({tp[i, 0]:g}, {tp[i, 1]:g}) is outside the polygon"
            )
    top_p = np.concatenate([tp, np.full((tp.shape[0], 1), 0.5 * h)], axis=1)
    top_n = np.tile([0.0, 0.0, 1.0], (tp.shape[0], 1))
    points = np.concatenate([side_p, top_p])
    normals = np.concatenate([side_n, top_n])
    if unit_moment:
        points = points / polygon.max_moment
    return points, normals


def physical_tasks(load: float, n_contacts: int, yaw: float = 0.0) -> dict[str, NDArray]:
    """Task wrenches (6,) of the physical test, by stage name (:data:`PHYSICAL_STAGES`).

    ``load`` is m*g in units of the unit contact force (see the module's docstring). The block
    hangs in the hand under its weight m*g (-z), then an extra m*g through the centre of mass
    pushes it along +x, -x, +y, -y, +z, -z of the world, whose x axis is at angle ``yaw`` in the
    object frame (z is shared: the prism stands upright). The contacts must cancel the
    external wrench w: sum_i w_i = -w, so in Eq. 13's form (mean contact wrench) the task is
    t = -w / n. In the centre-of-mass frame w has no moment; "+z" cancels the weight (t = 0).
    """
    if not (isinstance(load, int | float | np.floating | np.integer) and np.isfinite(load)):
        raise ContactError(f"load must be a finite number, got {load!r}")
    if load < 0.0:
        raise ContactError(f"load must be >= 0 (m*g in unit contact forces), got {load:g}")
    if not isinstance(n_contacts, int | np.integer) or n_contacts < 1:
        raise ContactError(f"n_contacts must be a positive integer, got {n_contacts!r}")
    if not np.isfinite(yaw):
        raise ContactError(f"yaw must be a finite angle, got {yaw!r}")
    c, s = np.cos(yaw), np.sin(yaw)
    axes = {
        "+x": (c, s, 0.0),
        "-x": (-c, -s, 0.0),
        "+y": (-s, c, 0.0),
        "-y": (s, -c, 0.0),
        "+z": (0.0, 0.0, 1.0),
        "-z": (0.0, 0.0, -1.0),
    }
    weight = np.array([0.0, 0.0, -1.0])
    tasks = {"hang": weight}
    tasks.update({name: weight + np.array(d) for name, d in axes.items()})
    return {
        name: np.concatenate([-load * f / n_contacts, np.zeros(3)]) + 0.0
        for name, f in tasks.items()
    }


def worst_task_score(
    points: ArrayLike,
    normals: ArrayLike,
    load: float,
    yaw: float = 0.0,
    friction: float = FRICTION,
    torsion: float | None = None,
) -> tuple[str, GraspScore3D]:
    """The stage of the physical test with the worst S_G (an infeasible one first, else the
    largest S_G; ties go to the earlier stage) and its score, for contacts in the
    centre-of-mass frame (:func:`prism_contacts`)."""
    p, nrm, _ = check_contacts(points, normals, None)
    tasks = physical_tasks(load, p.shape[0], yaw)
    worst: tuple[str, GraspScore3D] | None = None
    for name, task in tasks.items():
        score = grasp_score_3d(p, nrm, task, friction, torsion)
        if worst is None or score.s_g > worst[1].s_g:
            worst = (name, score)
        if not score.feasible:
            break
    assert worst is not None
    return worst
