"""The task cycle (fsm): the transition table, the finger-to-contact rule, and whole episodes run
physically: success judged from the simulation, failures with their named reasons, the same seed
giving the same episode, and the files written in every case."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from controllers.grasp import paper_object
from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.synthesis import GraspSynthesis, separate_contacts
from controllers.grasp.trials import run_trials
from controllers.hand.finger_assignment import assign_fingers
from fsm import handlers
from fsm.context import EpisodeOptions
from fsm.machine import run_episode
from fsm.run import main, options_from_args
from fsm.states import TRANSITIONS, Failure, State, allowed, table_markdown
from hand_sim.recorder import read_recording as _read
from tests.fsm.clutter3 import shared_clutter3_run


def read_recording(path: Path) -> dict[str, dict[str, int]]:
    """Entities of a recording, without the leading slash of rerun's entity paths."""
    return {name.lstrip("/"): columns for name, columns in _read(path).items()}


#: The controller the episode tests run (the shipped default).
CONTROLLER = "pi"


# --- the table ----------------------------------------------------------------------------------
def test_every_state_has_a_handler_a_budget_and_named_failures() -> None:
    assert set(TRANSITIONS) == set(handlers.HANDLERS)
    for state, spec in TRANSITIONS.items():
        assert spec.state is state and spec.next and spec.guard
        assert allowed(state, State.FAILED)
        for following in State:
            assert allowed(state, following) == (
                following in spec.next or following is State.FAILED
            )
    assert not allowed(State.DONE, State.SELECT_MODEL)
    text = table_markdown()
    for state in TRANSITIONS:
        assert state.value in text
    used = {f for spec in TRANSITIONS.values() for f in spec.failures}
    assert {
        Failure.NO_COARSE_PATH,
        Failure.CONTACT_UNREACHABLE,
        Failure.SLIPPED_DURING_LIFT,
    } <= used


# --- fingers and contacts -----------------------------------------------------------------------
def test_finger_assignment_is_the_optimal_one_and_ignores_contact_order() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        tips = rng.normal(size=(4, 3))
        points = rng.normal(size=(4, 3))
        got = assign_fingers(tips, points)

        def cost(perm, tips=tips, points=points) -> float:
            return sum(float(np.sum((tips[f] - points[perm[f]]) ** 2)) for f in range(4))

        best = min(itertools.permutations(range(4)), key=cost)
        assert cost(got) == pytest.approx(cost(best))
        shuffle = rng.permutation(4)  # the controller's order of the contacts plays no part
        again = assign_fingers(tips, points[shuffle])
        assert [shuffle[i] for i in again] == list(got)


def test_separated_contacts_keep_pad_centres_apart_and_still_grasp() -> None:
    """The projection keeps 8.5 mm pads 21 mm apart on every paper object, and the grasps it
    gives are still force-closure grasps by S_G as often as the paper's controller's."""
    rng = np.random.default_rng(0)
    for name in ("triangle", "irregular_triangle", "square", "pentagon"):
        poly = paper_object(name)
        fails = 0
        for i in range(25):
            theta0 = rng.uniform(-np.pi, np.pi, 4)
            syn = GraspSynthesis(
                poly, KnowledgeBased(), theta0, np.random.default_rng(i),
                min_separation=0.021, separation_offset=0.0085,
            )  # fmt: skip
            while not syn.done:
                syn.step()
            frames = poly.locate(syn.theta)
            centres = frames.point + 0.0085 * frames.normal
            gaps = np.linalg.norm(centres[:, None] - centres[None], axis=-1)[np.triu_indices(4, 1)]
            assert gaps.min() >= 0.021 - 1e-6, name
            fails += not syn.finish().success
        assert fails <= 5, f"{name}: {fails} of 25 separated grasps fail S_G"
    far = separate_contacts(paper_object("square"), np.array([0.0, 1.6, 3.1, -1.6]), 0.021, 0.0085)
    np.testing.assert_allclose(far, [0.0, 1.6, 3.1, -1.6])  # already apart: untouched


def test_synthesis_without_separation_is_the_papers_controller() -> None:
    poly = paper_object("pentagon")
    theta0 = np.array([[0.6, 0.0, -0.6, 3.1]])
    batch = run_trials(
        [poly], [0], KnowledgeBased(), np.random.default_rng(0), theta_initial=theta0
    )
    syn = GraspSynthesis(poly, KnowledgeBased(), theta0[0], np.random.default_rng(0))
    while not syn.done:
        syn.step()
    np.testing.assert_allclose(syn.theta, batch.theta_final[0], atol=1e-12)
    assert syn.steps == batch.steps[0] and syn.converged == batch.converged[0]
    assert syn.finish().s_g == pytest.approx(batch.s_g[0])


# --- whole episodes ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def clutter3_episode(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out, code = shared_clutter3_run(tmp_path_factory)  # --controller pi, shared with test_live
    summary = json.loads((out / "summary.json").read_text())
    return out, {"code": code, **summary}


@pytest.mark.e2e
def test_clutter3_is_picked_and_placed_physically(clutter3_episode) -> None:
    _, s = clutter3_episode
    assert s["code"] == 0 and s["success"], s["failure_detail"]
    (cycle,) = s["cycles"]
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    assert j["palm_distance_m"] >= 0.05
    assert max(j["other_blocks_moved_m"].values()) < 0.01
    assert cycle["s_g"] is not None and cycle["s_g"] <= 0.4
    assert min(cycle["grip_forces"]) > 0.5 * min(cycle["grip_target"])
    states = [v["state"] for v in s["visits"]]
    assert states[:3] == ["Select/Model", "Coarse Reach", "Fine Reach"]
    assert {"Posture Control", "Wrench Closure", "Grasp Object", "Deliver"} <= set(states)
    assert s["transitions"][-1].startswith("Deliver -> Done")
    # the perceived polygon is the vision's, close to the truth
    assert cycle["polygon_error"]["centroid_mm"] < 2.0
    assert cycle["polygon_error"]["edges"] == cycle["polygon_error"]["true_edges"]


@pytest.mark.e2e
def test_clutter3_recording_holds_what_a_reader_needs(clutter3_episode) -> None:
    out, _ = clutter3_episode
    rrd = out / "episode.rrd"
    assert 0 < rrd.stat().st_size < 50e6
    entities = read_recording(rrd)
    names = set(entities)

    def has(prefix: str) -> bool:
        return any(n.startswith(prefix) for n in names)

    assert has("world/bodies/arm.hand.palm") and has("world/bodies/pentagon")
    assert has("world/cameras/overhead") and has("world/cameras/vision")
    assert has("events")
    assert any("contacts" in n for n in names)
    assert any("eps" in n.lower() or "synthesis" in n.lower() for n in names)


@pytest.mark.e2e
def test_same_seed_same_episode(tmp_path: Path) -> None:
    runs = []
    for k in range(2):
        options = EpisodeOptions(
            scene="random", seed=4, controller=CONTROLLER, out=tmp_path / str(k), record=False
        )
        runs.append(run_episode(options))
    a, b = runs
    assert [(v.state, v.next, v.reason) for v in a.visits] == [
        (v.state, v.next, v.reason) for v in b.visits
    ]
    assert a.cycles[0]["judgement"] == b.cycles[0]["judgement"]


@pytest.mark.e2e
def test_a_3d_grasp_holds_the_block_at_its_contacts_heights_and_delivers_it(tmp_path: Path) -> None:
    """``--model 3d``: the contacts the hand takes are the 3-D controller's, below the planar
    grasp depth, in the top grasp's band; the block is really delivered (the judge's
    measurements), and the recording shows the synthesis."""
    from controllers.reach.fine import TOP_GRASP_DEPTHS

    code = main(["--scene", "single_square", "--model", "3d", "--out", str(tmp_path)])
    s = json.loads((tmp_path / "summary.json").read_text())
    assert code == 0 and s["success"], s["failure_detail"]
    assert s["options"]["grasp_model"] == "3d"
    (cycle,) = s["cycles"]
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0 and not j["finger_contact"]
    top = 0.75 + 0.20  # the scene's table height and block height
    depth = top - np.array(cycle["contacts"])[:, 2]
    assert np.all(depth >= TOP_GRASP_DEPTHS[0] - 1e-3) and np.all(
        depth <= TOP_GRASP_DEPTHS[1] + 1e-3
    )
    assert depth.mean() > TOP_GRASP_DEPTHS[0] + 0.005  # lower than the planar grasp depth
    assert cycle["s_g"] is not None and cycle["s_g"] <= 0.4
    recording = read_recording(tmp_path / "episode.rrd")
    assert "world/synthesis/contacts" in recording
    assert any(path.endswith("synthesis/s_g") for path in recording)  # the final S_G


def _scene_file(tmp_path: Path, table_x: float, position: tuple[float, float]) -> Path:
    path = tmp_path / "far.toml"
    path.write_text(
        f'target = "a"\nplace = [{table_x - 0.2}, -0.2]\n[table]\nposition = [{table_x}, 0.0]\n'
        f'[[blocks]]\nname = "a"\nshape = "square"\nposition = [{position[0]}, {position[1]}]\n'
    )
    return path


@pytest.mark.e2e
def test_a_block_out_of_reach_fails_with_its_reason_and_writes_both_files(tmp_path: Path) -> None:
    # the table moved away from the arm: the block stands 1.45 m from the waist axis
    scene = _scene_file(tmp_path, 0.45, (0.85, 0.0))
    out = tmp_path / "out"
    code = main(["--scene", str(scene), "--controller", CONTROLLER, "--out", str(out)])
    assert code == 1
    s = json.loads((out / "summary.json").read_text())
    assert not s["success"] and s["failure"] == Failure.NO_COARSE_PATH.value
    assert (out / "episode.rrd").stat().st_size > 0
    assert "events" in read_recording(out / "episode.rrd")


@pytest.mark.e2e
def test_an_unstable_simulation_fails_cleanly(tmp_path: Path, monkeypatch) -> None:
    original = handlers.HANDLERS[State.FINE_REACH]

    def blow_up(ep):
        ep.simulated.data.qvel[0] = np.nan  # the physics itself goes unstable
        return original(ep)

    monkeypatch.setitem(handlers.HANDLERS, State.FINE_REACH, blow_up)
    options = EpisodeOptions(scene="clutter3", controller=CONTROLLER, out=tmp_path, record=True)
    result = run_episode(options)
    assert result.failure == Failure.SIMULATION_UNSTABLE.value
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["failure"] == Failure.SIMULATION_UNSTABLE.value
    assert "events" in read_recording(tmp_path / "episode.rrd")


@pytest.mark.e2e
def test_a_state_past_its_budget_fails(tmp_path: Path, monkeypatch) -> None:
    import dataclasses

    spec = TRANSITIONS[State.COARSE_REACH]
    monkeypatch.setitem(TRANSITIONS, State.COARSE_REACH, dataclasses.replace(spec, budget=0.5))
    options = EpisodeOptions(scene="clutter3", controller=CONTROLLER, out=tmp_path, record=False)
    result = run_episode(options)
    assert result.failure == Failure.TIME_BUDGET_EXCEEDED.value
    assert "Coarse Reach" in result.failure_detail


@pytest.mark.e2e
def test_interrupt_keeps_the_summary_and_the_recording(tmp_path: Path, monkeypatch) -> None:
    def interrupt(ep):
        raise KeyboardInterrupt

    monkeypatch.setitem(handlers.HANDLERS, State.FINE_REACH, interrupt)
    code = main(["--scene", "clutter3", "--controller", CONTROLLER, "--out", str(tmp_path)])
    assert code == 130
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["failure"] == Failure.INTERRUPTED.value
    assert "world/bodies/pentagon" in {
        n.split("/geoms")[0] for n in read_recording(tmp_path / "episode.rrd")
    }


def test_the_lateral_gate_reaches_the_episodes_config(tmp_path: Path) -> None:
    """``--lateral-gate`` sets ``TaskConfig.lateral_gate`` (the paper's 0.4 without it); the
    rest of the configuration stays the default."""
    out = ["--out", str(tmp_path / "o"), "--no-record"]
    assert options_from_args(["--scene", "clutter3", *out]).config.lateral_gate == 0.4
    options = options_from_args(["--scene", "clutter3", "--lateral-gate", "0.6", *out])
    assert options.config.lateral_gate == 0.6
    assert options.config.lateral_contacts == "sampled-first"
    assert options.config.lateral_gate_rule == "opposition"
    paper = options_from_args(["--scene", "clutter3", "--lateral-gate-rule", "paper", *out])
    assert paper.config.lateral_gate_rule == "paper" and paper.config.lateral_gate == 0.4


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scene", "nowhere"], "unknown scene"),
        (["--pick", "cube"], "not a block"),
        (["--pick-pixel", "960,1300"], "table"),
        (["--pick-pixel", "5000,10"], "outside the 1920x1440"),
        (["--place", "0.8,0.0"], "off the table"),
        (["--place", "-0.3,0.0"], "waist"),
        (["--place", "0.02,0.11"], "occupied"),
        (["--cycles", "0"], "--cycles"),
        (["--seed", "-1"], "--seed"),
        (["--controller", "xx"], "controller"),
        (["--model", "4d"], "--model"),
        (["--hand", "banana"], "--hand"),
        (["--lateral-gate", "-0.5"], "positive S_G"),
        (["--lateral-gate", "inf"], "--lateral-gate"),
        (["--lateral-gate-rule", "thumb"], "--lateral-gate-rule"),
        (["--out", ""], "--out"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, message, tmp_path: Path, capsys) -> None:
    args = argv if "--out" in argv else [*argv, "--out", str(tmp_path / "o")]
    code = main(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "o" / "summary.json").exists()
