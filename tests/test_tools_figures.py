"""Tests of the figure tools' own logic (tools/): the push spans of the grasp-tension figure."""

from __future__ import annotations

import numpy as np

from tools.tendon_grasp_figure import push_spans


def test_push_spans_name_each_push_by_its_direction_and_skip_the_rest() -> None:
    t = np.arange(10) * 0.5
    push = np.zeros((10, 3))
    push[2:4] = (2.2, 0.0, 0.0)
    push[4:6] = (-2.2, 0.0, 0.0)
    push[7:9] = (0.0, 0.0, -2.2)
    assert push_spans(t, push) == [(1.0, 1.5, "+x"), (2.0, 2.5, "-x"), (3.5, 4.0, "-z")]
    assert push_spans(t, np.zeros((10, 3))) == []
    push[:] = (0.0, 1.0, 0.0)  # a push to the end of the log
    assert push_spans(t, push) == [(0.0, 4.5, "+y")]
