"""The rule that gives the grasp controller's contacts to the fingers (section 5.2): the
assignment of contacts to fingers by reach distance, and a three-contact grasp's idle finger.

The grasp controller moves virtual contacts on a polygon and knows nothing of fingers; the fingers
(ff, mf, rf, th) take them by the optimal assignment on squared reach distance (Hungarian method),
or in the order of the assignments :func:`ranked_assignments` lists, which
:func:`controllers.hand.reachability.reachable_contacts` tests in turn. In a three-contact grasp
(:func:`controllers.preshape.lateral_grasp.three_contact_lateral_grasp`: a lateral thumb against two
fingers) one finger, ``idle``, takes no contact: its row holds its own fingertip, a zero normal and
a NaN contact coordinate, and it stays where its posture holds it.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from controllers.hand.finger_geometry import PerceivedPrism, fingertips_at
from controllers.reach.coarse import ReachTarget
from controllers.reach.fine import GRASP_DEPTH
from hand_sim import robot
from hand_sim.world import World

#: Contacts stay at least GRASP_DEPTH (m) below the block's top (where Fine Reach takes the
#: fingertips; a contact nearer the top edge is pressed by the side of the fingertip) and
#: BOTTOM_MARGIN (m) above the table.
TOP_MARGIN = GRASP_DEPTH
BOTTOM_MARGIN = 0.02


def assign_fingers(tips: ArrayLike, points: ArrayLike) -> tuple[int, ...]:
    """The explicit finger-to-contact rule: the assignment of the four fingertips (ff, mf, rf,
    th; rows of ``tips`` (4, 3)) to the contacts (rows of ``points`` (4, 3)) that minimises the
    sum of squared reach distances (an optimal assignment, Hungarian method). Returns, per finger,
    the index of its contact. The controller's own order of the contacts plays no part."""
    t = np.asarray(tips, dtype=float)
    p = np.asarray(points, dtype=float)
    if t.shape != p.shape or t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"tips and points must both be (n, 3), got {t.shape} and {p.shape}")
    cost = ((t[:, None, :] - p[None, :, :]) ** 2).sum(axis=-1)
    rows, cols = linear_sum_assignment(cost)
    out = np.empty(len(t), dtype=int)
    out[rows] = cols
    return tuple(int(c) for c in out)


@dataclass(frozen=True, eq=False)
class FingerContacts:
    """Contacts given to fingers: row f is finger f's (ff, mf, rf, th) contact."""

    points: NDArray[np.float64]  #: (4, 3) world contact points on the side faces
    normals: NDArray[np.float64]  #: (4, 3) outward face normals (horizontal)
    theta: NDArray[np.float64]  #: (4,) contact coordinates on the perceived polygon
    contact_of_finger: tuple[int, ...]  #: index of each finger's contact in the controller's set
    #: a three-contact grasp's finger that takes no contact (its row: its own fingertip, a zero
    #: normal, theta NaN, contact index -1), or None
    idle: int | None = None

    @property
    def pressing(self) -> NDArray[np.int64]:
        """The fingers that take a contact, in finger order."""
        return pressing_fingers(self.idle)


def pressing_fingers(idle: int | None) -> NDArray[np.int64]:
    """The fingers (ff, mf, rf, th indices, in order) that take a contact when ``idle`` (or
    none, when None) takes none."""
    return np.array([f for f in range(len(robot.FINGERS)) if f != idle], dtype=np.int64)


def contacts_at_tips(
    target: ReachTarget, theta: NDArray[np.float64], tips: NDArray[np.float64], table_z: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """World xy (n, 2), normals (n, 2) of contacts ``theta`` and the height each finger would
    take them at (4,)."""
    frames = target.polygon.locate(theta)
    c, s = np.cos(target.yaw), np.sin(target.yaw)
    R = np.array([[c, -s], [s, c]])
    xy = frames.point @ R.T + np.asarray(target.position_xy)
    z = np.clip(tips[:, 2], table_z + BOTTOM_MARGIN, target.top_z - TOP_MARGIN)
    return xy, frames.normal @ R.T, z


def given_contacts(
    theta: NDArray[np.float64],
    xy: NDArray[np.float64],
    nxy: NDArray[np.float64],
    z: NDArray[np.float64],
    order: ArrayLike,
) -> FingerContacts:
    """Finger f on contact ``order[f]`` (:func:`contacts_at_tips`), at finger f's height."""
    order = np.asarray(order, dtype=int)
    points = np.column_stack([xy[order], z])
    normals = np.column_stack([nxy[order], np.zeros(len(order))])
    return FingerContacts(points, normals, theta[order], tuple(int(i) for i in order))


def finger_contacts(
    target: ReachTarget, theta: ArrayLike, tips: ArrayLike, table_z: float
) -> FingerContacts:
    """The controller's contacts ``theta`` (polar angles on the perceived polygon) given to the
    fingers by the optimal assignment on squared reach distance (:func:`assign_fingers`).
    Contacts are planar (section 5: the grasp acts on the prism's horizontal cross-section);
    each lies at the height its fingertip has now, kept between the table and the block's top
    by the margins above."""
    th = np.asarray(theta, dtype=float)
    tips = np.asarray(tips, dtype=float)
    xy, nxy, z = contacts_at_tips(target, th, tips, table_z)
    # contact j as finger f would take it: at finger f's height
    candidate = np.concatenate(
        [np.broadcast_to(xy, (4, 4, 2)), z[:, None, None] * np.ones((4, 4, 1))], axis=2
    )
    cost = ((tips[:, None, :] - candidate) ** 2).sum(axis=-1)
    rows, cols = linear_sum_assignment(cost)
    order = np.empty(4, dtype=int)
    order[rows] = cols
    return given_contacts(th, xy, nxy, z, order)


def ranked_assignments(
    world: World,
    prism: PerceivedPrism,
    target: ReachTarget,
    theta: ArrayLike,
    *,
    model: mujoco.MjModel | None = None,
    qpos: ArrayLike | None = None,
    heights: ArrayLike | None = None,
    count: int | None = None,
    idle: int | None = None,
) -> list[FingerContacts]:
    """The 24 ways to give the contacts ``theta`` to the four fingers, each as the contacts
    given (at each fingertip's height, or at ``heights``, a 3-D grasp's), ranked by total
    squared reach distance from the fingertips of ``qpos`` (the world's state when None): the
    order :func:`reachable_contacts` checks them in, without the reach test; the first ``count``
    of them (all when None). With ``idle`` (a three-contact grasp: three contacts) the six ways
    to give them to the other three fingers; the idle finger's row is its own fingertip at
    ``qpos`` (:func:`idle_row`)."""
    th = np.asarray(theta, dtype=float)
    model = world.model if model is None else model
    tips = world.fingertip_positions() if qpos is None else fingertips_at(model, qpos)
    pressing = pressing_fingers(idle)
    if len(th) != len(pressing):
        raise ValueError(f"{len(pressing)} fingers take contacts, got {len(th)} contacts")
    xy, nxy, z = contacts_at_tips(target, th, tips[pressing], prism.bottom)
    perms = np.array(list(itertools.permutations(range(len(th)))))
    # each finger's height in each assignment: its tip's, or its contact's own (3-D)
    zs = (
        np.broadcast_to(z[None, :], perms.shape)
        if heights is None
        else np.asarray(heights, dtype=float)[perms]
    )
    pts = np.concatenate([xy[perms], zs[:, :, None]], 2)
    cost = ((pts - tips[pressing][None]) ** 2).sum(axis=(1, 2))
    ranked = np.argsort(cost, kind="stable")[:count]
    given = [given_contacts(th, xy, nxy, zs[k], perms[k]) for k in ranked]
    return given if idle is None else [idle_row(c, idle, tips[idle]) for c in given]


def idle_row(contacts: FingerContacts, idle: int, tip: ArrayLike) -> FingerContacts:
    """``contacts`` of the fingers other than ``idle`` (rows in finger order) with the idle
    finger's row put in: its fingertip ``tip`` (3,), a zero normal, theta NaN, contact -1."""
    points = np.insert(contacts.points, idle, np.asarray(tip, dtype=float), axis=0)
    normals = np.insert(contacts.normals, idle, np.zeros(3), axis=0)
    theta = np.insert(contacts.theta, idle, np.nan)
    order = list(contacts.contact_of_finger)
    order.insert(idle, -1)
    return FingerContacts(points, normals, theta, tuple(order), idle)
