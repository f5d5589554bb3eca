"""Planar convex polygon objects and the paper's contact coordinate.

A contact is located by ``theta``, its polar angle about the polygon centroid (Appendix B of the
paper). On edge ``j`` (outward normal at angle ``a_j = normal_angle[j]``, line at distance
``d_j = offset[j]`` from the centroid) the contact sits at radius ``d_j / cos(theta - a_j)`` and
has the surface coordinate ``s = d_j * tan(theta - a_j)`` along the edge's CCW tangent; ``s`` is
also the moment ``m_z`` of a unit inward normal force there (Eq. 9 with phi = 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp.errors import PolygonError

#: Vertices closer than this (relative to the polygon size) are the same vertex.
RELATIVE_TOLERANCE = 1e-9
#: Minimum area, relative to the squared diameter, of an acceptable polygon.
MIN_RELATIVE_AREA = 1e-6
#: Limits on user polygons, in the unit of their coordinates (any unit: metres in the simulator):
#: coordinates within +-MAX_COORDINATE, at least MIN_EXTENT across, at most MAX_VERTICES vertices
#: (the self-intersection test compares every pair of edges).
MAX_COORDINATE = 1e6
MIN_EXTENT = 1e-9
MAX_VERTICES = 256
#: A polygon may lie at most this many times its size from the origin: float64 coordinates carry
#: about 16 digits, so a tiny polygon far away has too few left for its shape.
MAX_OFFSET_RATIO = 1e5


class ContactFrames(NamedTuple):
    """Where contacts at polar angles ``theta`` touch a polygon; every field has theta's shape
    (plus a trailing 2 for vectors)."""

    edge: NDArray[np.int64]  #: index of the edge touched
    point: NDArray[np.float64]  #: contact point, object frame
    normal: NDArray[np.float64]  #: outward unit normal of the edge
    normal_angle: NDArray[np.float64]  #: polar angle of that normal (rad)
    offset: NDArray[np.float64]  #: distance from the centroid to the edge's line
    surface: NDArray[np.float64]  #: surface coordinate s along the CCW tangent (= m_z, Eq. 9)


def locate_contacts(
    normal_angle: NDArray[np.float64], offset: NDArray[np.float64], theta: ArrayLike
) -> ContactFrames:
    """Locate contacts on convex polygons given by their edge normals and offsets.

    ``normal_angle`` and ``offset`` have shape ``(..., E)``; ``theta`` has shape ``(..., n)`` with
    the same leading shape (broadcastable). Padding edges may have ``offset = inf``. A ray from the
    centroid at angle theta leaves a convex polygon through the edge whose line it meets first:
    ``argmin_j offset_j / cos(theta - normal_angle_j)`` over edges facing the ray.
    """
    theta = np.asarray(theta, dtype=float)
    rel = theta[..., :, None] - normal_angle[..., None, :]
    facing = np.cos(rel)
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = np.where(facing > 1e-12, offset[..., None, :] / facing, np.inf)
    edge = np.argmin(dist, axis=-1)
    nang = np.take_along_axis(
        np.broadcast_to(normal_angle[..., None, :], rel.shape), edge[..., None], -1
    )[..., 0]
    off = np.take_along_axis(np.broadcast_to(offset[..., None, :], rel.shape), edge[..., None], -1)[
        ..., 0
    ]
    radius = np.take_along_axis(dist, edge[..., None], -1)[..., 0]
    point = radius[..., None] * np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    normal = np.stack([np.cos(nang), np.sin(nang)], axis=-1)
    surface = off * np.tan(theta - nang)
    return ContactFrames(edge, point, normal, nang, off, surface)


def _as_vertex_array(vertices: ArrayLike) -> NDArray[np.float64]:
    try:
        v = np.array(vertices, dtype=float)
    except (TypeError, ValueError, OverflowError) as e:
        raise PolygonError(f"polygon vertices must be numbers, got {_short(vertices)}") from e
    if v.ndim != 2 or v.shape[1] != 2:
        raise PolygonError(f"polygon vertices must be a list of (x, y) pairs, got shape {v.shape}")
    if v.shape[0] < 3:
        raise PolygonError(f"a polygon needs at least 3 vertices, got {v.shape[0]}")
    if v.shape[0] > MAX_VERTICES:
        raise PolygonError(f"a polygon may have at most {MAX_VERTICES} vertices, got {v.shape[0]}")
    if not np.all(np.isfinite(v)):
        raise PolygonError("polygon vertices must be finite numbers (found NaN or inf)")
    if np.abs(v).max() > MAX_COORDINATE:
        raise PolygonError(
            f"polygon coordinates must be within +-{MAX_COORDINATE:g}, got {np.abs(v).max():g}; "
            "choose a unit that keeps them smaller"
        )
    return v


def _short(value: object, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _orientation(p: NDArray, q: NDArray, r: NDArray) -> NDArray[np.float64]:
    """Twice the signed area of triangles (p, q, r): > 0 when r is left of p -> q."""
    return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (
        r[..., 0] - p[..., 0]
    )


def _first_crossing(u: NDArray[np.float64], tol: float) -> tuple[int, int] | None:
    """The first pair of non-adjacent edges (i, j) of the closed outline ``u`` that cross or
    touch (orientation tests with tolerance ``tol``; collinear edges by their overlap)."""
    k = len(u)
    i, j = np.triu_indices(k, 2)
    keep = ~((i == 0) & (j == k - 1))  # the last edge is adjacent to the first
    i, j = i[keep], j[keep]
    a, b = u, np.roll(u, -1, axis=0)

    def side(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(np.abs(x) <= tol, 0.0, np.sign(x))

    s1, s2 = side(_orientation(a[j], b[j], a[i])), side(_orientation(a[j], b[j], b[i]))
    s3, s4 = side(_orientation(a[i], b[i], a[j])), side(_orientation(a[i], b[i], b[j]))
    collinear = (s1 == 0) & (s2 == 0) & (s3 == 0) & (s4 == 0)
    meet = (s1 * s2 <= 0) & (s3 * s4 <= 0) & ~collinear
    d = b[i] - a[i]
    t_c = np.einsum("ij,ij->i", a[j] - a[i], d)
    t_d = np.einsum("ij,ij->i", b[j] - a[i], d)
    length2 = np.einsum("ij,ij->i", d, d)
    overlap = collinear & (np.maximum(t_c, t_d) >= -tol) & (np.minimum(t_c, t_d) <= length2 + tol)
    hit = np.flatnonzero(meet | overlap)
    return (int(i[hit[0]]), int(j[hit[0]])) if hit.size else None


def centroid_of(vertices: ArrayLike) -> NDArray[np.float64]:
    """Area centroid of a polygon given by its vertices (any orientation)."""
    return _signed_area_and_centroid(_as_vertex_array(vertices))[1]


def _centroid_of_checked(v: NDArray[np.float64], size: float) -> NDArray[np.float64]:
    """Area centroid of a checked polygon. The shoelace sums lose precision on coordinates far
    from the origin (terms of offset^2 cancel), so a polygon farther than 10 times its size is
    shifted to its vertex mean first; nearer ones (all in the simulator) are not, which keeps
    their results bit for bit."""
    if float(np.abs(v).max()) <= 10.0 * size:
        return _signed_area_and_centroid(v)[1]
    mean = v.mean(axis=0)
    return mean + _signed_area_and_centroid(v - mean)[1]


def _signed_area_and_centroid(v: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
    """Shoelace formula: signed area (> 0 for CCW) and area centroid."""
    x, y = v[:, 0], v[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = 0.5 * float(cross.sum())
    if area == 0.0:
        return 0.0, v.mean(axis=0)
    cx = float(((x + xn) * cross).sum()) / (6.0 * area)
    cy = float(((y + yn) * cross).sum()) / (6.0 * area)
    return area, np.array([cx, cy])


@dataclass(frozen=True)
class Polygon:
    """A convex polygon, vertices CCW, centroid at the origin of its object frame.

    Build one with :meth:`from_vertices`, which checks the input and moves the centroid to the
    origin. Lengths are in whatever unit the vertices were given in (metres in the simulator);
    :meth:`unit_moment` gives the copy scaled as section 3.4 asks (maximum moment 1).
    """

    vertices: NDArray[np.float64]
    name: str = "polygon"
    normal_angle: NDArray[np.float64] = field(init=False, repr=False, compare=False)
    offset: NDArray[np.float64] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        v = self.vertices
        edges = np.roll(v, -1, axis=0) - v
        lengths = np.linalg.norm(edges, axis=1)
        outward = np.stack([edges[:, 1], -edges[:, 0]], axis=1) / lengths[:, None]
        object.__setattr__(self, "normal_angle", np.arctan2(outward[:, 1], outward[:, 0]))
        object.__setattr__(self, "offset", np.einsum("ij,ij->i", outward, v))
        v.setflags(write=False)
        self.normal_angle.setflags(write=False)
        self.offset.setflags(write=False)

    @classmethod
    def from_vertices(cls, vertices: ArrayLike, name: str = "polygon") -> Polygon:
        """Check ``vertices`` (any orientation) and return the CCW polygon centred on its centroid.

        Raises :class:`PolygonError` for fewer than 3 or more than MAX_VERTICES vertices,
        non-finite or too large values, repeated vertices, collinear vertices, a self-intersecting,
        a too thin or a non-convex outline. The checks run on a copy scaled to unit size, so they
        do not depend on the unit.
        """
        v = _as_vertex_array(vertices)
        size = float(np.ptp(v, axis=0).max())
        if size <= 0.0:
            raise PolygonError(f"polygon {name!r} has zero area: all vertices coincide")
        if size < MIN_EXTENT:
            raise PolygonError(
                f"polygon {name!r} is {size:g} across, less than {MIN_EXTENT:g}: choose a unit "
                "that makes it larger"
            )
        offset = float(np.abs(v).max())
        if offset > MAX_OFFSET_RATIO * size:
            raise PolygonError(
                f"polygon {name!r} is {size:g} across but {offset:g} from the origin: give its "
                f"coordinates relative to a nearby point (at most {MAX_OFFSET_RATIO:g} times its "
                "size away)"
            )
        u = (v - v.mean(axis=0)) / size  # unit size: tolerances below are relative
        edges = np.roll(u, -1, axis=0) - u
        short = np.linalg.norm(edges, axis=1) <= RELATIVE_TOLERANCE
        if np.any(short):
            i = int(np.flatnonzero(short)[0])
            raise PolygonError(
                f"polygon {name!r} repeats vertex {i} ({v[i, 0]:g}, {v[i, 1]:g}): remove duplicates"
            )
        spread = np.linalg.svd(u - u.mean(axis=0), compute_uv=False)
        if spread[-1] <= RELATIVE_TOLERANCE * spread[0]:
            raise PolygonError(f"polygon {name!r} has zero area: its vertices are collinear")
        crossing = _first_crossing(u, RELATIVE_TOLERANCE)
        if crossing is not None:
            raise PolygonError(
                f"polygon {name!r} is self-intersecting: edges {crossing[0]} and {crossing[1]} "
                "cross or touch; give the vertices in order around the outline"
            )
        area = _signed_area_and_centroid(u)[0]
        if abs(area) <= MIN_RELATIVE_AREA:
            raise PolygonError(
                f"polygon {name!r} has (nearly) zero area: it is a sliver, its vertices nearly "
                "collinear"
            )
        centroid = _centroid_of_checked(v, size)
        if area < 0.0:
            v, u = v[::-1].copy(), u[::-1].copy()
            edges = np.roll(u, -1, axis=0) - u
        turn = (
            edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1]
            - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
        )
        if np.any(turn < -RELATIVE_TOLERANCE):
            i = int((np.flatnonzero(turn < -RELATIVE_TOLERANCE)[0] + 1) % len(v))
            given = len(v) - 1 - i if area < 0.0 else i  # the index in the caller's order
            raise PolygonError(
                f"polygon {name!r} is not convex at vertex {given} ({v[i, 0]:g}, {v[i, 1]:g}); "
                "graspsim grasps convex polygons only (give the convex hull)"
            )
        heading = np.unwrap(np.arctan2(edges[:, 1], edges[:, 0]))
        total_turn = heading[-1] - heading[0] + _wrap(heading[0] - heading[-1])
        if total_turn > 2.0 * np.pi + 1e-6:
            raise PolygonError(
                f"polygon {name!r} is self-intersecting (its outline winds more than once)"
            )
        return cls(vertices=v - centroid, name=name)

    # --- derived geometry -------------------------------------------------------------------
    @property
    def n_edges(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def area(self) -> float:
        return _signed_area_and_centroid(self.vertices)[0]

    @property
    def vertex_angles(self) -> NDArray[np.float64]:
        """Polar angle of each vertex about the centroid (rad, in (-pi, pi])."""
        return np.arctan2(self.vertices[:, 1], self.vertices[:, 0])

    @property
    def max_moment(self) -> float:
        """Largest |m_z| a unit normal force can exert anywhere on the boundary (section 3.4)."""
        v = self.vertices
        tangent = np.stack([-np.sin(self.normal_angle), np.cos(self.normal_angle)], axis=1)
        s_start = np.einsum("ij,ij->i", tangent, v)
        s_end = np.einsum("ij,ij->i", tangent, np.roll(v, -1, axis=0))
        return float(np.max(np.abs(np.concatenate([s_start, s_end]))))

    @property
    def diameter(self) -> float:
        d = self.vertices[:, None, :] - self.vertices[None, :, :]
        return float(np.sqrt((d**2).sum(-1)).max())

    # --- transformations --------------------------------------------------------------------
    def scaled(self, factor: float) -> Polygon:
        if not np.isfinite(factor) or factor <= 0.0:
            raise PolygonError(f"scale factor must be a positive number, got {factor!r}")
        return Polygon(vertices=self.vertices * factor, name=self.name)

    def unit_moment(self) -> Polygon:
        """Copy scaled so that the maximum moment is 1 (section 3.4, 'maximum moment unitary')."""
        return self.scaled(1.0 / self.max_moment)

    def rotated(self, angle: float) -> Polygon:
        """The copy rotated by ``angle`` radians about the centroid."""
        if not np.isfinite(angle):
            raise PolygonError(f"rotation angle must be a finite number, got {angle!r}")
        c, s = np.cos(angle), np.sin(angle)
        return Polygon(vertices=self.vertices @ np.array([[c, s], [-s, c]]), name=self.name)

    # --- contacts ---------------------------------------------------------------------------
    def locate(self, theta: ArrayLike) -> ContactFrames:
        """Contact frames at polar angles ``theta`` (any shape)."""
        t = np.asarray(theta, dtype=float)
        frames = locate_contacts(self.normal_angle, self.offset, t.reshape(-1))
        return ContactFrames(*(a.reshape(t.shape + a.shape[1:]) for a in frames))

    def point_at(self, theta: ArrayLike) -> NDArray[np.float64]:
        return self.locate(theta).point

    def normal_at(self, theta: ArrayLike) -> NDArray[np.float64]:
        return self.locate(theta).normal

    def nearest_on_outline(self, points: ArrayLike):
        """For points (k, 2) in the object frame: the nearest point of the outline, the index of
        the edge it lies on (the first one at a vertex), and the distance to it."""
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        a = self.vertices
        d = np.roll(a, -1, axis=0) - a
        t = np.einsum("kej,ej->ke", p[:, None, :] - a[None], d) / (d**2).sum(-1)[None]
        q = a[None] + np.clip(t, 0.0, 1.0)[..., None] * d[None]
        dist = np.linalg.norm(p[:, None, :] - q, axis=-1)
        edge = np.argmin(dist, axis=1)
        rows = np.arange(p.shape[0])
        return q[rows, edge], edge, dist[rows, edge]

    def theta_of(self, point: ArrayLike) -> NDArray[np.float64]:
        """Contact coordinate (polar angle) of boundary points given in the object frame."""
        p = np.asarray(point, dtype=float)
        return np.arctan2(p[..., 1], p[..., 0])


def _wrap(angle: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles to (-pi, pi]."""
    a = np.asarray(angle, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


wrap_angle = _wrap


def parse_points(
    text: str, what: str = "polygon", dims: tuple[int, ...] = (2,)
) -> NDArray[np.float64]:
    """Parse ``"x,y;x,y;..."`` (the CLI's polygon and point format) into an (k, 2) array; with
    ``dims=(2, 3)`` every point may instead have three numbers (``"x,y,z;..."``, (k, 3))."""
    try:
        rows = [
            tuple(float(c) for c in part.split(",")) for part in text.strip().strip(";").split(";")
        ]
    except ValueError as e:
        raise PolygonError(f"{what} must be written 'x,y;x,y;...', got {_short(text)}") from e
    if dims == (2,) and any(len(r) != 2 for r in rows):
        raise PolygonError(
            f"{what} must be written 'x,y;x,y;...' (two numbers per point), got {_short(text)}"
        )
    if len({len(r) for r in rows}) != 1 or len(rows[0]) not in dims:
        raise PolygonError(
            f"{what} must be written 'x,y;x,y;...' or 'x,y,z;x,y,z;...' (the same two or three "
            f"numbers per point), got {_short(text)}"
        )
    points = np.array(rows, dtype=float)
    if not np.all(np.isfinite(points)) or np.abs(points).max() > MAX_COORDINATE:
        raise PolygonError(
            f"{what}: coordinates must be finite numbers within +-{MAX_COORDINATE:g}, "
            f"got {_short(text)}"
        )
    return points
