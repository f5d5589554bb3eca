"""benchmarks.bench_fsm's physics-only replay: the control inputs captured at every step of a
run, replayed on a freshly built world of the same scene and hand, give the same trajectory
(the tendon hand's joint loop replayed with it)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from benchmarks.bench_fsm import CapturingRecorder, StepLog, replay_physics
from fsm.context import EpisodeOptions
from fsm.layout import episode_scene
from fsm.recorder_protocol import NullRecorder
from hand_sim.world import World


@pytest.mark.parametrize("hand", ["tendon", "servo"])
def test_replayed_control_inputs_give_the_same_trajectory(tmp_path: Path, hand: str) -> None:
    options = EpisodeOptions(scene="clutter3", seed=0, out=tmp_path, record=False, hand=hand)
    world = World.build(episode_scene(options.scene, options.seed, options.blocks), hand=hand)
    log = StepLog()
    world.on_step = CapturingRecorder(NullRecorder(), log, world.model.opt.timestep).tick
    rng = np.random.default_rng(0)
    start, hand_start = world.arm_targets(), world.hand_targets()
    for n in (1, 5, 10, 3, 20, 7):  # steps of several lengths, the arm and the fingers moving
        world.set_arm_targets(start + rng.uniform(-0.05, 0.05, start.shape))
        world.set_hand_targets(hand_start + rng.uniform(0.0, 0.2, hand_start.shape))
        world.step(n)
    world.step(0)  # a call that steps nothing is not a step
    assert log.steps == [1, 5, 10, 3, 20, 7]
    moved = float(np.abs(world.arm_qpos() - start).max())
    assert moved > 1e-4  # the inputs did something to replay
    assert float(np.abs(world.hand_qpos() - hand_start).max()) > 1e-4
    replay = replay_physics(options, log, world.data.qpos.copy())
    assert replay.steps == 46
    assert replay.final_qpos_error == 0.0
    # another trajectory is told apart
    other = world.data.qpos.copy()
    other[0] += 1e-3
    assert replay_physics(options, log, other).final_qpos_error > 5e-4
