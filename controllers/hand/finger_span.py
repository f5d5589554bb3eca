"""A fingertip target no joint angles of its finger can reach, found without inverse kinematics.

The reach test of section 5.2's reachability criterion
(:func:`controllers.hand.reachability.check_reach`) runs the hand IK with the arm held, so each
finger's base is fixed. A finger's four hinge joints rotate its links about their anchors; the
distance between consecutive anchors (and from the last anchor to the fingertip site) is the same in
every posture, so the fingertip is never farther from the first joint's anchor (which its own
rotation does not move) than the sum of those distances, the finger's span. A target farther than
span + tolerance from that anchor leaves the fingertip more than the tolerance short in every
posture: the IK's verdict is "unreachable" before it runs. Posture Control's palm-pose searches
(:mod:`controllers.preshape.palm_search`) test hundreds of palm poses where the block is out of a
finger's span; this test lets them skip the IK there.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from hand_sim import robot
from hand_sim.indices import RobotIndices

#: Rounding allowance (m) added to a finger's span: a target is out of reach only when it is
#: farther than span + tolerance + this.
SPAN_SLACK = 1e-6


@dataclass(frozen=True)
class FingerSpans:
    """Each finger's (ff, mf, rf, th) first-joint anchor in the world (``base``, (4, 3)) for one
    configuration, and its span (``span``, (4,), m): the sum of the distances from anchor to
    anchor along the finger and from the last anchor to the fingertip site, an upper bound of
    the fingertip's distance from ``base`` in every finger posture."""

    base: NDArray[np.float64]
    span: NDArray[np.float64]

    @classmethod
    def of(cls, model: mujoco.MjModel, data: mujoco.MjData) -> FingerSpans:
        """The spans of ``model`` with the anchors of ``data`` (its kinematics computed)."""
        idx = RobotIndices.of(model)
        joints = idx.hand_joints.reshape(len(robot.FINGERS), robot.JOINTS_PER_FINGER)
        anchors = data.xanchor[joints]  # (4, 4, 3)
        chain = np.concatenate([anchors, data.site_xpos[idx.tip_sites][:, None]], axis=1)
        links = np.linalg.norm(np.diff(chain, axis=1), axis=2)
        return cls(base=anchors[:, 0].copy(), span=links.sum(axis=1))

    def out_of_reach(self, targets: ArrayLike, tolerance: float) -> NDArray[np.bool_]:
        """(4,) True for each finger whose fingertip target (row of ``targets``, (4, 3)) is
        farther than its span + ``tolerance`` (+ :data:`SPAN_SLACK`) from its base: no posture
        of that finger brings its fingertip within ``tolerance`` of the target."""
        distance = np.linalg.norm(np.asarray(targets, dtype=float) - self.base, axis=1)
        return distance > self.span + tolerance + SPAN_SLACK
