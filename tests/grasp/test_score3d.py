"""S_G in 3-D (Eq. 13 with 6-D wrenches): an independent polyhedral LP, the planar reduction,
hand-derived physical cases and bad input."""

import numpy as np
import pytest

from controllers.grasp import GraspError, PolygonError, grasp_score, paper_object
from controllers.grasp.objects import PAPER_OBJECTS, random_convex_polygon
from controllers.grasp.prism3d import (
    PHYSICAL_STAGES,
    physical_tasks,
    prism_contacts,
    worst_task_score,
)
from controllers.grasp.score3d import (
    ContactError,
    contact_forces,
    grasp_score_3d,
    tangent_basis,
    unit_wrenches,
)
from tests.grasp.independent_score3d import pyramid_z, random_basis

FACETS = 64
REL = 1e-7  # relative solver tolerance in comparisons of z


def random_grasp(rng: np.random.Generator, task_scale: float = 0.1):
    """A random prism (random convex polygon, height 0.3-3 diameters, unit-moment frame), 3-5
    contacts (each on the top face with probability 0.2, else on a side at a random height), a
    task (zero with probability 0.25), mu in [0.4, 1] and torsion (None with probability 0.7)."""
    poly = random_convex_polygon(rng)
    height = rng.uniform(0.3, 3.0) * poly.diameter
    n = int(rng.integers(3, 6))
    on_top = rng.random(n) < 0.2
    m = int((~on_top).sum())
    top = rng.dirichlet(np.ones(poly.n_edges), size=n - m) @ poly.vertices
    theta, z = rng.uniform(0, 2 * np.pi, m), rng.uniform(0, height, m)
    pts, nrm = prism_contacts(poly, theta, z, height, top=top, unit_moment=True)
    task = np.zeros(6) if rng.random() < 0.25 else rng.normal(scale=task_scale, size=6)
    torsion = None if rng.random() < 0.7 else float(rng.uniform(0.05, 0.5))
    return pts, nrm, task, float(rng.uniform(0.4, 1.0)), torsion


def z_of(score) -> float:
    """Eq. 13 inverted: z = n (S_G + 1)."""
    return len(score.normal_forces) * (score.s_g + 1.0)


# --- 1. agreement with an independent polyhedral LP ------------------------------------------
def test_cone_program_agrees_with_an_inscribed_pyramid_lp_on_random_grasps():
    """The independent LP (tests/grasp/independent_score3d.py, scipy HiGHS, its own random tangent
    basis) replaces each cone ||T|| <= mu N by the inscribed K-gon g(T) <= mu N and ||T|| in the
    objective by the gauge g(T) of that K-gon, where ||T|| <= g(T) <= ||T|| / c, c = cos(pi/K).
    Write z_K(mu) for its optimum and z for the cone's.

    Upper bound: the LP's feasible set lies inside the cone program's and its objective is >= the
    cone's at every point, so z <= z_K(mu) (S_G of the pyramid >= S_G of the cone), and the LP
    feasible implies the cone program feasible.

    Lower bound: the circumscribed K-gon (circumradius mu N / c, i.e. g(T) <= (mu / c) N) holds
    the cone, with objective sum N + c g(T) <= sum N + ||T||; so z >= min over g <= (mu/c) N of
    sum N + c g(T) >= c z_K(mu / c) (as c <= 1). Hence c z_K(mu/c) <= z <= z_K(mu), and the cone
    program feasible implies z_K(mu / c) feasible.

    The simple bound z_K(mu) <= z / c needs a factor in general: it follows only when the cone's
    optimum is inside every contact's inscribed K-gon (||T_i|| <= c mu N_i: then it is feasible
    for the LP, at gauge cost <= ||T_i|| / c). When a cone is saturated the pyramid must raise
    N_i by up to 1/c there and the other contacts must rebalance: a problem-dependent factor,
    unbounded near infeasibility (a cone-feasible grasp whose unique forces point mid-facet has
    no pyramid solution at all). So the test asserts the two-sided bracket on every grasp, the
    simple bound on the unsaturated ones, and the median gap within 1/c - 1."""
    rng = np.random.default_rng(20240611)
    c = np.cos(np.pi / FACETS)
    gaps, feasible, lost = [], 0, 0
    for _ in range(300):
        pts, nrm, task, mu, torsion = random_grasp(rng)
        s = grasp_score_3d(pts, nrm, task, mu, torsion)
        basis = random_basis(nrm, rng)
        z_in = pyramid_z(pts, nrm, task, mu, FACETS, basis, torsion)
        z_wide = pyramid_z(pts, nrm, task, mu / c, FACETS, basis, torsion)
        if z_in is not None:
            assert s.feasible, "the inscribed pyramid is feasible, the cone must be"
        if not s.feasible:
            continue
        feasible += 1
        z = z_of(s)
        assert z_wide is not None, "the cone is feasible, the circumscribed pyramid must be"
        assert c * z_wide <= z * (1 + REL)
        if z_in is None:
            lost += 1  # feasible only within the cone's margin over the pyramid
            continue
        assert z <= z_in * (1 + REL)
        gaps.append(z_in / z - 1.0)
        load = np.linalg.norm(s.tangential_forces, axis=1) / (mu * s.normal_forces)
        if load.max() <= c - 1e-7:
            assert z_in <= z / c * (1 + REL)
    gaps = np.array(gaps)
    # With this seed: 122 of 300 feasible (the rest infeasible for all three programs), none
    # lost; gap median 4.5e-4, 90th percentile 2.4e-3, max 0.55 (a nearly infeasible grasp).
    assert feasible >= 100
    assert lost <= 0.02 * feasible
    assert np.median(gaps) <= 1 / c - 1


def test_the_pyramid_gap_shrinks_as_the_facets_grow():
    rng = np.random.default_rng(7)
    cases = []
    while len(cases) < 25:
        g = random_grasp(rng)
        s = grasp_score_3d(*g)
        if s.feasible:
            cases.append((g, z_of(s), random_basis(g[1], rng)))
    upper, lower = [], []
    for k in (8, 32, 128):
        c = np.cos(np.pi / k)
        up, low = [], []
        for (pts, nrm, task, mu, torsion), z, basis in cases:
            z_in = pyramid_z(pts, nrm, task, mu, k, basis, torsion)
            z_wide = pyramid_z(pts, nrm, task, mu / c, k, basis, torsion)
            up.append(np.inf if z_in is None else z_in / z - 1.0)
            low.append(1.0 - c * z_wide / z)
        upper.append(max(up))
        lower.append(max(low))
    assert upper[0] > upper[1] > upper[2] and lower[0] > lower[1] > lower[2]
    assert upper[2] < 1e-2 and lower[2] < 1e-2  # 2.7e-3 and 7e-4 with this seed


# --- 2. reduction to the planar metric --------------------------------------------------------
@pytest.mark.parametrize("name", PAPER_OBJECTS)
def test_a_planar_grasp_scores_as_the_planar_metric(name):
    """Side contacts at one height with a planar task give score.grasp_score's S_G: the 3-D
    program has the planar one's variables plus T_i2 (vertical friction), whose zero is feasible
    and no dearer, and the vertical friction only enters f_z, m_x, m_y. At the centre of mass's
    height the planar task is (t_fx, t_fy, 0, 0, 0, t_mz); at height z0 above it the same planar
    forces have m_x = -z0 f_y, m_y = z0 f_x, so the task carries those moments."""
    rng = np.random.default_rng(PAPER_OBJECTS.index(name))
    poly = paper_object(name)
    unit = poly.unit_moment()
    height = 2.0 * poly.diameter
    for trial in range(8):
        n = int(rng.integers(2, 6))
        theta = rng.uniform(0, 2 * np.pi, n)
        planar = np.zeros(3) if trial == 0 else rng.normal(scale=0.2, size=3)
        frames = unit.locate(theta)
        expected = grasp_score(frames.point, frames.normal, planar)
        for z in (0.5 * height, rng.uniform(0, height)):
            pts, nrm = prism_contacts(poly, theta, np.full(n, z), height, unit_moment=True)
            z0 = pts[0, 2]
            task = [planar[0], planar[1], 0.0, -z0 * planar[1], z0 * planar[0], planar[2]]
            s = grasp_score_3d(pts, nrm, task)
            assert s.feasible == expected.feasible
            if s.feasible:
                assert s.s_g == pytest.approx(expected.s_g, abs=1e-6)


# --- 3. physical sense ------------------------------------------------------------------------
#: The square of Figure 6 (4 cm sides) extruded to 16 cm, a tall block like the physics study's.
SQUARE_HEIGHT = 0.16


def square_prism(theta, z):
    """Contacts at polar angles ``theta`` and heights ``z`` (metres above the base) on the
    square prism, in its unit-moment, centre-of-mass frame (the square's faces at +-1)."""
    poly = paper_object("square")
    return prism_contacts(poly, theta, z, SQUARE_HEIGHT, unit_moment=True)


def test_two_opposite_contacts_need_torsion_to_resist_a_moment_about_their_line():
    h = SQUARE_HEIGHT
    for z in (0.5 * h, 0.8 * h):  # the centre of mass's height and above it
        pts, nrm = square_prism([0.0, np.pi], [z, z])  # on the x axis, faces +x and -x
        twist = [0, 0, 0, 0.2, 0, 0]  # m_x: about the line joining the contacts
        assert not grasp_score_3d(pts, nrm, twist).feasible
        s = grasp_score_3d(pts, nrm, twist, torsion=0.3)
        assert s.feasible and s.s_g == pytest.approx(0.0, abs=1e-6)  # tau = +-0.2 <= 0.3 N
        np.testing.assert_allclose(s.torsion_moments, [0.2, -0.2], atol=1e-6)
        tilt = grasp_score_3d(pts, nrm, [0, 0, 0, 0, 0.2, 0])  # m_y: a vertical friction couple
        assert tilt.feasible and tilt.s_g == pytest.approx(0.2, abs=1e-6)


def test_hanging_between_two_contacts_scores_half_the_load():
    """Antipodal contacts hold a weight L (task f_z = L / 2 each, section 3.5's mean): vertical
    friction T = L / 2 at N = 1 while L / 2 <= mu, so S_G = L / 2; beyond, N = L / (2 mu) and
    S_G = (L / mu + L) / 2 - 1."""
    pts, nrm = square_prism([0.0, np.pi], [0.03, 0.03])
    for load, mu, expected in ((0.6, 1.0, 0.3), (1.6, 1.0, 0.8), (1.6, 0.5, 1.4)):
        s = grasp_score_3d(pts, nrm, physical_tasks(load, 2)["hang"], friction=mu)
        assert s.s_g == pytest.approx(expected, abs=1e-6)
        forces = contact_forces(s, nrm)
        np.testing.assert_allclose(forces.sum(axis=0), [0, 0, load], atol=1e-6)


def test_four_contacts_at_two_heights_resist_every_physical_task():
    h = SQUARE_HEIGHT
    theta = [0.0, np.pi, 0.5 * np.pi, 1.5 * np.pi]
    pts, nrm = square_prism(theta, [0.8 * h, 0.8 * h, 0.2 * h, 0.2 * h])
    tasks = physical_tasks(0.5, 4)
    assert list(tasks) == list(PHYSICAL_STAGES)
    np.testing.assert_allclose(tasks["+z"], 0.0)  # the push cancels the weight
    np.testing.assert_allclose(tasks["hang"], [0, 0, 0.125, 0, 0, 0])
    for task in tasks.values():
        assert grasp_score_3d(pts, nrm, task).feasible
    name, worst = worst_task_score(pts, nrm, 0.5)
    assert worst.feasible
    assert worst.s_g == max(grasp_score_3d(pts, nrm, t).s_g for t in tasks.values())
    assert name == "-z"  # twice the weight, carried by friction: 2 * 0.5 / 4 each
    assert worst.s_g == pytest.approx(0.25, abs=1e-6)
    # Pure forces at the centre of mass: the length unit does not change S_G.
    assert worst_task_score(3.7 * pts, nrm, 0.5)[1].s_g == pytest.approx(worst.s_g, abs=1e-6)


def test_a_sideways_push_on_a_tall_prism_costs_more_when_held_far_from_its_centre():
    """The physics study's drops: a sideways m*g at the centre of mass of a tall block held near
    its top is a moment the contacts must balance with vertical friction couples."""
    h = SQUARE_HEIGHT
    theta = [0.0, np.pi, 0.5 * np.pi, 1.5 * np.pi]
    scores = [
        grasp_score_3d(*square_prism(theta, [z] * 4), physical_tasks(1.0, 4)["+x"]).s_g
        for z in (0.5 * h, 0.7 * h, 0.9 * h)
    ]
    assert scores[0] < scores[1] < scores[2]


def test_the_tangent_basis_is_right_handed_and_horizontal_first():
    rng = np.random.default_rng(3)
    nrm = rng.normal(size=(20, 3))
    nrm[:5, 2] = 0.0
    nrm[5] = [0, 0, 1]
    nrm[6] = [0, 0, -1]
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    b = tangent_basis(nrm)
    frames = np.stack([b[:, 0], b[:, 1], nrm], axis=1)
    gram = frames @ frames.transpose(0, 2, 1)
    np.testing.assert_allclose(gram, np.tile(np.eye(3), (20, 1, 1)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(frames), 1.0, atol=1e-12)
    np.testing.assert_allclose(b[:, 0, 2][[0, 1, 2, 3, 4, 7, 8]], 0.0, atol=1e-12)
    np.testing.assert_allclose(b[:5, 1], np.tile([0, 0, 1.0], (5, 1)), atol=1e-12)
    # the planar code's CCW tangent for horizontal normals
    np.testing.assert_allclose(b[:5, 0, :2], np.stack([-nrm[:5, 1], nrm[:5, 0]], 1), atol=1e-12)
    w = unit_wrenches(np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    np.testing.assert_allclose(w[:, 0], [0, 1, 0, 0, 0, 1])


# --- 4. bad input -----------------------------------------------------------------------------
OK_P, OK_N = [[1.0, 0, 0], [-1.0, 0, 0]], [[1.0, 0, 0], [-1.0, 0, 0]]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"points": OK_P[:1]}, "as many normals as points"),
        ({"points": [[1.0, 0], [-1.0, 0]]}, "shape (n, 3)"),
        ({"normals": [[2.0, 0, 0], [-1.0, 0, 0]]}, "unit vectors: normal 0 has length 2"),
        ({"points": [[np.nan, 0, 0], [-1.0, 0, 0]]}, "finite"),
        ({"normals": [[1.0, 0, 0], [np.inf, 0, 0]]}, "finite"),
        ({"task": [0.0, 0.0, 1.0]}, "shape (6,)"),
        ({"task": [0.0] * 5 + [np.nan]}, "task wrench must be finite"),
        ({"friction": -0.5}, "friction must be a finite number >= 0"),
        ({"torsion": float("nan")}, "torsion must be a finite number >= 0"),
        ({"points": "abc"}, "must be numbers"),
    ],
)
def test_bad_contacts_raise_a_grasp_error_naming_the_problem(kwargs, message):
    args = {"points": OK_P, "normals": OK_N, **kwargs}
    with pytest.raises(ContactError, match=None) as info:
        grasp_score_3d(**args)
    assert isinstance(info.value, GraspError) and isinstance(info.value, ValueError)
    assert message in str(info.value)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"z": [0.5, 5.0]}, "contact 1 at z = 5 is off the sides"),
        ({"z": [0.5]}, "theta and z must have the same shape"),
        ({"height": -1.0}, "height must be positive"),
        ({"theta": [np.nan, 0.0]}, "theta must be finite"),
        ({"top": [[0.0, 0.0], [10.0, 0.0]]}, "top contact 1 at (10, 0) is outside the polygon"),
        ({"top": [0.0, 0.0]}, "top must be a 2-D array"),
        ({"polygon": [[0, 0], [1, 0], [0, 1]]}, "polygon must be a Polygon"),
    ],
)
def test_bad_prism_contacts_raise_a_polygon_error(kwargs, message):
    args = {"polygon": paper_object("square").unit_moment(), "theta": [0.0, 1.0]}
    args |= {"z": [0.5, 0.5], "height": 1.0, **kwargs}
    with pytest.raises(PolygonError) as info:
        prism_contacts(**args)
    assert message in str(info.value)


def test_bad_physical_tasks_raise():
    for kwargs, message in (
        ({"load": -1.0, "n_contacts": 3}, "load must be >= 0"),
        ({"load": np.nan, "n_contacts": 3}, "load must be a finite number"),
        ({"load": 1.0, "n_contacts": 0}, "n_contacts must be a positive integer"),
    ):
        with pytest.raises(ContactError, match=message):
            physical_tasks(**kwargs)
