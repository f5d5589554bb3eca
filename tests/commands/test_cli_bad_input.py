"""Every command keeps its promise on bad input (issue 10): one line on stderr that names the flag
or field and what is wrong, exit status 2, no traceback, nothing written.

The tables list, per command, the inputs of issue 10 and more. They run in-process through each
command's ``main(argv)`` (cheap: most fail while parsing); ``test_entry_points_exit_2`` runs one
case per command as a real process, to check the ``python -m`` wiring and the exit status.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from benchmarks import (
    arm_reach,
    bench_grasp,
    bench_lateral_search,
    bench_parallel,
    bench_reach,
    bench_sim,
    hand_reachability,
)
from controllers.grasp import cli as grasp_cli
from experiments.paper import cli as paper_cli
from hand_sim import show
from vision import bench as vision_bench
from vision.__main__ import main as vision_main

SQUARE = "0,0;2,0;2,2;0,2"
BOWTIE = "0,0;1,1;1,0;0,1"  # self-intersecting, zero signed area

# A valid scene, for the scene-file cases below (1e300 and a non-UTF-8 byte are patched in).
SCENE = """target = "a"
place = [0.0, -0.2]
[[blocks]]
name = "a"
vertices = [[0.0, 0.0], [0.04, 0.0], [0.0, 0.03]]
position = [0.0, 0.0]
"""


@pytest.fixture
def files(tmp_path: Path) -> dict[str, str]:
    """Paths the cases refer to as {name}: an existing file and folder, bad scene files."""
    (tmp_path / "afile").write_text("x")
    (tmp_path / "adir").mkdir()
    (tmp_path / "huge.toml").write_text(SCENE.replace("0.04, 0.0]", "1e300, 0.0]"))
    (tmp_path / "huge_int.toml").write_text(SCENE.replace("0.04, 0.0]", "9223372036854775807, 0]"))
    (tmp_path / "latin1.toml").write_bytes(SCENE.replace('"a"', '"\xe9"', 1).encode("latin-1"))
    (tmp_path / "bowtie.toml").write_text(
        SCENE.replace(
            "[[0.0, 0.0], [0.04, 0.0], [0.0, 0.03]]", "[[0,0],[0.03,0.03],[0.03,0],[0,0.03]]"
        )
    )
    return {
        "tmp": str(tmp_path),
        "afile": str(tmp_path / "afile"),
        "adir": str(tmp_path / "adir"),
        "huge": str(tmp_path / "huge.toml"),
        "huge_int": str(tmp_path / "huge_int.toml"),
        "latin1": str(tmp_path / "latin1.toml"),
        "bowtie": str(tmp_path / "bowtie.toml"),
    }


# python -m controllers.grasp: (argv, fragment of the one stderr line)
GRASP_CASES = [
    # paths that cannot be written: checked before the trials run
    (["trials", "--trials", "5", "--json", "/proc/x/out.json"], "--json: cannot write into"),
    (["trials", "--trials", "5", "--json", "{adir}"], "argument --json: '{adir}' is a folder"),
    (["trials", "--trials", "5", "--json", "{afile}/r.json"], "--json: cannot write into"),
    (["trials", "--trials", "5", "--json", "{tmp}/r.txt"], "argument --json: must end in .json"),
    (["trials", "--json", ""], "argument --json: must name a file"),
    # polygons: empty, huge, malformed, self-intersecting, non-convex, degenerate
    (["trials", "--polygon", ""], "--polygon must be written 'x,y;x,y;...'"),
    (["trials", "--polygon", "1e300,0;0,1;1,1"], "--polygon: coordinates must be finite"),
    (["trials", "--polygon", "nan,0;0,1;1,1"], "--polygon: coordinates must be finite"),
    (["trials", "--polygon", "0,0;1"], "--polygon must be written"),
    (["trials", "--polygon", "a,b;c,d;e,f"], "--polygon must be written"),
    (["trials", "--polygon", BOWTIE], "--polygon: polygon 'user' is self-intersecting"),
    (["trials", "--polygon", "0,0;2,0;1,0.2;1,2"], "--polygon: polygon 'user' is not convex"),
    (["trials", "--polygon", "0,0;1,1;2,2"], "collinear"),
    (["trials", "--polygon", "0,0;1,0"], "at least 3 vertices"),
    (["trials", "--polygon", "0,0;1,0;1,0;0,1"], "repeats vertex"),
    (["trials", "--polygon", "0,0;1e-12,0;0,1e-12"], "less than 1e-09"),
    # numbers: gain, trials, rotation, seed, contacts, steps
    (
        ["trials", "--controller", "pi", "--gain", "0"],
        "argument --gain: must be a number in (0, 10]",
    ),
    (["trials", "--gain", "-1"], "argument --gain: must be a number in (0, 10]"),
    (["trials", "--gain", "nan"], "argument --gain: must be a number in (0, 10]"),
    (["trials", "--gain", "inf"], "argument --gain: must be a number in (0, 10]"),
    (["trials", "--trials", "1e9"], "argument --trials: must be an integer from 1 to 100,000"),
    (["trials", "--trials", "1000000000"], "argument --trials: must be an integer from 1"),
    (["trials", "--trials", "0"], "argument --trials"),
    (["trials", "--rotate", "nan"], "argument --rotate: must be a number in [-360, 360]"),
    (["trials", "--rotate", "1e300"], "argument --rotate"),
    (["trials", "--seed", "-1"], "argument --seed: must be an integer from 0"),
    (["trials", "--seed", "x"], "argument --seed"),
    (["trials", "--contacts", "1"], "argument --contacts: must be an integer from 2 to 16"),
    (["trials", "--max-steps", "0"], "argument --max-steps"),
    # names and models
    (["trials", "--object", "circle"], "unknown object 'circle'; valid:"),
    (
        ["trials", "--controller", "magic"],
        "unknown controller 'magic'; valid: kb, pi, pi5, pi9, ql",
    ),
    (["trials", "--controller", "ql", "--models", "{adir}"], "--models: {adir} holds no reproduce"),
    (["trials", "--controller", "pi", "--models", "{tmp}/none"], "there is no folder"),
    (["trials", "--controller", "pi", "--models", "{afile}"], "is not a folder"),
    (["trials", "--bogus"], "unrecognized arguments: --bogus"),
    # score
    (["score", "--polygon", SQUARE, "--points", "2,1;0,1", "--task", "nan,0,0"], "argument --task"),
    (["score", "--polygon", SQUARE, "--points", "2,1;0,1", "--task", "1,2"], "3 or 6 finite"),
    # score, 3-D points (x,y,z on the prism of --height)
    (["score", "--polygon", SQUARE, "--points", "1,0,0.5"], "--height: points with three"),
    (["score", "--polygon", SQUARE, "--points", "1,0", "--height", "1"], "--height: applies to"),
    (["score", "--polygon", SQUARE, "--points", "1,0,2", "--height", "1"], "not on the prism's"),
    (["score", "--polygon", SQUARE, "--points", "1,1,0", "--height", "1"], "not on the prism's"),
    (["score", "--polygon", SQUARE, "--points", "1,0,1", "--height", "0"], "argument --height"),
    (["score", "--polygon", SQUARE, "--points", "1,0,1", "--height", "nan"], "argument --height"),
    (["score", "--polygon", SQUARE, "--points", "1,0;1,0,1"], "the same two or three numbers"),
    (["score", "--polygon", SQUARE, "--points", "1,0", "--task", "1,2,3,4,5,6"], "take 3 numbers"),
    (
        ["score", "--polygon", SQUARE, "--points", "1,0,1", "--height", "2", "--task", "0,0,1"],
        "the 3-D model takes 6 numbers",
    ),
    (["score", "--polygon", SQUARE, "--points", "2,1;0,1", "--task", "1e9,0,0"], "[-1e+06, 1e+06]"),
    (["score", "--polygon", SQUARE, "--points", "nan,nan;0,1"], "--points: coordinates must be"),
    (["score", "--polygon", SQUARE, "--points", "1,1;2,1"], "--points: point 0 (1.0, 1.0) is"),
    (["score", "--polygon", SQUARE, "--points", ""], "--points must be written"),
    (["score", "--polygon", "0,0;1,0", "--points", "0,0"], "--polygon: a polygon needs at least"),
    (["score", "--polygon", BOWTIE, "--points", "0,0"], "self-intersecting"),
    (["score", "--polygon", SQUARE, "--points", "2,1;0,1", "--json", "/proc/x.json"], "--json"),
    (["score", "--polygon", SQUARE], "the following arguments are required: --points"),
    ([], "the following arguments are required: COMMAND"),
]

# python -m experiments.paper
PAPER_CASES = [
    # table1
    (["table1", "--trials", "0"], "argument --trials"),
    (["table1", "--gain", "0"], "argument --gain"),
    (["table1", "--json", "/"], "argument --json: '/' is a folder"),
    # reproduce: output folders
    (["reproduce", "--out", ""], "argument --out: must name a folder, got an empty string"),
    (["reproduce", "--out", "/"], "argument --out: will not write into the root folder"),
    (["reproduce", "--out", "{afile}"], "argument --out: '{afile}' is a file, not a folder"),
    (["reproduce", "--out", "/proc/x"], "--out: cannot write into '/proc/x'"),
    (["reproduce", "--out", "{tmp}/r", "--seeds", "-1"], "argument --seeds"),
    (["reproduce", "--out", "{tmp}/r", "--seeds", "0,x"], "argument --seeds"),
    (["reproduce", "--out", "{tmp}/r", "--seeds", "1,1"], "distinct seeds"),
    (["reproduce", "--out", "{tmp}/r", "--workers", "0"], "argument --workers"),
    (["reproduce"], "the following arguments are required: --out"),
    ([], "the following arguments are required: COMMAND"),
]

# python -m hand_sim.show
SHOW_CASES = [
    (["--out", ""], "argument --out: must name a folder"),
    (["--out", "/"], "argument --out: will not write into the root folder"),
    (["--out", "{afile}"], "is a file, not a folder"),
    (["--out", "/proc/x"], "--out: cannot write into '/proc/x'"),
    (["--out", "{tmp}/o", "--seed", "-1"], "argument --seed: must be an integer from 0"),
    (["--out", "{tmp}/o", "--seed", "x"], "argument --seed: must be an integer from 0"),
    (["--out", "{tmp}/o", "--blocks", "2"], "--blocks: applies to --scene random only"),
    (["--out", "{tmp}/o", "--scene", "random", "--blocks", "99"], "argument --blocks"),
    (["--out", "{tmp}/o", "--width", "0"], "argument --width: must be an integer from 16 to 1,920"),
    (["--out", "{tmp}/o", "--height", "1e9"], "argument --height"),
    (["--out", "{tmp}/o", "--scene", "clutter9"], "unknown scene 'clutter9'; valid:"),
    (["--out", "{tmp}/o", "--scene", "{huge}"], "blocks[0].vertices: polygon coordinates must be"),
    (["--out", "{tmp}/o", "--scene", "{huge_int}"], "blocks[0].vertices: polygon coordinates"),
    (["--out", "{tmp}/o", "--scene", "{latin1}"], "not UTF-8 text"),
    (["--out", "{tmp}/o", "--scene", "{bowtie}"], "blocks[0].vertices: polygon 'a' is self-inter"),
    (["--out", "{tmp}/o", "--scene", "{tmp}/none.toml"], "scene file not found"),
    ([], "the following arguments are required: --out"),
]

# python -m vision (no case renders: each fails before)
VISION_CASES = [
    (["--pick-pixel", "nan,nan"], "argument --pick-pixel: must be 2 finite numbers"),
    (["--pick-pixel", "inf,0"], "argument --pick-pixel"),
    (["--pick-pixel", "-1,-1"], "--pick-pixel: (-1, -1) is outside the 1920x1440 image"),
    (["--pick-pixel", "640,480", "--width", "640", "--height", "480"], "outside the 640x480"),
    (["--pick-pixel", "1,2,3"], "argument --pick-pixel"),
    (["--near", "nan,0"], "argument --near: must be 2 finite numbers"),
    (["--near", "1e300,0"], "--near: (1e+300, 0) is off the table top: x must be in [-0.45, 0.45]"),
    (["--near", "0.5,0"], "--near: (0.5, 0) is off the table top"),
    (["--name", "x", "--seed", "-1"], "argument --seed: must be an integer from 0"),
    (["--name", "x", "--blocks", "3"], "--blocks: applies to --scene random only"),
    (["--name", "x", "--width", "0"], "argument --width"),
    (["--name", "x", "--overlay", "{tmp}/pick"], "argument --overlay: must end in .png or .jpg"),
    (["--name", "x", "--overlay", "{adir}"], "argument --overlay: '{adir}' is a folder"),
    (["--name", "x", "--overlay", "/proc/x/o.png"], "--overlay: cannot write into '/proc/x'"),
    (["--name", "x", "--scene", "nope"], "unknown scene 'nope'"),
    (["--name", "x", "--scene", "{latin1}"], "not UTF-8 text"),
    ([], "one of the arguments --pick-pixel --name --near is required"),
    (["--name", "x", "--near", "0,0"], "not allowed with argument"),
]

# python -m vision.bench
VISION_BENCH_CASES = [
    (["--trials", "0"], "argument --trials: must be an integer from 1 to 10,000"),
    (["--trials", "1e9"], "argument --trials"),
    (["--seed", "-1"], "argument --seed"),
    (["--width", "0"], "argument --width"),
    (["--shapes", "circles"], "argument --shapes: invalid choice: 'circles'"),
]

# python -m benchmarks.*
BENCHMARK_CASES = [
    (bench_grasp.main, ["--trials", "0"], "argument --trials"),
    (bench_grasp.main, ["--repeats", "x"], "argument --repeats"),
    (bench_lateral_search.main, ["--repeats", "0"], "argument --repeats"),
    (bench_sim.main, ["--seconds", "nan"], "argument --seconds: must be a number in (0, 600]"),
    (bench_sim.main, ["--width", "-5"], "argument --width"),
    (bench_sim.main, ["--scene", "nope"], "unknown scene 'nope'"),
    (bench_reach.main, ["--resolutions", "0"], "argument --resolutions: must be an integer from 4"),
    (bench_reach.main, ["--blocks", "99"], "argument --blocks"),
    (bench_reach.main, ["--random", "-1"], "argument --random"),
    (bench_reach.main, ["--scene", "nope"], "unknown scene 'nope'"),
    (arm_reach.main, ["--step", "0"], "argument --step: must be a number in [0.01, 0.45]"),
    (arm_reach.main, ["--step", "nan"], "argument --step"),
    (hand_reachability.main, ["--objects", "circle"], "argument --objects: invalid choice"),
    (hand_reachability.main, ["--seed", "-1"], "argument --seed"),
    (hand_reachability.main, ["--samples", "0"], "argument --samples"),
    (bench_parallel.main, ["--workers", "1"], "argument --workers"),
    (bench_parallel.main, ["--seeds", "4:4"], "argument --seeds"),
]


def check_one_line(
    main: Callable[[list[str]], int],
    argv: list[str],
    fragment: str,
    files: dict[str, str],
    capsys: pytest.CaptureFixture[str],
) -> None:
    argv = [a.format(**files) for a in argv]
    status = main(argv)
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert status == 2, (argv, err)
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert fragment.format(**files) in lines[0], (fragment, lines[0])


def no_output(files: dict[str, str]) -> None:
    """Nothing was written: the tmp folder holds only the fixture's files."""
    expected = {"afile", "adir", "huge.toml", "huge_int.toml", "latin1.toml", "bowtie.toml"}
    assert {p.name for p in Path(files["tmp"]).iterdir()} == expected


@pytest.mark.parametrize(("argv", "fragment"), GRASP_CASES)
def test_grasp_cli(argv, fragment, files, capsys) -> None:
    check_one_line(grasp_cli.main, argv, fragment, files, capsys)
    no_output(files)


@pytest.mark.parametrize(("argv", "fragment"), PAPER_CASES)
def test_paper_cli(argv, fragment, files, capsys) -> None:
    check_one_line(paper_cli.main, argv, fragment, files, capsys)
    no_output(files)


@pytest.mark.parametrize(("argv", "fragment"), SHOW_CASES)
def test_hand_sim_show(argv, fragment, files, capsys) -> None:
    check_one_line(show.main, argv, fragment, files, capsys)
    no_output(files)


@pytest.mark.parametrize(("argv", "fragment"), VISION_CASES)
def test_vision(argv, fragment, files, capsys) -> None:
    check_one_line(vision_main, ["--scene", "clutter3", *argv], fragment, files, capsys)
    no_output(files)


@pytest.mark.parametrize(("argv", "fragment"), VISION_BENCH_CASES)
def test_vision_bench(argv, fragment, files, capsys) -> None:
    check_one_line(vision_bench.main, argv, fragment, files, capsys)


@pytest.mark.parametrize(("main", "argv", "fragment"), BENCHMARK_CASES)
def test_benchmarks(main, argv, fragment, files, capsys) -> None:
    check_one_line(main, argv, fragment, files, capsys)


# The README's forms with negative numbers, as printed there: they run.
def test_negative_numbers_work_as_option_values(capsys) -> None:
    square = "-1,-1;1,-1;1,1;-1,1"
    assert grasp_cli.main(["score", "--polygon", square, "--points", "1,0;-1,0"]) == 0
    assert "S_G = 0.0000" in capsys.readouterr().out
    tri = "-0.02,-0.01;0.02,-0.01;0,0.02"
    assert grasp_cli.main(["trials", "--polygon", tri, "--trials", "5", "--rotate", "-30"]) == 0
    assert capsys.readouterr().out.startswith("user: 5 trials")


ENTRY_POINTS = [
    (["controllers.grasp", "trials", "--controller", "pi", "--gain", "0"], "--gain"),
    (["controllers.grasp", "score", "--polygon", BOWTIE, "--points", "0,0"], "self-intersecting"),
    (["hand_sim.show", "--out", ""], "--out"),
    (["vision", "--scene", "clutter3", "--pick-pixel", "nan,nan"], "--pick-pixel"),
    (["vision.bench", "--trials", "1e9"], "--trials"),
    (["benchmarks.bench_grasp", "--trials", "0"], "--trials"),
    (["benchmarks.bench_sim", "--seconds", "nan"], "--seconds"),
    (["benchmarks.bench_reach", "--resolutions", "0"], "--resolutions"),
    (["benchmarks.arm_reach", "--step", "0"], "--step"),
    (["benchmarks.hand_reachability", "--objects", "circle"], "--objects"),
    (["experiments.bench", "--seeds", "0:0"], "--seeds"),
]


def test_entry_points_exit_2() -> None:
    """Each ``python -m`` entry point, as a process: exit status 2 and one stderr line."""
    env = {**os.environ, "MUJOCO_GL": "egl"}
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", *argv],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
        )
        for argv, _ in ENTRY_POINTS
    ]
    for (argv, fragment), p in zip(ENTRY_POINTS, procs, strict=True):
        out, err = p.communicate(timeout=120)
        lines = err.strip().splitlines()
        assert p.returncode == 2, (argv, err)
        assert len(lines) == 1 and fragment in lines[0] and "Traceback" not in err, (argv, err)
        assert out == ""
