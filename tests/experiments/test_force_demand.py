"""The measured-force demand (experiments.physics.force_demand) against closed forms and an
independent linear programme (scipy's HiGHS with pyramidal friction cones)."""

import numpy as np
import pytest
from scipy.optimize import linprog

from controllers.grasp import paper_object
from controllers.grasp.score3d import ContactError, tangent_basis
from experiments.physics.force_demand import (
    ALPHA_CAP,
    PAD_FRICTION,
    force_demand,
    load_multiple,
)


def _pyramid_alpha(p, nrm, cap, load, mu, rho, facets, outer):
    """alpha of the same programme with a K-facet pyramid inscribed in (outer=False) or
    circumscribing (outer=True) each round cone: N, K facet weights, tau per contact."""
    n = len(p)
    basis = tangent_basis(nrm)
    ang = 2 * np.pi * np.arange(facets) / facets
    mu_k = mu / np.cos(np.pi / facets) if outer else mu
    cols, bounds = [], []
    for i in range(n):
        t1, t2 = basis[i, 0], basis[i, 1]
        edges = [-nrm[i] + mu_k * (np.cos(a) * t1 + np.sin(a) * t2) for a in ang]
        for e in edges:  # f = sum_k lambda_k e_k, N = sum lambda_k
            cols.append(np.concatenate([e, np.cross(p[i], e)]))
            bounds.append((0, None))
    for i in range(n):  # torsion moment
        cols.append(np.concatenate([np.zeros(3), nrm[i]]))
        bounds.append((None, None))
    cols.append(np.concatenate([load, np.zeros(3)]))
    bounds.append((0, ALPHA_CAP))
    a_eq = np.array(cols).T
    nv = a_eq.shape[1]
    a_ub, b_ub = [], []
    for i in range(n):
        row = np.zeros(nv)
        row[i * facets : (i + 1) * facets] = 1.0  # N_i <= cap_i
        a_ub.append(row)
        b_ub.append(cap[i])
        for sign in (1.0, -1.0):  # +-tau_i - rho N_i <= 0
            r = np.zeros(nv)
            r[n * facets + i] = sign
            r[i * facets : (i + 1) * facets] = -rho
            a_ub.append(r)
            b_ub.append(0.0)
    c = np.zeros(nv)
    c[-1] = -1.0
    res = linprog(c, A_ub=a_ub, b_ub=b_ub, A_eq=a_eq, b_eq=np.zeros(6), bounds=bounds)
    assert res.status == 0
    return res.x[-1]


def test_two_pads_hang_a_block_with_twice_their_friction():
    p = np.array([[0.03, 0.0, 0.0], [-0.03, 0.0, 0.0]])
    nrm = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    alpha = load_multiple(p, nrm, [5.0, 5.0], [0.0, 0.0, -2.0], friction=0.8, torsion=0.0)
    assert alpha == pytest.approx(2 * 0.8 * 5.0 / 2.0, rel=1e-5)


def test_a_push_along_the_squeeze_unloads_one_pad():
    p = np.array([[0.03, 0.0, 0.0], [-0.03, 0.0, 0.0]])
    nrm = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    # a push towards -x is resisted by the -x pad (it presses towards +x) alone, up to its
    # measured force; the +x pad can only unload
    alpha = load_multiple(p, nrm, [4.0, 6.0], [-1.0, 0.0, 0.0], friction=0.5, torsion=0.0)
    assert alpha == pytest.approx(6.0, rel=1e-5)


@pytest.mark.parametrize("seed", range(40))
def test_the_round_cone_lies_between_inscribed_and_circumscribed_pyramids(seed):
    rng = np.random.default_rng(seed)
    poly = paper_object(["square", "triangle", "hexagon", "irregular_pentagon"][seed % 4])
    theta = rng.uniform(0, 2 * np.pi, 4)
    f = poly.locate(theta)
    z = rng.uniform(-0.01, 0.06, 4)
    p = np.column_stack([f.point, z])
    nrm = np.column_stack([f.normal, np.zeros(4)])
    cap = rng.uniform(1.0, 8.0, 4)
    load = rng.normal(size=3) * rng.uniform(0.5, 5.0)
    mu, rho = rng.uniform(0.3, 1.2), rng.choice([0.0, 0.004])
    alpha = load_multiple(p, nrm, cap, load, friction=mu, torsion=rho)
    k = 64
    lo = _pyramid_alpha(p, nrm, cap, load, mu, rho, k, outer=False)
    hi = _pyramid_alpha(p, nrm, cap, load, mu, rho, k, outer=True)
    assert lo - 1e-5 * max(1.0, lo) <= alpha <= hi + 1e-5 * max(1.0, hi)
    assert hi - lo <= 0.06 * max(hi, 1e-3)  # the bracket is narrow: the check has teeth


def test_twice_the_grip_resists_twice_the_load():
    poly = paper_object("pentagon")
    f = poly.locate(np.array([0.2, 1.7, 3.1, 4.5]))
    p = np.column_stack([f.point, [0.04, 0.045, 0.05, 0.04]])
    nrm = np.column_stack([f.normal, np.zeros(4)])
    load = np.array([1.0, 0.5, -1.0])
    a1 = load_multiple(p, nrm, [2.0, 3.0, 2.5, 4.0], load)
    a2 = load_multiple(p, nrm, [4.0, 6.0, 5.0, 8.0], load)
    assert a2 == pytest.approx(2 * a1, rel=1e-5)


def test_contacts_above_the_centre_of_mass_make_a_sideways_push_harder():
    poly = paper_object("square")
    f = poly.locate(np.array([0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi]))
    nrm = np.column_stack([f.normal, np.zeros(4)])
    grip = [6.0] * 4
    low = force_demand(np.column_stack([f.point, np.zeros(4)]), nrm, grip, 2.0, block_yaw=0.2)
    high = force_demand(np.column_stack([f.point, np.full(4, 0.06)]), nrm, grip, 2.0, 0.2)
    assert low.demand is not None and high.demand is not None
    assert high.demand > low.demand
    assert high.worst_stage in ("+x", "-x", "+y", "-y")
    assert high.demand == pytest.approx(1.0 / min(high.alphas.values()))


def test_the_stages_are_the_physical_tests_loads_turned_into_the_block_frame():
    poly = paper_object("rectangle")
    f = poly.locate(np.array([0.1, 1.4, 3.2, 4.6]))
    p = np.column_stack([f.point, [0.05, 0.04, 0.06, 0.045]])
    nrm = np.column_stack([f.normal, np.zeros(4)])
    yaw, weight = 0.7, 1.5
    d = force_demand(p, nrm, [5.0, 6.0, 4.0, 5.5], weight, yaw)
    c, s = np.cos(-yaw), np.sin(-yaw)
    push_x = weight * np.array([c, s, -1.0])  # world +x push plus the weight, in the block frame
    assert d.alphas["+x"] == pytest.approx(
        load_multiple(p, nrm, [5.0, 6.0, 4.0, 5.5], push_x), rel=1e-6
    )
    assert d.alphas["+z"] == ALPHA_CAP  # the push up cancels the weight


@pytest.mark.parametrize(
    "cap, load",
    [([1.0, -1.0], [0, 0, -1.0]), ([1.0, np.nan], [0, 0, -1.0]), ([1.0, 1.0], [0, np.inf, 0])],
)
def test_bad_forces_or_loads_are_refused(cap, load):
    p = np.array([[0.03, 0.0, 0.0], [-0.03, 0.0, 0.0]])
    nrm = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])
    with pytest.raises(ContactError):
        load_multiple(p, nrm, cap, load, friction=PAD_FRICTION)
