"""Accuracy of an extracted model against the true block (used by the benchmark and the tests)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vision.model import ObjectModel


@dataclass(frozen=True)
class ModelError:
    """Errors of one extracted model; vertex and yaw errors only when the edge counts agree."""

    edges_right: bool
    centroid_mm: float  #: world xy distance of the centroids
    vertex_mm: NDArray[
        np.float64
    ]  #: (k,) distance of each vertex to its match (empty if counts differ)
    yaw_deg: float  #: rotation (deg) that best aligns the matched vertices (nan if counts differ)


def true_world_vertices(polygon_vertices: ArrayLike, position: ArrayLike, yaw: float) -> NDArray:
    """World xy of a block's footprint: object-frame vertices rotated by ``yaw``, moved to
    ``position``."""
    v = np.asarray(polygon_vertices, dtype=float)
    c, s = np.cos(yaw), np.sin(yaw)
    return v @ np.array([[c, s], [-s, c]]) + np.asarray(position, dtype=float)


def match_vertices(
    est: NDArray[np.float64], true: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float]:
    """Match two CCW polygons with the same number of vertices (best cyclic shift) and return the
    vertex distances and the rotation (rad) that best aligns ``est`` to ``true`` about their
    centroids."""
    k = len(true)
    best = None
    for shift in range(k):
        e = np.roll(est, shift, axis=0)
        d = np.linalg.norm(e - true, axis=1)
        if best is None or d.sum() < best[0].sum():
            best = (d, e)
    assert best is not None
    d, e = best
    a = e - e.mean(axis=0)
    b = true - true.mean(axis=0)
    cross = float((a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum())
    dot = float((a * b).sum())
    return d, float(np.arctan2(cross, dot))


def model_error(
    model: ObjectModel, polygon_vertices: ArrayLike, position: ArrayLike, yaw: float
) -> ModelError:
    """Compare ``model`` with the block whose object-frame footprint is ``polygon_vertices``
    (centroid at the origin), placed at ``position`` with ``yaw``."""
    true = true_world_vertices(polygon_vertices, position, yaw)
    centroid = 1000.0 * float(np.linalg.norm(model.centroid[:2] - np.asarray(position, float)))
    if model.n_edges != len(true):
        return ModelError(False, centroid, np.zeros(0), float("nan"))
    d, rot = match_vertices(model.world_vertices, true)
    return ModelError(True, centroid, 1000.0 * d, float(np.degrees(abs(rot))))
