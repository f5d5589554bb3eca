"""An empty hand whose wrist roll cannot turn where it is turns it above (issue 23), on random
scene 200: Coarse Reach ends at a lateral goal with the wrist rolled 90 deg, and the palm pose
the pre-shape search takes is rolled 170 deg. Between the two backed-out postures
(``controllers.preshape.moves.move_backed_out``) neither a straight line nor a harmonic path with
the roll turned at the start or at the goal is clear: the fingers would sweep through a neighbour.
Before, the arm went "straight there anyway" and knocked the neighbour over (132 mm; the picked
block was then delivered 0.8 mm from its place point and the episode failed for the
neighbour). Now the palm rises straight up until the roll turns clear and a harmonic path
leads on. The episode is stopped once Fine Reach is entered; the neighbours are judged where
the simulation has them. (The pre-shape search is the one before the reserve margin
(``NO_MARGIN``), whose first palm pose is the one traced; with the margin it is another.)"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import controllers.preshape.moves as motion
from fsm import handlers
from fsm.states import Failure, State, TaskFailedError
from hand_sim.scene import load_scene
from tests.fsm.lateral import NO_MARGIN, lateral_episode

SEED = 200
BLOCKS = 3  # the bench's count for seed 200 (experiments.bench.jobs.blocks_for_seed)


@pytest.mark.e2e
def test_a_wrist_roll_that_would_sweep_a_neighbour_turns_above_and_the_neighbour_stays(
    tmp_path: Path, monkeypatch
) -> None:
    scene = load_scene("random", seed=SEED, blocks=BLOCKS)
    moves: list[str] = []
    neighbours: dict[str, float] = {}
    move_backed_out = motion.move_backed_out

    def recorded(site, arm_q):
        how = move_backed_out(site, arm_q)
        moves.append(how)
        return how

    def stop_at_fine_reach(ep):
        for block in ep.world.scene.blocks:
            if block.name != scene.target:
                xy = ep.world.block_pose(block.name)[0][:2]
                neighbours[block.name] = float(np.linalg.norm(xy - np.asarray(block.position)))
        raise TaskFailedError(Failure.FINGERS_CANNOT_REACH, "stopped by the test at Fine Reach")

    monkeypatch.setattr(motion, "move_backed_out", recorded)
    monkeypatch.setitem(handlers.HANDLERS, State.FINE_REACH, stop_at_fine_reach)
    result = lateral_episode(tmp_path, "random", SEED, NO_MARGIN)
    assert result.failure_detail.endswith("stopped by the test at Fine Reach"), result
    assert len(neighbours) == BLOCKS - 1
    for name, moved in neighbours.items():
        assert moved < 0.005, (name, moved)
    assert "harmonic, the wrist roll turned above" in moves, moves
