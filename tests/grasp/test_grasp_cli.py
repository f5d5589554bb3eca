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


def _score_result(tmp_path, name: str, *args: str) -> dict:
    out = tmp_path / f"{name}.json"
    p = run("score", *args, "--json", str(out))
    assert p.returncode == 0, p.stderr
    return json.loads(out.read_text())


def test_3d_points_at_the_centre_of_mass_height_score_as_the_planar_command(tmp_path):
    """Three numbers a point select the 3-D model; at the centre of mass's height, with a planar
    task, it is the planar metric (no moment about a horizontal axis to resist)."""
    poly = paper_object("irregular_pentagon")
    rng = np.random.default_rng(11)
    shape = ";".join(f"{x},{y}" for x, y in poly.vertices)
    for k in range(4):
        pts = poly.locate(rng.uniform(-np.pi, np.pi, 4)).point
        task = f"{0.1 * k},{-0.05 * k},{0.02 * k}"
        flat = ";".join(f"{x},{y}" for x, y in pts)
        tall = ";".join(f"{x},{y},0.1" for x, y in pts)
        a = _score_result(tmp_path, f"a{k}", "--polygon", shape, "--points", flat, "--task", task)
        fx, fy, mz = (float(v) for v in task.split(","))
        b = _score_result(
            tmp_path,
            f"b{k}",
            *("--polygon", shape, "--points", tall, "--height", "0.2"),
            *("--task", f"{fx},{fy},0,0,0,{mz}"),
        )
        assert a["feasible"] == b["feasible"]
        if a["feasible"]:
            assert b["s_g"] == pytest.approx(a["s_g"], abs=1e-6)
            assert np.array(b["tangential_forces"]).shape == (4, 2)


def test_3d_score_is_the_librarys_on_the_prism_and_sees_the_twist(tmp_path):
    """The command's 3-D S_G is grasp_score_3d of the prism's contacts (unit-moment frame, a
    top-face contact included, in the order given); two contacts on one line cannot resist a
    moment about that line, which the planar metric cannot express."""
    from controllers.grasp import Polygon, grasp_score_3d, prism_contacts

    square = "0,0;0.05,0;0.05,0.05;0,0.05"
    pts = "0.05,0.025,0.15;0.025,0.03,0.2;0,0.025,0.05;0.025,0,0.12"
    got = _score_result(tmp_path, "g", "--polygon", square, "--points", pts, "--height", "0.2")
    poly = Polygon.from_vertices([[0, 0], [0.05, 0], [0.05, 0.05], [0, 0.05]], name="square")
    sides = np.array([[0.025, 0.0], [-0.025, 0.0], [0.0, -0.025]])  # centroid frame
    theta = np.array([poly.theta_of(p) for p in sides])
    p3, n3 = prism_contacts(
        poly, theta, [0.15, 0.05, 0.12], 0.2, top=[[0.0, 0.005]], unit_moment=True
    )
    given = [0, 3, 1, 2]  # side, top, side, side as on the command line
    ref = grasp_score_3d(p3[given], n3[given])
    assert got["feasible"] == ref.feasible
    assert got["s_g"] == pytest.approx(ref.s_g, abs=1e-6)
    assert got["normal_forces"] == pytest.approx(ref.normal_forces.tolist(), abs=1e-5)
    line = "0.05,0.025,0.1;0,0.025,0.1"
    twist = run("score", "--polygon", square, "--points", line, "--height", "0.2",
                "--task", "0.1,0,0,0.1,0,0")  # fmt: skip
    assert twist.returncode == 0 and twist.stdout.startswith("infeasible"), twist.stdout


def test_3d_trials_json_points_are_on_the_prism_in_the_band_and_score_as_the_score_command(
    tmp_path,
):
    out = tmp_path / "r3.json"
    p = run(
        "trials", "--model", "3d", "--object", "pentagon", "--controller", "kb",
        "--trials", "12", "--depths", "0.04,0.07", "--json", str(out),
    )  # fmt: skip
    assert p.returncode == 0, p.stderr
    assert "pentagon (3d): 12 trials, kb: failure" in p.stdout
    data = json.loads(out.read_text())
    assert data["summary"]["model"] == "3d" and data["summary"]["height"] == pytest.approx(0.2)
    poly = paper_object("pentagon")
    t = next(t for t in data["trials"] if t["feasible"])
    pts = np.array(t["points"])
    assert pts.shape == (4, 3)
    assert np.all((pts[:, 2] >= 0.2 - 0.07 - 1e-9) & (pts[:, 2] <= 0.2 - 0.04 + 1e-9))
    # on the outline at the contacts' polar angles
    assert np.allclose(pts[:, :2], poly.locate(np.array(t["theta_final"])).point, atol=1e-8)
    # the score command, given the same points, gives the same 3-D S_G
    text = ";".join(",".join(f"{v:.9f}" for v in q) for q in pts)
    verts = ";".join(f"{x},{y}" for x, y in poly.vertices)
    s = run("score", "--polygon", verts, "--points", text, "--height", "0.2", "--json",
            str(tmp_path / "s.json"))  # fmt: skip
    assert s.returncode == 0, s.stderr
    assert json.loads((tmp_path / "s.json").read_text())["s_g"] == pytest.approx(t["s_g"], abs=1e-5)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--height", "0.2"), "--model 3d"),
        (("--model", "3d", "--depths", "0.1,0.3"), "depths below the top"),
        (("--model", "3d", "--depths", "0.1"), "LO,HI"),
        (("--model", "4d"), "invalid choice"),
    ],
)
def test_bad_3d_trials_input_is_one_line_and_exit_2(tmp_path, args, message):
    out = tmp_path / "never.json"
    p = run("trials", *args, "--json", str(out))
    assert p.returncode == 2
    assert message in p.stderr and len(p.stderr.strip().splitlines()) == 1
    assert not out.exists()
