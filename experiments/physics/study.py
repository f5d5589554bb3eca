"""Does S_G (Eq. 13) predict a physical grasp? Grasps synthesized by the paper's controllers,
taken by the simulated hand and tested in MuJoCo.

One grasp, start to end (:func:`test_grasp`):
1. synthesis: a :class:`~controllers.grasp.synthesis.GraspSynthesis` (KB, QL or PI, section 3.6)
   from four contacts drawn uniformly in theta, run to convergence or its step limit, with the
   task cycle's pad spacing (``min_separation``); its S_G is the verdict under test;
2. placement (:mod:`experiments.physics.hand_placement`): the task cycle's Posture Control
   (arm and hand IK) started from palm-down postures over the block finds an arm posture, palm
   within 12 deg of vertical, from which the task cycle's reach test passes; the fingers'
   pre-contact postures from :func:`controllers.hand.grip.plan_grip`. The arm and hand are set there
   (not
   driven: the approach is not under test) and the servos hold them. A grasp no start reaches is
   *unreachable*;
3. the task cycle's Grasp Object: :func:`~controllers.hand.grip.close` with the touch guard, then
   :func:`~controllers.hand.grip.squeeze` to :data:`controllers.hand.grip.GRIP_FORCE` per finger,
   shared as
   the S_G LP's normal forces. A finger that never touches makes the grasp *not closed* (counted
   with the unreachable ones, not as a drop);
4. the physical test: the table's collisions are switched off (the block hangs in the hand), an
   external force of m*g on the block's centre of mass (``data.xfrc_applied``) along +x, -x, +y,
   -y, +z and -z (world axes), :data:`FORCE_TIME` each, then a :data:`LIFT_HEIGHT` lift of the
   palm with the arm (:func:`controllers.deliver.carry.lift`). The block's pose is measured in the
   palm's frame against its pose at the end of the squeeze; the grasp *holds* when it never
   moves more than :data:`MAX_SHIFT` nor turns more than :data:`MAX_TURN` (the first stage that
   exceeds either ends the test).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from controllers.deliver.carry import LIFT_HEIGHT, lift
from controllers.errors import ReachError
from controllers.grasp.registry import make_composer
from controllers.grasp.score import grasp_score
from controllers.grasp.task_height import HEIGHT_TRIES
from controllers.hand.finger_geometry import PerceivedPrism
from controllers.hand.grip import GRIP_FORCE, close, plan_grip, squeeze
from controllers.planning.cspace import CollisionChecker
from controllers.reach.coarse import ReachTarget
from controllers.timing import CONTROL_PERIOD, control_steps
from experiments.physics.compliance import grasp_compliance
from experiments.physics.force_demand import held_force_demand
from experiments.physics.hand_placement import HandPosture, Placement, place_hand, top_postures
from experiments.physics.measures import grasp_measures, held_contacts
from experiments.physics.outcome import GraspOutcome
from experiments.physics.regrasp import regrasp_start
from experiments.physics.synthesis import Synthesis, grasp_depths, synthesize
from hand_sim import robot
from hand_sim.errors import SimulationError
from hand_sim.indices import RobotIndices
from hand_sim.perturb import PerturbSpec, for_episode
from hand_sim.scene import load_scene
from hand_sim.world import DEFAULT_HAND, World

#: Duration (s) of each external force, its directions (world axes) and the lift (m).
FORCE_TIME = 2.0
DIRECTIONS: tuple[tuple[str, tuple[float, float, float]], ...] = (
    ("+x", (1.0, 0.0, 0.0)),
    ("-x", (-1.0, 0.0, 0.0)),
    ("+y", (0.0, 1.0, 0.0)),
    ("-y", (0.0, -1.0, 0.0)),
    ("+z", (0.0, 0.0, 1.0)),
    ("-z", (0.0, 0.0, -1.0)),
)
#: Settling (s) after the arm and hand are set in place, and after the table is taken away (the
#: block's weight alone: judged like a stage, called "hang").
PLACE_SETTLE = 0.2
HANG_TIME = 0.3
#: A grasp holds while the block stays within these of its pose at the end of the squeeze, in the
#: palm's frame (m, rad).
MAX_SHIFT = 0.02
MAX_TURN = np.deg2rad(10.0)
#: S_G threshold of a successful grasp (section 3.6: S_G <= 0.4).
PAPER_THRESHOLD = 0.4
#: Stages of the physical test, in order.
STAGES: tuple[str, ...] = ("hang", *(d for d, _ in DIRECTIONS), "lift")


def grasp_seed(seed: int, obj: int, controller: int, index: int) -> np.random.Generator:
    """The generator of one grasp: the same whatever process runs it."""
    return np.random.default_rng([seed, obj, controller, index])


def _palm_frame(world: World) -> tuple[np.ndarray, np.ndarray]:
    b = world.model.body(robot.hand_name(robot.PALM_BODY)).id
    return world.data.xpos[b].copy(), world.data.xmat[b].reshape(3, 3).copy()


def _block_in_palm(world: World, name: str) -> tuple[np.ndarray, np.ndarray]:
    p, R = _palm_frame(world)
    b = world.block_body_id(name)
    x = world.data.xpos[b]
    Rb = world.data.xmat[b].reshape(3, 3)
    return R.T @ (x - p), R.T @ Rb


def _turn(Ra: np.ndarray, Rb: np.ndarray) -> float:
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


class _Table:
    """Switch the table's collisions off and back on (the block then hangs in the hand)."""

    def __init__(self, world: World) -> None:
        m = world.model
        self.model = m
        self.geoms = [
            g
            for g in range(m.ngeom)
            if m.body(m.geom_bodyid[g]).name.startswith("table/")
            and (m.geom_contype[g] or m.geom_conaffinity[g])
        ]
        self.saved = (m.geom_contype[self.geoms].copy(), m.geom_conaffinity[self.geoms].copy())

    def off(self) -> None:
        self.model.geom_contype[self.geoms] = 0
        self.model.geom_conaffinity[self.geoms] = 0

    def on(self) -> None:
        self.model.geom_contype[self.geoms] = self.saved[0]
        self.model.geom_conaffinity[self.geoms] = self.saved[1]


#: Called with (stage name, world) at the end of the squeeze ("grasp") and of every stage.
Snapshot = Callable[[str, World], None]


@dataclass
class StudyWorld:
    """One block's world with its hand postures, reused for every grasp of that block."""

    world: World
    name: str
    target: ReachTarget
    prism: PerceivedPrism
    postures: list[HandPosture]
    checker: CollisionChecker
    #: the block's nominal weight (N): its volume times wood's density times g, what the
    #: controllers' task is set from (a perturbed block's true weight is not known to them)
    weight: float = 0.0

    @classmethod
    def of(cls, obj: str, model: str = "planar", hand: str = DEFAULT_HAND) -> StudyWorld:
        """``obj``'s world with the ``hand`` (``World.build``'s kinds: "servo" or "tendon") on
        the arm; the hand's seed postures pre-shaped at the depths ``model``'s contacts take
        (planar: the task cycle's grasp depth; 3-D: both ends of its band)."""
        world = World.build(load_scene(f"single_{obj}"), hand=hand)
        name = world.scene.target
        target = ReachTarget.from_world(world, name)
        prism = PerceivedPrism.of(target, world.scene.table.height)
        return cls(
            world,
            name,
            target,
            prism,
            top_postures(world, target, depths=grasp_depths(model)),
            CollisionChecker(world),
            world.block_weight(name),
        )

    def perturbed(self, perturb: str | None, seed: tuple[int, ...]) -> StudyWorld:
        """This block's world perturbed as ``perturb`` asks (``--perturb``; hand_sim.perturb),
        drawn from ``seed`` (the grasp's seed words), or itself when nothing is perturbed. The
        hand's seed postures, the checker and the nominal weight stay the nominal world's."""
        spec = PerturbSpec() if perturb is None else PerturbSpec.parse(perturb)
        p = for_episode(spec, seed, [self.name])
        if p is None:
            return self
        world = World.build(self.world.scene, hand=self.world.hand, perturbation=p)
        return dataclasses.replace(self, world=world)


def _set_robot(world: World, qpos: np.ndarray, hand_q: np.ndarray) -> None:
    """Arm and hand at ``qpos``'s arm and ``hand_q``, at rest, the servos holding them."""
    m = world.model
    arm_adr = robot.arm_qpos_addresses(m)
    hand_adr = RobotIndices.of(m).finger_qpos.ravel()
    world.data.qpos[arm_adr] = qpos[arm_adr]
    world.data.qpos[hand_adr] = hand_q
    world.data.qvel[:] = 0.0
    world.set_arm_targets(qpos[arm_adr])
    world.set_hand_targets(hand_q)
    mujoco.mj_forward(m, world.data)


def _stage(
    world: World, name: str, seconds: float, ref: tuple[np.ndarray, np.ndarray], out: GraspOutcome
) -> bool:
    """Step for ``seconds`` tracking the block's pose against ``ref``; False once it is lost."""
    steps = control_steps(world)
    worst_shift = worst_turn = 0.0
    for _ in range(max(1, round(seconds / CONTROL_PERIOD))):
        world.step(steps)
        x, R = _block_in_palm(world, out_name(world))
        worst_shift = max(worst_shift, float(np.linalg.norm(x - ref[0])))
        worst_turn = max(worst_turn, _turn(ref[1], R))
        if worst_shift > MAX_SHIFT or worst_turn > MAX_TURN:
            break
    out.shift[name] = round(worst_shift, 5)
    out.turn[name] = round(worst_turn, 5)
    return worst_shift <= MAX_SHIFT and worst_turn <= MAX_TURN


def out_name(world: World) -> str:
    """The block of a single-block scene."""
    return world.scene.target


def physical_test(
    sw: StudyWorld, grip, out: GraspOutcome, snapshot: Snapshot | None = None
) -> None:
    """Step 4 of the module docstring on a squeezed grasp; fills ``out``."""
    world = sw.world
    ref = _block_in_palm(world, sw.name)
    if snapshot is not None:
        snapshot("grasp", world)
    body = world.block_body_id(sw.name)
    weight = world.block_weight(sw.name)
    table = _Table(world)
    table.off()
    try:
        held = _stage(world, "hang", HANG_TIME, ref, out)
        if snapshot is not None and not held:
            snapshot("hang", world)
        for label, direction in DIRECTIONS:
            if not held:
                break
            world.data.xfrc_applied[body, :3] = weight * np.asarray(direction)
            held = _stage(world, label, FORCE_TIME, ref, out)
            world.data.xfrc_applied[body, :] = 0.0
            if snapshot is not None and not held:
                snapshot(label, world)
        if held:
            try:
                lift(world, sw.checker, sw.name, grip, height=LIFT_HEIGHT)
            except ReachError as e:
                out.result, out.reason = "unreachable", f"lift: {e}"
                return
            x, R = _block_in_palm(world, sw.name)
            out.shift["lift"] = round(float(np.linalg.norm(x - ref[0])), 5)
            out.turn["lift"] = round(_turn(ref[1], R), 5)
            held = out.shift["lift"] <= MAX_SHIFT and out.turn["lift"] <= MAX_TURN
            if snapshot is not None and not held:
                snapshot("lift", world)
    finally:
        world.data.xfrc_applied[body, :] = 0.0
        table.on()
    out.result = "held" if held else "dropped"
    if not held:
        out.failed_stage = next(s for s in STAGES if s in out.shift and not _ok(out, s))


def _ok(out: GraspOutcome, stage: str) -> bool:
    return out.shift[stage] <= MAX_SHIFT and out.turn[stage] <= MAX_TURN


def synthesize_on(
    sw: StudyWorld,
    model: str,
    composer,
    theta0: list[float],
    rng: np.random.Generator,
    *,
    height_tries: int = HEIGHT_TRIES,
    heights0: np.ndarray | None = None,
) -> Synthesis:
    """Step 1 on ``sw``'s block (:func:`experiments.physics.synthesis.synthesize`): the
    ``model``'s controller from contacts ``theta0`` (and, in 3-D, initial heights ``heights0``,
    m above the centre of mass), its task the physical test's (the block's weight over the grip
    force, the world x axis in the block's frame)."""
    return synthesize(
        model,
        sw.target.polygon,
        sw.world.scene.block(sw.name).height,
        composer,
        theta0,
        rng,
        load=sw.weight / GRIP_FORCE,
        yaw=-sw.target.yaw,
        height_tries=height_tries,
        heights_initial=heights0,
    )


def _place(
    sw: StudyWorld, syn: Synthesis, out: GraspOutcome, depth: float | None
) -> tuple[Placement, np.ndarray | None]:
    """Step 2 for the synthesized contacts ``syn`` (fills ``out``'s contacts and height rank):
    the placement found, and the world heights of the contacts at the first height offered
    (None for a planar grasp at its fingertips' heights)."""
    top_z = sw.target.top_z
    half = 0.5 * sw.world.scene.block(sw.name).height
    out.theta = [round(float(t), 6) for t in syn.theta]
    out.steps, out.converged, out.s_g = syn.steps, syn.converged, syn.s_g
    planar = None if depth is None else np.full(len(syn.theta), top_z - depth)
    # the contacts' world heights at each common height offered (one option for a planar grasp)
    options = [syn.heights] if not syn.height_options else list(syn.height_options)
    worlds = [planar] if syn.heights is None else [top_z - half + o for o in options]
    for rank, heights in enumerate(worlds):
        if syn.heights is not None:
            out.heights = [round(float(z), 6) for z in options[rank]]
            out.height_raise = round(float(np.mean(options[rank] - options[0])), 6)
        out.height_rank = rank
        placed = place_hand(
            sw.world,
            sw.prism,
            sw.target,
            syn.theta,
            sw.postures,
            checker=sw.checker,
            heights=heights,
        )
        if placed.reachable:
            break
    return placed, worlds[0]


def test_grasp(
    sw: StudyWorld,
    composer,
    rng: np.random.Generator,
    out: GraspOutcome,
    snapshot: Snapshot | None = None,
    depth: float | None = None,
    height_tries: int = HEIGHT_TRIES,
    regrasp: bool = True,
) -> GraspOutcome:
    """Synthesize, place, close, squeeze and test one grasp (module docstring); fills ``out``.
    ``depth`` (planar model): every contact that far (m) below the top. 3-D model: the hand
    tries up to ``height_tries`` common heights of the contacts, best first, and takes the first
    it reaches (:attr:`GraspOutcome.height_rank`). ``regrasp``: a grasp the hand cannot take is
    synthesized once more from contacts the hand holds (:mod:`experiments.physics.regrasp`)."""
    world = sw.world
    world.reset()
    spec = world.scene.block(sw.name)
    weight = world.block_weight(sw.name)
    load = weight / GRIP_FORCE

    def run(theta0: list[float], heights0: np.ndarray | None = None) -> Synthesis:
        return synthesize_on(
            sw, out.model, composer, theta0, rng, height_tries=height_tries, heights0=heights0
        )

    syn = run(out.theta_initial)
    placed, first_heights = _place(sw, syn, out, depth)
    if not placed.reachable and regrasp:
        out.regrasped, out.first_theta, out.first_reason = True, out.theta, placed.reason
        theta0, z0 = regrasp_start(
            sw.target, sw.postures, syn.theta, sw.prism.bottom, first_heights
        )
        out.regrasp_initial = [round(float(t), 6) for t in theta0]
        # world z -> m above the block's centre of mass
        syn = run(list(theta0), z0 - (sw.target.top_z - 0.5 * spec.height))
        placed, _ = _place(sw, syn, out, depth)
    if not placed.reachable:
        out.result, out.reason = "unreachable", placed.reason
        return out
    assert placed.qpos is not None and placed.contacts is not None and placed.reach is not None
    assert placed.yaw is not None and placed.tilt is not None
    out.palm_yaw, out.palm_tilt = round(placed.yaw, 6), round(placed.tilt, 6)
    unit = sw.target.polygon.unit_moment()
    frames = unit.locate(placed.contacts.theta)
    lp = grasp_score(frames.point, frames.normal)
    shares = lp.normal_forces if lp.feasible else np.ones(4)
    try:
        _set_robot(world, placed.qpos, placed.qpos[_hand_adr(world)])
        # the grip's IK from the hand posture the reachability check found (as the task cycle)
        grip = plan_grip(
            world,
            placed.contacts.points,
            placed.contacts.normals,
            shares,
            prism=sw.prism,
            start=placed.reach.hand_q,
        )
        _set_robot(world, placed.qpos, grip.q_pre)
        world.step(round(PLACE_SETTLE / world.model.opt.timestep))
        closing = close(world, grip)
        if not closing.all_touched:
            missing = [f for f, t in zip(robot.FINGERS, closing.touched, strict=True) if not t]
            out.result, out.reason = "not closed", f"{', '.join(missing)} did not touch"
            return out
        sq = squeeze(world, grip)
        out.squeeze_settled = bool(sq.settled)
        out.grip_force = [round(float(f), 3) for f in sq.touch]
        out.pad_force = [round(float(f), 3) for f in world.touch_sensors()]
        points = held_contacts(world, sw.name)
        if points is not None:
            out.measures = grasp_measures(points, sw.target.polygon, sw.target.yaw, load).to_json()
            compliance = grasp_compliance(world, sw.name, weight, DIRECTIONS)
            if compliance is not None:
                out.measures["predicted_turn"] = round(compliance.worst_turn, 6)
                out.measures["predicted_stage"] = compliance.worst_stage
                out.measures["saturated_servos"] = compliance.saturated
            yaw = sw.target.yaw
            demand = held_force_demand(points, sw.target.polygon, sq.touch, weight, yaw)
            d = demand.demand
            out.measures["force_demand"] = None if d is None else round(d, 6)
            out.measures["force_demand_stage"] = demand.worst_stage
            out.measures["points"] = np.round(points, 5).tolist()
        physical_test(sw, grip, out, snapshot)
    except SimulationError as e:
        out.result, out.reason = "sim error", str(e)
    return out


def _hand_adr(world: World) -> np.ndarray:
    return RobotIndices.of(world.model).finger_qpos.ravel()


@dataclass(frozen=True)
class Job:
    """A chunk of grasps of one object and controller (a unit of work for one process)."""

    obj: str
    obj_index: int
    controller: str
    controller_index: int
    indices: tuple[int, ...]
    seed: int
    model: str = "planar"
    #: planar model only: take every contact this far (m) below the top instead of at its
    #: fingertip's height (the probe behind the 3-D band: docs/findings.md, "Depth of a top grasp's
    #: contacts")
    depth: float | None = None
    #: the hand on the arm (``World.build``'s kinds; --hand)
    hand: str = DEFAULT_HAND
    #: 3-D model: common heights tried in turn (--height-tries; 1: only the task's best)
    height_tries: int = HEIGHT_TRIES
    #: an unreachable grasp is synthesized once more from contacts the hand holds (--regrasp)
    regrasp: bool = True
    #: how each grasp's world differs from the nominal one (--perturb; None: it does not),
    #: drawn from the grasp's seed words (seed, object, index): the same perturbed block for
    #: the three controllers' grasp of one index
    perturb: str | None = None


def initial_contacts(job: Job, index: int) -> tuple[list[float], np.random.Generator]:
    """The grasp's initial contacts (uniform in theta) and the generator that then feeds the
    controller's noise."""
    rng = grasp_seed(job.seed, job.obj_index, job.controller_index, index)
    return [float(t) for t in rng.uniform(0.0, 2.0 * np.pi, 4)], rng


def run_job(job: Job, snapshot: Snapshot | None = None) -> list[dict]:
    """Every grasp of ``job``, as JSON-ready dicts, in index order."""
    sw = StudyWorld.of(job.obj, job.model, job.hand)
    composer = make_composer(job.controller)
    out = []
    for i in job.indices:
        theta0, rng = initial_contacts(job, i)
        o = GraspOutcome(job.obj, job.controller, i, theta0, model=job.model, depth=job.depth)
        taken = sw.perturbed(job.perturb, (job.seed, job.obj_index, i))
        if taken.world.perturbation is not None:
            o.perturbation = taken.world.perturbation.to_json()
        test_grasp(
            taken,
            composer,
            rng,
            o,
            snapshot,
            depth=job.depth,
            height_tries=job.height_tries,
            regrasp=job.regrasp,
        )
        out.append(o.to_json())
    return out
