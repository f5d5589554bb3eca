"""Grasps that hold before the bands (``TaskConfig.lateral_reserve_before_bands``, issue 23), on
random scene 103: every sampled lateral grasp the hand reaches within the paper's S_G <= 0.4
(Eq. 13) keeps no friction reserve by the 3-D model (it holds the irregular triangle's weight
with no squeeze the fingers can give). With the bands searched in their order alone, the
pre-shape takes one of those; searched first for the grasps that keep a reserve, it takes one
of a later band (above 0.4, within the gate counted from the thumb's opposition) that does.
The reserve is the 3-D model's at the pre-shape's own contacts, squeezed as Grasp Object would
squeeze them; the episodes are stopped where Fine Reach would begin."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from controllers.grasp.score import SUCCESS_THRESHOLD
from controllers.hand.lateral_squeeze import lateral_squeeze
from fsm import handlers
from fsm.config import DEFAULT_CONFIG
from fsm.episode_queries import block_centre, planar_normal_forces
from fsm.states import Failure, State, TaskFailedError
from tests.fsm.lateral import lateral_episode

SEED = 103


def _first_preshape(tmp_path: Path, monkeypatch, before_bands: bool) -> tuple[float, float]:
    """The first pre-shape's S_G (from the log) and its contacts' friction reserve (N)."""
    reserves: list[float] = []

    def stop(ep) -> None:
        c = ep.preshape_contacts
        on = c.pressing
        planar = planar_normal_forces(ep, c.theta[on])
        squeeze = lateral_squeeze(
            c.points[on], c.normals[on], planar, ep.expected_load, block_centre(ep)
        )
        reserves.append(-np.inf if squeeze.reserve is None else squeeze.reserve)
        raise TaskFailedError(Failure.FINGERS_CANNOT_REACH, "stopped by the test at Fine Reach")

    monkeypatch.setitem(handlers.HANDLERS, State.FINE_REACH, stop)
    config = replace(DEFAULT_CONFIG, lateral_reserve_before_bands=before_bands)
    result = lateral_episode(tmp_path, "random", SEED, config)
    reach = next(v.reason for v in result.visits if v.state == State.COARSE_REACH.value)
    assert "sampled pre-shape" in reach, reach
    s_g = float(re.search(r"S_G (\d+\.\d+)", reach).group(1))
    (reserve,) = reserves
    return s_g, reserve


@pytest.mark.e2e
def test_a_grasp_that_keeps_a_reserve_is_taken_before_the_paper_band_s_ones(
    tmp_path: Path, monkeypatch
) -> None:
    s_g, reserve = _first_preshape(tmp_path / "bands", monkeypatch, before_bands=False)
    assert s_g <= SUCCESS_THRESHOLD and reserve < 0.0, (s_g, reserve)
    s_g, reserve = _first_preshape(tmp_path / "reserve", monkeypatch, before_bands=True)
    assert s_g > SUCCESS_THRESHOLD and reserve >= 0.0, (s_g, reserve)
