"""The task's common height and the next-best heights a hand can try (task_height, synthesis3d)."""

import numpy as np
import pytest

from controllers.grasp.errors import GraspError
from controllers.grasp.objects import paper_object
from controllers.grasp.prism3d import worst_task_score
from controllers.grasp.registry import make_composer
from controllers.grasp.task_height import ranked_shifts, spread_shifts
from controllers.grasp.trials3d import HeightBand, PrismBatch

HEIGHT = 0.2


def _pentagon_contacts(z: float = 3.0):
    batch = PrismBatch.of([paper_object("pentagon")], [HEIGHT])
    theta = np.array([[0.2, 1.7, 3.1, 4.6]])
    frames = batch.locate(np.zeros(1, dtype=np.int64), theta, np.full((1, 4), z))
    return frames.point[0], frames.normal[0]


def test_ranked_shifts_put_the_task_shift_first_and_then_order_the_rest_by_worst_task_s_g():
    p, n = _pentagon_contacts()
    ranked = ranked_shifts(p, n, 1.0, 4.0, load=0.5)
    assert all(ranked[0].score.s_g <= t.score.s_g + 1e-9 for t in ranked)
    assert len(ranked) == 9 and len({t.shift for t in ranked}) == 9
    # every entry's score is the worst-task S_G of its shifted contacts, computed independently
    for t in ranked:
        q = p.copy()
        q[:, 2] += t.shift
        assert worst_task_score(q, n, 0.5)[1].s_g == pytest.approx(t.score.s_g, abs=1e-9)
    s = [t.score.s_g for t in ranked[1:]]
    assert s == sorted(s)
    # the shifts span the band: the lowest contact at 1.0, the highest at 4.0
    shifts = sorted(t.shift for t in ranked)
    assert shifts[0] == pytest.approx(-2.0) and shifts[-1] == pytest.approx(1.0)


def test_spread_shifts_keep_the_best_and_skip_near_duplicates():
    p, n = _pentagon_contacts()
    ranked = ranked_shifts(p, n, 1.0, 4.0, load=0.5)  # 9 shifts 0.375 apart
    kept = spread_shifts(ranked, 4, 0.7)
    assert kept[0] is ranked[0] and len(kept) == 4
    gaps = [abs(a.shift - b.shift) for i, a in enumerate(kept) for b in kept[:i]]
    assert min(gaps) >= 0.7 - 1e-9
    # order kept: each kept entry comes after the ones before it in the ranking
    positions = [next(i for i, r in enumerate(ranked) if r is t) for t in kept]
    assert positions == sorted(positions)
    assert all(a is b for a, b in zip(spread_shifts(ranked, 9, 0.0), ranked, strict=True))
    assert [t.shift for t in spread_shifts(ranked, 1, 0.7)] == [ranked[0].shift]
    with pytest.raises(GraspError, match="tries"):
        spread_shifts(ranked, 0, 0.7)
    with pytest.raises(GraspError, match="gap"):
        spread_shifts(ranked, 2, float("nan"))


def test_a_finished_synthesis_offers_its_task_height_first_then_common_shifts_in_the_band():
    from controllers.grasp.synthesis3d import GraspSynthesis3D

    band = HeightBand.below_top(HEIGHT, 0.04, 0.06)
    z0 = np.array([0.05, 0.055, 0.045, 0.058])
    syn = GraspSynthesis3D(
        paper_object("square"),
        HEIGHT,
        band,
        make_composer("kb"),
        [0.3, 1.5, 2.9, 4.4],
        z0,
        np.random.default_rng(2),
        min_separation=0.021,
        separation_offset=0.0085,
        load=0.3,
    )
    assert len(syn.height_options(4, 0.005)) == 1  # nothing to offer before the run ends
    while not syn.done:
        syn.step()
    options = syn.height_options(4, 0.005)
    np.testing.assert_allclose(options[0], syn.heights, atol=1e-12)
    assert 2 <= len(options) <= 4
    low, high = band.low - 0.5 * HEIGHT, band.high - 0.5 * HEIGHT
    for o in options:
        shift = o - options[0]
        np.testing.assert_allclose(shift, shift[0], atol=1e-12)  # moved together
        assert o.min() >= low - 1e-9 and o.max() <= high + 1e-9
    shifts = [float(o[0] - options[0][0]) for o in options]
    assert min(abs(a - b) for i, a in enumerate(shifts) for b in shifts[:i]) >= 0.005 - 1e-9
    assert syn.height_options(1, 0.005)[0] is not None and len(syn.height_options(1, 0.005)) == 1
