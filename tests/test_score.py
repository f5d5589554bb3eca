"""The grasp evaluation metric S_G (Eq. 13): hand-derived cases and an independent LP solver."""

import numpy as np
import pytest
from scipy.optimize import linprog

from controllers.grasp import grasp_score, paper_object

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


def test_three_against_one_is_unbalanced():
    """DESIGN.md: a thumb opposing three fingers on parallel faces needs 3 against 1+1+1."""
    pts = [(1, -0.5), (1, 0.0), (1, 0.5), (-1, 0.0)]
    nrm = [SQUARE_NORMALS["+x"]] * 3 + [SQUARE_NORMALS["-x"]]
    assert grasp_score(pts, nrm).s_g == pytest.approx(0.5, abs=1e-6)


def linprog_score(points, normals, task=None, mu=1.0):
    """Independent S_G with scipy/HiGHS over x = [N, T+, T-]."""
    p, nrm = np.asarray(points, float), np.asarray(normals, float)
    task = np.zeros(3) if task is None else task
    n = len(p)
    tan = np.stack([-nrm[:, 1], nrm[:, 0]], 1)
    cols = []
    for f in (-nrm, tan, -tan):
        cols.append(np.stack([f[:, 0], f[:, 1], p[:, 0] * f[:, 1] - p[:, 1] * f[:, 0]]) / n)
    a_eq = np.hstack(cols)
    a_ub = np.hstack([-mu * np.eye(n), np.eye(n), np.eye(n)])
    res = linprog(
        np.ones(3 * n),
        A_ub=a_ub,
        b_ub=np.zeros(n),
        A_eq=a_eq,
        b_eq=task,
        bounds=[(1, None)] * n + [(0, None)] * (2 * n),
        method="highs",
    )
    return res.fun / n - 1.0 if res.status == 0 else None


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


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="as many normals"):
        grasp_score([(1, 0), (0, 1)], [(1, 0)])
    with pytest.raises(ValueError, match="finite"):
        grasp_score([(np.nan, 0), (0, 1)], [(1, 0), (0, 1)])
