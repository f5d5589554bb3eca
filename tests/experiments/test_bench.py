"""``python -m experiments.bench``: the per-seed block count, the results file, the report's numbers
(the Wilson interval against scipy's independent implementation), bad input, and real episodes run
in 2 worker processes, resumed in this process and on a local Ray instance, giving the same results
wherever they ran (wall times aside)."""

from __future__ import annotations

import importlib.util
import json
import re
import shutil
from collections import Counter
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from scipy.stats import binomtest

from experiments.bench import cli as bench
from experiments.bench import report as bench_report
from experiments.bench.jobs import (
    CRASHED,
    BenchError,
    Job,
    append_line,
    blocks_for_seed,
    drop_torn_tail,
    read_results,
    run_job,
    without_wall_times,
)
from experiments.bench.report import DPI, FIG_SIZE, FIGURES, write_report
from experiments.bench.stats import summarize, wilson_interval
from fsm import handlers
from fsm.states import State
from tests.session import session_lock

#: The controller the episode tests run (needs no trained model).
CONTROLLER = "kb"
QUICK = ["--scene", "random", "--blocks", "3:5", "--controller", CONTROLLER]


# --- helpers --------------------------------------------------------------------------------------
def lines_of(folder: Path) -> dict[int, dict[str, Any]]:
    return {line["seed"]: line for line in read_results(folder / "results.jsonl")}


def table(report: str, heading: str) -> list[list[str]]:
    """Rows (cells) of the first markdown table under ``## heading``, header excluded."""
    section = report.split(f"## {heading}\n", 1)[1].split("\n## ", 1)[0]
    rows = [r for r in section.splitlines() if r.startswith("|")]
    return [[c.strip() for c in r.strip("|").split("|")] for r in rows[2:]]


def percent(cell: str) -> float:
    return float(cell.rstrip(" %")) / 100.0


def interval(cell: str) -> tuple[float, float]:
    low, high = re.fullmatch(r"\[(.*) %, (.*) %\]", cell).groups()
    return float(low) / 100.0, float(high) / 100.0


def check_report(folder: Path) -> None:
    """report.md against results.jsonl, the Wilson interval against scipy's."""
    lines = list(lines_of(folder).values())
    report = (folder / "report.md").read_text()
    n, k = len(lines), sum(bool(x["success"]) for x in lines)
    rows = {r[0]: r for r in table(report, "Success rate")}
    _, episodes, delivered, rate, wilson = rows["all"]
    assert (int(episodes), int(delivered)) == (n, k)
    assert percent(rate) == pytest.approx(k / n, abs=5e-4)
    ref = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    assert interval(wilson) == pytest.approx((ref.low, ref.high), abs=5e-4)
    per_blocks = Counter(x["blocks"] for x in lines)
    for blocks, count in per_blocks.items():
        assert int(rows[str(blocks)][1]) == count
    failed = Counter(x["failure"] for x in lines if not x["success"])
    if failed:
        got = {r[0]: int(r[1]) for r in table(report, "Failure reasons")}
        assert got == dict(failed)
    else:
        assert "No episode failed." in report
    errors = [
        c["judgement"]["place_error_mm"]
        for x in lines
        for c in x["cycles"]
        if c.get("judgement") is not None
    ]
    if errors:
        (row,) = table(report, "Place error")
        assert int(row[0]) == len(errors)
        assert float(row[1]) == pytest.approx(np.percentile(errors, 50), abs=0.051)
        assert float(row[-1]) == pytest.approx(max(errors), abs=0.051)
    per_state = {r[0]: r for r in table(report, "Wall time per state")}
    for state in {v["state"] for x in lines for v in x["visits"]}:
        total = sum(v["wall_seconds"] for x in lines for v in x["visits"] if v["state"] == state)
        assert float(per_state[state][5]) == pytest.approx(total / n, abs=0.006)
    for name in FIGURES.values():
        img = cv2.imread(str(folder / name))
        assert img is not None and img.shape == (FIG_SIZE[1] * DPI, FIG_SIZE[0] * DPI, 3)


# --- the block count ------------------------------------------------------------------------------
def test_block_count_is_drawn_from_the_seed_alone_and_uniformly() -> None:
    seeds = range(3000)
    counts = [blocks_for_seed(s, 3, 5) for s in seeds]
    assert counts == [blocks_for_seed(s, 3, 5) for s in reversed(seeds)][::-1]
    assert counts[:5] == [int(np.random.default_rng([s, 12]).integers(3, 6)) for s in range(5)]
    freq = Counter(counts)
    assert set(freq) == {3, 4, 5}
    # each count 1/3 of the seeds, within 4 standard deviations of a binomial(3000, 1/3)
    assert all(abs(c - 1000) < 4 * np.sqrt(3000 * (1 / 3) * (2 / 3)) for c in freq.values())
    assert {blocks_for_seed(s, 4, 4) for s in range(20)} == {4}


# --- the results file -----------------------------------------------------------------------------
def test_results_file_keeps_whole_lines_and_drops_a_torn_one(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    append_line(path, {"seed": 3, "success": True})
    append_line(path, {"seed": 1, "success": False, "failure": "x"})
    with open(path, "a") as f:
        f.write('{"seed": 2, "succ')  # a writer killed mid-line
    assert [x["seed"] for x in read_results(path)] == [3, 1]
    assert drop_torn_tail(path) and not drop_torn_tail(path)
    append_line(path, {"seed": 2, "success": True})
    assert [x["seed"] for x in read_results(path)] == [3, 1, 2]
    path.write_text(path.read_text().replace('"seed":1', '"seed":"one"'))
    with pytest.raises(BenchError, match="line 2"):
        read_results(path)


# --- the report -----------------------------------------------------------------------------------
def _synthetic_lines() -> list[dict[str, Any]]:
    """Ten episodes with known outcomes: 7 delivered, 2 fingers that cannot reach, 1 crash;
    the even seeds delivered from the top, the odd ones from the side (seed 7 failed there)."""
    rng = np.random.default_rng(5)
    states = [s.value for s in State][:7]
    lines = []
    for seed in range(10):
        failure = {3: "fingers cannot reach", 7: "fingers cannot reach", 8: CRASHED}.get(seed)
        entered = states if failure is None else states[:3]
        lines.append(
            {
                "seed": seed,
                "blocks": 3 + seed % 3,
                "success": failure is None,
                "failure": failure,
                "failure_detail": "",
                "visits": [
                    {"state": s, "wall_seconds": float(rng.uniform(0.1, 5.0))} for s in entered
                ],
                "cycles": (
                    [{"approach": "lateral", "block_at_failure": {"knocked_over": True}}]
                    if seed == 7
                    else []
                )
                if failure
                else [
                    {
                        "approach": "lateral" if seed % 2 else "top",
                        "judgement": {"place_error_mm": float(rng.gamma(2.0, 2.0))},
                    }
                ],
                "sim_time": 30.0,
                "wall_time": 12.0,
            }
        )
    return lines


def test_report_numbers_match_the_results(tmp_path: Path) -> None:
    lines = _synthetic_lines()
    for line in lines:
        append_line(tmp_path / "results.jsonl", line)
    settings = {"scene": "random", "blocks": "3:5", "controller": "kb", "approach": "auto"}
    write_report(tmp_path, lines, settings)
    check_report(tmp_path)
    report = (tmp_path / "report.md").read_text()
    rows = {r[0]: r for r in table(report, "Failure reasons")}
    assert rows["fingers cannot reach"][4] == "3, 7" and rows[CRASHED][4] == "8"
    # seed 7's block was knocked over (its summary says so); seeds 3 and 8 have no cycle to
    # judge: unknown, never counted as upright
    assert rows["fingers cannot reach"][3] == "1 of 1 judged"
    assert rows[CRASHED][3] == "not judged"
    assert "--seeds 0:10 --blocks 3:5 --controller kb" in report
    split = {r[0]: r[1:3] for r in table(report, "Success rate") if "approach" in r[0]}
    assert split == {
        "lateral approach": ["4", "3"],
        "no approach chosen": ["2", "0"],
        "top approach": ["4", "4"],
    }
    s = summarize([*lines, dict(lines[0], success=False)])  # a seed's first line counts
    assert (s.episodes, s.successes) == (10, 7)


@pytest.mark.parametrize(("k", "n"), [(0, 10), (1, 10), (7, 10), (10, 10), (190, 200), (3, 1000)])
def test_wilson_interval_is_scipys(k: int, n: int) -> None:
    ref = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    w = wilson_interval(k, n)
    assert (w.low, w.high) == pytest.approx((ref.low, ref.high), abs=1e-12)
    assert w.estimate == k / n


@pytest.mark.parametrize("n", [1, 7, 29, 30, 31, 200, 997])
def test_wilson_interval_contains_the_estimate_at_the_ends(n: int) -> None:
    # every episode delivered (or none): p is an end of its interval, not a rounding error past it
    for k in (0, n):
        w = wilson_interval(k, n)
        assert w.low <= w.estimate <= w.high
    assert wilson_interval(n, n).high == 1.0 and wilson_interval(0, n).low == 0.0


def test_report_of_a_run_where_every_episode_was_delivered(tmp_path: Path) -> None:
    lines = [dict(line, success=True, failure=None) for line in _synthetic_lines()]
    for line in lines:
        line["cycles"] = [{"judgement": {"place_error_mm": 1.0 + line["seed"]}}]
        append_line(tmp_path / "results.jsonl", line)
    write_report(tmp_path, lines, {"scene": "random", "controller": "pi", "approach": "auto"})
    check_report(tmp_path)  # 10 of 10, "No episode failed."
    assert (tmp_path / FIGURES["success"]).stat().st_size > 0


def test_wilson_interval_textbook_value() -> None:
    # 0 successes in 10: the Wilson upper bound is 0.2775 (z = 1.96)
    assert wilson_interval(0, 10).high == pytest.approx(0.27753, abs=1e-5)


# --- bad input ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--seeds", "5:5"], "--seeds"),
        (["--seeds", "0-200"], "FIRST:END"),
        (["--seeds", "-1:4"], "--seeds"),
        (["--blocks", "0:3"], "--blocks"),
        (["--blocks", "5:3"], "LO:HI"),
        (["--blocks", "3:13"], "<= 12"),
        (["--scene", "clutter3", "--blocks", "3"], "random only"),
        (["--scene", "nowhere"], "unknown scene"),
        (["--workers", "0"], "--workers"),
        (["--controller", "xx"], "--controller"),
        (["--hand", "banana"], "--hand"),
        (["--lateral-gate", "0"], "positive S_G"),
        (["--lateral-gate", "wide"], "--lateral-gate"),
        (["--lateral-gate-rule", "thumb"], "--lateral-gate-rule"),
        (["--out", ""], "--out"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, message, tmp_path: Path, capsys) -> None:
    out = tmp_path / "o"
    args = [*argv, "--controller", CONTROLLER] if "--controller" not in argv else argv
    args = args if "--out" in argv else [*args, "--out", str(out)]
    assert bench.main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists() or not any(out.iterdir())


def test_the_hand_is_a_setting_of_the_bench_and_of_every_episode(tmp_path: Path) -> None:
    # the default is the Utah/MIT hand; results written before the hand was a setting were the
    # servo hand's, so a resume reads a missing hand as servo
    plan = bench.plan_from_args([*QUICK, "--seeds", "0:2", "--out", str(tmp_path / "o")])
    assert plan.settings["hand"] == "tendon" and {j.hand for j in plan.jobs} == {"tendon"}
    argv = [*QUICK, "--seeds", "0:2", "--hand", "servo", "--out", str(tmp_path / "t")]
    plan = bench.plan_from_args(argv)
    assert plan.settings["hand"] == "servo" and {j.hand for j in plan.jobs} == {"servo"}
    assert "hand" in bench.RESUME_KEYS and bench.SETTING_DEFAULTS["hand"] == "servo"


def test_the_lateral_gate_is_a_setting_of_the_bench_and_of_every_episode(
    tmp_path: Path, capsys
) -> None:
    """``--lateral-gate`` reaches every job and the bench's settings (a resume compares it, a
    folder from before it was a setting read as the paper's gate), and the report's command
    names it when it is not the paper's."""
    plan = bench.plan_from_args([*QUICK, "--seeds", "0:2", "--out", str(tmp_path / "o")])
    assert plan.settings["lateral_gate"] == 0.4 and {j.lateral_gate for j in plan.jobs} == {0.4}
    argv = [*QUICK, "--seeds", "0:2", "--lateral-gate", "0.6", "--out", str(tmp_path / "g")]
    plan = bench.plan_from_args(argv)
    assert plan.settings["lateral_gate"] == 0.6 and {j.lateral_gate for j in plan.jobs} == {0.6}
    assert "lateral_gate" in bench.RESUME_KEYS and bench.SETTING_DEFAULTS["lateral_gate"] == 0.4
    assert "--lateral-gate 0.6" in bench_report._command(plan.settings, range(0, 2))
    paper = {**plan.settings, "lateral_gate": 0.4}
    assert "--lateral-gate" not in bench_report._command(paper, [0])


def test_the_lateral_gate_rule_is_a_setting_of_the_bench_and_of_every_episode(
    tmp_path: Path,
) -> None:
    """``--lateral-gate-rule`` reaches every job and the bench's settings; a folder from before
    it was a setting ran the paper's rule (a resume reads it so, the report's command names
    it), and the default, opposition, is left out of the command."""
    plan = bench.plan_from_args([*QUICK, "--seeds", "0:2", "--out", str(tmp_path / "o")])
    assert plan.settings["lateral_gate_rule"] == "opposition"
    assert {j.lateral_gate_rule for j in plan.jobs} == {"opposition"}
    assert "--lateral-gate-rule" not in bench_report._command(plan.settings, [0])
    argv = [*QUICK, "--seeds", "0:2", "--lateral-gate-rule", "paper", "--out", str(tmp_path / "p")]
    plan = bench.plan_from_args(argv)
    assert {j.lateral_gate_rule for j in plan.jobs} == {"paper"}
    assert "lateral_gate_rule" in bench.RESUME_KEYS
    assert bench.SETTING_DEFAULTS["lateral_gate_rule"] == "paper"
    old = {k: v for k, v in plan.settings.items() if k != "lateral_gate_rule"}
    assert "--lateral-gate-rule paper" in bench_report._command(old, [0])


def test_a_controller_without_models_is_refused_before_anything_runs(tmp_path, capsys) -> None:
    models, out = tmp_path / "empty", tmp_path / "o"
    models.mkdir()
    argv = ["--controller", "ql", "--models", str(models), "--out", str(out)]
    assert bench.main(argv) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert "no trained" in err and not out.exists()


def test_ray_missing_is_one_line(tmp_path: Path, capsys, monkeypatch) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "ray" else real(name, *a)
    )
    argv = ["--ray", "local", "--controller", CONTROLLER, "--out", str(tmp_path / "o")]
    assert bench.main(argv) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert "--ray" in err and "graspsim[ray]" in err


@pytest.mark.e2e
def test_existing_results_need_resume_and_the_same_options(tmp_path: Path, capsys) -> None:
    lines = _synthetic_lines()
    for line in lines:
        append_line(tmp_path / "results.jsonl", line)
    settings = {
        "scene": "random",
        "blocks": "3:5",
        "controller": CONTROLLER,
        "approach": "auto",
        "grasp_model": "planar",
        "models": None,
        "cycles": "1",
        "place_fallback": "none",
    }
    (tmp_path / "bench.json").write_text(json.dumps(settings))
    before = (tmp_path / "results.jsonl").read_bytes()
    for argv, message in (
        ([*QUICK, "--seeds", "0:10"], "--resume"),
        ([*QUICK, "--seeds", "0:10", "--resume", "--approach", "top"], "--approach auto"),
        (["--seeds", "0:10", "--resume", "--controller", CONTROLLER], "--blocks 3:5"),
    ):
        assert bench.main([*argv, "--out", str(tmp_path)]) == 2
        (err,) = capsys.readouterr().err.strip().splitlines()
        assert message in err, err
    assert (tmp_path / "results.jsonl").read_bytes() == before
    # a folder of the planar model is not resumed on the default (3-D) model, named by its flag
    assert bench.main([*QUICK, "--seeds", "0:10", "--resume", "--out", str(tmp_path)]) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert "--model planar" in err, err
    # nor, written before the hand was a setting, on the default (tendon) hand
    argv = [*QUICK, "--seeds", "0:10", "--resume", "--model", "planar", "--out", str(tmp_path)]
    assert bench.main(argv) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert "--hand servo" in err, err
    # nor, written before the lateral gate's rule was a setting, on its default (opposition)
    argv = [*argv, "--hand", "servo"]
    assert bench.main(argv) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert "--lateral-gate-rule paper" in err, err
    # everything asked for is done: nothing runs, the report is rebuilt
    assert bench.main([*argv, "--lateral-gate-rule", "paper"]) == 0
    assert (tmp_path / "results.jsonl").read_bytes() == before
    check_report(tmp_path)


# --- real episodes --------------------------------------------------------------------------------
@pytest.mark.e2e
def test_a_bug_in_a_state_is_an_internal_error_with_its_recording(tmp_path, monkeypatch) -> None:
    def bug(ep):
        raise RuntimeError("a bug in Select/Model")

    monkeypatch.setitem(handlers.HANDLERS, State.SELECT_MODEL, bug)
    result = run_job(Job(seed=2, blocks=3, controller=CONTROLLER))
    line = result.line
    assert (line["seed"], line["blocks"], line["success"]) == (2, 3, False)
    assert line["failure"] == "internal error"
    assert "RuntimeError: a bug in Select/Model" in line["failure_detail"]
    assert "\n" not in line["failure_detail"] and "in bug" in line["traceback"]
    assert line["rrd"] == "rrd/seed-000002.rrd" and result.rrd is not None and len(result.rrd) > 0
    # the episode ran unrecorded, then again recorded for its .rrd, and ended the same way
    assert line["options"]["record"] is False and line["replay"] == {"recorded": True, "same": True}
    assert line["options"]["out"] is None and line["visits"][0]["state"] == "Select/Model"
    assert line["visits"][0]["next"] == "Failed"


def test_a_crash_outside_the_states_is_an_episode_crashed_line(monkeypatch) -> None:
    """An exception before the machine runs a state (here: the grasp controller cannot be made)
    is the bench's own last resort, ``episode crashed``, with the traceback."""
    import fsm.machine

    def broken(*args, **kwargs):
        raise RuntimeError("no composer today")

    monkeypatch.setattr(fsm.machine, "make_composer", broken)
    line = run_job(Job(seed=2, blocks=3, controller=CONTROLLER)).line
    assert (line["success"], line["failure"]) == (False, CRASHED)
    assert "RuntimeError: no composer today" in line["failure_detail"]
    assert "broken" in line["traceback"] and line["rrd"] is None


@pytest.fixture(scope="module")
def two_workers(tmp_path_factory) -> Path:
    """Seeds 0-2 (3 to 5 blocks each) in 2 worker processes, run once per test session: the
    workers of ``pytest -n`` share it through a lock (both cores are busy with it anyway)."""
    with session_lock(tmp_path_factory, "bench-two-workers") as root:
        out = root / "bench-two-workers"
        if not (out / "report.md").is_file():
            shutil.rmtree(out, ignore_errors=True)
            argv = [*QUICK, "--seeds", "0:3", "--workers", "2", "--out", str(out)]
            assert bench.main(argv) == 0
    return out


@pytest.mark.e2e
def test_two_workers_write_results_recordings_and_report(two_workers: Path) -> None:
    lines = lines_of(two_workers)
    assert sorted(lines) == [0, 1, 2]
    summary_keys = {"success", "failure", "failure_detail", "visits", "cycles", "sim_time"}
    for seed, line in lines.items():
        assert line["blocks"] == blocks_for_seed(seed, 3, 5)
        assert summary_keys <= set(line) and line["options"]["seed"] == seed
        assert line["options"]["blocks"] == line["blocks"]
        kept = sorted(p.name for p in (two_workers / "rrd").glob("*.rrd"))
        if line["success"]:  # judged physically: the block where it was asked to go
            assert line["cycles"][0]["judgement"]["place_error_mm"] < 20.0
            assert line["rrd"] is None and f"seed-{seed:06d}.rrd" not in kept
            assert "replay" not in line and line["options"]["record"] is False  # not recorded
        else:
            assert (two_workers / line["rrd"]).stat().st_size > 0
            assert line["replay"]["recorded"] and line["replay"]["same"]
    assert json.loads((two_workers / "bench.json").read_text())["blocks"] == "3:5"
    check_report(two_workers)
    assert not [p for p in two_workers.iterdir() if p.name.startswith(".")]


@pytest.mark.e2e
def test_resume_in_one_process_gives_the_two_workers_results(two_workers, tmp_path) -> None:
    """Seed 0 is kept, seeds 1 and 2 run one after the other in this process: the same lines as
    the 2-worker run, wall times aside."""
    out = tmp_path / "resumed"
    out.mkdir()
    shutil.copy(two_workers / "bench.json", out)
    first = (two_workers / "results.jsonl").read_text().splitlines(keepends=True)
    kept = next(x for x in first if json.loads(x)["seed"] == 0)
    (out / "results.jsonl").write_text(kept + '{"seed": 1, "succ')  # killed while appending seed 1
    argv = [*QUICK, "--seeds", "0:3", "--workers", "1", "--resume", "--out", str(out)]
    assert bench.main(argv) == 0
    text = (out / "results.jsonl").read_text()
    assert text.startswith(kept) and text.count("\n") == 3
    ours, theirs = lines_of(out), lines_of(two_workers)
    assert ours[0] == theirs[0]  # not run again
    for seed in (1, 2):
        assert without_wall_times(ours[seed]) == without_wall_times(theirs[seed])
    check_report(out)


@pytest.mark.skipif(
    importlib.util.find_spec("ray") is None,
    reason="ray is not installed (the optional extra: pip install -e '.[ray]')",
)
@pytest.mark.e2e
def test_ray_local_gives_the_same_results(two_workers: Path, tmp_path: Path) -> None:
    out = tmp_path / "ray"
    # one seed: what is checked is that Ray's path (its start, the task, the results file, the
    # report) gives the same line as the worker processes; a second seed only doubled the wait
    argv = [*QUICK, "--seeds", "1:2", "--ray", "local", "--workers", "2", "--out", str(out)]
    assert bench.main(argv) == 0
    ours, theirs = lines_of(out), lines_of(two_workers)
    assert sorted(ours) == [1]
    for seed in (1,):
        assert without_wall_times(ours[seed]) == without_wall_times(theirs[seed])
    check_report(out)
