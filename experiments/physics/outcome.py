"""One grasp's record in the physical study (:mod:`experiments.physics.study`): what the
controller synthesized, where the hand took it, what the squeeze reached and how the block moved
under each stage of the physical test; one line of ``results.jsonl``."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field


@dataclass
class GraspOutcome:
    """One grasp of the study. Lengths in m, angles in rad, forces in N."""

    object: str
    controller: str
    index: int
    theta_initial: list[float]
    model: str = "planar"  #: the grasp model the controller ran on ("planar" or "3d")
    depth: float | None = None  #: planar: every contact this far (m) below the top (--depth)
    theta: list[float] = field(default_factory=list)  #: final contact coordinates
    #: 3-D model: the controller's contact heights above the block's centre of mass (m)
    heights: list[float] = field(default_factory=list)
    #: 3-D model: which of the common heights offered the hand took (0: the task's best; the
    #: last tried when none was reachable)
    height_rank: int = 0
    #: 3-D model: how far (m) the hand's common height is above the task's best (0 at rank 0)
    height_raise: float | None = None
    steps: int = 0
    converged: bool = False
    s_g: float | None = None  #: None: the S_G LP is infeasible
    #: "held", "dropped", "unreachable" (no posture reaches the contacts), "not closed" (a finger
    #: never touched), "sim error" (MuJoCo went unstable)
    result: str = ""
    reason: str = ""
    palm_yaw: float | None = None  #: of the palm's x axis about the vertical
    palm_tilt: float | None = None  #: of the palm's approach axis from vertical
    squeeze_settled: bool = False
    #: N per finger after the squeeze, as the hand senses them (World.touch with the grip's
    #: normals: the servo hand's pads, the tendon hand's estimated force into each face)
    grip_force: list[float] = field(default_factory=list)
    #: N per finger after the squeeze, the pads' true normal forces (World.touch_sensors; the same
    #: as grip_force on the servo hand, the ground truth of the estimate on the tendon hand)
    pad_force: list[float] = field(default_factory=list)
    failed_stage: str = ""
    #: --regrasp: the first grasp was unreachable and this one was synthesized from contacts the
    #: hand holds (:mod:`experiments.physics.regrasp`); the first grasp's contacts, why the hand
    #: could not take it, and the second synthesis's initial contacts
    regrasped: bool = False
    first_theta: list[float] = field(default_factory=list)
    first_reason: str = ""
    regrasp_initial: list[float] = field(default_factory=list)
    #: per stage reached: the largest shift and turn of the block in the palm's frame
    shift: dict[str, float] = field(default_factory=dict)
    turn: dict[str, float] = field(default_factory=dict)
    #: the grasp as held at the end of the squeeze, scored (experiments.physics.measures)
    measures: dict = field(default_factory=dict)
    #: how the grasp's world differed from the nominal one (--perturb: what was asked and
    #: drawn, hand_sim.perturb), or None
    perturbation: dict | None = None

    @property
    def tested(self) -> bool:
        return self.result in ("held", "dropped")

    def to_json(self) -> dict:
        return asdict(self)
