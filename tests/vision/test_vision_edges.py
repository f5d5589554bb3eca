"""Sub-pixel edges (vision/edges.py) on synthetic anti-aliased images with a known outline: the
edge points must lie on the true edges, not half a pixel off."""

from __future__ import annotations

import numpy as np
import pytest

from vision import edges

#: Sub-samples per pixel side of the synthetic renderer (coverage exact to 1/256).
SUPERSAMPLE = 16
FACE = (200.0, 60.0, 40.0)
TABLE = (110.0, 120.0, 130.0)
SIDE = (70.0, 25.0, 15.0)


def coverage(verts: np.ndarray, h: int, w: int) -> np.ndarray:
    """Fraction of each pixel (centres at integer u, v) inside a convex polygon (u, v vertices
    with positive shoelace area), by supersampling."""
    sub = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE - 0.5
    us = (np.arange(w)[:, None] + sub).reshape(-1)
    vs = (np.arange(h)[:, None] + sub).reshape(-1)
    u, v = np.meshgrid(us, vs)
    inside = np.ones(u.shape, bool)
    for a, b in zip(verts, np.roll(verts, -1, axis=0), strict=True):
        inside &= (b[0] - a[0]) * (v - a[1]) - (b[1] - a[1]) * (u - a[0]) >= 0.0
    return inside.reshape(h, SUPERSAMPLE, w, SUPERSAMPLE).mean(axis=(1, 3))


def render(verts: np.ndarray, h: int = 80, w: int = 90, side_px: float = 0.0):
    """Face colour inside, table outside; with ``side_px`` > 0 a darker band (a side face seen in
    perspective) of that width lies just outside the face. Returns image and coverage."""
    c = coverage(verts, h, w)[..., None]
    img = c * np.asarray(FACE) + (1.0 - c) * np.asarray(TABLE)
    if side_px > 0:
        centre = verts.mean(axis=0)
        radius = np.linalg.norm(verts - centre, axis=1, keepdims=True)
        grown = centre + (verts - centre) * (1.0 + side_px / radius)
        band = coverage(grown, h, w)[..., None] - c
        img = img - band * np.asarray(TABLE) + band * np.asarray(SIDE)
    return img.astype(np.float32), c[..., 0]


def signed_edge_distance(pts: np.ndarray, verts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (px) of points to the nearest edge, positive outside; and to the nearest vertex."""
    best = np.full(len(pts), np.inf)
    signed = np.zeros(len(pts))
    for a, b in zip(verts, np.roll(verts, -1, axis=0), strict=True):
        length = np.linalg.norm(b - a)
        t = (b - a) / length
        outward = np.array([t[1], -t[0]])
        along = np.clip((pts - a) @ t, 0.0, length)
        d = np.linalg.norm(pts - (a + along[:, None] * t), axis=1)
        closer = d < best
        best[closer] = d[closer]
        signed[closer] = ((pts - a) @ outward)[closer]
    vertex = np.linalg.norm(pts[:, None] - verts[None], axis=2).min(axis=1)
    return signed, vertex


def pentagon(rng: np.random.Generator) -> np.ndarray:
    a = np.linspace(0.0, 2.0 * np.pi, 5, endpoint=False) + rng.uniform(0, 1) + rng.normal(0, 0.1, 5)
    r = rng.uniform(24.0, 30.0, 5)
    return np.stack([45.0 + r * np.cos(a), 40.0 + r * np.sin(a)], axis=1)


@pytest.mark.parametrize("side_px", [0.0, 2.5], ids=["table", "side_face"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_edge_points_lie_on_the_true_edges(seed: int, side_px: float) -> None:
    """Noiseless: measured mean signed error within 0.02 px, worst 0.17 px over these cases."""
    verts = pentagon(np.random.default_rng(seed))
    img, cov = render(verts, side_px=side_px)
    mask = (cov > 0.5).astype(np.uint8)
    out = edges.outline(mask, img, np.zeros(mask.shape, bool), 0.0)
    assert out.refined.mean() > 0.95 and out.trusted.all()
    signed, vertex = signed_edge_distance(out.point, verts)
    on_edge = out.refined & (vertex > 3.0)  # corners are rounded by the profiles
    assert on_edge.sum() > 100
    assert abs(signed[on_edge].mean()) < 0.05
    assert np.abs(signed[on_edge]).max() < 0.3
    # the outline pixels themselves are inside the face, about half a pixel from the edge
    pix, _ = signed_edge_distance(out.pixel, verts)
    assert -0.8 < pix[on_edge].mean() < -0.2
    # normals point outward
    probe = out.pixel + 3.0 * out.normal
    u, v = np.rint(probe).astype(int).T
    assert mask[v, u].mean() < 0.05


def test_edge_points_with_image_noise() -> None:
    """Colour noise sigma 4 (the vision bench's): the noise is measured, the edges still found
    (measured mean signed error 0.04 px, 95th percentile 0.10 px)."""
    rng = np.random.default_rng(3)
    verts = pentagon(rng)
    img, cov = render(verts)
    noisy = np.clip(img + rng.normal(0.0, 4.0, img.shape), 0, 255).astype(np.float32)
    mask = (cov > 0.5).astype(np.uint8)
    sigma = edges.noise_sigma(noisy, mask)
    assert sigma == pytest.approx(4.0, rel=0.1)
    np.testing.assert_allclose(edges.face_colour(noisy, mask), FACE, atol=1.0)
    assert edges.min_contrast(sigma) == pytest.approx(6.0 * sigma)
    assert edges.min_contrast(0.5) == edges.MIN_CONTRAST
    out = edges.outline(mask, noisy, np.zeros(mask.shape, bool), sigma)
    signed, vertex = signed_edge_distance(out.point, verts)
    on_edge = out.refined & (vertex > 3.0)
    assert on_edge.sum() > 100
    assert abs(signed[on_edge].mean()) < 0.1
    assert np.percentile(np.abs(signed[on_edge]), 95) < 0.25


def test_without_colour_contrast_the_mask_edge_is_used() -> None:
    """A face the colour of the table: no edge from colour, the point is half a pixel out."""
    verts = pentagon(np.random.default_rng(4))
    _, cov = render(verts)
    img = np.broadcast_to(np.float32(TABLE), (*cov.shape, 3)).copy()
    img += 5.0 * cov[..., None].astype(np.float32)  # 5 grey levels: below MIN_CONTRAST
    mask = (cov > 0.5).astype(np.uint8)
    bad = np.zeros(mask.shape, bool)
    bad[:, :40] = True  # left part next to an occluder
    out = edges.outline(mask, img, bad, 0.0)
    assert not out.refined.any()
    np.testing.assert_allclose(out.point, out.pixel + 0.5 * out.normal)
    np.testing.assert_array_equal(out.trusted, out.pixel[:, 0] >= 40)


def test_crossings_locate_a_pixel_integrated_step_exactly() -> None:
    """One profile across a step at offset e (anti-aliased by pixel integration, sampled by linear
    interpolation): the centroid of the rise is e."""
    d = edges.profile_offsets()
    for e_true in (-0.4, 0.0, 0.3, 0.77, 1.2):
        # pixel-integrated step: colour at the pixel centres c, linearly interpolated between
        centres = np.arange(-5.0, 7.0)
        frac_out = np.clip(centres - e_true + 0.5, 0.0, 1.0)
        grey = np.interp(d, centres, frac_out)[None, :, None] * np.array([90.0, 40.0, -60.0])
        e, ok = edges.crossings(grey, d, np.zeros(3), np.array([0.5]), 12.0)
        assert ok[0]
        assert e[0] == pytest.approx(e_true, abs=1e-6)
    # a rise below the contrast floor is refused
    e, ok = edges.crossings(grey * 0.05, d, np.zeros(3), np.array([0.5]), 12.0)
    assert not ok[0]


def _profile(values: np.ndarray) -> np.ndarray:
    """A one-profile (1, D, 3) colour array whose distance from black is ``values`` (D,)."""
    return values[None, :, None] * np.array([0.6, 0.8, 0.0])


def test_crossings_take_the_first_rise_not_a_stronger_one_beyond_the_search_window():
    """A neighbour's edge 3 px outside (stronger than the face's) is beyond OUTSIDE_OFFSET (1.75 px
    past the estimate): the face's own edge at 0.5 is found."""
    d = edges.profile_offsets()
    dist = np.interp(d, [-5, 0.0, 1.0, 3.0, 4.0, 9], [0, 0, 60, 60, 260, 260])
    e, ok = edges.crossings(_profile(dist), d, np.zeros(3), np.array([0.5]), 12.0)
    assert ok[0] and e[0] == pytest.approx(0.5, abs=1e-9)


def test_crossings_locate_a_blurred_edge_at_the_middle_of_its_ramp():
    """A 3.5 px wide ramp of 13 grey levels (every slope below 1 level per sample) is one rise."""
    d = edges.profile_offsets()
    dist = np.interp(d, [-5, -1.5, 2.0, 9], [0, 0, 13, 13])
    e, ok = edges.crossings(_profile(dist), d, np.zeros(3), np.array([0.5]), 12.0)
    assert ok[0] and e[0] == pytest.approx(0.25, abs=1e-9)


def test_crossings_refuse_a_profile_that_does_not_start_on_the_face():
    """The inner end of the profile must look like the face (within 0.3 of the rise): a narrow
    face whose far side shows at the profile's first sample is refused."""
    d = edges.profile_offsets()
    step = np.interp(d, [-5, 0.0, 1.0, 9], [0, 0, 60, 60])
    for first, accepted in ((0.25 * 60, True), (0.45 * 60, False)):
        dist = step.copy()
        dist[0] = first
        _, ok = edges.crossings(_profile(dist), d, np.zeros(3), np.array([0.5]), 12.0)
        assert ok[0] == accepted, first


@pytest.mark.parametrize(("contrast", "found"), [(20.0, True), (9.0, False)])
def test_faces_need_a_colour_contrast_of_12_grey_levels(contrast, found):
    """Without noise, an edge of 20 grey levels is found by colour; one of 9 falls back to the mask
    (MIN_CONTRAST = 12)."""
    verts = pentagon(np.random.default_rng(5))
    _, cov = render(verts)
    img = 100.0 + contrast * cov[..., None] * np.array([1.0, 0.0, 0.0])  # colour distance
    mask = (cov > 0.5).astype(np.uint8)
    out = edges.outline(mask, img.astype(np.float32), np.zeros(mask.shape, bool), 0.0)
    assert out.refined.mean() > 0.95 if found else not out.refined.any()


def test_a_narrow_face_still_gets_colour_edges():
    """A strip 7 px wide: the profiles reach only PROFILE_INSIDE = 3 px into the face, so they do
    not run into its far side."""
    verts = np.array([[10.0, 20.0], [70.0, 20.0], [70.0, 27.0], [10.0, 27.0]])
    img, cov = render(verts, h=48, w=80)
    mask = (cov > 0.5).astype(np.uint8)
    out = edges.outline(mask, img, np.zeros(mask.shape, bool), 0.0)
    signed, vertex = signed_edge_distance(out.point, verts)
    long_sides = out.refined & (vertex > 3.0)
    assert long_sides.sum() > 80
    assert np.abs(signed[long_sides]).max() < 0.2


def test_face_colour_comes_from_the_interior_not_the_rim():
    """The mask may reach past the top face (side-face pixels): the colour is the median of the
    mask eroded by 2 px. A 10 x 10 mask whose 2 px rim is another colour has a face-coloured
    6 x 6 core (36 of 100 pixels)."""
    img = np.full((20, 20, 3), 50.0, np.float32)
    img[7:13, 7:13] = FACE
    mask = np.zeros((20, 20), np.uint8)
    mask[5:15, 5:15] = 1
    np.testing.assert_allclose(edges.face_colour(img, mask), FACE)
    # a mask too small to erode: the median of the mask itself, never of pixels outside it
    tiny = np.zeros((20, 20), np.uint8)
    tiny[9:11, 9:11] = 1
    np.testing.assert_allclose(edges.face_colour(img, tiny), FACE)
    # no interior to measure noise on: noise 0, so MIN_CONTRAST decides
    assert edges.noise_sigma(img, tiny) == 0.0


def test_a_face_cut_by_the_image_border():
    """Outline pixels on the border are kept; the caller marks them untrusted through ``bad``."""
    verts = np.array([[40.0, 10.0], [95.0, 10.0], [95.0, 60.0], [40.0, 60.0]])  # past the right
    img, cov = render(verts, h=50, w=80)  # and the bottom edge
    mask = (cov > 0.5).astype(np.uint8)
    bad = np.zeros(mask.shape, bool)
    bad[:, -1] = bad[-1, :] = True
    out = edges.outline(mask, img, bad, 0.0)
    on_border = (out.pixel[:, 0] == 79) | (out.pixel[:, 1] == 49)
    assert on_border.sum() > 20
    np.testing.assert_array_equal(out.trusted, ~on_border)
    signed, vertex = signed_edge_distance(out.point, verts)
    seen = out.refined & out.trusted & (vertex > 3.0)
    assert seen.sum() > 50 and np.abs(signed[seen]).max() < 0.2


def test_a_brighter_neighbour_two_pixels_away_does_not_pull_the_edge():
    """Blocks may stand a few pixels apart: the face's edge is searched only up to 1.75 px past
    the mask's edge, so a brighter neighbour 2 px beyond it moves the edge by 0.06 px (0.3 px if
    the search started half a pixel further out)."""
    face = np.array([[10.0, 10.0], [40.0, 10.0], [40.0, 40.0], [10.0, 40.0]])
    neighbour = np.array([[42.0, 5.0], [60.0, 5.0], [60.0, 45.0], [42.0, 45.0]])
    cf = coverage(face, 50, 64)[..., None]
    cn = coverage(neighbour, 50, 64)[..., None]
    img = cf * np.array(FACE) + cn * np.array([250.0, 250.0, 250.0]) + (1 - cf - cn) * TABLE
    mask = (cf[..., 0] > 0.5).astype(np.uint8)
    out = edges.outline(mask, img.astype(np.float32), np.zeros(mask.shape, bool), 0.0)
    signed, vertex = signed_edge_distance(out.point, face)
    right = (out.pixel[:, 0] >= 39) & (vertex > 3.0)
    assert right.sum() > 20 and out.refined[right].all()
    assert np.abs(signed[right]).max() < 0.15


def test_crossings_ignore_shading_that_keeps_rising_past_the_edge():
    """Only slopes above RISE_FRACTION of the steepest belong to the edge: a slow drift after the
    step (shading, 0.2 grey levels per sample) does not shift it."""
    d = edges.profile_offsets()
    dist = np.interp(d, [-5, 0.0, 1.0, 2.25, 9], [0, 0, 60, 61, 61])
    e, ok = edges.crossings(_profile(dist), d, np.zeros(3), np.array([0.5]), 12.0)
    assert ok[0] and e[0] == pytest.approx(0.5, abs=1e-9)


def test_noise_is_measured_on_the_face_only():
    """A flat face on a very noisy table: the face's own noise (sigma 2) is what counts."""
    rng = np.random.default_rng(8)
    verts = pentagon(rng)
    img, cov = render(verts)
    table_noise = rng.normal(0.0, 40.0, img.shape) * (cov[..., None] < 0.01)
    face_noise = rng.normal(0.0, 2.0, img.shape)
    noisy = (img + table_noise + face_noise).astype(np.float32)
    mask = (cov > 0.5).astype(np.uint8)
    assert edges.noise_sigma(noisy, mask) == pytest.approx(2.0, rel=0.15)


@pytest.mark.parametrize("margin", [0.0, 2.0])
def test_a_face_just_inside_the_image_border(margin):
    """Outline pixels whose orientation probe (2 px out) lands on the first or last row or
    column, or past it, are handled: margin 0 puts the face's last pixels 2 px from the right
    and bottom ends, margin 2 its first pixels 2 px from the left and top ends."""
    h, w = 40, 50
    verts = np.array([[margin, margin], [w - 1 - margin, margin], [w - 1 - margin, h - 1 - margin]])
    verts = np.vstack([verts, [margin, h - 1 - margin]]) - 0.5
    img, cov = render(verts, h=h, w=w)
    mask = (cov > 0.5).astype(np.uint8)
    out = edges.outline(mask, img, np.zeros(mask.shape, bool), 0.0)
    signed, vertex = signed_edge_distance(out.point, verts)
    on_edge = out.refined & (vertex > 3.0)
    assert on_edge.sum() > 60 and np.abs(signed[on_edge]).max() < 0.2
    # outward normals, also along the border
    assert np.all(np.einsum("ij,ij->i", out.normal, out.pixel - verts.mean(axis=0)) > 0)


def test_a_face_of_a_few_pixels_still_has_an_outline():
    """A 3 x 3 pixel face: an 8-point outline with unit normals (the tangent span shrinks)."""
    mask = np.zeros((12, 12), np.uint8)
    mask[4:7, 4:7] = 1
    img = np.where(mask[..., None] > 0, np.float32(FACE), np.float32(TABLE)).astype(np.float32)
    out = edges.outline(mask, img, np.zeros(mask.shape, bool), 0.0)
    assert len(out.pixel) == 8
    np.testing.assert_allclose(np.linalg.norm(out.normal, axis=1), 1.0)
    outward = np.einsum("ij,ij->i", out.normal, out.pixel - [5.0, 5.0])
    assert np.all(outward > 0)
