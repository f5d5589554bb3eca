"""Truth and belief apart, on whole episodes: no controller, no vision step and no state but the
judge and the recording reads the simulated world; the robot reaches it only through its
sensors and servos (controllers.planning.belief_world). The simulated world of these episodes
is a tripwire: every read of its model, its state or a block's pose is noted with the module
that made it."""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import pytest

from fsm import machine
from fsm.context import EpisodeOptions
from fsm.machine import run_episode
from hand_sim.world import World

#: Modules that may read the simulated world: the simulation itself (its sensors, camera and
#: servos among it), the renderer's setup, the judge and the recording.
ALLOWED = ("hand_sim.", "vision.observation", "fsm.judge", "fsm.recording")


class Tripwire(World):
    """A simulated world that notes who reads its model, its data or a block's pose."""

    trips: list[tuple[str, str, str]]

    def _note(self, what: str) -> None:
        frame = sys._getframe(2)
        module = frame.f_globals.get("__name__", "")
        if not module.startswith(ALLOWED):
            self.__dict__.setdefault("trips", []).append((what, module, frame.f_code.co_name))

    @property
    def data(self) -> mujoco.MjData:
        self._note("data")
        return self.__dict__["_data"]

    @data.setter
    def data(self, value: mujoco.MjData) -> None:
        self.__dict__["_data"] = value

    @property
    def model(self) -> mujoco.MjModel:
        self._note("model")
        return self.__dict__["_model"]

    @model.setter
    def model(self, value: mujoco.MjModel) -> None:
        self.__dict__["_model"] = value

    def block_pose(self, name: str):
        self._note("block_pose")
        return super().block_pose(name)

    def block_body_id(self, name: str) -> int:
        self._note("block_body_id")
        return super().block_body_id(name)


@pytest.fixture
def tripwire(monkeypatch) -> list[Tripwire]:
    built: list[Tripwire] = []

    class Built(Tripwire):
        @classmethod
        def build(cls, scene, **kwargs):
            world = super().build(scene, **kwargs)
            built.append(world)
            return world

    monkeypatch.setattr(machine, "World", Built)
    return built


@pytest.mark.e2e
@pytest.mark.parametrize("perturb", [None, "woes"])
def test_only_the_judge_and_the_recording_read_the_simulated_world(
    tripwire: list[Tripwire], perturb: str | None, tmp_path: Path
) -> None:
    options = EpisodeOptions(
        scene="clutter3", out=tmp_path, record=perturb is None, perturb=perturb
    )
    result = run_episode(options)
    (world,) = tripwire
    assert world.__dict__.get("trips", []) == []
    # every episode ends delivered or with a named failure, judged on the truth
    assert result.success or result.failure not in (None, "internal error"), result
    if perturb is None:
        assert result.success and result.perturbation is None
    else:
        assert result.perturbation["asked"].startswith("camera=1")
