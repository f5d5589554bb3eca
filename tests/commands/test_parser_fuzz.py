"""Fuzz tests of the user-facing parsers (issue 10): polygons (``Polygon.from_vertices``, the CLI's
``parse_points``) and scene files (``parse_scene``, ``load_scene``). A seeded generator of malformed
inputs, some thousands per parser: every input is either accepted, giving a usable object, or
refused with the project's own error (``PolygonError``, ``SceneError``); anything else fails."""

from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np

from controllers.grasp import Polygon, PolygonError
from controllers.grasp.polygon import parse_points
from hand_sim.scene import Scene, SceneError, load_scene, parse_scene

SEED = 20240610
#: Awkward numbers: special floats, extremes, tiny and huge values, values Python cannot make a
#: float of, and things that are not numbers at all.
SPECIAL = [
    0.0, -0.0, 1.0, -1.0, 1e-300, 5e-324, 1e-9, 1e6, 1e7, 1e300, 1.7e308, -1e300, math.nan,
    math.inf, -math.inf, 10**400, -(10**19), True, None, "1", "x", [], [1, 2], {"x": 1},
]  # fmt: skip


def _number(rng: np.random.Generator) -> object:
    if rng.random() < 0.25:
        return SPECIAL[int(rng.integers(len(SPECIAL)))]
    return float(rng.choice([-1, 1]) * 10.0 ** rng.uniform(-12, 12))


def _vertices(rng: np.random.Generator) -> object:
    """A malformed-or-not vertex list: random, degenerate, permuted or broken convex polygons."""
    kind = int(rng.integers(8))
    k = int(rng.integers(0, 10))
    if kind == 0:  # random points, any magnitude
        return [[_number(rng), _number(rng)] for _ in range(k)]
    # a convex polygon (points on a circle) at a random scale and offset, then spoiled
    angles = np.sort(rng.uniform(0, 2 * np.pi, max(k, 3)))
    scale = 10.0 ** rng.uniform(-10, 7)
    v = scale * np.stack([np.cos(angles), np.sin(angles)], axis=1) + rng.uniform(-1e6, 1e6, 2)
    if kind == 1:  # permuted: usually self-intersecting
        v = v[rng.permutation(len(v))]
    elif kind == 2:  # a repeated vertex, adjacent or not
        i, j = rng.integers(len(v), size=2)
        v = np.insert(v, i, v[j], axis=0)
    elif kind == 3:  # squashed onto a line, or nearly
        v[:, 1] = v[:, 1] * rng.choice([0.0, 1e-12, 1e-7])
    elif kind == 4:  # one special value
        v = v.tolist()
        v[int(rng.integers(len(v)))][int(rng.integers(2))] = _number(rng)
        return v
    elif kind == 5:  # wrong shapes
        shapes = [v.ravel().tolist(), [[x] for x in v[:, 0]], v[:, None, :].tolist(), "abc"]
        return shapes[int(rng.integers(len(shapes)))]
    elif kind == 6:  # a vertex pushed inwards: non-convex
        i = int(rng.integers(len(v)))
        v[i] = v.mean(axis=0) + rng.uniform(0, 1) * (v[i] - v.mean(axis=0))
    return v.tolist()  # kind 7: the convex polygon itself


def test_polygon_from_vertices_accepts_or_raises_polygon_error() -> None:
    rng = np.random.default_rng(SEED)
    accepted = refused = 0
    for _ in range(4000):
        vertices = _vertices(rng)
        try:
            p = Polygon.from_vertices(vertices)
        except PolygonError:
            refused += 1
            continue
        accepted += 1
        # accepted: finite, CCW and convex (every turn left), area centroid at the origin, and
        # usable by the controllers
        v = p.vertices
        assert np.all(np.isfinite(v)) and p.area > 0
        e = np.roll(v, -1, axis=0) - v
        turns = e[:, 0] * np.roll(e, -1, axis=0)[:, 1] - e[:, 1] * np.roll(e, -1, axis=0)[:, 0]
        assert np.all(turns >= -1e-9 * p.diameter**2)
        x, y = v[:, 0], v[:, 1]
        cross = x * np.roll(y, -1) - np.roll(x, -1) * y
        cx = ((x + np.roll(x, -1)) * cross).sum() / (3.0 * cross.sum())
        cy = ((y + np.roll(y, -1)) * cross).sum() / (3.0 * cross.sum())
        assert np.hypot(cx, cy) <= 1e-6 * p.diameter
        u = p.unit_moment()
        assert np.all(np.isfinite(u.locate(np.linspace(-np.pi, np.pi, 16)).point))
    assert accepted > 300 and refused > 1500  # both outcomes are exercised


ALPHABET = list("0123456789") + list(".,;,;--+eE") + ["nan", "inf", " ", "\t", "1e400", "x"]


def _points_text(rng: np.random.Generator) -> str:
    """Random characters, or 'x,y;x,y;...' of awkward numbers with a character spoiled."""
    if rng.random() < 0.5:
        return "".join(rng.choice(ALPHABET, size=int(rng.integers(0, 30))))
    k = int(rng.integers(0, 6))
    text = ";".join(f"{_number(rng)!s},{_number(rng)!s}" for _ in range(k))
    if text and rng.random() < 0.5:
        i = int(rng.integers(len(text)))
        text = text[:i] + str(rng.choice(ALPHABET)) + text[i + 1 :]
    return text


def test_parse_points_accepts_or_raises_polygon_error() -> None:
    rng = np.random.default_rng(SEED + 1)
    accepted = 0
    for _ in range(3000):
        text = _points_text(rng)
        try:
            pts = parse_points(text)
        except PolygonError:
            continue
        accepted += 1
        assert pts.ndim == 2 and pts.shape[1] == 2 and np.all(np.isfinite(pts))
    assert accepted > 50


GOOD = """
name = "fuzz"
description = "a valid scene the fuzzer spoils"
target = "a"
place = [0.0, -0.2]
[table]
size = [0.9, 0.9]
height = 0.75
position = [0.0, 0.0]
[[blocks]]
name = "a"
shape = "square"
position = [0.0, 0.0]
yaw_deg = 30.0
height = 0.2
colour = "red"
[[blocks]]
name = "b"
vertices = [[0.0, 0.0], [0.04, 0.0], [0.0, 0.03]]
position = [0.12, 0.0]
rgba = [0.1, 0.2, 0.3, 1.0]
"""


def _value(rng: np.random.Generator, depth: int = 0) -> object:
    kind = int(rng.integers(7 if depth < 2 else 4))
    if kind == 0:
        return _number(rng) if rng.random() < 0.5 else float(rng.uniform(-0.5, 0.5))
    if kind == 1:
        return str(rng.choice(["", "a", "b", "square", "red", "random", "1.0", "é\n", "x" * 300]))
    if kind == 2:
        return bool(rng.integers(2))
    if kind == 3:
        return int(rng.integers(-(2**62), 2**62))
    if kind == 4:
        return [_value(rng, depth + 1) for _ in range(int(rng.integers(0, 5)))]
    if kind == 5:
        return [[_value(rng, depth + 1), _value(rng, depth + 1)] for _ in range(rng.integers(5))]
    return {str(rng.choice(["name", "size", "zzz"])): _value(rng, depth + 1)}


def _paths(doc: object, prefix: tuple = ()) -> list[tuple]:
    """Every key path into a parsed TOML document (dict keys and list indices)."""
    out = [prefix]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _paths(v, (*prefix, i))
    return out


def _mutate(doc: dict, rng: np.random.Generator) -> dict:
    doc = copy.deepcopy(doc)
    for _ in range(int(rng.integers(1, 4))):
        paths = [p for p in _paths(doc) if p]
        path = paths[int(rng.integers(len(paths)))]
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        last = path[-1]
        action = int(rng.integers(4))
        if action == 0 and isinstance(parent, dict):
            del parent[last]
        elif action == 1 and isinstance(parent, dict):
            parent[str(rng.choice(["extra", "yaw", "colour", "vertices", "shape"]))] = _value(rng)
        elif (
            action == 2
            and isinstance(parent[last], float | int)
            and not isinstance(parent[last], bool)
        ):
            parent[last] = parent[last] * float(rng.choice([-1, 0, 10, 1e300, math.nan]))
        else:
            parent[last] = _value(rng)
    return doc


def test_parse_scene_accepts_or_raises_scene_error() -> None:
    rng = np.random.default_rng(SEED + 2)
    base = tomllib.loads(GOOD)
    assert isinstance(parse_scene(base, "fuzz", "fuzz"), Scene)
    accepted = 0
    for _ in range(2500):
        doc = _mutate(base, rng)
        try:
            scene = parse_scene(doc, "fuzz", "fuzz")
        except SceneError as e:
            assert str(e).startswith("fuzz: ") and "\n" not in str(e), str(e)
            continue
        accepted += 1
        assert scene.target in scene.block_names
    assert accepted > 50


def test_scene_files_with_spoiled_bytes_load_or_raise_scene_error(tmp_path: Path) -> None:
    rng = np.random.default_rng(SEED + 3)
    good = GOOD.encode()
    path = tmp_path / "s.toml"
    outcomes = {"loaded": 0, "refused": 0}
    for _ in range(1000):
        data = bytearray(good)
        for _ in range(int(rng.integers(1, 4))):
            i = int(rng.integers(len(data)))
            op = int(rng.integers(3))
            if op == 0:
                data[i] = int(rng.integers(256))  # may break UTF-8 or the TOML syntax
            elif op == 1:
                del data[i]
            else:
                data.insert(i, int(rng.choice(list(b'[]{}=",.-0123456789\n\xff\xc3'))))
        path.write_bytes(bytes(data))
        try:
            load_scene(path)
            outcomes["loaded"] += 1
        except SceneError as e:
            assert str(e).startswith(str(path)), str(e)
            outcomes["refused"] += 1
    assert outcomes["loaded"] > 20 and outcomes["refused"] > 500
