"""The perceived prism's signed distance (controllers.hand.finger_geometry.PerceivedPrism), against
an independent computation: OpenCV's point-polygon test in the plane and the box's faces in
height."""

from __future__ import annotations

import cv2
import numpy as np

from controllers.hand.finger_geometry import PerceivedPrism


def _independent(prism: PerceivedPrism, points: np.ndarray) -> np.ndarray:
    """Signed distance from cv2.pointPolygonTest (positive inside, hence negated) combined with
    the distances to the top and bottom faces, point by point."""
    contour = prism.footprint.astype(np.float32).reshape(-1, 1, 2)
    out = []
    for x, y, z in points:
        d_xy = -cv2.pointPolygonTest(contour, (float(x), float(y)), True)
        d_z = max(prism.bottom - z, z - prism.top)
        if d_xy > 0 or d_z > 0:
            out.append(np.hypot(max(d_xy, 0.0), max(d_z, 0.0)))
        else:
            out.append(max(d_xy, d_z))
    return np.array(out)


def test_the_signed_distance_matches_an_independent_one_inside_and_out() -> None:
    rng = np.random.default_rng(7)
    signs = []
    for _ in range(20):
        k = int(rng.integers(3, 8))
        angles = np.sort(rng.uniform(0.0, 2 * np.pi, k))
        footprint = 0.03 * np.column_stack([np.cos(angles), np.sin(angles)]) + rng.uniform(
            -0.3, 0.3, 2
        )
        prism = PerceivedPrism(footprint, 0.0, float(rng.uniform(0.02, 0.08)))
        centre = np.array([*footprint.mean(axis=0), 0.5 * prism.top])
        points = centre + rng.normal(0.0, 0.02, (60, 3))
        got = prism.signed_distance(points.reshape(6, 10, 3)).ravel()  # any leading shape
        np.testing.assert_allclose(got, _independent(prism, points), atol=2e-6)
        signs += list(np.sign(got))
    assert signs.count(-1.0) > 100 and signs.count(1.0) > 100  # inside and out both tested


def test_the_near_distance_is_exact_near_the_prism_and_infinite_only_beyond_reach() -> None:
    rng = np.random.default_rng(8)
    footprint = np.array([[0.3, 0.0], [0.34, 0.01], [0.33, 0.05], [0.29, 0.04]])
    prism = PerceivedPrism(footprint, 0.0, 0.05)
    points = np.array([0.31, 0.025, 0.025]) + rng.normal(0.0, 0.05, (4000, 3))
    exact = prism.signed_distance(points)
    for within in (-0.002, 0.0, 0.004, 0.02):
        near = prism.signed_distance_near(points, within)
        measured = np.isfinite(near)
        np.testing.assert_array_equal(near[measured], exact[measured])
        assert np.all(exact[~measured] > within)  # left out only where it is further
        assert np.all(measured[exact <= within])
        assert (~measured).sum() > 1000  # and most far points are left out
