"""``--perturb NAME[=SCALE],...`` on ``fsm.run``, ``experiments.bench`` and
``experiments.physics`` keeps the command contract: a bad value is one line on stderr naming the
valid perturbations, exit status 2, nothing written; a good one reaches the episode's options
(and, for the bench, every job and the settings a resume compares)."""

from __future__ import annotations

from pathlib import Path

import pytest

from experiments.bench import cli as bench
from experiments.bench import report as bench_report
from experiments.physics import cli as physics
from fsm import run as fsm_run

CASES = [
    ("lens", "unknown perturbation 'lens'; valid: camera, arm_base, kinematics, object"),
    ("camera=7", "camera: scale must be a number from 0 to 4, got '7'"),
    ("camera=x", "camera: scale must be a number from 0 to 4"),
    ("camera,camera", "camera is named twice"),
    ("", "empty name"),
]


def _one_line(main, argv: list[str], fragment: str, tmp: Path, capsys) -> None:
    status = main(argv)
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert status == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert "--perturb" in lines[0] and fragment in lines[0], lines[0]
    assert not any(tmp.iterdir()), "nothing is written"


@pytest.mark.parametrize(("value", "fragment"), CASES)
def test_fsm_run_refuses(value: str, fragment: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    _one_line(fsm_run.main, ["--perturb", value, "--out", str(out)], fragment, tmp_path, capsys)


@pytest.mark.parametrize(("value", "fragment"), CASES)
def test_bench_refuses(value: str, fragment: str, tmp_path: Path, capsys) -> None:
    argv = ["--perturb", value, "--seeds", "0:1", "--out", str(tmp_path / "b")]
    _one_line(bench.main, argv, fragment, tmp_path, capsys)


@pytest.mark.parametrize(
    ("value", "fragment"),
    [
        (
            "camera",
            "unknown perturbation 'camera' for this command; valid: object, sensing, actuation",
        ),
        ("woes", "unknown perturbation 'woes' for this command; valid: object"),
        ("lens", "unknown perturbation 'lens'; valid: object, sensing, actuation"),
        ("object=9", "object: scale must be a number from 0 to 4"),
    ],
)
def test_physics_refuses_what_a_held_grasp_cannot_have(
    value: str, fragment: str, tmp_path: Path, capsys
) -> None:
    argv = ["--perturb", value, "--out", str(tmp_path / "p")]
    _one_line(physics.main, argv, fragment, tmp_path, capsys)


def test_values_reach_the_options(tmp_path: Path) -> None:
    opts = fsm_run.options_from_args(
        ["--perturb", "object=2,camera", "--out", str(tmp_path / "r"), "--no-record"]
    )
    assert opts.perturb == "camera=1,object=2"
    assert fsm_run.options_from_args(["--out", str(tmp_path / "s")]).perturb is None
    plan = bench.plan_from_args(
        ["--perturb", "woes=0.5", "--seeds", "0:2", "--out", str(tmp_path / "b"), "--workers", "1"]
    )
    expected = "camera=0.5,arm_base=0.5,kinematics=0.5,object=0.5,sensing=0.5,actuation=0.5"
    assert plan.settings["perturb"] == expected and {j.perturb for j in plan.jobs} == {expected}
    assert "perturb" in bench.RESUME_KEYS and bench.SETTING_DEFAULTS["perturb"] is None
    assert f"--perturb {expected}" in bench_report._command(plan.settings, range(0, 2))
    args = physics.build_parser().parse_args(["--out", "x", "--perturb", "object"])
    assert args.perturb == "object=1"


def test_help_names_the_perturbations(capsys) -> None:
    text = " ".join(fsm_run.parser().format_help().split())
    assert "--perturb NAME[=SCALE],..." in text and "camera, arm_base, kinematics" in text
    assert "woes" in text and "none: unperturbed" in text
