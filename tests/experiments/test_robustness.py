"""``python -m experiments.robustness`` (section 5.3's woes): bad input is refused before anything
runs, and ``run`` benches a perturbation and reports what its episodes' results say, counted
here again from the bench's own ``results.jsonl``."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest
from scipy.stats import binomtest

from experiments.robustness import cli as robustness


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["run", "--perturb", "gravity"], "unknown or repeated perturbation"),
        (["run", "--perturb", "camera,camera"], "unknown or repeated perturbation"),
        (["run", "--scales", "0"], "must be numbers in (0, 4]"),
        (["run", "--scales", "1,big"], "must be numbers in (0, 4]"),
        (["report", "no-such-folder"], "is not a bench folder"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_nothing_written(
    argv: list[str], message: str, tmp_path: Path, capsys
) -> None:
    out = tmp_path / "out"
    assert robustness.main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()


@pytest.mark.e2e
def test_run_benches_the_perturbation_and_reports_its_episodes(tmp_path: Path) -> None:
    out = tmp_path / "robustness"
    argv = ["run", "--perturb", "object", "--scales", "1", "--seeds", "1:2", "--workers", "1"]
    assert robustness.main([*argv, "--out", str(out)]) == 0
    bench = out / "object=1"
    (line,) = [json.loads(raw) for raw in (bench / "results.jsonl").read_text().splitlines()]
    drawn = line["perturbation"]
    masses = drawn["object"]["mass_factors"]
    assert drawn["asked"] == "object=1" and len(masses) == line["blocks"]
    assert any(abs(m - 1.0) > 1e-3 for m in masses.values())
    assert line["success"] or line["failure"]  # delivered, or a named failure
    (row,) = json.loads((out / "summary.json").read_text())
    assert (row["perturbation"], row["scale"], row["episodes"]) == ("object", 1.0, 1)
    assert row["delivered"] == int(bool(line["success"]))
    ci = binomtest(row["delivered"], 1).proportion_ci(confidence_level=0.95, method="wilson")
    assert row["wilson95"] == pytest.approx([ci.low, ci.high])
    assert "| object | 1 | 1 |" in (out / "report.md").read_text()
    figure = cv2.imread(str(out / "success_vs_scale.png"))
    assert figure is not None and figure.shape[0] > 200 and figure.std() > 0
