"""Right prisms over convex polygons and the paper's 3-D contact coordinates (section 3.4).

A :class:`Prism` is a convex :class:`Polygon` extruded from z = 0 (its base, the table) to
``height``. Its object frame has the origin at the centre of mass, height / 2 above the base
centroid, so the base is the plane z = -height/2 and the top face z = +height/2.

Contact coordinates (the 3-D form of Appendix B): a contact is located by the direction
``(theta, phi)`` of the ray from the centre of mass through it, ``theta`` its polar angle about
the vertical axis (the planar coordinate, unchanged) and ``phi`` its elevation in [-pi/2, pi/2].
On a side face ``phi`` grows with the contact's height (``tan(phi) = height above the centre of
mass / horizontal distance``) although the face normal stays horizontal. The force closure model
places the unit force of the contact on the Gaussian sphere at (theta, phi) (the smoothed, sphere
model, as the planar code uses the circle at theta); the moment closure model uses the true face:
its perpendicular ``(r_0, theta_0, phi_0)`` (``phi_0`` = 0 on side faces, +pi/2 on the top face,
-pi/2 on the base) and the surface coordinates ``(r_theta, r_phi)`` of the contact in the face
(Eq. 9):

    point = r_0 n + r_theta e_theta + r_phi e_phi,
    n = (cos th0 cos ph0, sin th0 cos ph0, sin ph0),
    e_theta = (-sin th0, cos th0, 0),  e_phi = (-cos th0 sin ph0, -sin th0 sin ph0, cos ph0).

On a side face ``r_theta`` is the planar surface coordinate and ``r_phi`` the height above the
centre of mass. On the top and base faces ``theta_0`` is taken equal to the contact's own
``theta`` (the face frame turns with the contact), so ``r_theta`` = 0 and ``|r_phi|`` is the
contact's distance from the vertical axis: ``r_phi = -rho`` on the top, ``+rho`` on the base.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.errors import PolygonError
from controllers.grasp.polygon import Polygon, locate_contacts

#: Face index of contacts on the top face (side faces are numbered as the polygon's edges).
TOP_FACE = -1
#: Face index of contacts on the base (the face the prism stands on: never a grasp contact).
BASE_FACE = -2
#: Elevation limit: |phi| is clipped to pi/2.
HALF_PI = 0.5 * np.pi


class ContactFrames3D(NamedTuple):
    """Where contacts at ray directions (theta, phi) touch a prism. Every field has theta's shape,
    plus a trailing 3 for points and normals and a trailing 2 for ``surface``."""

    face: NDArray[np.int64]  #: side face (polygon edge) index, TOP_FACE or BASE_FACE
    point: NDArray[np.float64]  #: contact point, centre-of-mass frame
    normal: NDArray[np.float64]  #: outward unit normal of the face
    theta: NDArray[np.float64]  #: contact coordinate: polar angle of the ray (Appendix B)
    phi: NDArray[np.float64]  #: contact coordinate: elevation of the ray
    normal_theta: NDArray[np.float64]  #: theta_0 of the face perpendicular
    normal_phi: NDArray[np.float64]  #: phi_0 of the face perpendicular (0 or +-pi/2)
    offset: NDArray[np.float64]  #: r_0, distance from the centre of mass to the face's plane
    surface: NDArray[np.float64]  #: (r_theta, r_phi), surface coordinates in the face (Eq. 9)

    @property
    def on_cap(self) -> NDArray[np.bool_]:
        """True for contacts on the top or base face."""
        return self.face < 0

    @property
    def horizontal_distance(self) -> NDArray[np.float64]:
        """rho, the contact's distance from the vertical axis through the centre of mass."""
        return np.hypot(self.point[..., 0], self.point[..., 1])


def face_axes(normal_theta: ArrayLike, normal_phi: ArrayLike):
    """The unit vectors (n, e_theta, e_phi) of face perpendiculars (theta_0, phi_0), each of
    shape ``theta_0.shape + (3,)``; (n, e_theta, e_phi) is a right-handed orthonormal frame."""
    th = np.asarray(normal_theta, dtype=float)
    ph = np.asarray(normal_phi, dtype=float)
    ct, st, cp, sp = np.cos(th), np.sin(th), np.cos(ph), np.sin(ph)
    n = np.stack([ct * cp, st * cp, sp], axis=-1)
    e_theta = np.stack([-st, ct, np.zeros_like(th)], axis=-1)
    e_phi = np.stack([-ct * sp, -st * sp, cp], axis=-1)
    return n, e_theta, e_phi


def locate_contacts_3d(
    normal_angle: NDArray[np.float64],
    offset: NDArray[np.float64],
    half_height: ArrayLike,
    theta: ArrayLike,
    phi: ArrayLike,
) -> ContactFrames3D:
    """Locate contacts on prisms given by their polygons' edge normals and offsets (shape
    ``(..., E)``, padding edges with ``offset = inf`` allowed, as :func:`locate_contacts`) and
    their half heights (shape ``(...)``), for rays ``theta``, ``phi`` of shape ``(..., n)``.

    The ray leaves the side band through the edge the planar ray at theta meets (horizontal
    distance rho_s) at distance rho_s / cos(phi), and the top or base plane at
    half_height / |sin(phi)|; it leaves the prism through the nearer of the two.
    """
    theta = np.asarray(theta, dtype=float)
    phi = np.clip(np.asarray(phi, dtype=float), -HALF_PI, HALF_PI)
    theta, phi = np.broadcast_arrays(theta, phi)
    hh = np.asarray(half_height, dtype=float)[..., None] * np.ones_like(theta)
    side = locate_contacts(normal_angle, offset, theta)
    rho_s = side.offset / np.cos(theta - side.normal_angle)  # horizontal distance on the side
    cphi, sphi = np.cos(phi), np.sin(phi)
    with np.errstate(divide="ignore"):
        t_side = np.where(cphi > 0.0, rho_s / np.where(cphi > 0.0, cphi, 1.0), np.inf)
        t_cap = np.where(sphi != 0.0, hh / np.abs(np.where(sphi != 0.0, sphi, 1.0)), np.inf)
    cap = t_cap < t_side
    up = sphi > 0.0
    face = np.where(cap, np.where(up, TOP_FACE, BASE_FACE), side.edge)
    # side faces: r_theta as the planar code, r_phi = height above the centre of mass
    r_theta = np.where(cap, 0.0, side.surface)
    tan_phi = np.tan(np.where(cap, 0.0, phi))
    cot_phi = cphi / np.where(sphi != 0.0, sphi, 1.0)
    rho_cap = np.where(cap, hh * np.abs(cot_phi), 0.0)
    r_phi = np.where(cap, -hh * cot_phi, rho_s * tan_phi)  # -rho on the top, +rho on the base
    rho = np.where(cap, rho_cap, rho_s)
    z = np.where(cap, np.where(up, hh, -hh), rho_s * tan_phi)
    point = np.stack([rho * np.cos(theta), rho * np.sin(theta), z], axis=-1)
    normal_theta = np.where(cap, theta, side.normal_angle)
    normal_phi = np.where(cap, np.where(up, HALF_PI, -HALF_PI), 0.0)
    r_0 = np.where(cap, hh, side.offset)
    normal = face_axes(normal_theta, normal_phi)[0]
    normal = np.where(cap[..., None], np.stack([0.0 * theta, 0.0 * theta, np.sign(z)], -1), normal)
    return ContactFrames3D(
        face=face,
        point=point,
        normal=normal,
        theta=theta,
        phi=phi,
        normal_theta=normal_theta,
        normal_phi=normal_phi,
        offset=r_0,
        surface=np.stack([r_theta, r_phi], axis=-1),
    )


def move_on_faces(frames: ContactFrames3D, theta: ArrayLike, phi: ArrayLike) -> ContactFrames3D:
    """The contacts moved to rays (theta, phi) while staying on the planes of their current faces
    (extended beyond the face edges): the facet model the moment closure controller reasons with
    (section 3.4.3). Equal to locating them again while no contact crosses an edge."""
    theta, phi = np.broadcast_arrays(np.asarray(theta, dtype=float), np.asarray(phi, dtype=float))
    cap = frames.on_cap
    u = np.stack([np.cos(phi) * np.cos(theta), np.cos(phi) * np.sin(theta), np.sin(phi)], -1)
    along = (u * frames.normal).sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        point = (frames.offset / along)[..., None] * u
        rel = theta - frames.normal_theta
        side = np.stack(
            [frames.offset * np.tan(rel), frames.offset / np.cos(rel) * np.tan(phi)], axis=-1
        )
        on_cap = np.stack([0.0 * theta, -frames.offset * np.cos(phi) / np.sin(phi)], axis=-1)
    return frames._replace(
        point=point,
        theta=theta,
        phi=phi,
        normal_theta=np.where(cap, theta, frames.normal_theta),
        surface=np.where(cap[..., None], on_cap, side),
    )


@dataclass(frozen=True)
class Prism:
    """A convex polygon (centroid at the origin, see :class:`Polygon`) extruded to ``height``.

    ``top`` says whether the top face may be touched (the base never is: the prism stands on
    it). Lengths are in the polygon's unit; :meth:`unit_moment` scales polygon and height together.
    """

    polygon: Polygon
    height: float
    top: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.polygon, Polygon):
            raise PolygonError(f"a prism is built on a Polygon, got {type(self.polygon).__name__}")
        h = self.height
        if not isinstance(h, int | float) or not np.isfinite(h) or h <= 0.0:
            raise PolygonError(f"prism height must be a positive number, got {h!r}")

    @property
    def name(self) -> str:
        return self.polygon.name

    @property
    def half_height(self) -> float:
        """Height of the centre of mass above the base (the origin of the object frame)."""
        return 0.5 * float(self.height)

    @property
    def max_moment(self) -> float:
        """Largest |m| = |r x f| of a unit normal force anywhere on the faces that may be touched.

        Moments are linear in the surface coordinates on each face, so the maximum is at a corner:
        sqrt(M_z^2 + (height/2)^2) on the side faces (M_z = the polygon's max_moment) and the
        largest vertex radius on the top face. A flat prism has the polygon's M_z."""
        side = float(np.hypot(self.polygon.max_moment, self.half_height))
        if not self.top:
            return side
        return max(side, float(np.linalg.norm(self.polygon.vertices, axis=1).max()))

    def scaled(self, factor: float) -> Prism:
        return Prism(self.polygon.scaled(factor), float(self.height) * factor, self.top)

    def unit_moment(self) -> Prism:
        """Copy scaled so that the largest moment is 1 (section 3.4: every w_ij in [-1, 1])."""
        return self.scaled(1.0 / self.max_moment)

    def locate(self, theta: ArrayLike, phi: ArrayLike) -> ContactFrames3D:
        """Contact frames at rays (theta, phi) (broadcast together, any shape)."""
        t, p = np.broadcast_arrays(np.asarray(theta, dtype=float), np.asarray(phi, dtype=float))
        frames = locate_contacts_3d(
            self.polygon.normal_angle,
            self.polygon.offset,
            self.half_height,
            t.reshape(-1),
            p.reshape(-1),
        )
        return ContactFrames3D(*(a.reshape(t.shape + a.shape[1:]) for a in frames))

    def allowed(self, frames: ContactFrames3D) -> NDArray[np.bool_]:
        """Which located contacts lie on a face that may be touched."""
        return (frames.face >= 0) | ((frames.face == TOP_FACE) & self.top)

    def coordinates_of(self, point: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Contact coordinates (theta, phi) of points given in the centre-of-mass frame."""
        p = np.asarray(point, dtype=float)
        return np.arctan2(p[..., 1], p[..., 0]), np.arctan2(
            p[..., 2], np.hypot(p[..., 0], p[..., 1])
        )

    def edge_elevation(self, theta: ArrayLike) -> NDArray[np.float64]:
        """Elevation of the top edge of the side band at polar angle theta: rays with a larger
        phi touch the top face."""
        side = self.polygon.locate(theta)
        rho_s = side.offset / np.cos(np.asarray(theta, dtype=float) - side.normal_angle)
        return np.arctan2(self.half_height, rho_s)
