"""The grasp model each command runs by default, and the physical study's help saying why its
default differs from the task cycle's: the study measures the paper's planar model (section 3),
the task cycle runs the 3-D one."""

from __future__ import annotations

from experiments.physics.cli import build_parser as physics_parser
from fsm.context import DEFAULT_GRASP_MODEL
from fsm.run import parser as run_parser


def test_the_task_cycle_runs_3d_and_the_physical_study_planar() -> None:
    assert DEFAULT_GRASP_MODEL == "3d"
    assert run_parser().parse_args([]).model == "3d"
    assert physics_parser().parse_args(["--out", "x"]).model == "planar"


def test_the_physical_study_help_says_why_its_default_differs() -> None:
    text = " ".join(physics_parser().format_help().split())
    assert "differs from the task cycle's" in text and "paper's own model" in text
    assert "--model 3d tests the task cycle's model" in text
