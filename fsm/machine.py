"""The finite state machine of Figure 14: it owns the loop, the clock and the recorder.

:func:`run_episode` builds the world (:func:`episode_world`), then :func:`run_cycles` enters
states one after another through the handlers of :mod:`fsm.handlers`, checking every hand-over
against :data:`fsm.states.TRANSITIONS` and every state's simulated time against its budget. A
failure of any kind (a named reason, an unstable simulation, a budget overrun, Ctrl-C) ends the
episode in ``Failed`` with its reason; the summary and the recording are written in every case.
An exception no state names (a bug) is the last resort ``internal error``, with the exception's
one line as the detail and its traceback in the summary; warnings (NumPy's among them) are kept
in the summary, not printed. The interactive mode (:mod:`fsm.interactive`) builds the world once
and runs :func:`run_cycles` once per cycle on it, each cycle with its own recording and summary.
"""

from __future__ import annotations

import json
import os
import time
import traceback
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from controllers.errors import ReachError
from controllers.grasp.registry import make_composer
from controllers.planning.belief_world import BeliefWorld
from fsm.config import DEFAULT_CONFIG
from fsm.context import Episode, EpisodeOptions, out_paths
from fsm.handlers import HANDLERS, TaskFailedError
from fsm.judge import block_at_failure, block_state_text
from fsm.layout import episode_perturbation, episode_scene
from fsm.recorder_protocol import NullRecorder, TaskRecorder
from fsm.states import TRANSITIONS, Failure, State, allowed
from hand_sim.errors import SimulationError
from hand_sim.world import World

if TYPE_CHECKING:
    from hand_sim.perturb import Perturbation

#: Whole-episode budget (simulated seconds) per cycle.
CYCLE_BUDGET = 150.0


class BudgetExceededError(Exception):
    """A state ran past its simulated-time budget."""


@dataclass
class Visit:
    """One stay in a state."""

    state: str
    cycle: int
    sim_start: float
    sim_seconds: float = 0.0
    wall_seconds: float = 0.0
    reason: str = ""  #: why it handed over (or failed)
    next: str = ""


@dataclass
class EpisodeResult:
    """Everything the summary holds."""

    success: bool
    failure: str | None
    failure_detail: str
    options: dict[str, Any]
    scene: str
    visits: list[Visit] = field(default_factory=list)
    cycles: list[dict[str, Any]] = field(default_factory=list)
    sim_time: float = 0.0
    wall_time: float = 0.0
    rrd: str | None = None
    #: warnings raised during the episode (``file:line: Category: message``, each once)
    warnings: list[str] = field(default_factory=list)
    #: the traceback of an ``internal error`` (None otherwise)
    traceback: str | None = None
    #: how the simulated world differed from the scene (hand_sim.perturb: what was asked and
    #: what was drawn); None when it did not
    perturbation: dict[str, Any] | None = None

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["transitions"] = [f"{v.state} -> {v.next}: {v.reason}" for v in self.visits]
        return out


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    return value


def options_json(options: EpisodeOptions) -> dict[str, Any]:
    """The summary's record of ``options``: every flag, and the task cycle's tuning only when
    it is not the default (:data:`fsm.config.DEFAULT_CONFIG`)."""
    out = {f.name: getattr(options, f.name) for f in fields(options) if f.name != "config"}
    if options.config != DEFAULT_CONFIG:
        out["config"] = asdict(options.config)
    return _jsonable(out)


def write_summary(path: Path, result: EpisodeResult) -> None:
    """Write ``summary.json`` atomically (a temporary name, then a rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(_jsonable(result.to_json()), indent=2, allow_nan=False) + "\n")
    os.replace(tmp, path)


class Clock:
    """Watches simulated time per state; installed as the world's step hook together with the
    recorder's tick."""

    def __init__(self, world: World, recorder: TaskRecorder) -> None:
        self.world = world
        self.recorder = recorder
        self.state_start = world.time
        self.budget = 0.0

    def enter(self, state: State) -> None:
        self.state_start = self.world.time
        spec = TRANSITIONS.get(state)
        self.budget = spec.budget if spec is not None else 0.0

    def __call__(self, world: World) -> None:
        self.recorder.tick(world)
        if self.budget and world.time - self.state_start > self.budget:
            raise BudgetExceededError(
                f"{world.time - self.state_start:.1f} s of simulated time "
                f"(budget {self.budget:g} s)"
            )


#: Warnings kept in the summary, at most.
MAX_WARNINGS = 20


def internal_error_detail(error: BaseException) -> str:
    """One line naming an unexpected exception and where it was raised:
    ``IndexError: <message> (vision/hough.py:72 in fit_tls)``."""
    message = " ".join(str(error).split()) or "(no message)"
    frames = traceback.extract_tb(error.__traceback__)
    where = ""
    if frames:
        last = frames[-1]
        parts = Path(last.filename).parts
        where = f" ({'/'.join(parts[-2:])}:{last.lineno} in {last.name})"
    return f"{type(error).__name__}: {message}{where}"


def _warning_lines(caught: list[warnings.WarningMessage]) -> list[str]:
    """Each distinct warning once, as ``file:line: Category: message``."""
    out: list[str] = []
    for w in caught:
        parts = Path(w.filename).parts
        line = f"{'/'.join(parts[-2:])}:{w.lineno}: {w.category.__name__}: {w.message}"
        if line not in out:
            out.append(line)
    return out[:MAX_WARNINGS]


def _failure_for(state: State, error: Exception) -> tuple[Failure, str]:
    if isinstance(error, TaskFailedError):
        return error.failure, error.detail
    if isinstance(error, SimulationError):
        return Failure.SIMULATION_UNSTABLE, str(error)
    if isinstance(error, BudgetExceededError):
        return Failure.TIME_BUDGET_EXCEEDED, f"{state.value}: {error}"
    if isinstance(error, ReachError):
        mapping = {
            State.DELIVER: Failure.PLACE_UNREACHABLE,
            State.POSTURE_CONTROL: Failure.CONTACT_UNREACHABLE,
            State.COARSE_REACH: Failure.NO_COARSE_PATH,
        }
        return mapping.get(state, Failure.FINGERS_CANNOT_REACH), str(error)
    return Failure.INTERNAL_ERROR, f"{state.value}: {internal_error_detail(error)}"


def run_episode(
    options: EpisodeOptions,
    *,
    announce: Callable[[str], None] | None = None,
    recorder_factory: Callable[[Path, World], TaskRecorder] | None = None,
) -> EpisodeResult:
    """Run one episode as ``options`` ask; write ``episode.rrd`` (unless ``options.record`` is
    False) and ``summary.json`` into ``options.out``, also when it fails. ``announce`` receives a
    line per state entered; ``recorder_factory(rrd_path, world)`` makes the recorder of a recorded
    episode (default :class:`fsm.recording.EpisodeRecorder`)."""
    wall0 = time.perf_counter()
    rrd_path, summary_path = out_paths(options.out)
    world, perturbation = episode_world(options)
    ep = new_episode(options, world)
    if options.record:
        if recorder_factory is None:
            from fsm.recording import EpisodeRecorder

            recorder_factory = EpisodeRecorder
        ep.recorder = recorder_factory(rrd_path, world)
    result = new_result(options, world, rrd_path if options.record else None, perturbation)
    return run_cycles(ep, result, summary_path, announce=announce, wall0=wall0)


def episode_world(options: EpisodeOptions) -> tuple[World, Perturbation | None]:
    """The world an episode runs in: the scene ``options`` name (its seed's layout), built with
    the hand asked for and the perturbation drawn for it (:func:`fsm.layout.episode_perturbation`;
    None: the nominal world)."""
    scene = episode_scene(options.scene, options.seed, options.blocks)
    perturbation = episode_perturbation(options.perturb, options.seed, scene)
    return World.build(scene, hand=options.hand, perturbation=perturbation), perturbation


def new_episode(options: EpisodeOptions, world: World) -> Episode:
    """An episode of ``options`` on ``world``: its grasp controller and random generator, and no
    recorder yet (:class:`~fsm.recorder_protocol.NullRecorder`; set ``ep.recorder``). The
    states work on the robot's view of ``world`` (``ep.world``, a
    :class:`~controllers.planning.belief_world.BeliefWorld`); ``ep.truth`` is ``world``."""
    models = {"model_dir": options.models} if options.models is not None else {}
    composer = make_composer(options.controller, **models)
    rng = np.random.default_rng(options.seed)
    belief = BeliefWorld.over(world)
    return Episode(
        options, belief, rng, composer, NullRecorder(), config=options.config, truth=world
    )


def new_result(
    options: EpisodeOptions,
    world: World,
    rrd: Path | None,
    perturbation: Perturbation | None,
) -> EpisodeResult:
    """The result of an episode (or of one interactive cycle) before it runs; ``rrd``: its
    recording, None when it is not recorded."""
    return EpisodeResult(
        success=False,
        failure=None,
        failure_detail="",
        options=options_json(options),
        scene=world.scene.name,
        rrd=None if rrd is None else str(rrd),
        perturbation=None if perturbation is None else perturbation.to_json(),
    )


def run_cycles(
    ep: Episode,
    result: EpisodeResult,
    summary_path: Path,
    *,
    announce: Callable[[str], None] | None = None,
    wall0: float | None = None,
    start: State = State.SELECT_MODEL,
    pause_at: State | None = None,
) -> EpisodeResult:
    """Run the machine on ``ep`` from ``start`` until Done or Failed or, with ``pause_at``, until
    it hands over to that state again (an interactive cycle ends where the machine goes back to
    Wait for Block); fill ``result`` with what the cycles begun here did, close ``ep.recorder``
    and write ``summary_path``, also when it fails or is interrupted (Ctrl-C is raised again).
    The world and the episode's context stay as the machine left them, for the next call.
    ``wall0``: the wall clock (``time.perf_counter``) the announced times count from."""
    wall0 = time.perf_counter() if wall0 is None else wall0
    world, recorder = ep.world, ep.recorder
    first = len(ep.cycles)  # cycle records begun before this call are not this result's
    clock = Clock(world, recorder)
    world.on_step = clock
    state = start
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("default")
            state = _loop(ep, result, clock, announce, wall0, start, pause_at, first)
    except KeyboardInterrupt:
        result.failure, result.failure_detail = Failure.INTERRUPTED.value, "Ctrl-C"
        if len(ep.cycles) > first:
            ep.record.failure = Failure.INTERRUPTED.value
            _judge_failed_cycle(ep)
        raise
    except Exception as e:  # the machine's own bug, outside any state: named all the same
        result.failure = Failure.INTERNAL_ERROR.value
        result.failure_detail = f"the machine: {internal_error_detail(e)}"
        result.traceback = "".join(traceback.format_exception(e))
    finally:
        world.on_step = None
        picked = [c for c in ep.cycles[first:] if c.block is not None]
        result.success = result.failure is None and bool(picked) and all(c.success for c in picked)
        if not result.success and result.failure is None:  # never a failure without a reason
            result.failure = Failure.INTERNAL_ERROR.value
            result.failure_detail = f"the machine stopped in {state.value} without a reason"
        result.cycles = [_jsonable(asdict(c)) for c in picked]
        result.sim_time = world.time
        result.wall_time = time.perf_counter() - wall0
        result.warnings = _warning_lines(caught)
        try:
            verdict = "delivered" if result.success else f"failed: {result.failure}"
            if not result.success and result.cycles:
                judged = block_state_text(
                    result.cycles[-1].get("block_at_failure"), result.cycles[-1].get("block")
                )
                verdict += f"; {judged}" if judged else ""
            recorder.log_verdict(result.success, verdict)
        finally:
            try:
                recorder.close()
            finally:
                write_summary(summary_path, result)
    return result


def _judge_failed_cycle(ep: Episode) -> None:
    """Record where the failed cycle's block is (fsm.judge.block_at_failure), if one was
    picked."""
    record = ep.record
    if record.block is None or record.block_start is None:
        return
    state = block_at_failure(ep.simulated, record.block, record.block_start)
    if np.isfinite([state["tilt_deg"], state["moved_mm"]]).all():  # not after a NaN in the physics
        record.block_at_failure = state


def _loop(
    ep: Episode,
    result: EpisodeResult,
    clock: Clock,
    announce: Callable[[str], None] | None,
    wall0: float,
    start: State = State.SELECT_MODEL,
    pause_at: State | None = None,
    first: int = 0,
) -> State:
    """Enter states from ``start`` until Done or Failed, or until the machine hands over to
    ``pause_at`` again; return the last. Any exception of a state (but Ctrl-C) ends the episode
    in Failed with a named reason (:func:`_failure_for`); ``first``: the index of the first cycle
    record begun in this run of the loop (a failure is noted on the current cycle's record only
    when it is one of these)."""
    world, recorder = ep.world, ep.recorder
    state = start
    while state not in (State.DONE, State.FAILED):
        if state is pause_at and result.visits:
            break
        visit = Visit(state.value, ep.cycle, world.time)
        result.visits.append(visit)
        clock.enter(state)
        if announce is not None:
            announce(
                f"[sim {world.time:7.2f} s | wall {time.perf_counter() - wall0:6.1f} s] "
                f"cycle {ep.cycle}: {state.value}"
            )
        t0 = time.perf_counter()
        try:
            step = HANDLERS[state](ep)
            following, reason = step.next, step.reason
            if not allowed(state, following):
                raise RuntimeError(f"the machine went from {state.value} to {following.value}")
        except Exception as e:  # every failure gets a name
            failure, detail = _failure_for(state, e)
            following, reason = State.FAILED, f"{failure.value}: {detail}"
            result.failure, result.failure_detail = failure.value, detail
            if failure is Failure.INTERNAL_ERROR:
                result.traceback = "".join(traceback.format_exception(e))
            if len(ep.cycles) > first:
                ep.record.failure, ep.record.failure_detail = failure.value, detail
                _judge_failed_cycle(ep)
        visit.sim_seconds = world.time - visit.sim_start
        visit.wall_seconds = time.perf_counter() - t0
        visit.reason, visit.next = reason, following.value
        level = "ERROR" if following is State.FAILED else "INFO"
        recorder.log_transition(state.value, following.value, reason, level=level)
        state = following
    return state
