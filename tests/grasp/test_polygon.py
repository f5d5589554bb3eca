"""Polygon objects and the contact coordinate (Appendix B), checked against independent geometry."""

import numpy as np
import pytest

from controllers.grasp import PAPER_OBJECTS, Polygon, PolygonError, UnknownNameError, paper_object
from controllers.grasp.objects import random_convex_polygon, regular_polygon
from controllers.grasp.polygon import centroid_of, parse_points


def ray_hit(vertices: np.ndarray, theta: float) -> np.ndarray:
    """Independent ray/segment intersection: where the ray from the origin at theta leaves."""
    u = np.array([np.cos(theta), np.sin(theta)])
    best = None
    for a, b in zip(vertices, np.roll(vertices, -1, axis=0), strict=True):
        m = np.array([u, a - b]).T
        if abs(np.linalg.det(m)) < 1e-14:
            continue
        r, s = np.linalg.solve(m, a)
        if r > 0 and -1e-12 <= s <= 1 + 1e-12 and (best is None or r < best):
            best = r
    return best * u


def test_from_vertices_centres_and_orients_ccw():
    cw = [(1.0, 1.0), (1.0, 3.0), (4.0, 3.0), (4.0, 1.0)]  # clockwise rectangle
    p = Polygon.from_vertices(cw)
    assert p.area > 0  # CCW now
    assert np.allclose(p.vertices.mean(axis=0), 0.0)
    assert p.area == pytest.approx(6.0)
    assert np.allclose(np.sort(p.offset), [1.0, 1.0, 1.5, 1.5])


@pytest.mark.parametrize(
    ("vertices", "message"),
    [
        ([(0, 0), (1, 0)], "at least 3 vertices"),
        ([(0, 0), (1, 0), (float("nan"), 1)], "finite"),
        ([(0, 0), (1, 0), (1, 0), (0, 1)], "repeats vertex"),
        ([(0, 0), (1, 1), (2, 2)], "zero area"),
        ([(0, 0), (2, 0), (1, 0.2), (1, 2)], "not convex"),
        ("abc", "vertices"),
    ],
)
def test_bad_polygons_are_refused(vertices, message):
    with pytest.raises(PolygonError, match=message):
        Polygon.from_vertices(vertices)


def test_self_intersecting_star_is_refused():
    a = np.arange(5) * 2 * (2 * np.pi / 5)  # pentagram: every left turn, winds twice
    with pytest.raises(PolygonError, match="self-intersecting"):
        Polygon.from_vertices(np.stack([np.cos(a), np.sin(a)], axis=1))


@pytest.mark.parametrize("name", PAPER_OBJECTS)
def test_locate_matches_ray_intersection(name):
    p = paper_object(name)
    theta = np.random.default_rng(0).uniform(-np.pi, np.pi, 200)
    f = p.locate(theta)
    expected = np.array([ray_hit(p.vertices, t) for t in theta])
    assert np.allclose(f.point, expected, atol=1e-12)
    # the point is on its edge's line, and the normal is the outward unit normal of that edge
    assert np.allclose(np.einsum("ij,ij->i", f.point, f.normal), f.offset)
    a, b = p.vertices[f.edge], p.vertices[(f.edge + 1) % p.n_edges]
    edge = b - a
    assert np.allclose(np.einsum("ij,ij->i", edge, f.normal), 0.0, atol=1e-12)
    rel = f.point - a
    cross = edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0]
    assert np.all(cross >= -1e-15)  # the polygon lies left of a CCW edge


def test_surface_coordinate_is_moment_of_unit_normal_force():
    p = paper_object("irregular_hexagon")
    f = p.locate(np.linspace(-3, 3, 50))
    force = -f.normal
    moment = f.point[:, 0] * force[:, 1] - f.point[:, 1] * force[:, 0]
    assert np.allclose(f.surface, moment)


@pytest.mark.parametrize("name", PAPER_OBJECTS)
def test_unit_moment_scaling(name):
    u = paper_object(name).unit_moment()
    dense = u.locate(np.linspace(-np.pi, np.pi, 200_001))
    assert np.abs(dense.surface).max() == pytest.approx(1.0, abs=1e-3)
    assert u.max_moment == pytest.approx(1.0)


def test_paper_objects_are_block_sized_and_named():
    for name in PAPER_OBJECTS:
        p = paper_object(name)
        assert 0.03 < p.diameter < 0.065, name
    assert paper_object("pentagon").n_edges == 5
    with pytest.raises(UnknownNameError, match="valid: hexagon"):
        paper_object("circle")


def test_rotation_preserves_shape_and_moves_normals():
    p = regular_polygon(4, 1.0, "sq")
    r = p.rotated(np.pi / 6)
    assert np.allclose(np.sort(r.offset), np.sort(p.offset))
    assert np.allclose(
        np.sort(np.mod(r.normal_angle, 2 * np.pi)),
        np.sort(np.mod(p.normal_angle + np.pi / 6, 2 * np.pi)),
    )


def test_random_polygons_are_seeded_convex_and_exact():
    a = random_convex_polygon(np.random.default_rng(3), sides=7)
    b = random_convex_polygon(np.random.default_rng(3), sides=7)
    assert np.array_equal(a.vertices, b.vertices)
    assert a.n_edges == 7
    assert a.diameter == pytest.approx(0.05)
    rng = np.random.default_rng(4)
    for _ in range(50):
        q = random_convex_polygon(rng)
        Polygon.from_vertices(q.vertices)  # re-validates convexity
        assert 3 <= q.n_edges <= 8


def test_parse_points():
    assert parse_points("0,0; 1,0;1,1").shape == (3, 2)
    with pytest.raises(PolygonError, match="x,y"):
        parse_points("0,0;1")


@pytest.mark.parametrize("clockwise", [False, True])
def test_non_convex_vertex_is_named_in_the_callers_order(clockwise):
    ccw = [(0, 0), (2, 0), (2, 2), (1, 1.8), (0, 2)]  # the dent is vertex 3
    given = ccw[::-1] if clockwise else ccw
    i = given.index((1, 1.8))
    with pytest.raises(PolygonError, match=rf"not convex at vertex {i} \(1, 1.8\)"):
        Polygon.from_vertices(given)


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_tolerances_are_relative_to_the_polygon_size(scale):
    """RELATIVE_TOLERANCE (1e-9) and MIN_RELATIVE_AREA (1e-6) scale with the polygon: the same
    shapes are accepted or refused in millimetres, metres or kilometres."""
    square = np.array([(0, 0), (1, 0), (1, 1), (0, 1)], float)

    def with_extra(gap):  # an extra vertex on the bottom edge, ``gap`` before the corner
        return np.insert(square, 1, (1.0 - gap, 0.0), axis=0) * scale

    assert Polygon.from_vertices(with_extra(3e-9)).n_edges == 5  # collinear vertices are fine
    assert Polygon.from_vertices(with_extra(0.5)).n_edges == 5
    with pytest.raises(PolygonError, match="repeats vertex 1"):
        Polygon.from_vertices(with_extra(3e-10))

    def thin(height):  # area height / 2 of a unit-size triangle
        return np.array([(0, 0), (1, 0), (0.5, height)]) * scale

    assert Polygon.from_vertices(thin(6e-6)).area == pytest.approx(3e-6 * scale**2)
    with pytest.raises(PolygonError, match="collinear"):
        Polygon.from_vertices(thin(1e-6))
    # a dent of relative depth 1e-6 is not convex, whatever the scale
    dented = np.array([(0, 0), (0.5, 1e-6), (1, 0), (1, 1), (0, 1)]) * scale
    with pytest.raises(PolygonError, match="not convex at vertex 1"):
        Polygon.from_vertices(dented)


def test_degenerate_inputs_name_the_problem():
    with pytest.raises(PolygonError, match="all vertices coincide"):
        Polygon.from_vertices([(1, 2), (1, 2), (1, 2)])
    with pytest.raises(PolygonError, match="collinear"):
        Polygon.from_vertices([(0, 0), (0, 1), (0, 3)])  # on a vertical line
    with pytest.raises(PolygonError, match=r"\(x, y\) pairs"):
        Polygon.from_vertices([(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    # the centroid of a degenerate outline is the mean of its points
    np.testing.assert_allclose(centroid_of([(0, 0), (2, 0), (4, 0)]), [2.0, 0.0])
    np.testing.assert_allclose(centroid_of([(0, 0), (3, 0), (0, 3)]), [1.0, 1.0])


def test_polygon_is_immutable_and_prints_its_vertices():
    p = paper_object("square")
    for a in (p.vertices, p.normal_angle, p.offset):
        with pytest.raises(ValueError, match="read-only"):
            a[0] = 1.0
    assert "normal_angle" not in repr(p) and "offset" not in repr(p) and "vertices" in repr(p)


def test_diameter_area_and_scaling():
    rect = Polygon.from_vertices([(0, 0), (5, 0), (5, 2.5), (0, 2.5)])
    assert rect.diameter == pytest.approx(np.hypot(5.0, 2.5))
    assert rect.area == pytest.approx(12.5)
    tri = Polygon.from_vertices([(0, 0), (4, 0), (0, 3)])
    assert tri.diameter == pytest.approx(5.0)
    big = tri.scaled(2.0)
    assert big.diameter == pytest.approx(10.0) and big.area == pytest.approx(24.0)
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(PolygonError, match="positive"):
            tri.scaled(bad)


def test_theta_of_inverts_point_at():
    p = paper_object("irregular_hexagon")
    theta = np.random.default_rng(2).uniform(-np.pi, np.pi, (3, 40))
    np.testing.assert_allclose(p.theta_of(p.point_at(theta)), theta, atol=1e-12)
    assert p.theta_of((0.0, 1.0)) == pytest.approx(np.pi / 2)


def test_the_first_reflex_vertex_is_named_after_collinear_ones():
    # vertex 1 is collinear (turn 0, allowed), vertex 4 is the dent
    v = [(0, 0), (1, 0), (2, 0), (2, 2), (1, 1.8), (0, 2)]
    with pytest.raises(PolygonError, match=r"not convex at vertex 4 \(1, 1.8\)"):
        Polygon.from_vertices(v)
