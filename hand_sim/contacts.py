"""Contacts between the robot and a body, with the forces MuJoCo computes for them
(``mj_contactForce``): which finger link (or the palm, or an arm link) touches a block, where, and
how hard. The touch sensors (:meth:`hand_sim.world.World.touch`) feel the fingertip pads only;
this sees every link, for guards (a finger link pressing a block), recordings (force arrows) and
judging an episode (no finger touches the delivered block).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from hand_sim import robot
from hand_sim.world import World


@dataclass(frozen=True)
class RobotContact:
    """One contact between a robot geom and another body."""

    finger: str  #: "ff", "mf", "rf", "th", "palm" or "arm"
    link: str  #: "proximal", "middle", "distal" for fingers; the body name otherwise
    geom: str  #: the robot geom's name
    position: NDArray[np.float64]  #: (3,) world contact point
    force: NDArray[np.float64]  #: (3,) world force the robot exerts on the other body (N)
    normal_force: float  #: its component along the contact normal (N, >= 0)
    distance: float  #: signed distance (m); negative = penetration


def robot_contacts(world: World, body: int) -> tuple[RobotContact, ...]:
    """Every contact between a robot geom and body ``body`` (a MuJoCo body id, e.g.
    ``world.block_body_id(name)``) in the world's current state."""
    m, d = world.model, world.data
    out = []
    wrench = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        b1, b2 = int(m.geom_bodyid[c.geom1]), int(m.geom_bodyid[c.geom2])
        if body not in (b1, b2) or b1 == b2:
            continue
        other_geom, other_body = (c.geom2, b2) if b1 == body else (c.geom1, b1)
        part = robot.robot_part(m.body(other_body).name)
        if part is None:
            continue
        mujoco.mj_contactForce(m, d, i, wrench)
        frame = c.frame.reshape(3, 3)  # rows: normal (geom1 -> geom2), two tangents
        on_geom2 = frame.T @ wrench[:3]  # force geom1 exerts on geom2, world axes
        on_body = on_geom2 if b2 == body else -on_geom2
        out.append(
            RobotContact(
                finger=part[0],
                link=part[1],
                geom=m.geom(other_geom).name,
                position=c.pos.copy(),
                force=on_body,
                normal_force=float(abs(wrench[0])),
                distance=float(c.dist),
            )
        )
    return tuple(out)


def finger_link_forces(world: World, body: int) -> dict[str, float]:
    """Total normal force (N) each finger, the palm and the arm exert on ``body`` now (keys
    ``ff``, ``mf``, ``rf``, ``th``, ``palm``, ``arm``; 0 when not touching)."""
    out = dict.fromkeys((*robot.FINGERS, "palm", "arm"), 0.0)
    for c in robot_contacts(world, body):
        out[c.finger] += c.normal_force
    return out


def pad_object_forces(world: World) -> NDArray[np.float64]:
    """(4,) normal force (N) between each fingertip pad (ff, mf, rf, th) and anything that is not
    the robot: what a touch guard should react to (:meth:`hand_sim.world.World.pad_forces`)."""
    return world.pad_forces()
