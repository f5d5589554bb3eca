"""Many unit-moment polygons as padded edge arrays, so that contacts on all of them are located at
once (the vectorized trials of section 3.6.2 and the arc-length noise of Appendix A)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.polygon import ContactFrames, Polygon, locate_contacts


@dataclass(frozen=True)
class PolygonBatch:
    """Unit-moment polygons stacked as padded edge arrays, for vectorized contact location.

    Padding edges (beyond a polygon's own) have offset inf and length 0. The perimeter arrays
    serve the arc-length reading of the pre-image noise (:mod:`controllers.grasp.preimaging`).
    """

    polygons: tuple[Polygon, ...]
    normal_angle: NDArray[np.float64]  #: (P, E_max); padding edges have offset inf
    offset: NDArray[np.float64]  #: (P, E_max)
    vertex: NDArray[np.float64]  #: (P, E_max, 2) start vertex of each edge (padding: 0)
    edge_length: NDArray[np.float64]  #: (P, E_max) (padding: 0)
    start_surface: NDArray[np.float64]  #: (P, E_max) surface coordinate of each edge's start
    arc_start: NDArray[np.float64]  #: (P, E_max) arc length from vertex 0 to each edge's start

    @classmethod
    def of(cls, polygons: Sequence[Polygon]) -> PolygonBatch:
        unit = tuple(p.unit_moment() for p in polygons)
        e_max = max(p.n_edges for p in unit)
        ang = np.zeros((len(unit), e_max))
        off = np.full((len(unit), e_max), np.inf)
        vert = np.zeros((len(unit), e_max, 2))
        length = np.zeros((len(unit), e_max))
        start_s = np.zeros((len(unit), e_max))
        for i, p in enumerate(unit):
            k = p.n_edges
            ang[i, :k] = p.normal_angle
            off[i, :k] = p.offset
            vert[i, :k] = p.vertices
            length[i, :k] = np.linalg.norm(np.roll(p.vertices, -1, axis=0) - p.vertices, axis=1)
            tangent = np.stack([-np.sin(p.normal_angle), np.cos(p.normal_angle)], axis=1)
            start_s[i, :k] = np.einsum("ij,ij->i", tangent, p.vertices)
        arc = np.cumsum(length, axis=1) - length
        return cls(unit, ang, off, vert, length, start_s, arc)

    @property
    def perimeter(self) -> NDArray[np.float64]:
        """(P,) perimeter of each unit-moment polygon."""
        return self.edge_length.sum(axis=1)

    def locate(self, object_index: NDArray[np.int64], theta: NDArray[np.float64]) -> ContactFrames:
        return locate_contacts(self.normal_angle[object_index], self.offset[object_index], theta)

    def arc_of(self, object_index: NDArray[np.int64], frames: ContactFrames):
        """Arc length along the outline (CCW from vertex 0) of located contacts, shape of theta."""
        rows = np.broadcast_to(object_index[:, None], frames.edge.shape)
        return (
            self.arc_start[rows, frames.edge]
            + frames.surface
            - self.start_surface[rows, frames.edge]
        )

    def theta_at_arc(
        self, object_index: NDArray[np.int64], arc: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Contact coordinate (polar angle) of the outline point at arc length ``arc`` (T, n),
        taken modulo each polygon's perimeter."""
        per = self.perimeter[object_index][:, None]
        a = np.mod(arc, per)
        end = (self.arc_start + self.edge_length)[object_index]  # (T, E)
        real = self.edge_length[object_index] > 0.0
        edge = ((end[:, None, :] <= a[..., None]) & real[:, None, :]).sum(-1)
        n_real = real.sum(-1)[:, None]
        edge = np.minimum(edge, n_real - 1)
        rows = np.broadcast_to(object_index[:, None], edge.shape)
        start = self.vertex[rows, edge]
        ang = self.normal_angle[rows, edge]
        tangent = np.stack([-np.sin(ang), np.cos(ang)], axis=-1)
        point = start + (a - self.arc_start[rows, edge])[..., None] * tangent
        return np.arctan2(point[..., 1], point[..., 0])
