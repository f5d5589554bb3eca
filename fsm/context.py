"""What the states of one episode share: the options it was started with and what each state
learned (the perceived block, the plan, the contacts, the grip), in one dataclass that travels
from state to state (no globals, nothing hidden in the World)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.grasp.composition import Composer
from controllers.grasp.synthesis import GraspSynthesis
from controllers.grasp.synthesis3d import GraspSynthesis3D
from controllers.hand.finger_assignment import FingerContacts
from controllers.hand.finger_geometry import PerceivedPrism
from controllers.hand.grip import Grip
from controllers.hand.reachability import HandReach
from controllers.planning.belief_world import BeliefWorld
from controllers.reach.coarse import CoarseReachPlan, ReachTarget
from fsm.config import DEFAULT_CONFIG, TaskConfig
from fsm.recorder_protocol import NullRecorder, TaskRecorder
from fsm.states import Failure
from hand_sim.world import DEFAULT_HAND, HAND_KINDS, World

if TYPE_CHECKING:
    from controllers.hand.finger_samples import FingerSamples
    from controllers.preshape.palm_candidates import PalmPose
    from fsm.user_protocol import ClickedBlock, UserChannel
    from vision import ObjectModel, Selection

#: Controllers and approaches the command line accepts.
CONTROLLERS = ("pi", "kb", "ql")
APPROACH_CHOICES = ("auto", "top", "lateral")
#: Grasp models of a top grasp (``--model``).
GRASP_MODELS = ("planar", "3d")
#: Chosen by the bench and the physical study: docs/findings.md, "Which grasp model by default".
DEFAULT_GRASP_MODEL = "3d"
#: Hands the arm can carry (``--hand``; hand_sim.assembly.HAND_KINDS).
HANDS = HAND_KINDS
#: What Deliver may do when it cannot set the block down at the place point asked for: "none"
#: fails the episode there (the default: an episode is judged where it was asked to deliver);
#: "nearest" delivers to the nearest free slot and reports it as delivered elsewhere.
PLACE_FALLBACKS = ("none", "nearest")
#: Who chose a cycle's place point (``CycleRecord.place_chosen_by``).
PLACE_BY_USER, PLACE_BY_SCENE, PLACE_BY_TASK = "user", "scene", "task cycle"


@dataclass(frozen=True)
class EpisodeOptions:
    """How an episode was asked for (``python -m fsm.run`` flags)."""

    scene: str = "clutter3"
    seed: int = 0
    blocks: int | None = None  #: number of blocks of a random scene
    pick: str | None = None  #: block name to pick first
    pick_pixel: tuple[float, float] | None = None  #: (u, v) in the vision image
    place: tuple[float, float] | None = None  #: world (x, y) of the first place point
    place_pixel: tuple[float, float] | None = None
    place_fallback: str = "none"  #: one of PLACE_FALLBACKS
    controller: str = "pi"
    approach: str = "auto"
    #: "planar" (the paper's controllers, contacts at the fingertips' height) or "3d" (contacts
    #: with heights, controllers.grasp.synthesis3d) for a top grasp
    grasp_model: str = DEFAULT_GRASP_MODEL
    cycles: int | None = 1  #: None: all blocks
    out: Path = Path("runs/clutter3-0")
    record: bool = True
    models: Path | None = None  #: trained models folder (default: the shipped ones)
    #: the hand on the arm: "servo" (models/hand.xml) or "tendon" (models/utah_mit_hand/)
    hand: str = DEFAULT_HAND
    config: TaskConfig = DEFAULT_CONFIG  #: the task cycle's tuning (fsm.config)
    #: how the simulated world differs from the scene (``--perturb NAME[=SCALE],...`` or
    #: ``none``; hand_sim.perturb); None: the scene file's ``[perturb]`` table, if any
    perturb: str | None = None


@dataclass
class CycleRecord:
    """What one pick-and-place cycle did, for the summary."""

    index: int
    block: str | None = None  #: scene name of the picked block (for judging)
    #: the place point asked for (--place, --place-pixel or the scene's; None in later cycles of
    #: --cycles, where no point was asked for), who chose the point used (PLACE_BY_*), the point
    #: the block was taken to and judged at, and whether that is another point than the asked
    #: one (--place-fallback nearest), how far (mm) from it
    place_asked: tuple[float, float] | None = None
    place_chosen_by: str = ""
    place_used: tuple[float, float] | None = None
    delivered_elsewhere: bool = False
    place_moved_mm: float | None = None
    approach: str = ""
    #: the approach axis's pitch below the horizontal (deg): 90 for a top grasp, 0 for a
    #: lateral one, 15-45 where the arm reaches a lateral goal only pitched down
    #: (controllers.reach.coarse.LATERAL_TILTS)
    approach_pitch_deg: float | None = None
    #: a lateral palm beyond the block facing back towards the arm's base (no goal on the
    #: base's side: controllers.reach.coarse.plan_coarse_reach)
    approach_far_side: bool = False
    #: under --approach auto, the approach given up because its grasp proved unreachable at its
    #: end, and why ("top: contact unreachable ...": fsm.recovery.other_approach_left); "" otherwise
    approach_given_up: str = ""
    polygon: list[list[float]] | None = None  #: perceived vertices, object frame (m)
    polygon_error: dict[str, float] | None = None  #: against the true footprint
    #: why each other block Select/Model could not model was not (each then counts as an
    #: obstacle: its pixels' hull grown by fsm.perception.OBSTACLE_MARGIN)
    obstacles_not_modelled: list[str] = field(default_factory=list)
    #: blocks a later cycle could not model and passed over for the next one, and why
    skipped_not_modelled: list[str] = field(default_factory=list)
    contacts: list[list[float]] | None = None  #: world contact points, finger order
    #: the fingers that took ``contacts`` (all four, or a three-contact lateral grasp's three)
    contact_fingers: list[str] | None = None
    contact_theta: list[float] | None = None
    s_g: float | None = None
    synthesis_steps: int = 0
    converged: bool = False
    posture_retries: int = 0
    regrasps: int = 0  #: restarts from Fine Reach with the hand turned or moved
    #: lateral grasps taken again after the block slipped at the lift (each also a regrasp)
    lift_retries: int = 0
    fine_reach_loops: int = 0
    reach_reasons: list[str] = field(default_factory=list)
    grip_forces: list[float] | None = None  #: N per finger after the squeeze
    grip_target: list[float] | None = None
    #: a lateral grasp's friction reserve (N) at its planned contacts, squeezed as hard in all as
    #: the hand squeezes, by the 3-D grasp force programme (controllers.grasp.holding; None: a
    #: top grasp, or no forces hold the weight by the model)
    squeeze_reserve: float | None = None
    lift_height: float | None = None  #: m, block rise during the lift
    lift_slip: float | None = None  #: m, palm rise minus block rise
    #: N, the load the wrist measured after the lift (sensed: the block's weight)
    lift_weight: float | None = None
    #: the overhead camera's calibration corrected against the table at this cycle's look
    #: (vision.calibration): {"shift_mm", "turn_deg"}; None when it had not drifted
    camera_recalibrated: dict[str, float] | None = None
    #: mm each fingertip (ff, mf, rf, th) moved in the palm's frame during the lift (sensed)
    lift_tip_motion_mm: list[float] | None = None
    #: deg, the block's tilt at the top of the lift, for judging only (not sensed)
    lift_tilt_deg: float | None = None
    lift_clearance: float = 0.0  #: m, highest block bottom above the table while carried
    #: how Deliver's plan lowers the block: "" keeping the planning clearance with the hand as
    #: it holds it, else how it does (controllers.deliver.plan: nearer its neighbours, from above
    #: them, turned about the place point)
    set_down: str = ""
    judgement: dict[str, Any] | None = None
    success: bool = False
    failure: str | None = None
    failure_detail: str = ""
    #: the picked block's true position (3,) when Select/Model saw it, for judging only
    block_start: list[float] | None = None
    #: a failed cycle's block as the simulation has it then (fsm.judge.block_at_failure): tilt,
    #: distance from block_start, knocked over
    block_at_failure: dict[str, Any] | None = None


@dataclass
class Episode:
    """The running episode: options, world, and what the states have learned so far.

    ``world`` is the robot's view of the world (a
    :class:`~controllers.planning.belief_world.BeliefWorld` over the simulated world): the
    nominal robot, the blocks the camera saw, the sensors' readings; every state reads and
    commands it. ``truth``, the simulated world itself, is for the judge and the summary's
    judged fields only (:mod:`fsm.judge`)."""

    options: EpisodeOptions
    world: BeliefWorld
    rng: np.random.Generator
    composer: Composer
    #: what the states tell the recording (fsm.recording.EpisodeRecorder; by default nothing)
    recorder: TaskRecorder = field(default_factory=NullRecorder)
    cycle: int = 0
    cycles: list[CycleRecord] = field(default_factory=list)
    delivered: list[str] = field(default_factory=list)  #: scene names of delivered blocks
    place: NDArray[np.float64] | None = None
    #: the arm's posture when the first Select/Model looked (parked clear of the view); Deliver
    #: returns the arm there before the next cycle's Select/Model
    parked_arm: NDArray[np.float64] | None = None
    #: the other blocks' perceived footprints and the picked block's circumradius (m), for the
    #: next place slot when the hand cannot set the block down at this cycle's first
    place_footprints: list[NDArray[np.float64]] = field(default_factory=list)
    place_radius: float = 0.0
    # Select/Model
    selection: Selection | None = None  #: the current view, segmented into blocks
    model: ObjectModel | None = None  #: the picked block as vision models it
    target: ReachTarget | None = None
    planning: mujoco.MjModel | None = None
    prism: PerceivedPrism | None = None
    others_before: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    # reach and grasp
    coarse: CoarseReachPlan | None = None
    posture_mode: str = "hold"  #: "hold" (after Fine Reach) or "contacts" (from Wrench Closure)
    synthesis: GraspSynthesis | GraspSynthesis3D | None = None
    contacts: FingerContacts | None = None
    reach: HandReach | None = None
    grip: Grip | None = None
    empty_hand_force: NDArray[np.float64] | None = None
    expected_load: float = 0.0  #: N, perceived volume x wood density x g
    #: N, the block's weight as the wrist measured it after the lift (the nominal
    #: ``expected_load`` with ``closed_loop.sensed_weight`` off)
    held_weight: float = 0.0
    #: sampled finger postures for lateral reachability searches (drawn on first use)
    finger_samples: FingerSamples | None = None
    #: a top grasp's palm poses of the last palm-pose search and what they were computed from
    #: (the world's qpos, the coarse reach's palm rotation, the target and planning model): a
    #: search repeated before anything has moved takes them again
    top_poses: tuple[tuple[bytes, bytes, int, int], list[PalmPose]] | None = None
    #: a lateral grasp's last contacts the hand reached in this synthesis: (theta, contacts,
    #: reach, step), or None
    last_reachable: tuple[NDArray[np.float64], FingerContacts, HandReach, int] | None = None
    #: the lateral pre-shape's contacts (a FingerContacts the reach test passed at its palm
    #: pose): Fine Reach's targets and the grasp controller's start; None without one
    preshape_contacts: FingerContacts | None = None
    #: the hand posture (16,) that took the sampled pre-shape's contacts in its reach test: the
    #: hand IK's start of the reach tests that follow (None without a sampled pre-shape)
    preshape_hand_q: NDArray[np.float64] | None = None
    #: the wrist rolls (rad) about the approach axis Posture Control's lateral search keeps
    #: after a sampled pre-shape taken at ``PalmPoseParams.lateral_more_rolls``; None: its own
    preshape_rolls: tuple[float, ...] | None = None
    #: after a lateral grasp failed with the fingers on the block and the camera looked again
    #: (fsm.recovery.look_again): (Failure, reason) the episode fails with when Coarse Reach
    #: finds no further palm pose; None otherwise
    regrasp_failure: tuple[Failure, str] | None = None
    #: after a lateral grasp lost its block at the lift, with
    #: ``config.lateral_retry_by_reserve``: that grasp's friction reserve (N, -inf where no
    #: forces held the weight by the 3-D model); the next pre-shapes take only grasps above it
    #: while any is left. None otherwise
    retry_floor: float | None = None
    #: after the lateral pre-shape search passed over ``config.lateral_grasp_set_down_checks``
    #: grasps that could not set the block down
    #: (controllers.preshape.set_down_check.SetDownGate): the pitch (rad) of the lateral axis
    #: Coarse Reach takes at least; inf once no further pitch had a path (the gate then takes
    #: poses unasked once spent); None otherwise
    set_down_floor: float | None = None
    #: under --approach auto, the approaches given up in this cycle because their grasp proved
    #: unreachable at their end (fsm.recovery.other_approach_left); Coarse Reach plans the others
    closed_approaches: tuple[str, ...] = ()
    #: the finished top 3-D synthesis whose next-best common heights Posture Control has
    #: searched (once per synthesis), or None
    heights_searched: GraspSynthesis3D | None = None
    config: TaskConfig = DEFAULT_CONFIG  #: the task cycle's tuning (fsm.config)
    #: interactive mode (fsm.interactive): the user who clicks the block and the place point
    #: (fsm.user_protocol); None in a batch episode, which never waits for anyone
    user: UserChannel | None = None
    #: the click Wait for Block took for this cycle, until Select/Model takes its block
    clicked: ClickedBlock | None = None
    #: the simulated world ``world`` is the robot's view of, for the judge (None: ``world`` is
    #: the simulated world itself)
    truth: World | None = None

    @property
    def simulated(self) -> World:
        """The simulated world, for the judge and the summary's judged fields only."""
        return self.world if self.truth is None else self.truth

    @property
    def record(self) -> CycleRecord:
        """The current cycle's record."""
        return self.cycles[-1]

    @property
    def target_name(self) -> str:
        """Scene name of the picked block (known to the simulator; used to address its body)."""
        name = self.record.block
        if name is None:
            raise RuntimeError("no block has been picked in this cycle")
        return name

    def use_place(self, point: NDArray[np.float64]) -> None:
        """Take this cycle's block to ``point`` (world xy): the record's ``place_used``, and
        whether it lies elsewhere than the point asked for, how far, and the recording."""
        self.place = np.asarray(point, dtype=float)
        record = self.record
        record.place_used = (float(self.place[0]), float(self.place[1]))
        if record.place_asked is not None:
            moved = float(np.linalg.norm(self.place - np.asarray(record.place_asked)))
            record.place_moved_mm = 1000.0 * moved
            record.delivered_elsewhere = moved > 1e-9
        self.recorder.log_place(
            record.place_asked, record.place_used, self.world.scene.table.height
        )

    def new_cycle(self) -> CycleRecord:
        self.cycles.append(CycleRecord(index=len(self.cycles)))
        self.model = self.target = self.planning = self.prism = None
        self.coarse = self.synthesis = self.contacts = self.reach = self.grip = None
        self.top_poses = None
        self.preshape_hand_q = None
        self.preshape_rolls = None
        self.regrasp_failure = None
        self.retry_floor = None
        self.set_down_floor = None
        self.closed_approaches = ()
        self.posture_mode = "hold"
        return self.record


def out_paths(out: Path) -> tuple[Path, Path]:
    """The episode's recording and summary files in folder ``out``."""
    return out / "episode.rrd", out / "summary.json"
