"""The paper's nine test objects (Figure 6), their shape families, and seeded random polygons.

The four regular objects are exact. Figure 6 gives the other five (irregular triangle, rectangle,
trapezoid, irregular pentagon and hexagon) without coordinates, so each is a family of shapes drawn
by a rule fixed before any controller was run (:func:`family_member`); the object of that name is
the family's member 0. Random convex polygons come in seeded sets ("train", "heldout") whose seeds
never overlap. Sizes are metres (blocks about 5 cm across, section 5.1); the controllers use
:meth:`Polygon.unit_moment` copies (section 3.4), so the physical scale changes no result.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.errors import UnknownNameError
from controllers.grasp.polygon import Polygon

CM = 0.01  # metres per centimetre


def regular_polygon(sides: int, circumradius: float, name: str, phase: float = 0.0) -> Polygon:
    """A regular polygon with one vertex at polar angle ``phase`` + pi/sides below the x axis:
    edge 0's outward normal points along +x when ``phase`` is 0."""
    a = phase + (2.0 * np.arange(sides) - 1.0) * np.pi / sides
    return Polygon.from_vertices(circumradius * np.stack([np.cos(a), np.sin(a)], axis=1), name)


#: Shapes that Figure 6 shows without coordinates (and that our copy of the paper does not show at
#: all: its figures are not in the text). Each is a *family* of seeded shapes made by the rules in
#: :func:`family_member`. Member 0 is the object ``paper_object`` returns (the one in the scenes
#: and in section 2's experiment); tables report the mean and the 5-95 % range over
#: :data:`FAMILY_SIZE` members.
#: Rules fixed in advance, not by their effect on a result: docs/findings.md, "Shape families".
FAMILY_OBJECTS: tuple[str, ...] = (
    "irregular_triangle",
    "rectangle",
    "trapezoid",
    "irregular_pentagon",
    "irregular_hexagon",
)
#: Members per family reported in Tables 1 and 2.
FAMILY_SIZE = 20
#: Size of every family member (section 5.1: blocks with "maximum distance between edges of 5 cm
#: (for the rectangle)"): the long side of a rectangle or trapezoid, the diameter of an irregular
#: k-gon. Size changes no grasp result (the controllers use unit-moment copies, section 3.4), only
#: the physical blocks. How it was set: docs/findings.md, "Shape families".
FAMILY_LENGTH = 5.0 * CM
#: Rectangle: aspect ratio (long / short side) uniform in this range (a block that is clearly not
#: a square, and not a plank).
RECTANGLE_ASPECT = (1.5, 2.5)
#: Trapezoid (isosceles): top side / bottom side and height / bottom side, each uniform in range.
TRAPEZOID_TOP = (0.3, 0.7)
TRAPEZOID_HEIGHT = (0.4, 0.7)
#: Irregular k-gons: :func:`random_convex_polygon` with exactly this many sides.
IRREGULAR_SIDES = {"irregular_triangle": 3, "irregular_pentagon": 5, "irregular_hexagon": 6}
#: Seeds of family members: member i of family f (its index in FAMILY_OBJECTS) is drawn by
#: ``default_rng(FAMILY_SEED + 1000 f + i)``. Disjoint from the seeds of the random-polygon sets of
#: :data:`POLYGON_SET_SEEDS`.
FAMILY_SEED = 3_000_000

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
    if name in FAMILY_OBJECTS:
        return family_member(name, 0)
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


def canonical(poly: Polygon) -> Polygon:
    """``poly`` rotated so that its longest edge is at the bottom (outward normal along -y).

    Rotation changes no grasp result (the controllers and the uniform initial contacts are
    rotation invariant); it only makes the shapes look alike in scenes and figures.
    """
    edges = np.roll(poly.vertices, -1, axis=0) - poly.vertices
    j = int(np.argmax(np.linalg.norm(edges, axis=1)))
    return poly.rotated(-0.5 * np.pi - float(poly.normal_angle[j]))


def family_seed(name: str, member: int) -> int:
    """The seed that draws ``member`` of the family ``name`` (see :data:`FAMILY_SEED`)."""
    if name not in FAMILY_OBJECTS:
        raise UnknownNameError("shape family", name, list(FAMILY_OBJECTS))
    if not 0 <= member < 1000:
        raise ValueError(f"family member must be in [0, 1000), got {member}")
    return FAMILY_SEED + 1000 * FAMILY_OBJECTS.index(name) + member


def family_member(name: str, member: int) -> Polygon:
    """Member ``member`` of the family ``name`` (metres, longest edge at the bottom; a 5 cm long
    side for a rectangle or trapezoid, a 5 cm diameter otherwise). The rules of the shapes
    (docs/findings.md, "Shape families"):

    - rectangle: sides 1 and 1/r, r uniform in :data:`RECTANGLE_ASPECT`;
    - trapezoid: isosceles, bottom 1, top uniform in :data:`TRAPEZOID_TOP`, height uniform in
      :data:`TRAPEZOID_HEIGHT`;
    - irregular triangle, pentagon, hexagon: :func:`random_convex_polygon` with 3, 5, 6 sides.
    """
    rng = np.random.default_rng(family_seed(name, member))
    if name == "rectangle":
        r = rng.uniform(*RECTANGLE_ASPECT)
        v = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0 / r), (0.0, 1.0 / r)])
        poly = Polygon.from_vertices(v, name)
    elif name == "trapezoid":
        top, h = rng.uniform(*TRAPEZOID_TOP), rng.uniform(*TRAPEZOID_HEIGHT)
        a = 0.5 * (1.0 - top)
        poly = Polygon.from_vertices(np.array([(0.0, 0.0), (1.0, 0.0), (1.0 - a, h), (a, h)]), name)
    else:
        poly = random_convex_polygon(rng, sides=IRREGULAR_SIDES[name])
    poly = Polygon(vertices=poly.vertices, name=name)
    if name in ("rectangle", "trapezoid"):  # the bottom side is 1
        return canonical(poly.scaled(FAMILY_LENGTH))
    return canonical(poly.scaled(FAMILY_LENGTH / poly.diameter))


def family(name: str, size: int = FAMILY_SIZE) -> list[Polygon]:
    """The first ``size`` members of a shape family; a regular paper object is its own family."""
    if name in FAMILY_OBJECTS:
        return [family_member(name, i) for i in range(size)]
    return [paper_object(name)]


#: Seeded sets of random convex polygons (:func:`random_convex_polygon`, 3-8 sides, diameter 5 cm):
#: polygon i of set s is drawn by ``default_rng(POLYGON_SET_SEEDS[s] + i)``. "train" teaches the
#: general F/S predictor, "validation" picks its settings, "heldout" is never used for either.
#: Each set owns a range of MAX_SET_SIZE seeds; the ranges never overlap with each other or with
#: the family seeds (FAMILY_SEED ...).
POLYGON_SET_SEEDS: dict[str, int] = {
    "train": 1_000_000,
    "heldout": 2_000_000,
    "validation": 4_000_000,
}
MAX_SET_SIZE = 1_000_000


def polygon_set_seeds(kind: str, count: int) -> range:
    """The seeds of the first ``count`` polygons of the set ``kind``."""
    if kind not in POLYGON_SET_SEEDS:
        raise UnknownNameError("polygon set", kind, list(POLYGON_SET_SEEDS))
    if not 0 <= count <= MAX_SET_SIZE:
        raise ValueError(f"a polygon set holds 0..{MAX_SET_SIZE} polygons, got {count}")
    start = POLYGON_SET_SEEDS[kind]
    return range(start, start + count)


def polygon_set(kind: str, count: int) -> list[Polygon]:
    """The first ``count`` polygons of the seeded set ``kind`` (a key of POLYGON_SET_SEEDS)."""
    return [random_convex_polygon(np.random.default_rng(s)) for s in polygon_set_seeds(kind, count)]


@dataclass(frozen=True)
class ObjectSet:
    """The objects of an experiment, each a family of one or more shapes (a regular paper object
    is a family of one). Trial k of an object uses member ``k mod size``, so an object's trials
    cycle through its family. ``polygons`` is the flat list (object 0's members first)."""

    names: tuple[str, ...]
    members: tuple[tuple[Polygon, ...], ...]
    first: NDArray[np.int64] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.names) != len(self.members) or not self.members:
            raise ValueError("an object set needs one name per object and at least one object")
        if any(len(m) == 0 for m in self.members):
            raise ValueError("every object needs at least one shape")
        first = np.concatenate([[0], np.cumsum([len(m) for m in self.members])[:-1]])
        object.__setattr__(self, "first", first.astype(np.int64))

    @classmethod
    def of(cls, objects: Sequence[Polygon | Sequence[Polygon]]) -> ObjectSet:
        """From polygons (families of one) or sequences of polygons (families)."""
        members = tuple((o,) if isinstance(o, Polygon) else tuple(o) for o in objects)
        return cls(tuple(m[0].name for m in members), members)

    @classmethod
    def paper(
        cls, names: Sequence[str] = PAPER_OBJECTS, family_size: int = FAMILY_SIZE
    ) -> ObjectSet:
        """The paper objects ``names`` with their shape families of ``family_size`` members."""
        return cls(tuple(names), tuple(tuple(family(n, family_size)) for n in names))

    @property
    def polygons(self) -> tuple[Polygon, ...]:
        return tuple(p for m in self.members for p in m)

    @property
    def sizes(self) -> NDArray[np.int64]:
        return np.array([len(m) for m in self.members], dtype=np.int64)

    def polygon_index(self, obj: NDArray[np.int64], k: NDArray[np.int64]) -> NDArray[np.int64]:
        """Flat index of member ``k mod size`` of each object ``obj``."""
        obj = np.asarray(obj, dtype=np.int64)
        return self.first[obj] + np.asarray(k, dtype=np.int64) % self.sizes[obj]

    def object_of(self, polygon_index: NDArray[np.int64]) -> NDArray[np.int64]:
        """Object of each flat polygon index."""
        return np.searchsorted(self.first, np.asarray(polygon_index), side="right") - 1

    def test_index(self, trials: int, trials_per_member: int) -> NDArray[np.int64]:
        """Flat polygon index of each test trial: ``trials`` on a family of one, and
        ``trials_per_member`` on each member of a larger family, object by object."""
        out = []
        for o, m in enumerate(self.members):
            reps = trials if len(m) == 1 else trials_per_member
            out.append(np.repeat(self.first[o] + np.arange(len(m)), reps))
        return np.concatenate(out)
