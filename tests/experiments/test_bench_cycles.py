"""The bench's count of outcomes (issue 22): an episode delivered elsewhere (``--place-fallback
nearest``) is counted apart and never in the success rate; with ``--cycles`` the report counts the
blocks delivered, delivered elsewhere and failed per cycle, and the share of tables cleared. The
numbers are checked against counts made here from hand-written results lines, and the flags
against bad input."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from scipy.stats import binomtest

from experiments.bench import cli as bench
from experiments.bench.report import write_report
from experiments.bench.stats import DELIVERED, ELSEWHERE, FAILED, outcome, summarize
from tests.experiments.test_bench import interval, percent, table


def _cycle(success: bool, elsewhere: bool = False) -> dict[str, Any]:
    return {
        "success": success,
        "delivered_elsewhere": elsewhere,
        "judgement": {"place_error_mm": 2.0} if success else None,
    }


def _line(seed: int, blocks: int, cycles: list[dict[str, Any]], failure: str | None) -> dict:
    return {
        "seed": seed,
        "blocks": blocks,
        "success": failure is None,
        "failure": failure,
        "failure_detail": "",
        "visits": [{"state": "Select/Model", "wall_seconds": 1.0}],
        "cycles": cycles,
        "sim_time": 10.0,
        "wall_time": 5.0,
    }


#: seed: (blocks, cycles, failure). Seeds 0-1 clear their tables where asked, seed 2 clears it
#: with its first block elsewhere, seed 3 fails in cycle 1, seed 4 in cycle 0, seed 5 in cycle 2
#: after a block elsewhere in cycle 1.
LINES = [
    _line(0, 3, [_cycle(True), _cycle(True), _cycle(True)], None),
    _line(1, 2, [_cycle(True), _cycle(True)], None),
    _line(2, 2, [_cycle(True, True), _cycle(True)], None),
    _line(3, 3, [_cycle(True), _cycle(False)], "block dropped in transport"),
    _line(4, 3, [], "polygon not modelled"),
    _line(5, 4, [_cycle(True), _cycle(True, True)], "internal error"),
]


def test_outcomes_keep_delivered_elsewhere_out_of_the_success_rate() -> None:
    assert [outcome(x) for x in LINES] == [
        DELIVERED,
        DELIVERED,
        ELSEWHERE,
        FAILED,
        FAILED,
        FAILED,
    ]
    s = summarize(LINES)
    assert (s.episodes, s.successes, s.elsewhere) == (6, 2, 1)
    assert s.rate.estimate == pytest.approx(2 / 6)
    assert {f.reason: f.seeds for f in s.failures} == {
        "block dropped in transport": (3,),
        "polygon not modelled": (4,),
        "internal error": (5,),
    }
    # per cycle, counted by hand from LINES: (reached, delivered, elsewhere, failed)
    got = [(r.cycle, r.reached, r.delivered, r.elsewhere, r.failed) for r in s.cycles]
    assert got == [(0, 6, 4, 1, 1), (1, 5, 3, 1, 1), (2, 2, 1, 0, 1)]
    assert s.tables_cleared == 3  # seeds 0, 1 and 2 (elsewhere, but every block delivered)


def test_report_shows_elsewhere_cycles_and_tables_cleared(tmp_path: Path) -> None:
    settings = {
        "scene": "random",
        "blocks": "2:4",
        "controller": "kb",
        "approach": "auto",
        "cycles": "all",
        "place_fallback": "nearest",
    }
    write_report(tmp_path, LINES, settings)
    report = (tmp_path / "report.md").read_text()
    assert "--cycles all --place-fallback nearest" in report
    _, episodes, delivered, rate, wilson = {r[0]: r for r in table(report, "Success rate")}["all"]
    assert (int(episodes), int(delivered)) == (6, 2)
    assert percent(rate) == pytest.approx(2 / 6, abs=5e-4)
    ref = binomtest(2, 6).proportion_ci(confidence_level=0.95, method="wilson")
    assert interval(wilson) == pytest.approx((ref.low, ref.high), abs=5e-4)
    assert "Delivered elsewhere: 1. Failed: 3." in report
    rows = table(report, "Cycles")
    assert rows == [
        ["0", "6", "4", "1", "1"],
        ["1", "5", "3", "1", "1"],
        ["2", "2", "1", "0", "1"],
    ]
    assert "Tables cleared (every block of the scene delivered): 3 of 6 (50.0 %)" in report
    failures = {r[0]: int(r[1]) for r in table(report, "Failure reasons")}
    assert failures == {
        "block dropped in transport": 1,
        "polygon not modelled": 1,
        "internal error": 1,
    }


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--cycles", "0"], "--cycles"),
        (["--cycles", "some"], "'all'"),
        (["--cycles", "51"], "1-50"),
        (["--place-fallback", "farthest"], "--place-fallback"),
    ],
)
def test_bad_cycles_or_fallback_is_one_line_and_exit_2(argv, message, tmp_path, capsys) -> None:
    out = tmp_path / "o"
    assert bench.main([*argv, "--controller", "kb", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists() or not any(out.iterdir())


def test_results_judged_by_the_old_rule_are_not_resumed(tmp_path: Path, capsys) -> None:
    """A bench folder written before --cycles and --place-fallback existed holds episodes whose
    place point could move unreported: --resume refuses to add strict episodes to them."""
    import json

    from experiments.bench.jobs import append_line

    append_line(tmp_path / "results.jsonl", LINES[0])
    old = {"scene": "random", "blocks": "2:4", "controller": "kb", "approach": "auto"}
    (tmp_path / "bench.json").write_text(json.dumps({**old, "models": None}))
    before = (tmp_path / "results.jsonl").read_bytes()
    argv = ["--blocks", "2:4", "--controller", "kb", "--seeds", "0:2", "--resume"]
    assert bench.main([*argv, "--out", str(tmp_path)]) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert "--resume" in err and "old rule" in err, err
    assert (tmp_path / "results.jsonl").read_bytes() == before
