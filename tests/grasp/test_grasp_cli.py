"""The grasp core's command line: JSON results that agree with themselves, errors as one line."""

import json
import subprocess
import sys

import numpy as np
import pytest

from controllers.grasp import grasp_score, paper_object


def run(*args):
    return subprocess.run(
        [sys.executable, "-m", "controllers.grasp", *args], capture_output=True, text=True
    )


def test_trials_json_is_consistent(tmp_path):
    out = tmp_path / "r.json"
    p = run("trials", "--object", "square", "--trials", "60", "--seed", "3", "--json", str(out))
    assert p.returncode == 0, p.stderr
    data = json.loads(out.read_text())
    trials = data["trials"]
    assert len(trials) == 60
    assert data["summary"]["failure_rate"] == pytest.approx(
        1 - np.mean([t["success"] for t in trials])
    )
    assert f"{100 * data['summary']['failure_rate']:.2f} %" in p.stdout
    # re-score one trial's final points independently: the JSON's S_G is the metric's
    poly = paper_object("square")
    unit = poly.unit_moment()
    t = next(t for t in trials if t["feasible"])
    frames = unit.locate(np.array(t["theta_final"]))
    assert np.allclose(
        np.array(t["points"]), poly.locate(np.array(t["theta_final"])).point, atol=1e-9
    )
    assert grasp_score(frames.point, frames.normal).s_g == pytest.approx(t["s_g"], abs=1e-6)
    assert t["success"] == (t["s_g"] <= 0.4)


def test_trials_on_a_user_polygon_rotated():
    p = run(
        "trials",
        "--polygon",
        "0,0;3,0;3,1;0,1",
        "--rotate",
        "30",
        "--trials",
        "20",
        "--contacts",
        "3",
    )
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("user: 20 trials")


def test_score_command():
    p = run("score", "--polygon", "0,0;2,0;2,2;0,2", "--points", "2,1;1,2")
    assert p.returncode == 0 and "S_G = 1.0000" in p.stdout and "failure" in p.stdout
    p = run("score", "--polygon", "0,0;2,0;2,2;0,2", "--points", "2,1.5;2,0.5")
    assert p.returncode == 0 and "infeasible" in p.stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("trials", "--object", "circle"), "unknown object 'circle'"),
        (("trials", "--polygon", "0,0;2,0;1,0.2;1,2"), "not convex"),
        (("trials", "--controller", "magic"), "unknown controller 'magic'"),
        (
            ("score", "--polygon", "0,0;2,0;2,2;0,2", "--points", "1,1;2,1"),
            "away from the polygon outline",
        ),
        (("score", "--polygon", "0,0;1,0", "--points", "0,0"), "at least 3 vertices"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(args, message):
    p = run(*args)
    assert p.returncode == 2
    assert message in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1


def _score_json(tmp_path, vertices, points):
    out = tmp_path / "s.json"
    fmt = ";".join  # repr keeps every bit of a float
    p = run(
        "score",
        "--polygon=" + fmt(f"{float(x)!r},{float(y)!r}" for x, y in vertices),
        "--points=" + fmt(f"{float(x)!r},{float(y)!r}" for x, y in points),
        "--json",
        str(out),
    )
    assert p.returncode == 0, p.stderr
    return json.loads(out.read_text())["s_g"]


def test_score_cli_agrees_with_the_library_on_and_near_the_outline(tmp_path):
    """Points on the outline give the library's S_G; a point slightly off it (within the
    tolerance) is moved to the nearest outline point, not along the polar ray."""
    from controllers.grasp.objects import polygon_set

    rng = np.random.default_rng(8)
    offset = np.array([0.31, -0.17])  # the CLI takes any frame and any vertex order
    checked = 0
    for poly in polygon_set("heldout", 6):
        unit = poly.unit_moment()
        for _ in range(20):
            theta = rng.uniform(-np.pi, np.pi, 4)
            lib = grasp_score(*unit.locate(theta)[1:3])
            if not lib.feasible or not 0.3 < lib.s_g < 3.0:  # weak grasps
                continue
            frames = poly.locate(theta)
            # push contact 0 off its edge, outward, by 0.2 % of the diameter
            pts = frames.point.copy()
            pts[0] += 0.002 * poly.diameter * frames.normal[0]
            cli = _score_json(tmp_path, poly.vertices[::-1] + offset, pts + offset)
            assert cli == pytest.approx(lib.s_g, abs=1e-6)
            checked += 1
            break
    assert checked >= 4
