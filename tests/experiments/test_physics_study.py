"""The physical grasp study (issue 12, part 2): the quick run end to end, the physical test's
verdicts against the block's measured motion, the ROC against an independent count, seeds."""

from __future__ import annotations

import dataclasses
import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from controllers.hand.finger_geometry import fingertips_at, pad_normals
from controllers.hand.reachability import CONTACT_TOLERANCE, MAX_PAD_ANGLE, grip_targets
from controllers.planning.cspace import PALM_SITE
from experiments.physics.hand_placement import (
    MAX_PALM_TILT,
    SEEDS_TRIED,
    HandPosture,
    Placement,
    interleaved_starts,
    place_from,
    place_hand,
    ranked_starts,
)
from experiments.physics.report import QUICK_OBJECTS
from experiments.physics.roc import auc_mann_whitney, roc
from experiments.physics.study import (
    MAX_SHIFT,
    MAX_TURN,
    STAGES,
    GraspOutcome,
    Job,
    StudyWorld,
    physical_test,
    run_job,
)
from experiments.physics.synthesis import TOP_GRASP_DEPTHS
from hand_sim.indices import RobotIndices

ROOT = Path(__file__).resolve().parents[2]


def _cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MUJOCO_GL": "egl"}
    return subprocess.run(
        [sys.executable, "-m", "experiments.physics", *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.fixture(scope="module")
def quick(tmp_path_factory) -> tuple[Path, list[dict], dict]:
    out = tmp_path_factory.mktemp("physics") / "run"
    run = _cli("--out", str(out), "--quick", "--model", "both", "--grasps", "1", "--workers", "2")
    assert run.returncode == 0, run.stderr
    results = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    return out, results, json.loads((out / "summary.json").read_text())


@pytest.mark.e2e
def test_quick_run_covers_every_grasp_and_judges_by_the_measured_motion(quick) -> None:
    out, results, summary = quick
    assert len(results) == 2 * len(QUICK_OBJECTS) * 3  # both models, 1 grasp each
    keys = {(r["model"], r["object"], r["controller"], r["index"]) for r in results}
    assert len(keys) == len(results)
    outcomes = {r["result"] for r in results}
    assert outcomes <= {"held", "dropped", "unreachable", "not closed", "sim error"}
    tested = [r for r in results if r["result"] in ("held", "dropped")]
    assert tested, "no grasp of the quick run reached the physical test"
    for r in tested:
        assert len(r["grip_force"]) == 4 and min(r["grip_force"]) > 0.0  # every pad pressed
        if r["result"] == "held":  # every stage run, none beyond the limits
            assert set(r["shift"]) == set(STAGES)
            assert max(r["shift"].values()) <= MAX_SHIFT
            assert max(r["turn"].values()) <= MAX_TURN
        else:
            st = r["failed_stage"]
            assert r["shift"][st] > MAX_SHIFT or r["turn"][st] > MAX_TURN
    for r in results:
        if r["result"] == "unreachable":
            assert r["reason"] and not r["shift"]
    for r in tested:  # scored as held: four real contacts, the same grasp's three measures
        m = r["measures"]
        assert len(m["heights"]) == 4 and m["worst_stage"]
        assert m["sg3d"] is None or m["worst_sg3d"] is None or m["worst_sg3d"] >= m["sg3d"] - 1e-6
    for r in results:
        if r["model"] == "3d":  # the controller's heights lie in the top grasp's band
            depth = 0.1 - np.array(r["heights"])  # 20 cm blocks: CoM 10 cm below the top
            assert np.all(
                (depth >= TOP_GRASP_DEPTHS[0] - 1e-6) & (depth <= TOP_GRASP_DEPTHS[1] + 1e-6)
            )
        else:
            assert r["heights"] == []
    assert summary["tested"] == len(tested)
    assert summary["held"] == sum(r["result"] == "held" for r in tested)
    report = (out / "report.md").read_text()
    assert "S_G of the synthesized contacts as a predictor" in report
    assert (out / "roc.png").stat().st_size > 1000
    assert (out / "roc_measures.png").stat().st_size > 1000
    assert "### Model: 3d" in report and "3-D S_G, worst test task" in report
    assert set(summary["measures"]) == {
        "planar_sg",
        "sg3d",
        "worst_sg3d",
        "predicted_turn",
        "force_demand",
    }
    for r in tested:
        if r["measures"]:  # every finger touches: the compliance prediction exists
            assert 0.0 <= r["measures"]["predicted_turn"] <= np.pi
            assert r["measures"]["predicted_stage"] in ("hang", "+x", "-x", "+y", "-y", "+z", "-z")
            assert np.shape(r["measures"]["points"]) == (4, 3)
            demand = r["measures"]["force_demand"]
            assert demand is None or demand > 0.0
            assert r["measures"]["force_demand_stage"] in ("hang", "+x", "-x", "+y", "-y", "-z")


@pytest.mark.e2e
def test_a_grasp_gives_the_same_result_in_its_own_process_and_chunk(quick) -> None:
    """A grasp's result does not depend on where it runs: the first grasp of the quick run's
    worker pool is the same run here in this process, and the second grasp is the same run
    alone as after the first in one chunk (nothing carried over from grasp to grasp); on the
    3-D model (the planar one runs the same jobs through the same pool)."""
    _, results, _ = quick
    obj = QUICK_OBJECTS[0]
    from controllers.grasp.objects import PAPER_OBJECTS

    model = "3d"
    first, second = run_job(Job(obj, PAPER_OBJECTS.index(obj), "pi", 2, (0, 1), 0, model))
    [alone] = run_job(Job(obj, PAPER_OBJECTS.index(obj), "pi", 2, (1,), 0, model))
    [pooled] = [
        r
        for r in results
        if (r["model"], r["object"], r["controller"], r["index"]) == (model, obj, "pi", 0)
    ]
    assert first == pooled
    assert alone == second


@pytest.mark.e2e
def test_a_3d_grasp_out_of_reach_at_the_tasks_height_is_taken_and_held_higher_up() -> None:
    """Seed 0, irregular hexagon, KB grasp 5: the hand cannot take its contacts at the task's
    best common height (the lowest); tried higher in turn, it takes them 5 mm or more up, all
    together, and the block is held through the physical test."""
    from controllers.grasp.objects import PAPER_OBJECTS
    from controllers.grasp.task_height import HEIGHT_GAP

    obj = "irregular_hexagon"
    job = Job(obj, PAPER_OBJECTS.index(obj), "kb", 0, (5,), 0, "3d", regrasp=False)
    [only] = run_job(dataclasses.replace(job, height_tries=1))
    [tried] = run_job(job)
    assert only["result"] == "unreachable" and only["height_rank"] == 0
    assert tried["height_rank"] >= 1 and tried["result"] == "held"
    raised = np.subtract(tried["heights"], only["heights"])
    np.testing.assert_allclose(raised, raised[0], atol=2e-6)  # moved together
    assert raised[0] >= HEIGHT_GAP - 1e-6
    assert tried["height_raise"] == pytest.approx(raised[0], abs=2e-6)
    assert max(tried["turn"].values()) <= MAX_TURN and max(tried["shift"].values()) <= MAX_SHIFT


def _at_placement(model: mujoco.MjModel, placed: Placement) -> mujoco.MjData:
    """``model`` with the arm where ``placed`` found it and the hand at its reach test's
    posture, kinematics computed."""
    assert placed.qpos is not None and placed.reach is not None
    data = mujoco.MjData(model)
    data.qpos[:] = placed.qpos
    data.qpos[RobotIndices.of(model).finger_qpos.ravel()] = placed.reach.hand_q
    mujoco.mj_kinematics(model, data)
    return data


def _tip_errors(model: mujoco.MjModel, placed: Placement, data: mujoco.MjData) -> np.ndarray:
    """Each fingertip's distance (m) from its grip target on the contacts ``placed`` gives it."""
    assert placed.contacts is not None
    tips, _ = grip_targets(placed.contacts.points, placed.contacts.normals)
    return np.linalg.norm(fingertips_at(model, data.qpos) - tips, axis=1)


def test_the_arm_moves_the_fingers_onto_a_contact_on_every_face_of_the_square() -> None:
    """The grasp the old fixed-palm placement never reached (one contact per face: two fingers
    would take faces their pads turn away from), checked by the kinematics, not the verdict."""
    sw = StudyWorld.of("square")
    theta = sw.target.polygon.normal_angle  # the middle of every face
    assert len({round(float(t), 6) for t in theta}) == 4
    placed = place_hand(sw.world, sw.prism, sw.target, theta, sw.postures, checker=sw.checker)
    assert placed.reachable, placed.reason
    assert placed.qpos is not None and placed.contacts is not None and placed.reach is not None
    assert sorted(placed.contacts.contact_of_finger) == [0, 1, 2, 3]
    assert placed.tilt is not None and placed.tilt <= MAX_PALM_TILT
    model = sw.world.model
    data = _at_placement(model, placed)
    palm_z = data.site_xmat[model.site(PALM_SITE).id].reshape(3, 3)[:, 2]
    assert np.degrees(np.arccos(-palm_z[2])) <= np.degrees(MAX_PALM_TILT) + 1e-6
    assert _tip_errors(model, placed, data).max() <= CONTACT_TOLERANCE
    cosine = -np.einsum("fd,fd->f", pad_normals(model, data), placed.contacts.normals)
    assert np.all(cosine >= np.cos(MAX_PAD_ANGLE))


def _posture(gap: float, depth: float) -> HandPosture:
    return HandPosture(0.0, np.zeros(3), np.zeros((4, 3)), np.zeros((4, 3)), gap, depth)


def test_interleaved_starts_try_every_kind_of_seed_before_any_kind_twice() -> None:
    kinds = [(0.005, 0.04), (0.02, 0.04), (0.005, 0.06)]
    rng = np.random.default_rng(3)
    # a ranking in which the first kind holds the first five places
    order = [0] * 5 + list(rng.integers(0, 3, 20))
    pairs = [(_posture(*kinds[k]), object()) for k in order]
    out = interleaved_starts(pairs, 7)
    got = [(p.gap, p.depth) for p, _ in out]
    assert len(out) == 7
    assert set(got[:3]) == set(kinds)  # each kind once before any twice
    assert set(got[3:6]) == set(kinds)
    # each kind's own starts keep their ranked order, and the kinds go by their best start
    for kind in kinds:
        ranked = [c for p, c in pairs if (p.gap, p.depth) == kind]
        mine = [c for p, c in out if (p.gap, p.depth) == kind]
        assert mine == ranked[: len(mine)]
    firsts = sorted(kinds, key=lambda k: order.index(kinds.index(k)))
    assert got[:3] == firsts
    # fewer pairs than asked: all of them, none twice
    assert len(interleaved_starts(pairs[:4], 10)) == 4


def test_a_square_grasp_the_best_ranked_starts_miss_is_placed_from_another_kind_of_seed() -> None:
    """Seed 0, square, KB grasp 0 (3-D, at the task's height): the six best-ranked (seed,
    assignment) pairs come from two of the four kinds of seed (the square's quarter turns give
    each problem four times) and none places it; taken in turn from each kind, the same number
    of starts does, from a kind the ranking left out, fingertips on the contacts."""
    from controllers.grasp.objects import PAPER_OBJECTS
    from controllers.grasp.registry import make_composer
    from experiments.physics.study import initial_contacts, synthesize_on

    obj = "square"
    job = Job(obj, PAPER_OBJECTS.index(obj), "kb", 0, (0,), 0, "3d")
    sw = StudyWorld.of(obj, "3d")
    theta0, rng = initial_contacts(job, 0)
    spec = sw.world.scene.block(sw.name)
    syn = synthesize_on(sw, "3d", make_composer("kb"), theta0, rng)
    heights = sw.target.top_z - 0.5 * spec.height + syn.heights
    ranked = ranked_starts(sw.target, syn.theta, sw.postures, sw.prism.bottom, heights)
    first = ranked[:SEEDS_TRIED]
    kinds = {(p.gap, p.depth) for p in sw.postures}
    assert len(kinds) == 4
    assert len({(p.gap, p.depth) for p, _ in first}) < len(kinds)
    assert {(p.gap, p.depth) for p, _ in interleaved_starts(ranked, SEEDS_TRIED)} == kinds

    assert not place_from(
        sw.world, sw.prism, sw.target, syn.theta, first, checker=sw.checker
    ).reachable
    placed = place_hand(
        sw.world, sw.prism, sw.target, syn.theta, sw.postures, checker=sw.checker, heights=heights
    )
    assert placed.reachable, placed.reason
    assert placed.seed is not None
    assert (placed.seed.gap, placed.seed.depth) not in {(p.gap, p.depth) for p, _ in first}
    assert placed.qpos is not None and placed.contacts is not None and placed.reach is not None
    model = sw.world.model
    assert _tip_errors(model, placed, _at_placement(model, placed)).max() <= CONTACT_TOLERANCE
    np.testing.assert_allclose(
        placed.contacts.points[:, 2],
        heights[list(placed.contacts.contact_of_finger)],
        atol=CONTACT_TOLERANCE,
    )


def test_a_block_the_hand_does_not_hold_is_dropped_when_the_table_goes() -> None:
    sw = StudyWorld.of("trapezoid")
    sw.world.reset()  # hand open above the table, nothing holds the block
    out = GraspOutcome("trapezoid", "none", 0, [0.0] * 4)
    physical_test(sw, grip=None, out=out)
    assert out.result == "dropped" and out.failed_stage == "hang"
    assert out.shift["hang"] > MAX_SHIFT


def test_roc_and_auc_agree_with_a_pairwise_count() -> None:
    rng = np.random.default_rng(3)
    s_g = [float(x) for x in rng.uniform(0, 0.6, 40)] + [None, None]
    held = [bool(x) for x in (np.array(s_g[:40]) + rng.normal(0, 0.15, 40) < 0.3)] + [False, True]
    s = np.array([np.inf if v is None else v for v in s_g])
    y = np.array(held)
    pairs = [1.0 if a < b else 0.5 if a == b else 0.0 for a, b in itertools.product(s[y], s[~y])]
    r = roc(s_g, held)
    assert r.auc == pytest.approx(np.mean(pairs), abs=1e-12)
    assert auc_mann_whitney(np.array([0.1, 0.2]), np.array([0.3, 0.4])) == 1.0
    # the best threshold maximises TPR - FPR over every observed S_G
    best = max(((s[y] <= t).mean() - (s[~y] <= t).mean()) for t in np.unique(s[np.isfinite(s)]))
    assert r.best_j == pytest.approx(best)
    assert r.tpr[0] == 0.0 and r.tpr[-1] == 1.0 and r.fpr[-1] == 1.0


def test_bad_objects_are_refused_with_one_line_and_nothing_written(tmp_path: Path) -> None:
    out = tmp_path / "never"
    run = _cli("--out", str(out), "--objects", "square,circle")
    assert run.returncode == 2
    assert "circle" not in run.stdout and len(run.stderr.strip().splitlines()) == 1
    assert "valid" in run.stderr and not out.exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--model", "3d", "--depth", "0.06"), "--depth"),
        (("--depth", "0.5"), "--depth"),
        (("--model", "3d", "--height-tries", "0"), "--height-tries"),
        (("--model", "3d", "--height-tries", "six"), "--height-tries"),
        (("--model", "flat"), "--model"),
    ],
)
def test_bad_model_or_depth_is_refused_with_one_line_and_nothing_written(
    tmp_path: Path, args, message
) -> None:
    out = tmp_path / "never"
    run = _cli("--out", str(out), *args)
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1
    assert message in run.stderr and not out.exists()


@pytest.mark.e2e
def test_the_demand_recomputed_from_the_results_file_is_the_studys_own(quick, capsys) -> None:
    from experiments.physics.demand_variants import (
        VARIANTS,
        BlockFacts,
        main,
        recompute,
        scored,
    )

    out, results, _ = quick
    rs = [r for r in scored(results) if r["measures"]["force_demand"] is not None]
    assert rs, "no grasp of the quick run has a demand"
    blocks = {obj: BlockFacts.of(obj) for obj in {r["object"] for r in rs}}
    registered, no_torsion, target = (recompute(rs, v, blocks) for v in VARIANTS)
    for r, a, b in zip(rs, registered, no_torsion, strict=True):
        # the stored points and forces are rounded: 1e-3 relative
        assert a.demand == pytest.approx(r["measures"]["force_demand"], rel=2e-3)
        assert a.worst_stage == r["measures"]["force_demand_stage"]
        assert b.demand is None or b.demand >= a.demand - 1e-9  # torsion only helps
    assert any(
        t.demand != pytest.approx(a.demand, rel=1e-3)
        for t, a in zip(target, registered, strict=True)
    )
    assert main([str(out / "results.jsonl")]) == 0
    printed = capsys.readouterr().out
    assert all(f"{v.name}: pooled" in printed for v in VARIANTS)
    assert main([str(out / "missing.jsonl")]) == 2


def test_the_height_tries_flag_defaults_to_the_libraries_constant() -> None:
    from controllers.grasp.task_height import HEIGHT_TRIES
    from experiments.physics.cli import build_parser

    assert build_parser().parse_args(["--out", "x"]).height_tries == HEIGHT_TRIES
    assert build_parser().parse_args(["--out", "x", "--height-tries", "1"]).height_tries == 1


def test_the_height_table_counts_each_rank_and_the_grasps_no_height_reached() -> None:
    from experiments.physics.heights import height_section

    def grasp(rank: int, result: str, raise_m: float | None) -> dict:
        return {"model": "3d", "height_rank": rank, "result": result, "height_raise": raise_m}

    results = [
        grasp(0, "held", 0.0),
        grasp(0, "dropped", 0.0),
        grasp(1, "held", 0.006),
        grasp(2, "held", 0.012),
        grasp(2, "not closed", 0.014),
        grasp(2, "unreachable", 0.013),
        {"model": "planar", "result": "held"},
    ]
    lines = height_section(results)
    rows = {line.split("|")[1].strip(): line for line in lines if line.startswith("| ")}
    assert rows["0"].startswith("| 0 | 2 | 2 | 1 / 2 ")
    assert rows["1"].startswith("| 1 | 1 | 1 | 1 / 1 ") and rows["1"].endswith("| 6.0 |")
    assert rows["2"].startswith("| 2 | 2 | 1 | 1 / 1 ") and rows["2"].endswith("| 13.0 |")
    assert "Reached at no height: 1 of 6 3-D grasps." in lines
    assert height_section([{"model": "planar", "result": "held"}]) == []
