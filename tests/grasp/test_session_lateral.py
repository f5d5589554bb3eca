"""The lateral grasp's 3-D controller (controllers.grasp.synthesis_lateral): its contacts stay on
their arcs at the heights given, it reduces to the planar lateral grasp when the heights are
equal, and it scores in 3-D with the weight's task."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.grasp.errors import GraspError
from controllers.grasp.objects import paper_object
from controllers.grasp.prism3d import physical_tasks
from controllers.grasp.registry import make_composer
from controllers.grasp.score3d import grasp_score_3d
from controllers.grasp.synthesis import GraspSynthesis, clamp_to_arcs
from controllers.grasp.synthesis_lateral import LateralSynthesis3D
from controllers.grasp.trials3d import HeightBand

HEIGHT = 0.06
BAND = HeightBand(0.02, HEIGHT - 0.015)
#: a lateral hand's two arcs (left and right of its approach axis, rad), two contacts on each
LEFT, RIGHT = (0.15, 1.35), (3.3, 4.5)
ARCS = np.array([LEFT, LEFT, RIGHT, RIGHT])
THETA0 = np.array([0.4, 1.1, 3.5, 4.2])
SEPARATION = {"min_separation": 0.021, "separation_offset": 0.0085}


def _lateral(controller: str, z, seed: int = 1, load: float | None = None) -> LateralSynthesis3D:
    return LateralSynthesis3D(
        paper_object("rectangle"),
        HEIGHT,
        BAND,
        make_composer(controller),
        THETA0,
        z,
        np.random.default_rng(seed),
        arcs=ARCS,
        load=load,
        **SEPARATION,
    )


def _on_arcs(theta) -> bool:
    return bool(np.allclose(clamp_to_arcs(theta, ARCS), theta, atol=1e-12))


@pytest.mark.parametrize("controller", ["kb", "pi"])
def test_contacts_stay_on_their_arcs_at_the_heights_given(controller):
    z0 = np.array([0.012, 0.01, -0.004, -0.006])  # the thumb side lower, as a lateral hand's
    syn = _lateral(controller, z0)
    assert _on_arcs(syn.theta)
    while not syn.done:
        syn.step()
        assert _on_arcs(syn.theta)
        np.testing.assert_allclose(syn.heights, z0, atol=1e-12)
    assert syn.steps > 1
    # heights from a reach test are taken (clipped to the band), theta is left
    theta = syn.theta
    syn.set_heights([0.0, 0.0, 0.0, 0.5])
    np.testing.assert_allclose(syn.heights, [0.0, 0.0, 0.0, BAND.high - 0.5 * HEIGHT])
    np.testing.assert_array_equal(syn.theta, theta)


@pytest.mark.parametrize("controller", ["kb", "ql", "pi"])
@pytest.mark.parametrize("common", [0.0, 0.012, -0.01])
def test_equal_heights_move_the_contacts_as_the_planar_lateral_grasp(controller, common):
    """At one common height eps_MC (moments about the contacts' mean height) is the planar one
    and the theta gradients are the planar ones: the same contacts, step by step."""
    syn = _lateral(controller, np.full(4, common))
    planar = GraspSynthesis(
        paper_object("rectangle"),
        make_composer(controller),
        THETA0,
        np.random.default_rng(1),
        arcs=ARCS,
        **SEPARATION,
    )
    np.testing.assert_allclose(syn.theta, planar.theta, atol=1e-12)
    while not planar.done:
        a, b = syn.step(), planar.step()
        np.testing.assert_allclose(a.theta, b.theta, atol=1e-9)
        assert a.eps_fc == pytest.approx(b.eps_fc, abs=1e-9)
        assert a.eps_mc == pytest.approx(b.eps_mc, abs=1e-9)
    assert syn.done and syn.steps == planar.steps and syn.converged == planar.converged
    # the null task's 3-D S_G of contacts in one horizontal plane is the planar S_G
    assert syn.finish().s_g == pytest.approx(planar.finish().s_g, abs=1e-5)


def test_the_score_is_3d_with_the_weight_and_stop_at_keeps_the_heights():
    z0 = np.array([0.012, 0.01, -0.004, -0.006])
    syn = _lateral("kb", z0, load=0.4)
    while not syn.done:
        syn.step()
    frames = syn._batch.locate(syn._index, syn._theta, syn._z)
    weight = physical_tasks(0.4, 4)["hang"]
    want = grasp_score_3d(frames.point[0], frames.normal[0], weight)
    got = syn.finish()
    assert got.feasible and got.s_g == pytest.approx(want.s_g, abs=1e-9)
    null = grasp_score_3d(frames.point[0], frames.normal[0])
    assert got.s_g > null.s_g  # carrying the weight costs friction
    syn = _lateral("kb", z0, load=0.4)
    syn.step()
    syn.stop_at(THETA0)
    assert syn.done and syn.stopped and not syn.converged
    np.testing.assert_allclose(syn.theta, THETA0)
    np.testing.assert_allclose(syn.heights, z0, atol=1e-12)
    assert syn.score_at(THETA0).s_g == pytest.approx(syn.score().s_g, abs=1e-12)


def test_bad_input():
    with pytest.raises(GraspError, match="arcs"):
        LateralSynthesis3D(
            paper_object("rectangle"),
            HEIGHT,
            BAND,
            make_composer("kb"),
            THETA0,
            np.zeros(4),
            np.random.default_rng(0),
            arcs=ARCS[:3],
        )
    with pytest.raises(GraspError, match="heights"):
        _lateral("kb", np.zeros(4)).set_heights([0.0, np.nan, 0.0, 0.0])
