"""The object model the vision hands to the grasp controller (section 5.2, Select/Model: "a 2D
object contour model, which is extruded in the z direction ... the object centroid, number of
edges and overall shape")."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from controllers.grasp import Polygon


@dataclass(frozen=True)
class ObjectModel:
    """One block as seen from above: a prism whose cross-section is ``polygon``.

    The object frame has its origin at the top face's centroid and its x axis at angle ``yaw``
    from the world x axis (the outward normal of the polygon's longest edge, our choice: the
    paper leaves the frame open); z is up.
    """

    name: str  #: the block's name when known (scene names), else ``block<i>``
    polygon: Polygon  #: cross-section in metres, object frame, CCW, centroid at the origin
    centroid: NDArray[np.float64]  #: (3,) world (x, y, z_top): top face centroid
    yaw: float  #: rad, world angle of the object frame's x axis, in (-pi, pi]
    height: float  #: m, top face above the table (from depth)
    n_edges: int
    pixel_contour: NDArray[np.float64]  #: (k, 2) image vertices (u, v), pixels
    world_vertices: NDArray[np.float64]  #: (k, 2) world xy of the polygon's vertices, CCW
    refined_edges: int  #: edges placed from colour profiles (the others from depth alone)

    def to_world(self, points: ArrayLike) -> NDArray[np.float64]:
        """World xy of object-frame points (..., 2)."""
        p = np.asarray(points, dtype=float)
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return p @ np.array([[c, s], [-s, c]]) + self.centroid[:2]

    def to_object(self, points: ArrayLike) -> NDArray[np.float64]:
        """Object-frame coordinates of world xy points (..., 2)."""
        p = np.asarray(points, dtype=float) - self.centroid[:2]
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return p @ np.array([[c, -s], [s, c]])
