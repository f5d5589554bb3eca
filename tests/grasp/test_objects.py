"""Paper objects, their pre-registered shape families, object sets and seeded polygon sets."""

import numpy as np
import pytest

from controllers.grasp.errors import UnknownNameError
from controllers.grasp.objects import (
    FAMILY_LENGTH,
    FAMILY_OBJECTS,
    FAMILY_SEED,
    FAMILY_SIZE,
    IRREGULAR_SIDES,
    MAX_SET_SIZE,
    POLYGON_SET_SEEDS,
    RECTANGLE_ASPECT,
    TRAPEZOID_HEIGHT,
    TRAPEZOID_TOP,
    ObjectSet,
    family,
    family_member,
    family_seed,
    paper_object,
    polygon_set,
    polygon_set_seeds,
)
from controllers.grasp.qlearning import epoch_objects, epoch_trials
from experiments.paper.tasks import ReproduceConfig, general_training_set


def _edges(p):
    return np.roll(p.vertices, -1, axis=0) - p.vertices


@pytest.mark.parametrize("name", FAMILY_OBJECTS)
def test_family_members_follow_their_rule(name):
    members = family(name)
    assert len(members) == FAMILY_SIZE
    assert np.array_equal(members[0].vertices, paper_object(name).vertices)
    assert np.array_equal(family_member(name, 7).vertices, members[7].vertices)  # seeded
    assert len({m.vertices.round(9).tobytes() for m in members}) == FAMILY_SIZE  # all different
    for m in members:
        assert m.name == name
        length = np.linalg.norm(_edges(m), axis=1)
        size = length.max() if name in ("rectangle", "trapezoid") else m.diameter
        assert size == pytest.approx(FAMILY_LENGTH)
        e = _edges(m)
        longest = int(np.argmax(np.linalg.norm(e, axis=1)))
        assert np.allclose(np.cos(m.normal_angle[longest]), 0, atol=1e-12)  # at the bottom
        assert np.sin(m.normal_angle[longest]) == pytest.approx(-1.0)
        if name in IRREGULAR_SIDES:
            assert m.n_edges == IRREGULAR_SIDES[name]
        else:
            assert m.n_edges == 4
            length = np.linalg.norm(e, axis=1)
            cross = e[:, 0] * np.roll(e, 2, axis=0)[:, 1] - e[:, 1] * np.roll(e, 2, axis=0)[:, 0]
            assert np.isclose(cross[0], 0, atol=1e-15) or np.isclose(cross[1], 0, atol=1e-15)
        if name == "rectangle":
            dots = np.einsum("ij,ij->i", e, np.roll(e, -1, axis=0))
            assert np.allclose(dots, 0, atol=1e-15)
            aspect = length.max() / length.min()
            assert RECTANGLE_ASPECT[0] <= aspect <= RECTANGLE_ASPECT[1]
        if name == "trapezoid":
            s = np.sort(length)
            bottom, top = length[longest], length[(longest + 2) % 4]
            legs = length[[(longest + 1) % 4, (longest + 3) % 4]]
            assert legs[0] == pytest.approx(legs[1])  # isosceles
            assert bottom == s[-1]
            assert TRAPEZOID_TOP[0] <= top / bottom <= TRAPEZOID_TOP[1]
            height = np.ptp(m.vertices[:, 1])
            assert TRAPEZOID_HEIGHT[0] <= height / bottom <= TRAPEZOID_HEIGHT[1]


def test_regular_objects_are_families_of_one_and_unknown_names_are_refused():
    assert len(family("square")) == 1
    with pytest.raises(UnknownNameError, match="valid"):
        family_member("square", 0)
    with pytest.raises(UnknownNameError, match="valid"):
        polygon_set("test", 3)
    with pytest.raises(ValueError, match="polygons"):
        polygon_set_seeds("train", MAX_SET_SIZE + 1)


def test_seed_ranges_of_sets_and_families_never_overlap():
    ranges = {k: set(polygon_set_seeds(k, MAX_SET_SIZE)) for k in POLYGON_SET_SEEDS}
    ranges["families"] = {family_seed(n, i) for n in FAMILY_OBJECTS for i in range(1000)}
    names = list(ranges)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert ranges[a].isdisjoint(ranges[b]), (a, b)
    assert min(ranges["families"]) == FAMILY_SEED


@pytest.mark.parametrize("cfg", [ReproduceConfig.paper(), ReproduceConfig.quick_run()])
def test_general_predictor_never_trains_on_held_out_or_validation_polygons(cfg):
    train = general_training_set(cfg).polygons
    assert len(train) == cfg.predictor_epochs * cfg.general_trials
    train_seeds = set(polygon_set_seeds("train", len(train)))
    for kind, n in (("heldout", cfg.heldout_polygons), ("validation", cfg.validation_polygons)):
        assert train_seeds.isdisjoint(polygon_set_seeds(kind, n))
        held = {p.vertices.round(12).tobytes() for p in polygon_set(kind, min(n, 50))}
        assert held.isdisjoint({p.vertices.round(12).tobytes() for p in train[:200]})


def test_object_set_cycles_through_family_members():
    objs = ObjectSet.paper(("square", "rectangle", "trapezoid"), family_size=4)
    assert objs.sizes.tolist() == [1, 4, 4] and objs.first.tolist() == [0, 1, 5]
    assert len(objs.polygons) == 9
    flat = objs.polygon_index(np.array([0, 1, 1, 2]), np.array([3, 5, 8, 2]))
    assert flat.tolist() == [0, 2, 1, 7]
    assert objs.object_of(np.arange(9)).tolist() == [0, 1, 1, 1, 1, 2, 2, 2, 2]
    idx = objs.test_index(trials=5, trials_per_member=2)
    assert np.bincount(idx).tolist() == [5] + [2] * 8
    # training: 10 trials per object per epoch, so every member of a family is visited each epoch
    obj = epoch_objects(3, 10, np.random.default_rng(0))
    seen = np.concatenate([epoch_trials(objs, obj, e, 10) for e in range(2)])
    assert set(seen.tolist()) == set(range(9))
    assert np.bincount(objs.object_of(seen)).tolist() == [20, 20, 20]
