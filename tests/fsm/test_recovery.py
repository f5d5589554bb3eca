"""The task cycle's recovery loops (Figure 14: back to Posture Control when a contact is out of
reach; issue 9): Posture Control's palm-pose search when the arm's IK from its wrist-roll seeds
reaches no posture, and the regrasp after the squeeze loses a finger. Each runs in a whole random
episode (the bench's scene for that seed) whose outcome is judged physically, and the loop is
seen in the transition log."""

from __future__ import annotations

import dataclasses
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from experiments.bench.jobs import blocks_for_seed
from fsm.config import DEFAULT_CONFIG, TaskConfig
from fsm.context import EpisodeOptions
from fsm.layout import episode_scene
from fsm.machine import run_episode
from fsm.states import State, allowed
from tests.fsm.lateral import BALANCED_SQUEEZE, NO_MARGIN, lateral_episode

#: The controller the episodes run (the shipped default).
CONTROLLER = "pi"
#: The grasp model whose grasp of random scene 2 loses a finger in the squeeze.
PLANAR = "planar"


def _random_episode(
    seed: int,
    out: Path,
    config: TaskConfig = DEFAULT_CONFIG,
    grasp_model: str | None = None,
    hand: str | None = None,
    approach: str = "auto",
    block_range: tuple[int, int] = (3, 5),
):
    """The bench's episode of ``seed`` (random scene, ``block_range`` blocks), tuned by
    ``config``, on the default grasp model or ``grasp_model``, the default hand or ``hand``, by
    ``approach``."""
    model = {} if grasp_model is None else {"grasp_model": grasp_model}
    if hand is not None:
        model["hand"] = hand
    options = EpisodeOptions(
        **model,
        scene="random",
        seed=seed,
        blocks=blocks_for_seed(seed, *block_range),
        controller=CONTROLLER,
        approach=approach,
        out=out,
        record=False,
        config=config,
    )
    return run_episode(options)


def _delivered_physically(result) -> None:
    assert result.success, f"{result.failure}: {result.failure_detail}"
    (cycle,) = result.cycles
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]
    assert max(j["other_blocks_moved_m"].values()) < 0.01


def test_grasp_object_may_hand_back_to_fine_reach_for_a_regrasp() -> None:
    assert allowed(State.GRASP_OBJECT, State.FINE_REACH)
    assert allowed(State.GRASP_OBJECT, State.DELIVER)
    assert not allowed(State.GRASP_OBJECT, State.WRENCH_CLOSURE)
    assert allowed(State.FINE_REACH, State.FINE_REACH)  # a finger held off: regrasp


@pytest.mark.e2e
def test_a_finger_the_block_holds_off_in_fine_reach_is_felt_and_brought_to_a_contact(
    tmp_path: Path,
) -> None:
    """Random scene 140 on the tendon hand: Fine Reach's touch guard stops the ring finger where
    it meets the triangle, more than 2 cm from its surface point, and feels it (the guard takes
    the least pad force the tensions allow); Posture Control and Wrench Closure then bring the
    contacts within the hand's reach and the block is delivered. With the guard of 4094175 (the
    estimate above twice its stiction uncertainty) the finger was not felt, "rf stayed 47 mm from
    its surface point", and the episode failed after four regrasps. (Scene 157, which this test
    used for Fine Reach's own regrasp, no longer holds a finger off: no random scene of the
    tendon hand's 200 does since that guard; docs/models.md.)"""
    result = _random_episode(140, tmp_path, hand="tendon")
    log = [f"{v.state} -> {v.next}: {v.reason}" for v in result.visits]
    reach = next(v for v in result.visits if v.state == State.FINE_REACH.value)
    assert reach.next == State.POSTURE_CONTROL.value, log
    errors = re.match(r"fingertips \[([^\]]*)\] mm", reach.reason)
    assert errors is not None, log
    held_off = [float(e) for e in errors.group(1).split(",")]
    assert held_off[2] > 20.0, log  # rf, held off by the block
    stopped = reach.reason.split("stopped on touch: ")[-1].split(", ")
    assert "stopped on touch" in reach.reason and "rf" in stopped, log
    _delivered_physically(result)


@pytest.mark.e2e
def test_a_finger_fine_reach_leaves_far_off_gives_up_with_its_reason(tmp_path: Path) -> None:
    """Random scene 4 (a triangle alone), lateral, servo hand: Fine Reach leaves the ring finger
    more than 3 cm (``fine_reach_give_up``) from its surface point without touching anything, so
    Fine Reach asks for a regrasp; there is no other palm pose beside the block, and the episode
    fails naming the finger and its distance ("fingers cannot reach"). On the servo hand, where
    the scene was found: on the tendon hand Fine Reach ends with ff, mf and rf "stopped on
    touch" 36-69 mm from their surface points, never giving up, and the episode fails later in
    Posture Control ("contact unreachable after posture retries: ... ff 40 mm short"). With the
    pinch pre-shape's contacts (``lateral_contacts="pinch"``), where the scene was found: from
    sampled contacts, the default since, the hand reaches the triangle and delivers it."""
    pinch = dataclasses.replace(DEFAULT_CONFIG, lateral_contacts="pinch")
    result = _random_episode(
        4, tmp_path, pinch, approach="lateral", block_range=(1, 3), hand="servo"
    )
    log = [f"{v.state} -> {v.next}: {v.reason}" for v in result.visits]
    assert not result.success and result.failure == "fingers cannot reach", log
    gave_up = re.match(r"(\w\w) stayed (\d+) mm from its surface point", result.failure_detail)
    give_up_mm = DEFAULT_CONFIG.fine_reach_give_up * 1000.0
    assert gave_up is not None and int(gave_up.group(2)) > give_up_mm, result.failure_detail
    assert result.visits[-1].state == State.FINE_REACH.value, log
    assert "no other palm pose to regrasp from" in result.failure_detail


@pytest.mark.e2e
def test_palm_pose_search_finds_a_posture_the_roll_seeds_miss(tmp_path: Path) -> None:
    """Random scene 40 (a hexagon): the arm's IK from every wrist-roll seed reaches none of the
    contacts; the palm-pose search above the block finds a posture, and the block is
    delivered. (Scene 11 does the same in an episode twice as long.)"""
    result = _random_episode(40, tmp_path)
    searched = [
        v
        for v in result.visits
        if v.state == State.POSTURE_CONTROL.value and "palm turned" in v.reason
    ]
    assert searched, [v.reason for v in result.visits]
    assert searched[0].next == State.WRENCH_CLOSURE.value
    _delivered_physically(result)


@pytest.mark.e2e
@pytest.mark.skip(
    reason="the scenario of this seed no longer arises since the robot plans around the blocks "
    "it saw (docs/robustness.md); a seed that shows it is to be found again"
)
def test_a_squeeze_that_loses_a_finger_opens_the_hand_and_regrasps(tmp_path: Path) -> None:
    """Random scene 104 (an irregular pentagon among five blocks): after three regrasps from
    Posture Control the thumb loses the block in the squeeze; the hand opens and regrasps from
    Fine Reach with the wrist turned, and the block is delivered. (Random scene 2's planar grasp
    showed this until Posture Control's hold stopped pressing the pads into the block: its
    squeeze now holds at once, as on seeds 3-14.) On the servo hand, where the scene was found:
    the tendon hand, whose squeeze regulates each pad's force into its face, holds scene 104's
    block at its first squeeze (after two regrasps from Posture Control) and delivers it,
    1.4 mm from the place point, never regrasping from Grasp Object (docs/models.md, "The
    default hand")."""
    result = _random_episode(104, tmp_path, hand="servo")
    regrasps = [
        v
        for v in result.visits
        if v.state == State.GRASP_OBJECT.value and v.next == State.FINE_REACH.value
    ]
    assert regrasps, [f"{v.state} -> {v.next}: {v.reason}" for v in result.visits]
    assert "squeeze did not reach the grip force" in regrasps[0].reason
    assert "regrasp" in regrasps[0].reason
    _delivered_physically(result)


@pytest.mark.e2e
def test_regrasps_are_bounded_and_keep_the_failure_reason(tmp_path: Path) -> None:
    """With no regrasp allowed, random scene 104's first call for one (Posture Control's, after
    its posture retries: the thumb short) ends the episode there, with Posture Control's own
    reason, not the regrasp's; no visit goes back to Fine Reach. (Its fourth call, with three
    allowed, is the squeeze's: the same bound, 2.5 times the run.) The top approach is asked
    for: under ``auto`` the unreachable top grasp now gives way to the lateral approach, which
    has a path there and delivers (``fsm.recovery.other_approach_left``)."""
    config = dataclasses.replace(DEFAULT_CONFIG, max_regrasps=0)
    result = _random_episode(104, tmp_path, config, approach="top")
    assert not result.success
    assert result.failure == "contact unreachable after posture retries"
    assert result.failure_detail.startswith("after 0 regrasps"), result.failure_detail
    assert result.visits[-1].state == State.POSTURE_CONTROL.value
    assert State.FINE_REACH.value not in {v.next for v in result.visits[3:]}


def test_deliver_and_grasp_object_may_hand_back_to_coarse_reach_to_look_again() -> None:
    assert allowed(State.DELIVER, State.COARSE_REACH)
    assert allowed(State.GRASP_OBJECT, State.COARSE_REACH)
    assert not allowed(State.DELIVER, State.FINE_REACH)


@pytest.mark.parametrize("retries", [-1, 1.5, True, "1"])
def test_lift_retries_that_are_not_a_count_are_refused(retries: object) -> None:
    with pytest.raises(ValueError, match="lift_retries must be a whole number"):
        TaskConfig(lift_retries=retries)  # type: ignore[arg-type]


def _single_irregular_pentagon(out: Path, config: TaskConfig = DEFAULT_CONFIG):
    """``single_irregular_pentagon`` at seed 0, --approach lateral, tuned by ``config``."""
    return lateral_episode(out, "single_irregular_pentagon", 0, config)


@pytest.mark.e2e
def test_a_lateral_block_that_slips_at_the_lift_is_seen_again_and_grasped_from_the_next_pose(
    tmp_path: Path,
) -> None:
    """single_irregular_pentagon, --approach lateral, seed 0: the first pose's grasp (the thumb
    low, three fingers high on the tall block) loses the block as the arm lifts. With no lift
    retry the episode ends there, a slip sensed by the pads and the wrist; with the default one
    the hand lets go, the arm parks, the overhead camera models the block again where it
    stands, and Coarse Reach takes the pre-shape at the next palm pose, whose grasp holds: the
    block is delivered, judged physically. Both with the balanced squeeze
    (``BALANCED_SQUEEZE``; the holding squeeze's first grasp holds there)."""
    none = _single_irregular_pentagon(tmp_path / "none", replace(BALANCED_SQUEEZE, lift_retries=0))
    assert not none.success
    assert none.failure == "block slipped during lift", none.failure_detail
    assert none.cycles[0]["block_at_failure"]["tilt_deg"] < 10.0  # it still stands

    result = _single_irregular_pentagon(tmp_path / "one", BALANCED_SQUEEZE)
    back = [v for v in result.visits if v.next == State.COARSE_REACH.value and v.state == "Deliver"]
    assert len(back) == 1, [f"{v.state} -> {v.next}: {v.reason}" for v in result.visits]
    assert back[0].reason.startswith("slipped at the lift")
    assert "seen again" in back[0].reason
    reaches = [v.reason for v in result.visits if v.state == State.COARSE_REACH.value]
    assert len(reaches) == 2
    pose = re.compile(r"pre-shape, (.*?) \(reach load")
    assert pose.search(reaches[0]).group(1) != pose.search(reaches[1]).group(1), reaches
    (cycle,) = result.cycles
    assert cycle["lift_retries"] == 1 and cycle["regrasps"] >= 1
    assert result.success, f"{result.failure}: {result.failure_detail}"
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]


@pytest.mark.e2e
def test_a_lateral_regrasp_after_a_finger_missed_looks_at_the_block_again(tmp_path: Path) -> None:
    """Random scene 93 (two blocks), --approach lateral, the pre-shape's reposition as before
    issue 23's twenty-fifth session (``MotionParams.backin_as_clear`` off: the move to the
    pre-shape pose swept the fingers past the block; with it on the first grasp holds and this
    recovery never runs), the search before the reserve margin (``NO_MARGIN``: with it the
    first grasp is another): the thumb misses the irregular hexagon as the hand closes, and the
    fingers that touched it have pushed it centimetres from where Select/Model saw it (a
    regrasp planned on the old model missed it four times over). The hand lets go, the arm
    parks, the camera models the block where it now stands, Coarse Reach takes the next palm
    pose's pre-shape, and the block is delivered, judged physically."""
    options = EpisodeOptions(
        scene="random",
        seed=93,
        blocks=2,
        controller=CONTROLLER,
        approach="lateral",
        out=tmp_path,
        record=False,
        config=replace(NO_MARGIN, motion=replace(NO_MARGIN.motion, backin_as_clear=False)),
    )
    result = run_episode(options)
    log = [f"{v.state} -> {v.next}: {v.reason}" for v in result.visits]
    again = [
        v
        for v in result.visits
        if v.state == State.GRASP_OBJECT.value and v.next == State.COARSE_REACH.value
    ]
    assert again, log
    assert "did not touch the block" in again[0].reason
    moved = float(re.search(r"seen again (\d+) mm", again[0].reason).group(1))
    assert moved >= 10.0, again[0].reason  # the block was no longer where it had been modelled
    assert result.success, log
    (cycle,) = result.cycles
    assert cycle["regrasps"] >= 1
    j = cycle["judgement"]
    assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0
    assert j["lift_clearance_m"] >= 0.05 and not j["finger_contact"]


@pytest.mark.e2e
def test_clutter5_is_cleared_block_by_block(tmp_path: Path) -> None:
    """`--scene clutter5 --cycles all` (issue 9's acceptance): five cycles, each block picked,
    carried and set down at a free slot, judged physically after each retreat; later slots lie
    next to blocks delivered before, where the set-down's descent must keep the hand clear of
    them (or take the next slot)."""
    options = EpisodeOptions(
        scene="clutter5", seed=0, controller=CONTROLLER, cycles=None, out=tmp_path, record=False
    )
    result = run_episode(options)
    assert result.success, f"{result.failure}: {result.failure_detail}"
    assert len(result.cycles) == 5
    assert len({c["block"] for c in result.cycles}) == 5
    for cycle in result.cycles:
        j = cycle["judgement"]
        assert j["place_error_mm"] < 20.0 and j["tilt_deg"] < 10.0, cycle["block"]
        assert max(j["other_blocks_moved_m"].values()) < 0.01, cycle["block"]


@pytest.mark.e2e
def test_a_place_point_between_tall_neighbours_is_set_down_at_the_nearer_clearance(
    tmp_path: Path,
) -> None:
    """Random scene 159 on the tendon hand: at every turn about the place point the hand holding
    the pentagon passes within the planning clearance (1 cm) of a neighbour as tall as the
    block, at the carry height or on the way down (Deliver used to fail there, "no
    collision-free posture above the place point"); lowered keeping SET_DOWN_CLEARANCE (3 mm)
    instead, the block is set down where it was asked, and no neighbour is knocked away."""
    result = _random_episode(159, tmp_path, hand="tendon")
    _delivered_physically(result)
    (cycle,) = result.cycles
    assert cycle["set_down"].startswith("lowered keeping 3 mm (not 10 mm) from everything")
    assert cycle["place_used"] == cycle["place_asked"] and not cycle["delivered_elsewhere"]


@pytest.mark.e2e
def test_a_place_point_the_held_hand_cannot_set_down_at_is_reached_turned(tmp_path: Path) -> None:
    """Random scene 18: at its place point a finger of the hand, as it holds the block (and
    turned with the waist), would land on the block beside it, so Deliver once found no set-down
    posture there (under the old rule it went to a free slot 8 cm away). Turned about the place
    point (controllers.deliver.plan.SET_DOWN_TURNS) the hand clears it: even with --place-fallback
    nearest the block is set down where it was asked, judged physically there, not elsewhere.
    The planar grasp model's hold, the one this scene was found with. (Since Posture Control's
    hold keeps the pads out of the block the grasp here differs and its set-down needs no turn
    (its summary's ``set_down`` is empty); the turns themselves are tested in
    tests/controllers/test_reach.py.)"""
    scene = episode_scene("random", 18, blocks_for_seed(18, 3, 5))
    options = EpisodeOptions(
        scene="random",
        seed=18,
        blocks=blocks_for_seed(18, 3, 5),
        controller=CONTROLLER,
        place_fallback="nearest",
        grasp_model=PLANAR,
        out=tmp_path,
        record=False,
    )
    result = run_episode(options)
    _delivered_physically(result)
    (cycle,) = result.cycles
    assert not cycle["delivered_elsewhere"]
    assert cycle["place_asked"] == cycle["place_used"] == list(scene.place)
    final = np.asarray(cycle["judgement"]["final_position"][:2])
    assert np.linalg.norm(final - np.asarray(scene.place)) < 0.02


@pytest.mark.e2e
@pytest.mark.skip(
    reason="the scenario of this seed no longer arises since the robot plans around the blocks "
    "it saw (docs/robustness.md); a seed that shows it is to be found again"
)
def test_a_regrasp_that_starts_beside_a_neighbour_rises_clear_and_delivers(tmp_path: Path) -> None:
    """Random scene 79 (two blocks), --approach lateral, the hand backing off the block before
    it rises (``lateral_retreat_rise`` off: the default rises first, and this start no longer
    arises there; the rise in Coarse Reach stays for any start in collision): the first
    squeeze does not settle, the hand lets go and backs out, and no path parks the arm from
    there; the next Coarse Reach's start is within the planning clearance of the block with the
    hand pre-shaped, so the palm first rises straight up until it is clear, the reach is
    planned from there, and the block is delivered (before: "no coarse path: lateral: the start
    posture is in collision"). With the balanced squeeze (``BALANCED_SQUEEZE``), whose first
    squeeze fell short here."""
    backing = replace(BALANCED_SQUEEZE, lateral_retreat_rise=False)
    result = _random_episode(79, tmp_path, backing, approach="lateral", block_range=(1, 3))
    reaches = [v.reason for v in result.visits if v.state == State.COARSE_REACH.value]
    assert len(reaches) >= 2, reaches
    assert "risen" not in reaches[0]
    assert any("the palm first risen" in r for r in reaches[1:]), reaches
    _delivered_physically(result)
