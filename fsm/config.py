"""The task cycle's tuning (section 5.2): one frozen dataclass, :class:`TaskConfig`, that an
episode carries (``Episode.config``) and :class:`fsm.context.EpisodeOptions` passes in; a test
or a study changes it with ``dataclasses.replace(DEFAULT_CONFIG, ...)``. The motion primitives'
and the palm-pose search's own parameters are nested
(:class:`controllers.preshape.moves.MotionParams`,
:class:`controllers.preshape.palm_candidates.PalmPoseParams`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from controllers.grasp.score import SUCCESS_THRESHOLD, opposition_floor
from controllers.grasp.task_height import HEIGHT_TRIES
from controllers.preshape.moves import MotionParams
from controllers.preshape.palm_candidates import PalmPoseParams
from fsm.closed_loop import ClosedLoopParams

#: Values of ``TaskConfig.lateral_contacts``.
LATERAL_CONTACTS = ("pinch", "sampled", "sampled-first")
#: Values of ``TaskConfig.lateral_gate_rule``.
LATERAL_GATE_RULES = ("opposition", "paper")


@dataclass(frozen=True)
class TaskConfig:
    """Thresholds, tolerances and limits of the task cycle's states. A ``lateral_*`` rule that
    is on by default stays a switch: a test or a study turns it off to reach the behaviour
    without it (the recovery tests, for instance, to make a grasp slip that the rule avoids)."""

    #: Fine Reach leaves each fingertip this far (m) outside its surface point; Wrench Closure
    #: then works from their projections.
    fine_reach_standoff: float = 0.008
    #: Fine Reach counts as reached with every fingertip this close (m) to its target; beyond
    #: ``fine_reach_give_up`` (m) the fingers cannot reach the block at all.
    fine_reach_tolerance: float = 0.006
    fine_reach_give_up: float = 0.03
    #: Posture Control after Fine Reach: fingertips may drift this far (m) before Fine Reach
    #: repeats.
    posture_drift: float = 0.005
    #: Wrench Closure checks the contacts' reachability every this many controller steps and at
    #: the end (the paper: "until convergence, or until the reachability criterion is no longer
    #: satisfied").
    reach_check_every: int = 10
    #: How far (m) past its contact a lateral grasp's fingertip must reach (SQUEEZE_REACH for a
    #: top grasp). A lateral squeeze runs along each finger's normal-squeeze direction, past the
    #: inside posture by extrapolation (controllers.hand.grip.plan_grip, along_normal), so the
    #: reach only has to show that the pad gets into the face.
    #: Chosen by its effect on lateral episodes: docs/findings.md, "A lateral squeeze reach".
    lateral_squeeze_reach: float = 0.004
    #: Where a lateral pre-shape's contacts come from: "sampled-first" (default), the
    #: lowest-S_G combination of contacts the hand's sampled finger postures take at palm poses
    #: beside the block (controllers.preshape.lateral_grasp; each contact then stays on its own
    #: face, the fingers come in along its normal), the pinch pre-shape's (the points across the
    #: approach axis from its fingertips) only where no pose has one. Study settings: "sampled",
    #: the pinch's first and the sampled ones where no pose reaches the pinch's; "pinch", the
    #: pinch's only (the recovery tests reach a finger held off its surface point with it).
    #: Measured: docs/findings.md, "Sampled contacts first".
    lateral_contacts: str = "sampled-first"
    #: The S_G (Eq. 13) a lateral grasp must reach: the paper's 0.4 by default; a study
    #: setting (``--lateral-gate``). The grasps a lateral hand beside the block can take score
    #: 0.50 on many blocks (the thumb against three fingers on parallel faces pushes three
    #: times as hard) and 0.57-0.58 on triangles (two faces, friction carries the rest). Above
    #: 0.4, a sampled grasp scoring up to the gate is the pre-shape only where none scores 0.4
    #: and the pinch reaches nothing, and Wrench Closure accepts a lateral grasp up to it.
    #: Measured on the lateral bench: docs/findings.md, "Eq. 13's gate bounds the lateral grasp".
    lateral_gate: float = SUCCESS_THRESHOLD
    #: Where no palm pose has a sampled grasp of four contacts within the gate, the lateral
    #: pre-shape takes one of three: the thumb against two fingers, the third finger held
    #: clear of the block (controllers.preshape.lateral_grasp.three_contact_lateral_grasp;
    #: Eq. 13 over three contacts: a thumb against two fingers on parallel faces scores 0.33
    #: where against three it scores 0.50). Before the pinch pre-shape.
    #: Measured: docs/findings.md, "Three contacts where four cannot pass Eq. 13".
    lateral_three_contacts: bool = True
    #: How ``lateral_gate`` applies to a lateral grasp of n contacts. "opposition" (default):
    #: S_G <= lateral_gate + (n - 2) / n, the gate counted from Eq. 13's floor for a thumb
    #: against the other n - 1 fingers (controllers.grasp.score.opposition_floor: 0.5 for
    #: four contacts, 1/3 for three), because a lateral hand's fingers all stand across the
    #: block from its thumb; the gate's paper values, 0.4, before any grasp above them, and
    #: before the pinch. "paper": S_G <= lateral_gate, whatever the hand (a study setting,
    #: ``--lateral-gate-rule``). Section 3.5 calls where the cutoff sits "completely
    #: arbitrary", and section 5.2's Wrench Closure runs to convergence.
    #: Measured: docs/findings.md, "Eq. 13's gate counted from the thumb's opposition".
    lateral_gate_rule: str = "opposition"
    #: A lateral squeeze's pressing finger that feels nothing closes again at the closing
    #: speed (controllers.hand.grip.squeeze ``seek``): a balanced lateral squeeze gives a light
    #: finger a few tenths of a newton, and the force loop alone moves it a few millimetres a
    #: second towards a face the other fingers have pushed away.
    #: Measured on the lateral bench: docs/findings.md, "A light finger that seeks its face".
    lateral_squeeze_seek: bool = True
    #: A lateral hand leaving a block standing on the table rises until its fingertips clear
    #: the block's top before it backs off (controllers.deliver.carry.retreat ``clear_top``):
    #: backing off first drags a block set down upright and may tip it.
    #: Measured on the lateral bench: docs/findings.md, "A retreat that rises first".
    lateral_retreat_rise: bool = True
    #: A lateral squeeze presses with the normal forces that hold the block's perceived weight
    #: with the most friction to spare at the planned contacts, each at most GRIP_FORCE
    #: (controllers.grasp.holding: a 3-D grasp force programme, clarabel); False: the shares
    #: that balance the planned contacts by least squares, without the weight or the friction
    #: cones (controllers.hand.grip.balanced_shares).
    #: Measured on the lateral bench: docs/findings.md, "A squeeze that holds the weight".
    lateral_holding_forces: bool = True
    #: The sampled lateral pre-shape search tries, within each band of S_G, the palm poses
    #: whose grasp keeps a friction reserve by the 3-D model (controllers.hand.lateral_squeeze)
    #: before those whose grasp does not.
    #: Measured on the lateral bench: docs/findings.md, "A squeeze that holds the weight".
    lateral_reserve_first: bool = True
    #: The sampled lateral pre-shape search tries the palm poses whose grasp keeps a friction
    #: reserve by the 3-D model in every band of S_G before any whose grasp does not (the bands
    #: searched once for each tier of ``lateral_reserve_margin``, in their order).
    #: Measured on the lateral bench: docs/findings.md, "Grasps that hold before the bands".
    lateral_reserve_before_bands: bool = True
    #: With ``lateral_reserve_before_bands``, the search's first pass takes only the grasps
    #: whose friction reserve by the 3-D model is at least this (N), then a pass takes those
    #: that keep less but some, then the rest (0: the two passes without a margin; the recovery
    #: tests use it to reach a grasp that slips at the lift). A finger presses as hard as the
    #: tendon hand's estimate says (hand_sim.contact_estimate), whose error's 90th percentile
    #: per finger is 1.0-1.6 N at the squeeze's forces (docs/models.md): a reserve below that is
    #: within what the squeeze cannot tell.
    #: Chosen by the lifts of the lateral bench: docs/findings.md, "A reserve the squeeze can tell".
    lateral_reserve_margin: float = 1.0
    #: With ``--model 3d``, when Posture Control finds no arm posture for a finished top grasp's
    #: contacts at the task's common height, it searches at the next-best common heights (by
    #: the worst-task S_G, 5 mm apart), once per synthesis: this many heights in all (1: only
    #: the task's; controllers.grasp.task_height.HEIGHT_TRIES).
    #: Set before any result with it was seen: docs/findings.md, "The next-best common heights".
    height_tries: int = HEIGHT_TRIES
    #: Regrasps after the contacts stay out of reach, and how a top grasp's hand is turned (rad)
    #: for each (``regrasp_rolls``).
    #: Chosen by its effect on the bench: docs/findings.md, "Four regrasps".
    max_regrasps: int = 4
    #: Lateral grasps: times a block that slipped at the lift (and still stands where the
    #: overhead camera sees it, as modelled) is grasped again, from the next palm pose, each
    #: counting as a regrasp (the lift as the grasp's test, fsm.recovery.look_again).
    #: Set before any episode with it ran: docs/findings.md, "The lift as the grasp's test".
    lift_retries: int = 1
    #: Lateral grasps: after a grasp lost its block at the lift, the regrasp takes only palm
    #: poses whose grasp keeps more friction in reserve by the 3-D model than the one that
    #: slipped (strictly more, in their usual order), and the next pose in order only where
    #: none is left (fsm.handlers.coarse_reach).
    #: Measured: docs/findings.md, "The regrasp after a slip keeps more reserve".
    lateral_retry_by_reserve: bool = True
    #: Lateral grasps: a block that the hand still holds at the top of the lift, but whose
    #: pressing fingertips moved more than this (m) in the palm's frame as it rose (it turned or
    #: slid in the hand: sensed by the hand's kinematics), is lowered back onto the table and
    #: grasped again (``lift_retries``), instead of being carried tilted and set down on an
    #: edge; with no lift retry left it is carried as held. 0 turns it off.
    #: Chosen by the fingertips' motion: docs/findings.md, "A block that turns in the hand".
    lateral_tip_motion_limit: float = 0.002
    #: Lateral grasps: Coarse Reach first asks whether a hand holding the block as its goal
    #: would can set it down at the place point, and where it cannot, takes the first goal
    #: pitched further down (controllers.reach.coarse.LATERAL_TILTS) whose hand can
    #: (controllers.preshape.set_down_check.pitch_for_set_down).
    #: Measured: docs/findings.md, "A lateral approach pitched for its set-down".
    lateral_set_down_pitch: bool = True
    #: Lateral grasps: the sampled pre-shape's palm-pose search passes over a pose whose grasp
    #: (the hand at its contacts) cannot set the block down at the place point, as it passes
    #: over one whose approach collides (controllers.preshape.set_down_check.SetDownGate),
    #: until this many poses have been passed over for it in one search. Then, while a lateral
    #: axis pitched further down is left (controllers.reach.coarse.LATERAL_TILTS), Coarse Reach
    #: is entered again for it; at the last pitch the poses after are taken unasked. 0 turns it
    #: off.
    #: Measured on the lateral bench: docs/findings.md, "Each grasp asked for its own set-down".
    lateral_grasp_set_down_checks: int = 4
    regrasp_rolls: tuple[float, ...] = (np.pi / 4, -np.pi / 4, np.pi / 2, -np.pi / 2)
    #: The held load must be at least this share of the perceived block's weight after the lift,
    #: and during the carry (wrist sensor), else the block slipped / was dropped.
    min_held_share: float = 0.5
    #: Pads that carry at least this share of the grip's mean force count for the lift's slip
    #: check in a lateral grasp.
    carrying_share: float = 0.5
    #: A carried block counts as dropped when, over ``drop_window`` control periods, fewer than
    #: two pads feel it; after the carry, at rest, the wrist sensor must still show
    #: ``min_held_share`` of its weight. (The wrist's load while the arm moves is not a drop
    #: sensor: the accelerometer at the wrist does not see the hand's rotational accelerations;
    #: docs/findings.md, "The wrist is not a drop sensor".)
    drop_window: int = 15
    #: Place slots a later cycle tries when the hand cannot set its block down at the first.
    max_place_slots: int = 4
    #: Horizontal distances (m) from the arm's base a place slot may lie at.
    place_reach: tuple[float, float] = (0.35, 0.95)
    #: Time (s) the hand holds still after the carry before the wrist sensor weighs the load.
    weigh_time: float = 0.3
    #: The motion primitives' distances and times (retract, reposition, pre-shape, approach).
    motion: MotionParams = field(default_factory=MotionParams)
    #: Posture Control's palm poses and limits.
    palm_pose: PalmPoseParams = field(default_factory=PalmPoseParams)
    #: The closed-loop corrections for a world that differs from the robot's model
    #: (fsm.closed_loop; docs/robustness.md).
    closed_loop: ClosedLoopParams = field(default_factory=ClosedLoopParams)

    def __post_init__(self) -> None:
        if self.lateral_contacts not in LATERAL_CONTACTS:
            raise ValueError(
                f"lateral_contacts must be one of {', '.join(LATERAL_CONTACTS)}; "
                f"got {self.lateral_contacts!r}"
            )
        if self.lateral_gate_rule not in LATERAL_GATE_RULES:
            raise ValueError(
                f"lateral_gate_rule must be one of {', '.join(LATERAL_GATE_RULES)}; "
                f"got {self.lateral_gate_rule!r}"
            )
        for name, what in (
            ("lift_retries", "retries"),
            ("lateral_grasp_set_down_checks", "palm poses to pass over"),
        ):
            count = getattr(self, name)
            if isinstance(count, bool) or not (isinstance(count, int) and count >= 0):
                raise ValueError(
                    f"{name} must be a whole number of {what}, 0 or more; got {count!r}"
                )
        if not (
            np.isfinite(self.lateral_tip_motion_limit)
            and 0.0 <= self.lateral_tip_motion_limit < 0.02
        ):
            raise ValueError(
                "lateral_tip_motion_limit must lie in [0, 0.02) m (0: off); "
                f"got {self.lateral_tip_motion_limit!r}"
            )
        margin = self.lateral_reserve_margin
        if not (np.isfinite(margin) and margin >= 0.0):
            raise ValueError(
                f"lateral_reserve_margin must be a friction reserve of 0 N or more; got {margin!r}"
            )
        if not (np.isfinite(self.lateral_gate) and self.lateral_gate > 0.0):
            raise ValueError(
                f"lateral_gate must be a positive S_G (Eq. 13; the paper's is "
                f"{SUCCESS_THRESHOLD}); got {self.lateral_gate!r}"
            )

    def lateral_gate_for(self, contacts: int) -> float:
        """The S_G (Eq. 13) a lateral grasp of ``contacts`` contacts must reach, by
        ``lateral_gate_rule``."""
        if self.lateral_gate_rule == "paper":
            return self.lateral_gate
        return self.lateral_gate + opposition_floor(contacts)


DEFAULT_CONFIG = TaskConfig()
