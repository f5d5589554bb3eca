"""The physical study's regrasp (``--regrasp``): a grasp the hand cannot take is synthesized once
more from contacts the hand holds, and that grasp is placed and physically tested."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from controllers.grasp.objects import PAPER_OBJECTS
from controllers.grasp.registry import make_composer
from experiments.physics.hand_placement import place_hand
from experiments.physics.regrasp import regrasp_section, regrasp_start
from experiments.physics.study import (
    MAX_SHIFT,
    MAX_TURN,
    Job,
    StudyWorld,
    initial_contacts,
    run_job,
    synthesize_on,
)
from experiments.physics.synthesis import top_grasp_band

OBJ = "hexagon"
#: Seed 0, hexagon, KB grasp 0 (3-D): its contacts ask ff to press with the side of its
#: fingertip from every start tried (docs/physics_study.md, "Limits").
JOB = Job(OBJ, PAPER_OBJECTS.index(OBJ), "kb", 0, (0,), 0, "3d")


@pytest.fixture(scope="module")
def hexagon() -> StudyWorld:
    return StudyWorld.of(OBJ, "3d")


def _first_synthesis(sw: StudyWorld):
    theta0, rng = initial_contacts(JOB, 0)
    return synthesize_on(sw, "3d", make_composer("kb"), theta0, rng)


def test_the_regrasp_starts_from_contacts_on_the_faces_that_the_hand_reaches(hexagon) -> None:
    """The start the regrasp gives for the unreachable grasp: points on the hexagon's side faces
    (the polygon's own point at each theta), in the 3-D band, and a hand placement reaches them."""
    sw = hexagon
    syn = _first_synthesis(sw)
    spec = sw.world.scene.block(sw.name)
    base = sw.target.top_z - spec.height
    heights = base + 0.5 * spec.height + syn.heights
    assert not place_hand(
        sw.world, sw.prism, sw.target, syn.theta, sw.postures, checker=sw.checker, heights=heights
    ).reachable
    theta, z = regrasp_start(sw.target, sw.postures, syn.theta, sw.prism.bottom, heights)
    # the polygon's point at each theta, in the world, is where the regrasp starts
    c, s = np.cos(sw.target.yaw), np.sin(sw.target.yaw)
    on_face = sw.target.polygon.point_at(theta) @ np.array([[c, s], [-s, c]])
    on_face = on_face + sw.target.position_xy
    band = top_grasp_band(spec.height)
    assert np.all((z - base >= band.low - 1e-9) & (z - base <= band.high + 1e-9))
    placed = place_hand(
        sw.world, sw.prism, sw.target, theta, sw.postures, checker=sw.checker, heights=z
    )
    assert placed.reachable, placed.reason
    assert placed.contacts is not None
    # the hand's contacts are those points (in its own finger order)
    order = list(placed.contacts.contact_of_finger)
    np.testing.assert_allclose(placed.contacts.points[:, :2], on_face[order], atol=1e-6)


@pytest.mark.e2e
def test_an_unreachable_grasp_is_regrasped_then_taken_and_held(hexagon) -> None:
    """With --regrasp the same grasp's record says the first synthesis (the controller's own
    contacts, recomputed here) was unreachable, and the second one is taken and holds the block
    through the physical test."""
    syn = _first_synthesis(hexagon)
    [out] = run_job(dataclasses.replace(JOB, regrasp=True))
    assert out["regrasped"] and "side of its fingertip" in out["first_reason"]
    np.testing.assert_allclose(out["first_theta"], syn.theta, atol=1e-6)
    assert not np.allclose(out["theta"], out["first_theta"], atol=1e-3)
    assert out["result"] == "held", out["reason"]
    assert max(out["turn"].values()) <= MAX_TURN and max(out["shift"].values()) <= MAX_SHIFT


def test_the_regrasp_table_counts_first_takes_and_regrasps_apart() -> None:
    def grasp(regrasped: bool, result: str) -> dict:
        return {"model": "3d", "regrasped": regrasped, "result": result}

    rows = [
        grasp(False, "held"),
        grasp(False, "dropped"),
        grasp(True, "held"),
        grasp(True, "unreachable"),
        grasp(True, "held"),
    ]
    [line] = [x for x in regrasp_section(rows) if x.startswith("| 3d")]
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[1:3] == ["5", "2"]
    assert cells[3].startswith("1 / 2")
    assert cells[4:6] == ["3", "2"]
    assert cells[6].startswith("2 / 2") and cells[7] == "1"
    assert regrasp_section([grasp(False, "held")]) == []


def test_the_study_regrasps_by_default_and_no_regrasp_turns_it_off(tmp_path) -> None:
    """The command line's default is the task cycle's loop; ``--no-regrasp`` (and only it) gives
    the study of grasps as first synthesized, down to the jobs the workers run."""
    from experiments.physics.cli import build_parser
    from experiments.physics.report import jobs_for

    parse = build_parser().parse_args
    assert parse(["--out", str(tmp_path / "a")]).regrasp
    assert not parse(["--out", str(tmp_path / "b"), "--no-regrasp"]).regrasp
    assert all(j.regrasp for j in jobs_for(("square",), 2, 0))
    assert not any(j.regrasp for j in jobs_for(("square",), 2, 0, regrasp=False))
