"""Honest episodes (issue 22): any exception inside a state is a named failure (``internal error``
with the exception's one line, as a last resort) in the summary, the transition log, the
recording and the exit status, with NumPy's warnings kept out of the terminal; the first cycle's
place point is the one asked for, moved to a free slot only with ``--place-fallback nearest``;
later cycles choose their own."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from controllers.planning.belief_world import BeliefWorld
from fsm import handlers
from fsm.context import PLACE_BY_SCENE, PLACE_BY_TASK, PLACE_BY_USER, EpisodeOptions
from fsm.layout import SLOT_CLEARANCE, place_is_free
from fsm.machine import run_episode
from fsm.perception import obstacle_footprint, perceive, place_for_cycle
from fsm.run import main
from fsm.states import Failure, State, Step, TaskFailedError
from hand_sim.scene import load_scene
from hand_sim.world import World
from tests.fsm.test_recording import rows

#: A controller that needs no trained model and loads fastest.
CONTROLLER = "kb"


def _index_error(ep) -> Step:
    """A bug of the kind issue 22 met: NumPy warns about an empty mean, then an index fails."""
    np.mean(np.zeros(0))
    return Step(State.DONE, str(np.zeros((0, 2))[-1]))


def test_an_exception_in_a_state_is_a_named_failure_everywhere(
    tmp_path: Path, monkeypatch, capfd
) -> None:
    monkeypatch.setitem(handlers.HANDLERS, State.SELECT_MODEL, _index_error)
    code = main(["--scene", "clutter3", "--controller", CONTROLLER, "--out", str(tmp_path)])
    out, err = capfd.readouterr()
    assert code == 1
    assert "Traceback" not in out + err and "Warning" not in out + err, err
    (failed,) = [line for line in out.splitlines() if line.startswith("FAILED")]
    assert failed.startswith("FAILED: internal error: Select/Model: IndexError: index -1")
    assert "test_honest.py" in failed and "_index_error" in failed  # where it was raised
    s = json.loads((tmp_path / "summary.json").read_text())
    assert (s["success"], s["failure"]) == (False, Failure.INTERNAL_ERROR.value)
    assert s["failure_detail"].startswith("Select/Model: IndexError: index -1")
    assert "\n" not in s["failure_detail"] and "_index_error" in s["traceback"]
    assert s["transitions"] == [f"Select/Model -> Failed: internal error: {s['failure_detail']}"]
    assert any("RuntimeWarning: Mean of empty slice" in w for w in s["warnings"]), s["warnings"]
    events = [v[0] for _, v in rows(tmp_path / "episode.rrd", "/events", "TextLog:text")]
    assert f"Select/Model -> Failed: internal error: {s['failure_detail']}" in events
    assert events[-1] == "FAILED: failed: internal error"


def test_a_hand_over_the_table_does_not_list_is_an_internal_error(
    tmp_path: Path, monkeypatch
) -> None:
    monkeypatch.setitem(
        handlers.HANDLERS, State.SELECT_MODEL, lambda ep: Step(State.GRASP_OBJECT, "skip")
    )
    options = EpisodeOptions(scene="clutter3", controller=CONTROLLER, out=tmp_path, record=False)
    result = run_episode(options)
    assert result.failure == Failure.INTERNAL_ERROR.value
    assert "the machine went from Select/Model to Grasp Object" in result.failure_detail
    assert result.visits[-1].next == State.FAILED.value


# --- the place point ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def clutter3_world() -> World:
    return World.build(load_scene("clutter3"))


def _square(centre: tuple[float, float], half: float = 0.02) -> np.ndarray:
    c = np.asarray(centre)
    return c + half * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def test_the_first_place_point_is_the_one_asked_for(clutter3_world: World) -> None:
    world = clutter3_world
    asked = np.asarray(world.scene.place)
    radius = 0.026
    free = place_for_cycle(world, EpisodeOptions(), 0, [], radius, (0.35, 0.95))
    assert free.chosen_by == PLACE_BY_SCENE
    assert np.array_equal(free.asked, asked) and np.array_equal(free.point, asked)
    # a block standing on the asked point: the episode fails there, saying what would move it
    blocked = [_square((float(asked[0]) + 0.03, float(asked[1])))]
    with pytest.raises(TaskFailedError) as caught:
        place_for_cycle(world, EpisodeOptions(), 0, blocked, radius, (0.35, 0.95))
    assert caught.value.failure is Failure.PLACE_UNREACHABLE
    assert "occupied" in caught.value.detail and "--place-fallback nearest" in caught.value.detail
    # ... unless the user lets it go to the nearest free slot: asked and used both kept
    moved = place_for_cycle(
        world,
        EpisodeOptions(place=(0.0, -0.25), place_fallback="nearest"),
        0,
        blocked,
        radius,
        (0.35, 0.95),
    )
    assert moved.chosen_by == PLACE_BY_USER and np.array_equal(moved.asked, asked)
    assert np.linalg.norm(moved.point - asked) > 0.05
    assert place_is_free(moved.point, radius, blocked, world.scene.table, SLOT_CLEARANCE)
    # later cycles: nothing was asked, the task cycle chooses
    later = place_for_cycle(world, EpisodeOptions(), 1, [], radius, (0.35, 0.95))
    assert later.asked is None and later.chosen_by == PLACE_BY_TASK
    assert np.allclose(later.point, asked)


def _with_region(sel, mask: np.ndarray):
    """``sel`` with one block: its first region with top face ``mask``."""
    region = dataclasses.replace(sel.blocks[0], top_mask=mask)
    seg = dataclasses.replace(sel.segmentation, blocks=(region,))
    return dataclasses.replace(sel, segmentation=seg, names=(sel.names[0],))


def test_an_unmodelled_block_is_an_obstacle_grown_by_the_margin(clutter3_world: World) -> None:
    """A region of one pixel still stands in the way: a polygon around the pixel's point on
    the top plane, the margin away from it in every direction (within the octagon's sag); a
    region without a pixel is no obstacle."""
    sel = perceive(BeliefWorld.over(clutter3_world))
    region = sel.blocks[0]
    one = np.zeros_like(region.top_mask)
    u, v = (round(c) for c in region.pixel_centroid)
    one[v, u] = True
    footprint = obstacle_footprint(_with_region(sel, one), 0, margin=0.01)
    point = sel.observation.geometry.pixel_to_plane(np.array([u, v], float), region.z_top)[:2]
    d = np.linalg.norm(footprint - point, axis=1)
    assert len(footprint) >= 8
    assert np.all(d <= 0.0101) and np.all(d >= 0.01 * np.cos(np.pi / 8) - 1e-4)
    assert obstacle_footprint(_with_region(sel, np.zeros_like(one)), 0) is None


# --- a place point a neighbour crowds (issue 22's acceptance) -----------------------------------
#: The pentagon of clutter3 to deliver at (0, -0.25), where three squares stand 8 mm beyond its
#: circumradius (east, west, south): the block fits (the scenes' 5 mm gap), the hand's fingers
#: around it do not, so Deliver finds no set-down posture there.
CROWDED = """name = "crowded_place"
target = "pentagon"
place = [0.0, -0.25]

[[blocks]]
name = "pentagon"
shape = "pentagon"
position = [0.0, 0.0]
yaw_deg = 15.0

[[blocks]]
name = "east"
shape = "square"
position = [0.054, -0.25]

[[blocks]]
name = "west"
shape = "square"
position = [-0.054, -0.25]

[[blocks]]
name = "south"
shape = "square"
position = [0.0, -0.304]
"""


@pytest.fixture(scope="module")
def crowded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[int, dict, Path]]:
    """The crowded scene run by ``python -m fsm.run`` without and with the fallback: exit status,
    summary and output folder of each."""
    root = tmp_path_factory.mktemp("crowded")
    scene = root / "crowded.toml"
    scene.write_text(CROWDED)
    runs = {}
    for fallback in ("none", "nearest"):
        out = root / fallback
        argv = ["--scene", str(scene), "--controller", CONTROLLER, "--out", str(out)]
        code = main([*argv, "--place-fallback", fallback])
        runs[fallback] = (code, json.loads((out / "summary.json").read_text()), out)
    return runs


@pytest.mark.e2e
def test_a_crowded_place_point_fails_by_default_with_its_reason(crowded) -> None:
    code, s, out = crowded["none"]
    assert code == 1 and not s["success"]
    assert s["failure"] == Failure.PLACE_UNREACHABLE.value
    assert "no set-down posture at the place point asked for [0.0, -0.25]" in s["failure_detail"]
    assert "--place-fallback nearest" in s["failure_detail"]
    assert s["transitions"][-1].startswith("Deliver -> Failed: place point unreachable")
    (cycle,) = s["cycles"]  # grasped and lifted: only the set-down failed
    assert cycle["place_asked"] == cycle["place_used"] == [0.0, -0.25]
    assert not cycle["delivered_elsewhere"] and cycle["lift_height"] > 0.05
    events = [v[0] for _, v in rows(out / "episode.rrd", "/events", "TextLog:text")]
    assert any(e.startswith("Deliver -> Failed: place point unreachable") for e in events)


@pytest.mark.e2e
def test_the_fallback_delivers_elsewhere_and_says_so_everywhere(crowded) -> None:
    from experiments.bench.stats import ELSEWHERE, outcome, summarize

    code, s, out = crowded["nearest"]
    assert code == 0 and s["success"], s["failure_detail"]
    (cycle,) = s["cycles"]
    asked, used = np.asarray(cycle["place_asked"]), np.asarray(cycle["place_used"])
    assert np.array_equal(asked, [0.0, -0.25]) and cycle["delivered_elsewhere"]
    assert cycle["place_moved_mm"] == pytest.approx(1000 * np.linalg.norm(used - asked))
    # judged physically at the point used: the block's final position, not a commanded target
    final = np.asarray(cycle["judgement"]["final_position"][:2])
    assert np.linalg.norm(final - used) < 0.02 < np.linalg.norm(final - asked)
    # no slot is free of the crowd's 3 cm clearance closer than one grid step
    assert cycle["place_moved_mm"] >= 1000 * 0.08 - 1e-6
    note = f"asked (0.000, -0.250), used ({used[0]:.3f}, {used[1]:.3f}), "
    assert any(note in t and "delivered elsewhere" in t for t in s["transitions"])
    assert s["transitions"][-1].startswith("Deliver -> Done") and note in s["transitions"][-1]
    assert s["options"]["place_fallback"] == "nearest"
    # the recording shows both points, the used one labelled with the distance
    asked_rows = rows(out / "episode.rrd", "/world/place/asked", "Points3D:positions")
    used_rows = rows(out / "episode.rrd", "/world/place/used", "Points3D:positions")
    assert np.allclose(asked_rows[-1][1][0][:2], asked)
    assert np.allclose(used_rows[-1][1][0][:2], used)
    labels = rows(out / "episode.rrd", "/world/place/used", "Points3D:labels")
    assert f"{cycle['place_moved_mm']:.0f} mm from the asked one" in labels[-1][1][0]
    # the bench counts it apart, not in the success rate
    line = {"seed": 0, "blocks": 4, **s}
    assert outcome(line) == ELSEWHERE
    summary = summarize([line])
    assert (summary.successes, summary.elsewhere, summary.rate.estimate) == (0, 1, 0.0)


def test_an_exception_of_the_machine_itself_is_named_too(tmp_path: Path, monkeypatch) -> None:
    """Outside any state (here: the recorder's transition log breaks), the episode still ends
    with a named failure and a summary."""
    from fsm.recorder_protocol import NullRecorder

    class Broken(NullRecorder):
        def log_transition(self, *args, **kwargs) -> None:
            raise OSError("disk full")

    options = EpisodeOptions(scene="clutter3", controller=CONTROLLER, out=tmp_path, record=True)
    monkeypatch.setitem(
        handlers.HANDLERS, State.SELECT_MODEL, lambda ep: Step(State.DONE, "nothing to do")
    )
    result = run_episode(options, recorder_factory=lambda path, world: Broken())
    assert (result.success, result.failure) == (False, Failure.INTERNAL_ERROR.value)
    assert result.failure_detail.startswith("the machine: OSError: disk full")
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["failure"] == Failure.INTERNAL_ERROR.value and "OSError" in s["traceback"]


def _tip_over_and_fail(ep) -> Step:
    """The picked block laid on its side in the simulated world (as a hand that pushes it over
    would), then a named failure."""
    world, name = ep.simulated, ep.record.block
    m = world.model
    body = world.block_body_id(name)
    adr = m.jnt_qposadr[m.body_jntadr[body]]
    world.data.qpos[adr + 3 : adr + 7] = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]
    world.data.qpos[adr : adr + 2] += [0.03, 0.04]
    mujoco.mj_forward(m, world.data)
    raise TaskFailedError(Failure.FINGERS_CANNOT_REACH, "rf did not touch the block")


def test_a_failed_cycle_says_whether_its_block_was_knocked_over(
    tmp_path: Path, monkeypatch, capfd
) -> None:
    monkeypatch.setitem(handlers.HANDLERS, State.COARSE_REACH, _tip_over_and_fail)
    code = main(["--scene", "clutter3", "--controller", CONTROLLER, "--out", str(tmp_path)])
    out, _ = capfd.readouterr()
    assert code == 1
    s = json.loads((tmp_path / "summary.json").read_text())
    (cycle,) = s["cycles"]
    state = cycle["block_at_failure"]
    assert state["knocked_over"] and state["tilt_deg"] == pytest.approx(90.0, abs=0.1)
    assert state["moved_mm"] == pytest.approx(50.0, abs=0.1)  # the 3-4-5 shift
    # the reference is where the block stood when Select/Model saw it: the scene's position
    start = np.asarray(cycle["block_start"])
    scene = load_scene("clutter3")
    assert np.linalg.norm(start[:2] - scene.block(cycle["block"]).position) < 1e-3
    assert s["failure_detail"] == "rf did not touch the block"  # the FSM's reason is unchanged
    judged = f"{cycle['block']} knocked over (judged: tilted 90 deg, 50 mm from where it stood)"
    (failed,) = [line for line in out.splitlines() if line.startswith("FAILED")]
    assert failed.endswith(f"; {judged}")
    # the recording's verdict says it too
    events = [v[0] for _, v in rows(tmp_path / "episode.rrd", "/events", "TextLog:text")]
    assert events[-1] == f"FAILED: failed: fingers cannot reach; {judged}"


def test_a_block_left_standing_is_judged_upright(clutter3_world: World) -> None:
    from fsm.judge import block_at_failure, block_state_text

    world = clutter3_world
    name = world.scene.target
    start = world.block_pose(name)[0]
    state = block_at_failure(world, name, start + np.array([0.0, 0.002, 0.0]))
    assert not state["knocked_over"] and state["tilt_deg"] < 1.0
    assert state["moved_mm"] == pytest.approx(2.0, abs=0.05)
    assert block_state_text(state, name) == (
        f"{name} upright (judged: tilted 0 deg, 2 mm from where it stood)"
    )
    assert block_state_text(None, name) == ""
