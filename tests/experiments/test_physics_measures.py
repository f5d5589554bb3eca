"""The held grasp's three measures (experiments.physics.measures) against independent ones."""

import numpy as np
import pytest

from controllers.grasp import grasp_score, paper_object
from controllers.grasp.prism3d import physical_tasks
from controllers.grasp.score3d import grasp_score_3d
from experiments.physics.measures import grasp_measures


@pytest.mark.parametrize("name", ["square", "triangle", "irregular_pentagon"])
def test_contacts_at_the_centre_of_mass_height_score_as_the_planar_metric(name):
    poly = paper_object(name)
    theta = np.random.default_rng(1).uniform(0, 2 * np.pi, 4)
    xy = poly.locate(theta).point
    m = grasp_measures(np.column_stack([xy, np.zeros(4)]), poly, block_yaw=0.3, load=0.4)
    unit = poly.unit_moment().locate(theta)
    planar = grasp_score(unit.point, unit.normal)
    assert m.planar_sg == pytest.approx(planar.s_g, abs=1e-6)
    assert m.sg3d == pytest.approx(planar.s_g, abs=1e-6)
    assert m.worst_sg3d >= m.sg3d - 1e-9


def test_the_worst_task_is_the_worst_of_the_physical_tasks_scored_one_by_one():
    poly = paper_object("rectangle")
    theta = np.array([0.1, 1.4, 3.2, 4.6])
    f = poly.locate(theta)
    z = np.array([0.05, 0.04, 0.06, 0.045])  # above the centre of mass, metres
    yaw = 0.7
    m = grasp_measures(np.column_stack([f.point, z]), poly, block_yaw=yaw, load=0.3)
    scale = poly.max_moment
    p = np.column_stack([f.point / scale, z / scale])
    n = np.column_stack([f.normal, np.zeros(4)])
    scores = {k: grasp_score_3d(p, n, t).s_g for k, t in physical_tasks(0.3, 4, -yaw).items()}
    assert m.worst_sg3d == pytest.approx(max(scores.values()), abs=1e-6)
    assert scores[m.worst_stage] == pytest.approx(max(scores.values()), abs=1e-6)
    assert m.heights == pytest.approx(list(z))
