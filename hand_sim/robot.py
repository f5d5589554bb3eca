"""Names of the robot's MJCF elements: the GE P50-style arm and the Utah/MIT-style hand (section 5).

The models in ``models/`` use Menagerie-style names; once :mod:`hand_sim.world` attaches them,
dm_control prefixes every arm name with ``arm/`` and every hand name with ``arm/hand/``.
:func:`qualified` turns a bare name into the compiled model's name.
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

from hand_sim.errors import HandSimError

#: Model names given to the attached arm and hand (they become the dm_control name prefixes).
ARM_MODEL, HAND_MODEL = "arm", "hand"
ARM_PREFIX = ARM_MODEL + "/"
HAND_PREFIX = ARM_PREFIX + HAND_MODEL + "/"

#: The arm's five revolute joints, base to wrist (GE P50: waist, shoulder, elbow, wrist pitch/roll).
ARM_JOINTS: tuple[str, ...] = ("waist", "shoulder", "elbow", "wrist_pitch", "wrist_roll")
#: The arm's position actuators, one per joint, in ARM_JOINTS order.
ARM_ACTUATORS: tuple[str, ...] = ARM_JOINTS
#: Site of the arm's flange where the hand mounts, and the arm's keyframe of its rest posture.
ATTACHMENT_SITE = "attachment_site"
HOME_KEYFRAME = "home"

#: Fingers of the hand: first, middle, ring and the opposed thumb.
FINGERS: tuple[str, ...] = ("ff", "mf", "rf", "th")
#: Joints per finger: abduction (j0) then three flexions (j1..j3).
JOINTS_PER_FINGER = 4
HAND_JOINTS: tuple[str, ...] = tuple(f"{f}j{i}" for f in FINGERS for i in range(JOINTS_PER_FINGER))
#: Each finger's entries (in FINGERS order) in the hand's 16 joints, actuators and targets.
FINGER_JOINT_SLICES: tuple[slice, ...] = tuple(
    slice(JOINTS_PER_FINGER * f, JOINTS_PER_FINGER * (f + 1)) for f in range(len(FINGERS))
)
HAND_ACTUATORS: tuple[str, ...] = tuple(
    f"{f}a{i}" for f in FINGERS for i in range(JOINTS_PER_FINGER)
)
FINGERTIP_SITES: tuple[str, ...] = tuple(f"{f}_tip" for f in FINGERS)
#: Centre of each fingertip's rounded end: the tip site lies one pad radius from it, along the
#: pad normal (30 deg from the palmar normal towards the tip).
PAD_CENTRE_SITES: tuple[str, ...] = tuple(f"{f}_pad_centre" for f in FINGERS)
#: Radius (m) of the fingertip pads (models/hand.xml).
PAD_RADIUS = 0.0085
TOUCH_SENSORS: tuple[str, ...] = tuple(f"{f}_touch" for f in FINGERS)
PALM_BODY = "palm"
#: The hand's mount site (its frame at the back of the palm) and the wrist force/torque sensors
#: there (force, torque).
MOUNT_SITE = "mount"
WRIST_SENSORS: tuple[str, ...] = ("wrist_force", "wrist_torque", "wrist_accel")
#: Standard gravity (m/s^2): the worlds' gravity (MuJoCo's default, along -z) and the factor that
#: turns a mass into a weight.
STANDARD_GRAVITY = 9.81
#: Links of a finger, palm side first, as the hand model names its bodies (``ff_proximal``...).
FINGER_LINKS: tuple[str, ...] = ("proximal", "middle", "distal")

_ARM_NAMES = frozenset((*ARM_JOINTS, *ARM_ACTUATORS, ATTACHMENT_SITE))
_HAND_NAMES = frozenset(
    (
        *HAND_JOINTS,
        *HAND_ACTUATORS,
        *FINGERTIP_SITES,
        *TOUCH_SENSORS,
        PALM_BODY,
        MOUNT_SITE,
        *PAD_CENTRE_SITES,
        *WRIST_SENSORS,
    )
)


def qualified(name: str) -> str:
    """The compiled model's name of the arm or hand element ``name`` (e.g. ``ffj0`` ->
    ``arm/hand/ffj0``, ``elbow`` -> ``arm/elbow``).

    Names of other elements of the models are qualified with :func:`arm_name`/:func:`hand_name`.
    Raises :class:`HandSimError` listing the known names.
    """
    if name in _HAND_NAMES:
        return HAND_PREFIX + name
    if name in _ARM_NAMES:
        return ARM_PREFIX + name
    raise HandSimError(
        f"unknown robot element {name!r}; valid: {', '.join(sorted(_ARM_NAMES | _HAND_NAMES))}"
    )


def arm_name(name: str) -> str:
    """Any element name of models/arm.xml as it appears in the compiled world model."""
    return ARM_PREFIX + name


def hand_name(name: str) -> str:
    """Any element name of models/hand.xml as it appears in the compiled world model."""
    return HAND_PREFIX + name


def qpos_addresses(model: mujoco.MjModel, joints: tuple[str, ...]) -> NDArray[np.int64]:
    """Addresses in ``qpos`` of the robot's single-DOF ``joints`` (bare names, e.g.
    :data:`ARM_JOINTS`) in the compiled world ``model``, in the order given."""
    return np.array(
        [model.jnt_qposadr[model.joint(qualified(j)).id] for j in joints], dtype=np.int64
    )


def arm_qpos_addresses(model: mujoco.MjModel) -> NDArray[np.int64]:
    """Addresses in ``qpos`` of the arm's joints, :data:`ARM_JOINTS` order."""
    return qpos_addresses(model, ARM_JOINTS)


def hand_qpos_addresses(model: mujoco.MjModel) -> NDArray[np.int64]:
    """Addresses in ``qpos`` of the hand's joints, :data:`HAND_JOINTS` order."""
    return qpos_addresses(model, HAND_JOINTS)


def robot_part(body_name: str) -> tuple[str, str] | None:
    """(finger, link) of a body name of the compiled world: ``("ff", "distal")``...,
    ``("palm", <body>)`` for the hand's other bodies, ``("arm", <body>)`` for the arm's; None
    for a body that is not the robot's."""
    if body_name.startswith(HAND_PREFIX):
        local = body_name[len(HAND_PREFIX) :]
        for finger in FINGERS:
            for link in FINGER_LINKS:
                if local == f"{finger}_{link}":
                    return finger, link
        return "palm", local
    if body_name.startswith(ARM_PREFIX):
        return "arm", body_name[len(ARM_PREFIX) :]
    return None
