"""The paper's nine test objects (Figure 6) and a seeded generator of random convex polygons.

Figure 6 gives the shapes but no coordinates; the vertices below (metres, a prism block about 5 cm
across as in section 5.1) are our choice and are documented in the README. The grasp controllers
use :meth:`Polygon.unit_moment` copies (section 3.4), so the physical scale does not change them.
"""

from __future__ import annotations

import numpy as np

from controllers.grasp.errors import UnknownNameError
from controllers.grasp.polygon import Polygon

CM = 0.01  # metres per centimetre


def regular_polygon(sides: int, circumradius: float, name: str, phase: float = 0.0) -> Polygon:
    """A regular polygon with one vertex at polar angle ``phase`` + pi/sides below the x axis:
    edge 0's outward normal points along +x when ``phase`` is 0."""
    a = phase + (2.0 * np.arange(sides) - 1.0) * np.pi / sides
    return Polygon.from_vertices(circumradius * np.stack([np.cos(a), np.sin(a)], axis=1), name)


#: Vertex lists (cm) of the non-regular paper objects, CCW.
IRREGULAR_VERTICES_CM: dict[str, list[tuple[float, float]]] = {
    "irregular_triangle": [(0.0, 0.0), (4.0, 0.0), (2.8, 3.6)],
    "rectangle": [(0.0, 0.0), (5.0, 0.0), (5.0, 2.5), (0.0, 2.5)],
    "trapezoid": [(0.0, 0.0), (5.0, 0.0), (3.75, 2.5), (1.25, 2.5)],
    "irregular_pentagon": [(0.0, 0.0), (5.0, 0.0), (5.0, 3.0), (2.0, 4.0), (0.0, 2.0)],
    "irregular_hexagon": [(0.0, 0.0), (3.4, -0.6), (5.0, 1.4), (4.2, 3.6), (1.6, 4.1), (-0.6, 2.0)],
}

#: The nine objects in the order of Table 1 of the paper.
PAPER_OBJECTS: tuple[str, ...] = (
    "triangle",
    "square",
    "pentagon",
    "hexagon",
    "irregular_triangle",
    "rectangle",
    "trapezoid",
    "irregular_pentagon",
    "irregular_hexagon",
)

#: Table 1 labels of the paper.
PAPER_LABELS: dict[str, str] = {
    "triangle": "Triangle",
    "square": "Square",
    "pentagon": "Pentagon",
    "hexagon": "Hexagon",
    "irregular_triangle": "Irreg. Triangle",
    "rectangle": "Rectangle",
    "trapezoid": "Trapezoid",
    "irregular_pentagon": "Irreg. Pentagon",
    "irregular_hexagon": "Irreg. Hexagon",
}


def paper_object(name: str) -> Polygon:
    """One of the nine objects of Figure 6, in metres, centroid at the origin.

    Raises :class:`UnknownNameError` listing the valid names.
    """
    if name == "triangle":
        return regular_polygon(3, 2.9 * CM, name)
    if name == "square":
        return regular_polygon(4, 2.0 * np.sqrt(2.0) * CM, name)
    if name == "pentagon":
        return regular_polygon(5, 2.6 * CM, name)
    if name == "hexagon":
        return regular_polygon(6, 2.5 * CM, name)
    if name in IRREGULAR_VERTICES_CM:
        return Polygon.from_vertices(np.array(IRREGULAR_VERTICES_CM[name]) * CM, name)
    raise UnknownNameError("object", name, list(PAPER_OBJECTS))


def random_convex_polygon(
    rng: np.random.Generator,
    sides: int | None = None,
    diameter: float = 5.0 * CM,
    min_sides: int = 3,
    max_sides: int = 8,
) -> Polygon:
    """A random convex polygon with exactly ``sides`` vertices (drawn in [min_sides, max_sides]
    when None), random aspect ratio in [1, 2] and rotation, scaled to ``diameter``.

    Vertices are points of a circle at sorted random angles (at least 0.35 * 2 pi / sides apart),
    which is always convex; an affine stretch keeps it convex.
    """
    k = int(rng.integers(min_sides, max_sides + 1)) if sides is None else int(sides)
    if k < 3:
        raise ValueError(f"a polygon needs at least 3 sides, got {k}")
    min_gap = 0.35 * 2.0 * np.pi / k
    gaps = rng.dirichlet(np.ones(k)) * (2.0 * np.pi - k * min_gap) + min_gap
    ang = rng.uniform(0.0, 2.0 * np.pi) + np.cumsum(gaps)
    pts = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    pts[:, 0] *= rng.uniform(1.0, 2.0)
    rot = rng.uniform(0.0, 2.0 * np.pi)
    c, s = np.cos(rot), np.sin(rot)
    pts = pts @ np.array([[c, s], [-s, c]])
    poly = Polygon.from_vertices(pts, name=f"random{k}")
    return poly.scaled(diameter / poly.diameter)
