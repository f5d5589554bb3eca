"""Tests of hand_sim.scene, hand_sim.geometry and hand_sim.random_scene: scene files load, the
layouts are physically sensible, and bad files are refused with a message naming file and field."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial import ConvexHull

from controllers.grasp import PAPER_OBJECTS, paper_object
from hand_sim.geometry import (
    convex_polygon_distance,
    convex_polygons_intersect,
    inside_rectangle,
    place_polygon,
    point_in_convex_polygon,
    rotation_2d,
)
from hand_sim.random_scene import load_generator_config
from hand_sim.scene import MIN_BLOCK_GAP, SceneError, load_scene, scene_names

NAMED = [n for n in scene_names() if n != "random"]


def boundary_samples(footprint: np.ndarray, per_edge: int = 400) -> np.ndarray:
    """Dense points on a polygon's outline (independent of the SAT-based distance)."""
    t = np.linspace(0.0, 1.0, per_edge, endpoint=False)[:, None]
    nxt = np.roll(footprint, -1, axis=0)
    return np.concatenate([a + t * (b - a) for a, b in zip(footprint, nxt, strict=True)])


def sampled_gap(a: np.ndarray, b: np.ndarray, per_edge: int = 400) -> float:
    """Smallest distance between the sampled outlines (never below the true gap)."""
    pa, pb = boundary_samples(a, per_edge), boundary_samples(b, per_edge)
    return float(np.sqrt(((pa[:, None, :] - pb[None, :, :]) ** 2).sum(-1)).min())


def test_scene_names_cover_the_issue() -> None:
    names = set(scene_names())
    assert {"clutter3", "clutter5", "random"} <= names
    assert {f"single_{o}" for o in PAPER_OBJECTS} <= names


@pytest.mark.parametrize("name", NAMED)
def test_named_scene_is_physically_sensible(name: str) -> None:
    scene = load_scene(name)
    assert scene.target in scene.block_names
    t = scene.table
    lo = np.array(t.position_xy) - 0.5 * np.array(t.size_xy)
    hi = np.array(t.position_xy) + 0.5 * np.array(t.size_xy)
    fps = [b.footprint() for b in scene.blocks]
    for fp in fps:
        assert np.all(fp >= lo) and np.all(fp <= hi)
    for i in range(len(fps)):
        for j in range(i):
            assert sampled_gap(fps[i], fps[j], 100) >= MIN_BLOCK_GAP - 1e-4
    assert np.all(np.array(scene.place) >= lo) and np.all(np.array(scene.place) <= hi)
    for b in scene.blocks:
        # the paper's blocks are about 20 cm tall; a scene may add taller pillars around them
        tall = b.name != scene.target and "pillar" in b.name
        assert b.height == pytest.approx(0.40 if tall else 0.20)
        if name == "wide_square":  # wider than the paper's blocks, on purpose (issue 23)
            assert b.polygon.diameter == pytest.approx(0.09 * np.sqrt(2))
        else:
            assert 0.03 <= b.polygon.diameter <= 0.07  # "about 5 cm across"


def test_clutter_scenes_hold_different_blocks_close_together() -> None:
    for name, k in (("clutter3", 3), ("clutter5", 5)):
        scene = load_scene(name)
        assert len(scene.blocks) == k
        assert (
            len({b.polygon.n_edges * 1000 + round(b.polygon.area * 1e6) for b in scene.blocks}) == k
        )
        centres = np.array([b.position for b in scene.blocks])
        nearest = [np.sort(np.linalg.norm(centres - c, axis=1))[1] for c in centres]
        assert max(nearest) < 0.15  # every block has a neighbour within 15 cm


@pytest.mark.parametrize("obj", PAPER_OBJECTS)
def test_single_scene_holds_that_paper_object(obj: str) -> None:
    scene = load_scene(f"single_{obj}")
    (block,) = scene.blocks
    np.testing.assert_allclose(block.polygon.vertices, paper_object(obj).vertices)
    assert scene.target == block.name


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    return p


GOOD = """
target = "a"
place = [0.0, -0.2]
[[blocks]]
name = "a"
shape = "square"
position = [0.0, 0.0]
yaw_deg = 30.0
[[blocks]]
name = "b"
vertices = [[0.0, 0.0], [0.04, 0.0], [0.0, 0.03]]
position = [0.12, 0.0]
rgba = [0.1, 0.2, 0.3, 1.0]
"""


def test_file_path_loads_with_degrees_and_explicit_vertices(tmp_path: Path) -> None:
    scene = load_scene(write(tmp_path, GOOD))
    a, b = scene.blocks
    assert a.yaw == pytest.approx(math.radians(30.0))
    assert b.polygon.area == pytest.approx(0.5 * 0.04 * 0.03)
    np.testing.assert_allclose(
        b.polygon.vertices.mean(axis=0), [0.04 / 3 - 0.04 / 3, 0.0], atol=1e-12
    )
    assert b.rgba == (0.1, 0.2, 0.3, 1.0)
    # the square's footprint is rotated by 30 degrees about its centroid
    fp = a.footprint()
    np.testing.assert_allclose(fp.mean(axis=0), [0.0, 0.0], atol=1e-12)
    expected = paper_object("square").vertices @ np.array(
        [[math.cos(0.5236), math.sin(0.5236)], [-math.sin(0.5236), math.cos(0.5236)]]
    )
    np.testing.assert_allclose(fp, expected, atol=1e-4)


BAD_CASES = {
    "unknown_shape": (
        GOOD.replace('"square"', '"circle"'),
        ["blocks[0].shape", "circle", "valid", "pentagon"],
    ),
    "overlap": (
        GOOD.replace("[0.12, 0.0]", "[0.03, 0.0]"),
        ["blocks[1].position", "overlaps", "'a'"],
    ),
    "too_close": (  # axis-aligned 4 cm square and a triangle whose left edge is 3 mm away
        GOOD.replace("[0.12, 0.0]", "[0.03633, 0.0]").replace("yaw_deg = 30.0", "yaw_deg = 0.0"),
        ["blocks[1].position", "3.0 mm from"],
    ),
    "off_table": (
        GOOD.replace("[0.12, 0.0]", "[0.12, 0.449]"),
        ["blocks[1].position", "off the table"],
    ),
    "unknown_top_key": ("colour = 'red'\n" + GOOD, ["bad.toml", ": colour:", "unknown key"]),
    "unknown_block_key": (
        GOOD.replace("yaw_deg = 30.0", "yaw = 30.0"),
        ["blocks[0].yaw", "unknown key", "yaw_deg"],
    ),
    "target_not_block": (
        GOOD.replace('target = "a"', 'target = "z"'),
        ["target", "'z'", "not a block", "a, b"],
    ),
    "place_off_table": (
        GOOD.replace("place = [0.0, -0.2]", "place = [2.0, 0.0]"),
        ["place", "off the table"],
    ),
    "place_inside_other": (
        GOOD.replace("place = [0.0, -0.2]", "place = [0.125, 0.005]"),
        ["place", "inside block 'b'"],
    ),
    "non_convex": (
        GOOD.replace(
            "[[0.0, 0.0], [0.04, 0.0], [0.0, 0.03]]", "[[0, 0], [0.04, 0], [0.01, 0.01], [0, 0.04]]"
        ),
        ["blocks[1].vertices", "not convex"],
    ),
    "vertices_in_cm": (
        GOOD.replace("[[0.0, 0.0], [0.04, 0.0], [0.0, 0.03]]", "[[0, 0], [4, 0], [0, 3]]"),
        ["blocks[1].vertices", "metres"],
    ),
    "missing_position": (
        GOOD.replace("position = [0.0, 0.0]\n", ""),
        ["blocks[0].position", "missing"],
    ),
    "bad_position": (
        GOOD.replace("position = [0.0, 0.0]", 'position = [0.0, "x"]'),
        ["blocks[0].position", "2 finite numbers"],
    ),
    "duplicate_name": (GOOD.replace('name = "b"', 'name = "a"'), ["blocks[1].name", "duplicate"]),
    "colour_and_rgba": (
        GOOD.replace("rgba =", "colour = 'red'\nrgba ="),
        ["blocks[1].colour", "at most one"],
    ),
    "unknown_colour": (
        GOOD.replace("yaw_deg = 30.0", 'yaw_deg = 30.0\ncolour = "mauve"'),
        ["blocks[0].colour", "mauve", "red"],
    ),
    "shape_and_vertices": (
        GOOD.replace('shape = "square"', 'shape = "square"\nvertices = [[0,0],[0.03,0],[0,0.03]]'),
        ["blocks[0].shape", "exactly one"],
    ),
    "no_blocks": ('target = "a"\nplace = [0.0, 0.0]\n', ["blocks", "at least one"]),
    "syntax": (GOOD + "[[blocks]\n", ["bad.toml", "not valid TOML"]),
    "table_key": (GOOD + "[table]\nwidth = 1.0\n", ["table.width", "unknown key", "size"]),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_scene_file_is_refused_naming_file_field_and_problem(tmp_path: Path, case: str) -> None:
    text, fragments = BAD_CASES[case]
    path = write(tmp_path, text)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_unknown_scene_name_lists_valid_names() -> None:
    with pytest.raises(SceneError, match=r"unknown scene 'clutter9'.*clutter3.*single_triangle"):
        load_scene("clutter9")
    with pytest.raises(ValueError):  # SceneError is a ValueError
        load_scene("nope")


def test_seed_only_for_random() -> None:
    with pytest.raises(SceneError, match="random"):
        load_scene("clutter3", seed=1)


def opencv_overlap_area(a: np.ndarray, b: np.ndarray) -> float:
    """Area (mm^2) of the intersection of two convex polygons given in metres, by OpenCV
    (independent of the SAT). In millimetres: OpenCV drops areas below an absolute epsilon."""
    mm = 1000.0
    area, _ = cv2.intersectConvexConvex((mm * a).astype(np.float32), (mm * b).astype(np.float32))
    return float(area)


def test_convex_polygon_distance_matches_sampling() -> None:
    rng = np.random.default_rng(0)
    square = paper_object("square").vertices
    tri = paper_object("triangle").vertices
    n_overlap = 0
    for _ in range(20):
        a = place_polygon(square, rng.uniform(-0.05, 0.05, 2), rng.uniform(-np.pi, np.pi))
        b = place_polygon(tri, rng.uniform(-0.05, 0.05, 2), rng.uniform(-np.pi, np.pi))
        d = convex_polygon_distance(a, b)
        if d > 0:
            assert d == pytest.approx(sampled_gap(a, b), abs=2e-4)
            assert opencv_overlap_area(a, b) == 0.0
        else:  # reported as overlapping: OpenCV finds a common area
            n_overlap += 1
            assert opencv_overlap_area(a, b) > 0.0
    assert 3 <= n_overlap <= 17  # both branches ran
    unit = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    assert convex_polygon_distance(unit, unit + np.array([3.0, 0.0])) == pytest.approx(2.0)
    diagonal = convex_polygon_distance(unit, unit + np.array([2.0, 2.0]))
    assert diagonal == pytest.approx(math.sqrt(2.0))
    assert convex_polygon_distance(unit, unit + np.array([0.5, 0.5])) == 0.0


def test_separating_axis_of_the_second_polygon_is_found() -> None:
    """A diamond 0.1 to the left of a box: no edge normal of the diamond separates them (its
    projections overlap the box's on both diagonals), only the box's x axis does."""
    diamond = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    box = np.array([[1.1, -0.5], [2.1, -0.5], [2.1, 0.5], [1.1, 0.5]])
    assert not convex_polygons_intersect(diamond, box)
    assert not convex_polygons_intersect(box, diamond)
    assert convex_polygon_distance(diamond, box) == pytest.approx(0.1)
    assert convex_polygon_distance(box, diamond) == pytest.approx(0.1)
    assert convex_polygons_intersect(diamond, box - [0.2, 0.0])
    assert convex_polygons_intersect(diamond, box - [0.1, 0.0])  # touching counts


def test_overlap_agrees_with_opencv_on_random_pairs() -> None:
    """Random convex polygons of different sizes and shapes, near each other: the SAT verdict is
    OpenCV's (pairs within float32 noise of touching are skipped)."""
    rng = np.random.default_rng(1)

    def hull() -> np.ndarray:  # 3 to 8 vertices, up to 6 cm across, random aspect
        pts = rng.uniform(-0.03, 0.03, (int(rng.integers(3, 12)), 2)) * [1.0, rng.uniform(0.2, 1)]
        return place_polygon(pts[ConvexHull(pts).vertices], rng.uniform(-0.03, 0.03, 2), 0.0)

    verdicts = []
    for _ in range(400):
        a, b = hull(), hull()
        gap, area = convex_polygon_distance(a, b), opencv_overlap_area(a, b)
        if 0.0 < gap < 1e-4 or 0.0 < area < 1e-2:  # within float32 noise of touching
            continue
        overlap = area > 0.0
        assert convex_polygons_intersect(a, b) == overlap
        assert (gap == 0.0) == overlap
        verdicts.append(overlap)
    assert len(verdicts) > 380 and 50 < sum(verdicts) < len(verdicts) - 50


def test_point_in_polygon_and_rectangle_containment() -> None:
    tri = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]])
    assert point_in_convex_polygon((0.5, 0.5), tri)
    assert point_in_convex_polygon((1.0, 1.0), tri)  # on the edge
    assert not point_in_convex_polygon((1.01, 1.01), tri)
    assert not point_in_convex_polygon((-0.01, 0.5), tri)
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert inside_rectangle(square, (0.5, 0.5), (1.0, 1.0))
    assert not inside_rectangle(square, (0.5, 0.5), (1.0, 1.0), margin=0.01)
    assert inside_rectangle(square, (0.5, 0.5), (1.04, 1.04), margin=0.01)
    for shift in ((0.0, 0.03), (-0.03, 0.0)):  # out at the top, out at the left
        moved = square + np.array(shift)
        assert not inside_rectangle(moved, (0.5, 0.5), (1.04, 1.04), margin=0.01)
    assert inside_rectangle((-0.4, 0.3), (0.0, 0.0), (0.9, 0.9))
    assert not inside_rectangle((-0.46, 0.0), (0.0, 0.0), (0.9, 0.9))


def test_place_polygon_rotates_then_translates() -> None:
    v = np.array([[1.0, 0.0], [0.0, 2.0]])
    np.testing.assert_allclose(place_polygon(v, (3.0, -1.0), np.pi / 2), [[3.0, 0.0], [1.0, -1.0]])
    np.testing.assert_allclose(rotation_2d(0.3) @ rotation_2d(-0.3), np.eye(2), atol=1e-15)
    np.testing.assert_allclose(rotation_2d(np.pi / 2) @ [1.0, 0.0], [0.0, 1.0], atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_random_scene_is_seeded_collision_free_and_in_reach(seed: int) -> None:
    cfg = load_generator_config()
    scene = load_scene("random", seed=seed, blocks=5)
    again = load_scene("random", seed=seed, blocks=5)
    assert [b.position for b in scene.blocks] == [b.position for b in again.blocks]
    assert scene.place == again.place
    assert len(scene.blocks) == 5
    fps = [b.footprint() for b in scene.blocks]
    for i in range(5):
        for j in range(i):
            assert sampled_gap(fps[i], fps[j], 100) >= cfg.min_gap - 1e-4
    for b in scene.blocks:
        r = math.dist(b.position, cfg.reach_centre)
        assert cfg.reach[0] <= r <= cfg.reach[1]
        assert cfg.region_x[0] <= b.position[0] <= cfg.region_x[1]
    target = scene.target_block
    at_place = place_polygon(target.polygon.vertices, scene.place, target.yaw)
    for b, fp in zip(scene.blocks, fps, strict=True):
        if b.name != target.name:
            assert sampled_gap(at_place, fp, 100) >= cfg.min_gap - 1e-4


def test_random_scenes_differ_between_seeds() -> None:
    a = load_scene("random", seed=10, blocks=3)
    b = load_scene("random", seed=11, blocks=3)
    assert [x.position for x in a.blocks] != [x.position for x in b.blocks]


def test_random_scene_refuses_impossible_requests() -> None:
    with pytest.raises(SceneError, match="blocks must be"):
        load_scene("random", seed=0, blocks=0)
    with pytest.raises(SceneError, match="blocks must be"):
        load_scene("random", seed=0, blocks=100)
