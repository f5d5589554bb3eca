"""Vision on degenerate regions (issue 22): an empty region, one a pixel wide, one cut by the image
border, two faces merged into one, an outline whose missed edge scatters about its line. Each is
modelled or refused with :class:`ExtractionError` saying why; nothing else is raised (the
task cycle once died of an ``IndexError`` in ``fit_tls`` on an empty point set)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.vision.test_vision_edges import render
from vision import edges
from vision.contour import PixelPolygon, fit_polygon
from vision.edge_count import add_missed_lines
from vision.errors import ExtractionError
from vision.hough import Line, fit_tls


def _square_outline() -> tuple[np.ndarray, list[Line], list[np.ndarray], np.ndarray]:
    """An ordered outline: the four edges of the square 0..40 px (one point a pixel), then a run
    of 21 points beyond its right edge zigzagging 0.3-0.5 px about the line u = 45 (an edge the
    transform missed, whose points all lie farther from their own line than the fit distance).
    Returns the points, the square's four lines (normals out), their runs and the zigzag's."""
    t = np.arange(0.0, 40.0)
    bottom = np.column_stack([t, np.zeros_like(t)])
    right = np.column_stack([np.full_like(t, 40.0), t])
    top = np.column_stack([40.0 - t, np.full_like(t, 40.0)])
    left = np.column_stack([np.zeros_like(t), 40.0 - t])
    v = np.arange(10.0, 31.0)
    scatter = np.resize([0.3, -0.3, 0.5, -0.5], len(v))
    zigzag = np.column_stack([45.0 + scatter, v])
    pts = np.vstack([bottom, right, top, left, zigzag])
    lines = [
        Line(np.array([0.0, -1.0]), 0.0, 40),
        Line(np.array([1.0, 0.0]), 40.0, 40),
        Line(np.array([0.0, 1.0]), 40.0, 40),
        Line(np.array([-1.0, 0.0]), 0.0, 40),
    ]
    members = [np.arange(k * 40, (k + 1) * 40) for k in range(4)]
    return pts, lines, members, np.arange(160, 160 + len(v))


def test_no_line_is_fitted_to_no_point() -> None:
    """``fit_tls`` on an empty or a one-point set (no line is defined) says so."""
    centre = np.zeros(2)
    for pts in (np.zeros((0, 2)), np.array([[3.0, 4.0]]), np.array([[1.0, 1.0], [1.0, 1.0]])):
        with pytest.raises(ExtractionError, match="edge point"):
            fit_tls(pts, centre)
    # two points are enough: the line through them, normal away from the inside point
    n, c = fit_tls(np.array([[0.0, 5.0], [4.0, 5.0]]), np.array([2.0, 0.0]))
    assert np.allclose(n, [0.0, 1.0]) and c == pytest.approx(5.0)


def test_a_missed_edge_whose_points_scatter_about_its_line_keeps_its_run() -> None:
    """The region that reached ``fit_tls`` with no point: a missed edge (the zigzag run) whose
    points all lie 0.3-0.5 px from the line fitted to them, farther than the fit distance (0.2 px).
    Its refit run was empty; the line was added with no point, proposed again, merged with
    itself, and the merged line was fitted to nothing (``IndexError: vt[-1]``). Now the line keeps
    the run it was proposed from: one extra line, on u = 45, carried by the zigzag's points."""
    pts, lines, members, zigzag = _square_outline()
    usable = np.ones(len(pts), bool)
    centre = np.array([20.0, 20.0])
    box = np.array([[-10.0, -10.0], [60.0, -10.0], [60.0, 60.0], [-10.0, 60.0]])
    far = np.full(len(pts), 0.3)
    fit = np.full(len(pts), 0.2)
    out_lines, out_members = add_missed_lines(lines, members, pts, usable, centre, box, far, fit)
    assert len(out_lines) == 5
    assert all(len(m) >= 4 for m in out_members)
    extra, run = out_lines[-1], out_members[-1]
    assert sorted(run.tolist()) == zigzag.tolist()
    # the zigzag's own total-least-squares line: u = 45 (its points' mean), normal along u
    assert np.allclose(extra.normal, [1.0, 0.0], atol=0.05)
    assert extra.offset == pytest.approx(pts[zigzag, 0].mean(), abs=0.1)


def _face(h: int = 80, w: int = 90) -> tuple[np.ndarray, np.ndarray]:
    """A rendered square face (u, v 20..60) and its mask."""
    verts = np.array([[20.0, 20.0], [60.0, 20.0], [60.0, 60.0], [20.0, 60.0]])
    img, cover = render(verts, h, w)
    return img.astype(np.uint8), cover > 0.5


def _masks(mask: np.ndarray) -> dict[str, np.ndarray]:
    empty = np.zeros_like(mask)
    row = empty.copy()
    row[40, 20:61] = True
    column = empty.copy()
    column[20:61, 40] = True
    two_rows = empty.copy()
    two_rows[40:42, 20:61] = True
    pixel = empty.copy()
    pixel[40, 40] = True
    border = np.zeros_like(mask)
    border[:, : 41 - 20] = mask[:, 20:41]  # the face's left half moved onto the image border
    sparse = mask & (np.random.default_rng(3).random(mask.shape) < 0.3)
    return {
        "empty": empty,
        "one pixel": pixel,
        "one row": row,
        "one column": column,
        "two rows": two_rows,
        "touching the border": border,
        "sparse pixels": sparse,
    }


@pytest.mark.parametrize("kind", list(_masks(np.zeros((80, 90), bool))))
def test_a_degenerate_region_is_modelled_or_refused_with_a_reason(kind: str) -> None:
    img, mask = _face()
    region = _masks(mask)[kind]
    untrusted = np.zeros_like(mask)
    try:
        out = fit_polygon(region, img, untrusted)
    except ExtractionError as e:
        assert str(e) and "\n" not in str(e)
        return
    # modelled: a convex polygon inside the region's pixels' bounding box (grown by a pixel)
    assert isinstance(out, PixelPolygon) and len(out.vertices) >= 3
    v, u = np.nonzero(region)
    lo, hi = np.array([u.min(), v.min()]) - 1.5, np.array([u.max(), v.max()]) + 1.5
    assert (out.vertices >= lo).all() and (out.vertices <= hi).all()


def test_two_faces_merged_into_one_region_with_a_long_outline() -> None:
    """A region 860 x 380 px (two faces merged into one, e.g. with the hand between them): an
    outline of 2,480 points, whose 29 profile samples each are more than the 32767 rows
    ``cv2.remap`` takes (it once raised ``cv2.error``). The region is one convex face: it is
    modelled as its four edges."""
    h, w = 420, 900
    mask = np.zeros((h, w), bool)
    mask[20:400, 20:880] = True
    img = np.where(mask[..., None], np.array([200, 60, 40]), np.array([110, 120, 130]))
    out = fit_polygon(mask, img.astype(np.uint8), np.zeros_like(mask))
    assert len(out.vertices) == 4
    lo, hi = out.vertices.min(axis=0), out.vertices.max(axis=0)
    assert np.allclose(lo, [19.5, 19.5], atol=0.6) and np.allclose(hi, [879.5, 399.5], atol=0.6)


def test_sampling_many_points_matches_bilinear_interpolation() -> None:
    """``edges.sample`` at 40,000 points (more rows than ``cv2.remap`` takes at once) equals a
    bilinear interpolation written out in NumPy."""
    rng = np.random.default_rng(0)
    img = rng.uniform(0, 255, (30, 40, 3)).astype(np.float32)
    pts = rng.uniform([0.0, 0.0], [38.99, 28.99], (200, 200, 2))
    got = edges.sample(img, pts)
    u, v = pts[..., 0], pts[..., 1]
    u0, v0 = np.floor(u).astype(int), np.floor(v).astype(int)
    fu, fv = (u - u0)[..., None], (v - v0)[..., None]
    want = (
        img[v0, u0] * (1 - fu) * (1 - fv)
        + img[v0, u0 + 1] * fu * (1 - fv)
        + img[v0 + 1, u0] * (1 - fu) * fv
        + img[v0 + 1, u0 + 1] * fu * fv
    )
    assert got.shape == (200, 200, 3)
    assert np.abs(got - want).max() < 0.05
