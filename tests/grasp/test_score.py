"""The grasp evaluation metric S_G (Eq. 13): hand-derived cases and an independent LP solver."""

import clarabel
import numpy as np
import pytest

from controllers.grasp import SUCCESS_THRESHOLD, GraspScore, grasp_score, paper_object
from tests.grasp.independent_score import linprog_score

SQUARE_NORMALS = {"+x": (1.0, 0.0), "-x": (-1.0, 0.0), "+y": (0.0, 1.0), "-y": (0.0, -1.0)}


def test_antipodal_contacts_on_a_square_score_zero():
    s = grasp_score([(1, 0), (-1, 0)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["-x"]])
    assert s.feasible and s.success
    assert s.s_g == pytest.approx(0.0, abs=1e-6)


def test_adjacent_faces_of_a_square_score_one():
    # forces must run along the diagonal: N = T = 1 on both contacts, z = 4, S_G = 4/2 - 1
    s = grasp_score([(1, 0), (0, 1)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["+y"]])
    assert s.feasible and not s.success
    assert s.s_g == pytest.approx(1.0, abs=1e-6)
    assert np.allclose(np.abs(s.tangential_forces), s.normal_forces, atol=1e-6)


def test_offset_antipodal_pair_scores_half():
    # contacts (1, .5) and (-1, -.5): the line between them is 26.6 deg off the normal, T = N/2
    s = grasp_score([(1, 0.5), (-1, -0.5)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["-x"]])
    assert s.s_g == pytest.approx(0.5, abs=1e-6)


def test_same_face_contacts_are_infeasible_not_an_error():
    s = grasp_score([(1, 0.5), (1, -0.5)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["+x"]])
    assert not s.feasible and not s.success
    assert s.s_g == float("inf")
    assert s.status == "PrimalInfeasible"  # clarabel's status, without the enum's name
    ok = grasp_score([(1, 0), (-1, 0)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["-x"]])
    assert ok.status == "Solved"


def test_three_against_one_is_unbalanced():
    """A thumb opposing three fingers on parallel faces needs a thumb force of 3 against 1+1+1, so
    S_G = 0.5 > 0.4: an unbalanced grasp fails (docs/models.md)."""
    pts = [(1, -0.5), (1, 0.0), (1, 0.5), (-1, 0.0)]
    nrm = [SQUARE_NORMALS["+x"]] * 3 + [SQUARE_NORMALS["-x"]]
    assert grasp_score(pts, nrm).s_g == pytest.approx(0.5, abs=1e-6)


def test_a_task_force_loads_the_contact_it_pushes_against():
    # antipodal contacts, task (0.5, 0, 0): (N_2 - N_1) / 2 = 0.5, so N = (1, 2) and S_G = 0.5
    pts, nrm = [(1, 0), (-1, 0)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["-x"]]
    s = grasp_score(pts, nrm, task=(0.5, 0.0, 0.0))
    assert s.s_g == pytest.approx(0.5, abs=1e-6)
    np.testing.assert_allclose(s.normal_forces, [1.0, 2.0], atol=1e-6)
    np.testing.assert_allclose(s.tangential_forces, [0.0, 0.0], atol=1e-6)
    flipped = grasp_score(pts, nrm, task=(-0.5, 0.0, 0.0))
    np.testing.assert_allclose(flipped.normal_forces, [2.0, 1.0], atol=1e-6)


@pytest.mark.parametrize("tau", [0.3, -0.3])
def test_a_task_moment_is_made_by_tangential_forces_of_its_sign(tau):
    # antipodal contacts: a CCW moment tau needs T_1 = T_2 = tau along the CCW tangents, S_G = |tau|
    s = grasp_score([(1, 0), (-1, 0)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["-x"]], (0, 0, tau))
    assert s.s_g == pytest.approx(abs(tau), abs=1e-6)
    np.testing.assert_allclose(s.tangential_forces, [tau, tau], atol=1e-6)
    np.testing.assert_allclose(s.normal_forces, [1.0, 1.0], atol=1e-6)


@pytest.mark.parametrize(("tau", "expected"), [(0.5, 0.0), (0.0, 0.5), (-0.5, 1.0)])
def test_the_offset_pair_suits_one_moment_sign(tau, expected):
    """Contacts (1, .5) and (-1, -.5): unit normal forces make a CCW moment of 1/2 on their own
    (p x f = 0.5 each); T = tau - N/2 balances a task moment tau. tau = 0.5 needs no friction
    (S_G = 0); tau = -0.5 needs T = -N, the edge of the cone (S_G = 1)."""
    s = grasp_score(
        [(1, 0.5), (-1, -0.5)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["-x"]], (0.0, 0.0, tau)
    )
    assert s.feasible
    assert s.s_g == pytest.approx(expected, abs=1e-6)


def test_friction_coefficient_bounds_the_tangential_force():
    # adjacent faces need |T| = N (S_G = 1, above); with mu = 0.5 no force balances
    adjacent = ([(1, 0), (0, 1)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["+y"]])
    assert not grasp_score(*adjacent, friction=0.5).feasible
    # the offset pair needs |T| = N/2: feasible at mu = 0.5, not at mu = 0.4
    offset = ([(1, 0.5), (-1, -0.5)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["-x"]])
    assert grasp_score(*offset, friction=0.5).s_g == pytest.approx(0.5, abs=1e-6)
    assert not grasp_score(*offset, friction=0.4).feasible


@pytest.mark.parametrize("name", ["triangle", "irregular_pentagon", "rectangle", "hexagon"])
def test_score_agrees_with_an_independent_lp_solver(name):
    poly = paper_object(name).unit_moment()
    rng = np.random.default_rng(7)
    task = np.array([0.05, -0.05, 0.1])
    n_feasible = 0
    for _ in range(40):
        f = poly.locate(rng.uniform(-np.pi, np.pi, 4))
        for t in (np.zeros(3), task):
            ours = grasp_score(f.point, f.normal, t)
            ref = linprog_score(f.point, f.normal, t)
            assert ours.feasible == (ref is not None)
            if ref is not None:
                n_feasible += 1
                assert ours.s_g == pytest.approx(ref, abs=1e-5)
    assert n_feasible > 20


def test_score_with_lower_friction_agrees_with_the_independent_lp():
    poly = paper_object("square").unit_moment()
    rng = np.random.default_rng(8)
    task = np.array([-0.03, 0.02, -0.08])
    results = set()
    for _ in range(40):
        f = poly.locate(rng.uniform(-np.pi, np.pi, 3))
        ours = grasp_score(f.point, f.normal, task, friction=0.6)
        ref = linprog_score(f.point, f.normal, task, mu=0.6)
        assert ours.feasible == (ref is not None)
        results.add(ours.feasible)
        if ref is not None:
            assert ours.s_g == pytest.approx(ref, abs=1e-5)
    assert results == {True, False}


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="as many normals"):
        grasp_score([(1, 0), (0, 1)], [(1, 0)])
    with pytest.raises(ValueError, match="finite"):
        grasp_score([(np.nan, 0), (0, 1)], [(1, 0), (0, 1)])


def test_success_is_s_g_at_most_0_4():
    """Section 3.5: a grasp with S_G <= 0.4 is a success (the threshold itself included)."""
    assert SUCCESS_THRESHOLD == 0.4
    none = np.zeros(0)
    assert GraspScore(True, 0.4, none, none, "Solved").success
    assert not GraspScore(True, 0.4000001, none, none, "Solved").success
    assert not GraspScore(False, 0.1, none, none, "PrimalInfeasible").success


def test_one_contact_is_infeasible_and_no_contact_is_an_error():
    s = grasp_score([(1, 0)], [SQUARE_NORMALS["+x"]])
    assert not s.feasible and s.s_g == float("inf")
    assert s.normal_forces.size == 0 and s.tangential_forces.size == 0
    with pytest.raises(ValueError, match="as many normals"):
        grasp_score(np.zeros((0, 2)), np.zeros((0, 2)))
    with pytest.raises(ValueError, match="finite"):
        grasp_score([(1, 0), (0, 1)], [(1, 0), (np.inf, 1)])


def test_the_solver_prints_nothing(capfd):
    grasp_score([(1, 0), (-1, 0)], [SQUARE_NORMALS["+x"], SQUARE_NORMALS["-x"]])
    out, err = capfd.readouterr()
    assert out == "" and err == ""


class _FakeSolution:
    def __init__(self, x):
        self.x = x
        self.status = clarabel.SolverStatus.Solved


@pytest.mark.parametrize(
    ("x", "feasible"),
    [
        ([1.0, 1.0, 0.0, 0.0, 0.0, 0.0], True),  # N = (1, 1): balances the antipodal pair
        ([1.0, 1.2, 0.0, 0.0, 0.0, 0.0], False),  # net force 0.1 != 0
        ([1.2, 1.0, 0.0, 0.0, 0.0, 0.0], False),  # net force -0.1 != 0
        ([1.0, 1.0, 0.0, 3e-6, 0.0, 3e-6], False),  # net force 1.5e-6 (tolerance 1e-6)
        ([0.5, 0.5, 0.0, 0.0, 0.0, 0.0], False),  # balanced, but N < 1
        ([1 - 5e-6, 1 - 5e-6, 0.0, 0.0, 0.0, 0.0], False),  # N < 1 beyond the 1e-6 tolerance
        ([1 - 5e-7, 1 - 5e-7, 0.0, 0.0, 0.0, 0.0], True),  # within it
        ([1.0, 1.0, 0.5, 0.5] + [0.0] * 8, False),  # four contacts, balanced, two N < 1
        ([1.0, 1.0, 1.0, 1.0] + [0.0] * 8, True),
    ],
)
def test_a_solver_answer_that_breaks_the_constraints_is_not_trusted(monkeypatch, x, feasible):
    """The LP's answer is checked (net wrench = task within 1e-6, every N >= 1) before it is
    believed, whatever status the solver reports."""
    pts = [(1, 0), (-1, 0), (0, 1), (0, -1)][: len(x) // 3]
    nrm = [SQUARE_NORMALS[k] for k in ("+x", "-x", "+y", "-y")][: len(x) // 3]

    class FakeSolver:
        def __init__(self, *args):
            pass

        def solve(self):
            return _FakeSolution(x)

    monkeypatch.setattr(clarabel, "DefaultSolver", FakeSolver)
    s = grasp_score(pts, nrm)
    assert s.feasible == feasible
    if feasible:
        assert s.s_g == pytest.approx(0.0, abs=1e-6)
