"""What the robot's hand senses (section 5.1: the Utah/MIT hand's tendon tension sensors and the
wrist's force/torque sensor; the generic hand's fingertip touch pads), as methods of
:class:`hand_sim.world.World`: the fingertip forces (the pads, or the estimate from the tendon
tensions, :mod:`hand_sim.contact_estimate`), the wrist's force, torque and acceleration in world
axes, the tensions and the joint torques.

Each reading comes from the world's own model and data through hooks that a world standing for
the robot's belief (``controllers.planning.belief_world``) replaces with the simulated sensors':
:meth:`HandSenses.wrist_readings` (the wrist sensors in their own frame),
:meth:`HandSenses.touch_sensors` and :meth:`HandSenses.pad_forces` (the pads' forces against
anything not the robot); the frames and the estimate use the world's kinematics.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from hand_sim import robot
from hand_sim.contact_estimate import DETECTION_THRESHOLD, ContactEstimate
from hand_sim.errors import HandSimError

#: What :meth:`HandSenses.touch` reads: the fingertip touch pads (the servo hand), or the contact
#: forces estimated from the tendon tensions (the tendon hand, :mod:`hand_sim.contact_estimate`).
TOUCH_PADS, TOUCH_TENDONS = "touch pads", "tendon-tension estimate"


class HandSenses:
    """The hand's senses, for a class with a compiled ``model`` and its ``data``, the robot's
    indices ``_idx``, the tendon hand's ``contact_estimator``, ``tendon_drive`` and
    ``friction_memory`` (None for the servo hand), ``hand`` and ``_require_robot``
    (:class:`hand_sim.world.World`)."""

    @property
    def touch_source(self) -> str:
        """What :meth:`touch` reads: :data:`TOUCH_PADS` or :data:`TOUCH_TENDONS`."""
        return TOUCH_TENDONS if self.contact_estimator is not None else TOUCH_PADS

    @property
    def touch_floor(self) -> float:
        """Force (N) at or below which :meth:`touch` means "no contact" (a lost grip): 0 for the
        touch pads; the estimate's error floor for the tendon hand
        (:data:`hand_sim.contact_estimate.DETECTION_THRESHOLD`)."""
        return DETECTION_THRESHOLD if self.contact_estimator is not None else 0.0

    def touch_felt(self, threshold: float, forces: ArrayLike | None = None) -> NDArray[np.bool_]:
        """(4,) whether a guard may take each finger for touching now: with touch pads, its pad
        force (``forces``, default :meth:`touch_sensors`) above ``threshold``; for the tendon
        hand, the least pad force its tensions allow, every stuck joint's friction anywhere in
        [-F, F] (:attr:`~hand_sim.contact_estimate.ContactEstimate.least`), above ``threshold``
        and :data:`~hand_sim.contact_estimate.DETECTION_THRESHOLD`: a finger that friction alone
        could hold where it is is not taken for a touching one, and a finger pressing harder than
        its friction could explain is, however unsure the estimate's friction."""
        if self.contact_estimator is None:
            self._require_robot()
            pads = self.touch_sensors() if forces is None else np.asarray(forces, dtype=float)
            return pads > threshold
        least = self.contact_estimator.estimate(
            self.model, self.data, self.friction_memory.direction, least=True
        ).least
        return np.asarray(least) > max(threshold, DETECTION_THRESHOLD)

    def touch(self, normals: ArrayLike | None = None) -> NDArray[np.float64]:
        """(4,) fingertip normal forces (N), order ff, mf, rf, th, as the hand senses them: the
        servo hand's touch pads (:meth:`touch_sensors`); the tendon hand, which like the real
        Utah/MIT hand has no fingertip sensors, the estimate from its tendon tensions and joint
        angles (:meth:`contact_estimate`). :attr:`touch_source` says which. ``normals`` (4, 3):
        the contacts' outward face normals (world axes), when the caller knows them (a planned
        grip): the tendon hand then reports each estimated force's component into its face
        (the pads measure the normal force anyway)."""
        if self.contact_estimator is not None:
            return self.contact_estimate(normals).normal
        return self.touch_sensors()

    def touch_sensors(self) -> NDArray[np.float64]:
        """(4,) fingertip touch sensor readings (N), order ff, mf, rf, th: the normal force on the
        palmar side and tip of each distal pad (contacts on the back of a fingertip, or on other
        finger links, are not felt; :func:`hand_sim.contacts.hand_contacts` lists those). Both
        hands have them; for the tendon hand they are the ground truth its estimate is judged
        against, not something its guards read."""
        self._require_robot()
        return self.data.sensordata[self._idx.touch_adr].copy()

    def contact_estimate(self, normals: ArrayLike | None = None) -> ContactEstimate:
        """The tendon hand's fingertip forces estimated from its 32 tension sensors and joint
        angles (:class:`~hand_sim.contact_estimate.ContactEstimator`; ``normals``: the contacts'
        outward face normals, as in :meth:`touch`); raises for the servo hand."""
        self._require_robot()
        if self.contact_estimator is None:
            raise HandSimError(f"the {self.hand} hand has no tendons to estimate forces from")
        faces = None if normals is None else np.asarray(normals, dtype=float).reshape(4, 3)
        return self.contact_estimator.estimate(
            self.model, self.data, self.friction_memory.direction, normals=faces
        )

    def wrist_wrench(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The wrist force/torque sensor between the arm's flange and the hand: force (3,) in N
        and torque (3,) in N m that the flange exerts on the hand, in world axes. With the hand
        at rest it carries the hand's weight plus whatever the hand holds."""
        self._require_robot()
        raw = self.wrist_readings()
        R = self.data.site_xmat[self._idx.mount_site].reshape(3, 3)
        return R @ raw[0:3], R @ raw[3:6]

    def wrist_acceleration(self) -> NDArray[np.float64]:
        """The wrist accelerometer (m/s^2, world axes): the hand's acceleration minus gravity, so
        (0, 0, 9.81) at rest."""
        self._require_robot()
        raw = self.wrist_readings()
        R = self.data.site_xmat[self._idx.mount_site].reshape(3, 3)
        return R @ raw[6:9]

    def hand_tensions(self) -> NDArray[np.float64]:
        """(16, 2) tendon tensions (N) of the tendon hand's joints (:data:`robot.HAND_JOINTS`
        order; flexor, extensor), read by its tension sensors; raises for the servo hand."""
        self._require_robot()
        if self.tendon_drive is None:
            raise HandSimError(f"the {self.hand} hand has no tendons")
        return np.column_stack(self.tendon_drive.layout.tensions(self.data))

    def hand_joint_torques(self) -> NDArray[np.float64]:
        """(16,) torques (N m) the hand's actuators apply to its joints (the servos, or the
        tendon pairs), :data:`robot.HAND_JOINTS` order."""
        self._require_robot()
        return self.data.qfrc_actuator[self._idx.hand_dof].copy()

    def wrist_readings(self) -> NDArray[np.float64]:
        """(9,) the wrist's force (N), torque (N m) and accelerometer (m/s^2) readings in the
        sensors' own frame (the hand's mount site)."""
        idx, d = self._idx, self.data.sensordata
        i, j, k = idx.wrist_force_adr, idx.wrist_torque_adr, idx.wrist_accel_adr
        return np.concatenate([d[i : i + 3], d[j : j + 3], d[k : k + 3]])

    def pad_forces(self) -> NDArray[np.float64]:
        """(4,) normal force (N) between each fingertip pad (ff, mf, rf, th) and anything that is
        not the robot: what the servo hand's touch guard reacts to (the pads also feel a
        fingertip pressing another finger; this leaves those out)."""
        self._require_robot()
        m, d = self.model, self.data
        pads = {m.geom(robot.hand_name(f"{f}_pad")).id: i for i, f in enumerate(robot.FINGERS)}
        out = np.zeros(len(robot.FINGERS))
        wrench = np.zeros(6)
        for i in range(d.ncon):
            c = d.contact[i]
            for pad, other in ((c.geom1, c.geom2), (c.geom2, c.geom1)):
                if pad in pads and robot.robot_part(m.body(m.geom_bodyid[other]).name) is None:
                    mujoco.mj_contactForce(m, d, i, wrench)
                    out[pads[pad]] += abs(wrench[0])
        return out

    def pads_pressing(self, threshold: float) -> NDArray[np.bool_]:
        """(4,) the fingertips that press on something that is not the robot by more than
        ``threshold`` (N), as the hand senses it: the servo hand's pads (:meth:`pad_forces`),
        the tendon hand's tensions (:meth:`touch_felt`, whose least force must exceed the
        estimate's error floor too)."""
        if self.contact_estimator is None:
            return self.touch_felt(threshold, forces=self.pad_forces())
        return self.touch_felt(threshold)
