"""Scenes with blocks taller than the target (issue 23): the approach follows from the paths
(section 5.2), and a grasp beside a taller neighbour still delivers."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fsm.run import main


@pytest.mark.e2e
def test_auto_comes_from_the_side_when_a_pillar_blocks_the_top_and_delivers(
    tmp_path: Path,
) -> None:
    """Issue 23, section 5.2 ("the path computed determines whether a top or lateral grasp will
    be executed"): behind_a_pillar leaves the top approach no goal posture; ``auto`` takes the
    lateral one, says why in the transition log, and the block is delivered (judged physically)
    while the pillar stays standing where it was."""
    out = tmp_path / "pillar"
    code = main(["--scene", "behind_a_pillar", "--out", str(out), "--no-record"])
    s = json.loads((out / "summary.json").read_text())
    assert code == 0 and s["success"], s["failure_detail"]
    (cycle,) = s["cycles"]
    assert cycle["approach"] == "lateral"
    coarse = next(t for t in s["transitions"] if t.startswith("Coarse Reach -> Fine Reach"))
    assert "lateral approach: the only approach with a path (top: no collision-free goal" in coarse
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    assert j["other_blocks_moved_m"]["pillar"] < 0.005


@pytest.mark.e2e
def test_a_top_grasp_beside_a_taller_pillar_rises_clear_of_it_and_delivers(tmp_path: Path) -> None:
    """The pillar 3 cm behind the target: the top approach has its goal and is the shorter path,
    and after the lift the hand is still within the planner's clearance of the pillar; the
    delivery raises the block further before the transit (before: "transit: the start posture
    is in collision"), and the block is delivered with the pillar untouched."""
    text = (Path(__file__).parents[2] / "scenes" / "behind_a_pillar.toml").read_text()
    scene = tmp_path / "pillar_3cm.toml"
    scene.write_text(text.replace("position = [0.075, 0.0]", "position = [0.08, 0.0]"))
    out = tmp_path / "top"
    code = main(["--scene", str(scene), "--out", str(out), "--no-record"])
    s = json.loads((out / "summary.json").read_text())
    assert code == 0 and s["success"], s["failure_detail"]
    (cycle,) = s["cycles"]
    assert cycle["approach"] == "top"
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["other_blocks_moved_m"]["pillar"] < 0.005
