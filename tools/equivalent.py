"""Mutants of ``tools.mutate`` that no test can kill, each with the reason
(docs/contributor_guide.md, "How to test").

An entry names the mutant by its module, the source line it changes (stripped), the column and
the change, so it still matches after unrelated edits move the line; when the line itself
changes, the mutant is run again and shows up as a plain survivor until the entry is updated.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Equivalent:
    """One surviving mutant and why no test can tell it from the original."""

    path: str
    line: str  #: the mutated source line, stripped
    col: int
    original: str
    replacement: str
    reason: str


SAME = "same result for every input (the change cancels out)"
FLOAT_TIE = "differs only when two floats are exactly equal, which the inputs never make"
GUARD = "a guard against dividing by ~0: 10x changes no result a test could justify"
LEFT_TURNS = (
    "the outline has only left turns here (checked just before): the total turn is 2*pi*k and "
    "the mutant still exceeds 2*pi exactly when k >= 2"
)
POLYGON_EQ = "Polygon == already compares vertex arrays, which raises unless identical"
STATUS = "str(clarabel status) has no '.', so rsplit returns the whole name either way"
WINDOW = "samples beyond the 1.75 px search window are never used"
FLAT_FACE = (
    "the face is one flat colour (docstring): any erosion of at least 2 px, or any partner "
    "pixel inside it, gives the same median"
)
TINY = (
    "faces under 4 interior pixels: the fallback's threshold (4 or 5) is not a requirement; "
    "MIN_CONTRAST decides there"
)
ORIENTATION = (
    "OpenCV traces external contours in one direction, so the unflipped normal always points "
    "into the face and the vote always flips it; the probe leaves the image only for faces "
    "thinner than 2 px"
)
SPAN = (
    "the tangent's chord (3 or 4 outline steps; fewer on tiny outlines) changes only corner "
    "normals, and the edge points within 3 px of a corner are not used for lines"
)

ENTRIES: tuple[Equivalent, ...] = (
    Equivalent("controllers/grasp/wrench.py", "AT_MINIMUM = 1e-12", 13, "1e-12", "1e-11", GUARD),
    Equivalent(
        "controllers/grasp/wrench.py",
        "eps_star = ((rho[:, :2] ** 2).sum(-1))[:, None] * np.ones_like(theta)",
        15,
        "((rho[:, :2] ** 2).sum(-1))[:, None] * np.ones_like(theta)",
        "((rho[:, :2] ** 2).sum(-1)[:, None] / np.ones_like(theta))",
        SAME,
    ),
    Equivalent(
        "controllers/grasp/wrench.py",
        "safe = np.abs(run) > AT_MINIMUM",
        11,
        "np.abs(run) > AT_MINIMUM",
        "(np.abs(run) >= AT_MINIMUM)",
        FLOAT_TIE,
    ),
    Equivalent(
        "controllers/grasp/wrench.py",
        "return np.where(safe, 2.0 * np.maximum(rise, 0.0) / np.where(safe, run, 1.0), 0.0)",
        76,
        "1.0",
        "2.0",
        "the placeholder denominator where the result is replaced by 0 anyway: " + SAME,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "dist = np.where(facing > 1e-12, offset[..., None, :] / facing, np.inf)",
        24,
        "facing > 1e-12",
        "(facing >= 1e-12)",
        FLOAT_TIE,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "dist = np.where(facing > 1e-12, offset[..., None, :] / facing, np.inf)",
        33,
        "1e-12",
        "1e-11",
        "a ray within 1e-11 of parallel to an edge meets it 1e11 offsets away, never first",
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "normal_angle: NDArray[np.float64] = field(init=False, repr=False, compare=False)",
        78,
        "False",
        "True",
        POLYGON_EQ,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "offset: NDArray[np.float64] = field(init=False, repr=False, compare=False)",
        72,
        "False",
        "True",
        POLYGON_EQ,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "short = np.linalg.norm(edges, axis=1) <= RELATIVE_TOLERANCE * size",
        16,
        "np.linalg.norm(edges, axis=1) <= RELATIVE_TOLERANCE * size",
        "(np.linalg.norm(edges, axis=1) < RELATIVE_TOLERANCE * size)",
        FLOAT_TIE,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "if abs(area) <= MIN_RELATIVE_AREA * size**2:",
        11,
        "abs(area) <= MIN_RELATIVE_AREA * size**2",
        "(abs(area) < MIN_RELATIVE_AREA * size ** 2)",
        FLOAT_TIE,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "if area < 0.0:",
        11,
        "area < 0.0",
        "(area <= 0.0)",
        "a zero area was refused two lines before: " + SAME,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "given = len(v) - 1 - i if area < 0.0 else i  # the index in the caller's order",
        38,
        "area < 0.0",
        "(area <= 0.0)",
        "a zero area was refused before: " + SAME,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "if np.any(turn < -RELATIVE_TOLERANCE * size**2):",
        18,
        "turn < -RELATIVE_TOLERANCE * size**2",
        "(turn <= -RELATIVE_TOLERANCE * size ** 2)",
        FLOAT_TIE,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "i = int((np.flatnonzero(turn < -RELATIVE_TOLERANCE * size**2)[0] + 1) % len(v))",
        36,
        "turn < -RELATIVE_TOLERANCE * size**2",
        "(turn <= -RELATIVE_TOLERANCE * size ** 2)",
        FLOAT_TIE,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "total_turn = heading[-1] - heading[0] + _wrap(heading[0] - heading[-1])",
        21,
        "heading[-1] - heading[0] + _wrap(heading[0] - heading[-1])",
        "(heading[-1] - heading[0] - _wrap(heading[0] - heading[-1]))",
        LEFT_TURNS,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "total_turn = heading[-1] - heading[0] + _wrap(heading[0] - heading[-1])",
        43,
        "0",
        "1",
        LEFT_TURNS,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "total_turn = heading[-1] - heading[0] + _wrap(heading[0] - heading[-1])",
        75,
        "-1",
        "0",
        LEFT_TURNS,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "if total_turn > 2.0 * np.pi + 1e-6:",
        11,
        "total_turn > 2.0 * np.pi + 1e-6",
        "(total_turn >= 2.0 * np.pi + 1e-06)",
        "the total turn is a multiple of 2*pi to rounding (1e-15): " + FLOAT_TIE,
    ),
    Equivalent(
        "controllers/grasp/polygon.py",
        "if total_turn > 2.0 * np.pi + 1e-6:",
        38,
        "1e-6",
        "1e-05",
        "the total turn is a multiple of 2*pi to rounding (1e-15); any small slack works",
    ),
    Equivalent(
        "controllers/grasp/score.py",
        "b = np.concatenate([t, -MIN_NORMAL_FORCE * np.ones(n), np.zeros(3 * n)])",
        27,
        "-MIN_NORMAL_FORCE * np.ones(n)",
        "(-MIN_NORMAL_FORCE / np.ones(n))",
        SAME,
    ),
    Equivalent(
        "controllers/grasp/score.py",
        'status = str(sol.status).rsplit(".", 1)[-1]',
        41,
        "1",
        "2",
        STATUS,
    ),
    Equivalent(
        "controllers/grasp/score.py",
        'status = str(sol.status).rsplit(".", 1)[-1]',
        44,
        "-1",
        "0",
        STATUS,
    ),
    Equivalent(
        "controllers/grasp/score.py",
        "ok = residual < 1e-6 and np.all(x[:n] >= MIN_NORMAL_FORCE - 1e-6)",
        13,
        "residual < 1e-6",
        "(residual <= 1e-06)",
        FLOAT_TIE,
    ),
    Equivalent(
        "controllers/grasp/score.py",
        "ok = residual < 1e-6 and np.all(x[:n] >= MIN_NORMAL_FORCE - 1e-6)",
        40,
        "x[:n] >= MIN_NORMAL_FORCE - 1e-6",
        "(x[:n] > MIN_NORMAL_FORCE - 1e-06)",
        FLOAT_TIE,
    ),
    Equivalent("vision/edges.py", "PROFILE_OUTSIDE = 4.0", 18, "4.0", "8.0", WINDOW),
    Equivalent("vision/edges.py", "TANGENT_HALF_SPAN = 3", 20, "3", "4", SPAN),
    Equivalent(
        "vision/edges.py",
        "return np.arange(-PROFILE_INSIDE, PROFILE_OUTSIDE + 1e-9, PROFILE_STEP)",
        38,
        "PROFILE_OUTSIDE + 1e-9",
        "(PROFILE_OUTSIDE - 1e-09)",
        "drops the last sample (4 px out): " + WINDOW,
    ),
    Equivalent(
        "vision/edges.py",
        "return np.arange(-PROFILE_INSIDE, PROFILE_OUTSIDE + 1e-9, PROFILE_STEP)",
        56,
        "1e-9",
        "1e-08",
        SAME,
    ),
    Equivalent(
        "vision/edges.py",
        "allowed = mid[None, :] <= (e_est + OUTSIDE_OFFSET)[:, None]",
        14,
        "mid[None, :] <= (e_est + OUTSIDE_OFFSET)[:, None]",
        "(mid[None, :] < (e_est + OUTSIDE_OFFSET)[:, None])",
        "sample midpoints are odd multiples of 1/8 px, the bound 0.5 + 1.75 is not: " + SAME,
    ),
    Equivalent(
        "vision/edges.py",
        "rising = allowed & (slope > RISE_FRACTION * slope[rows, peak][:, None])",
        24,
        "slope > RISE_FRACTION * slope[rows, peak][:, None]",
        "(slope >= RISE_FRACTION * slope[rows, peak][:, None])",
        FLOAT_TIE,
    ),
    Equivalent(
        "vision/edges.py",
        "e = (rise * mid[None, :]).sum(axis=1) / np.maximum(total, 1e-9)",
        62,
        "1e-9",
        "1e-08",
        GUARD,
    ),
    Equivalent(
        "vision/edges.py",
        "inside = dist[:, 0] < 0.3 * np.maximum(total, 1e-9)",
        13,
        "dist[:, 0] < 0.3 * np.maximum(total, 1e-9)",
        "(dist[:, 0] <= 0.3 * np.maximum(total, 1e-09))",
        FLOAT_TIE,
    ),
    Equivalent(
        "vision/edges.py",
        "inside = dist[:, 0] < 0.3 * np.maximum(total, 1e-9)",
        50,
        "1e-9",
        "1e-08",
        GUARD,
    ),
    Equivalent(
        "vision/edges.py",
        "ok = (total > min_contrast) & inside & (slope[rows, peak] > 0)",
        10,
        "total > min_contrast",
        "(total >= min_contrast)",
        FLOAT_TIE,
    ),
    Equivalent(
        "vision/edges.py",
        "ok = (total > min_contrast) & inside & (slope[rows, peak] > 0)",
        44,
        "slope[rows, peak] > 0",
        "(slope[rows, peak] >= 0)",
        "a zero steepest slope means a zero rise, refused by the contrast test: " + SAME,
    ),
    *(
        Equivalent(
            "vision/edges.py",
            "inner = cv2.erode(mask, np.ones((5, 5), np.uint8)) > 0",
            col,
            "5",
            "6",
            FLAT_FACE,
        )
        for col in (37, 40)
    ),
    Equivalent(
        "vision/edges.py", "if inner.sum() < 4:", 7, "inner.sum() < 4", "(inner.sum() <= 4)", TINY
    ),
    Equivalent("vision/edges.py", "if inner.sum() < 4:", 21, "4", "5", TINY),
    Equivalent("vision/edges.py", "if ys.size < 4:", 7, "ys.size < 4", "(ys.size <= 4)", TINY),
    Equivalent("vision/edges.py", "if ys.size < 4:", 17, "4", "5", TINY),
    Equivalent(
        "vision/edges.py",
        "diff = img[ys, xs] - img[ys, xs + 1]",
        33,
        "xs + 1",
        "(xs - 1)",
        FLAT_FACE,
    ),
    Equivalent("vision/edges.py", "diff = img[ys, xs] - img[ys, xs + 1]", 38, "1", "2", FLAT_FACE),
    Equivalent("vision/edges.py", "k = min(TANGENT_HALF_SPAN, max(1, n // 4))", 35, "1", "2", SPAN),
    Equivalent(
        "vision/edges.py",
        "k = min(TANGENT_HALF_SPAN, max(1, n // 4))",
        38,
        "n // 4",
        "(n / 4)",
        "np.roll takes the float 2.0 as 2; " + SPAN,
    ),
    Equivalent("vision/edges.py", "k = min(TANGENT_HALF_SPAN, max(1, n // 4))", 43, "4", "5", SPAN),
    Equivalent(
        "vision/edges.py",
        "tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)",
        74,
        "1e-9",
        "1e-08",
        GUARD,
    ),
    *(
        Equivalent(
            "vision/edges.py",
            "okp = (probe[:, 0] >= 0) & (probe[:, 0] < w) & (probe[:, 1] >= 0) & (probe[:, 1] < h)",
            col,
            original,
            replacement,
            ORIENTATION,
        )
        for col, original, replacement in (
            (11, "probe[:, 0] >= 0", "(probe[:, 0] > 0)"),
            (20, "0", "1"),
            (26, "0", "1"),
            (32, "probe[:, 0] < w", "(probe[:, 0] <= w)"),
            (41, "0", "1"),
            (52, "probe[:, 1] >= 0", "(probe[:, 1] > 0)"),
            (67, "0", "1"),
            (73, "probe[:, 1] < h", "(probe[:, 1] <= h)"),
        )
    ),
    Equivalent(
        "vision/edges.py",
        "inside[okp] = mask[probe[okp, 1], probe[okp, 0]] > 0",
        18,
        "mask[probe[okp, 1], probe[okp, 0]] > 0",
        "(mask[probe[okp, 1], probe[okp, 0]] >= 0)",
        ORIENTATION,
    ),
    Equivalent(
        "vision/edges.py",
        "if inside.mean() > 0.5:",
        7,
        "inside.mean() > 0.5",
        "(inside.mean() >= 0.5)",
        ORIENTATION,
    ),
    Equivalent(
        "vision/edges.py", "if inside.mean() > 0.5:", 7, "inside.mean", "inside.sum", ORIENTATION
    ),
    Equivalent(
        "hand_sim/geometry.py",
        "best = min(best, _point_segment_distance(point, q[i], q[(i + 1) % len(q)]))",
        73,
        "i + 1",
        "(i - 1)",
        "the same set of edges, each taken from its other end: " + SAME,
    ),
    Equivalent(
        "hand_sim/geometry.py",
        "return bool(np.all(np.abs(p - np.asarray(centre, dtype=float)) <= half + 1e-12))",
        23,
        "np.abs(p - np.asarray(centre, dtype=float)) <= half + 1e-12",
        "(np.abs(p - np.asarray(centre, dtype=float)) < half + 1e-12)",
        FLOAT_TIE,
    ),
    Equivalent(
        "hand_sim/geometry.py",
        "return bool(np.all(np.abs(p - np.asarray(centre, dtype=float)) <= half + 1e-12))",
        77,
        "1e-12",
        "1e-11",
        "the slack for a point exactly on the border; 1e-11 m is as good as 1e-12 m",
    ),
)


def reason_for(path: str, line: str, col: int, original: str, replacement: str) -> str:
    """The reason a mutant is equivalent, or "" when it is not listed."""
    for e in ENTRIES:
        if (e.path, e.line, e.col, e.original, e.replacement) == (
            path,
            line.strip(),
            col,
            original,
            replacement,
        ):
            return e.reason
    return ""
