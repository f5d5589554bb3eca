"""The timing every physical controller of section 5.2 shares: its control period and how long
position servos are given to settle, and the number of physics steps in one control period."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hand_sim.world import World

#: Control period (s) of the physical controllers: they set servo targets (and read sensors)
#: once per period and step the physics in between.
CONTROL_PERIOD = 0.02
#: Time (s) the arm's and hand's position servos are given to come to rest once their targets
#: stop moving (after an arm path, after a posture move and after each servo correction).
SERVO_SETTLE_TIME = 0.5


def control_steps(world: World) -> int:
    """Physics steps in one :data:`CONTROL_PERIOD` of ``world`` (at least one)."""
    return max(1, round(CONTROL_PERIOD / world.model.opt.timestep))
