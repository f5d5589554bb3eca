"""Reusable MuJoCo state for the kinematic queries of posture control and the reach test.

Posture Control's searches (section 5.2) run thousands of small IK problems in an episode, each on
the world's model or on a planning model of the same layout: the hand and arm IK
(:func:`controllers.posture.solver.solve_posture`) and the reach test's
(:func:`controllers.hand.reachability.check_reach`). Making a fresh ``MjData`` for each (and mink's
:class:`~mink.Configuration`, which makes another, and its :class:`~mink.ConfigurationLimit`) costs
about a millisecond per problem, a sixth of a slow episode's Posture Control. The state here is made
once per model and reused: every query sets the whole ``qpos`` and recomputes the kinematics from
it, so what it computes does not depend on what the state held before.
"""

from __future__ import annotations

from dataclasses import dataclass

import mink
import mujoco

from hand_sim.indices import RobotIndices
from hand_sim.world import World

#: Scratch state is kept for this many models (the world's and the planning models used last).
SCRATCH_MODELS = 4


@dataclass(eq=False)
class KinematicScratch:
    """Reusable state of one model: ``data`` for forward kinematics and collision queries (the
    reach test's), ``configuration`` and ``limit`` for mink's IK (posture control's), and the
    robot's ``indices`` in it."""

    model: mujoco.MjModel
    data: mujoco.MjData
    configuration: mink.Configuration
    limit: mink.ConfigurationLimit
    indices: RobotIndices


def kinematic_scratch(world: World, model: mujoco.MjModel) -> KinematicScratch:
    """The scratch state of ``model`` kept on ``world`` (:attr:`World.scratch`), made on first
    use; the :data:`SCRATCH_MODELS` models used last keep theirs. A caller must not hold it across
    another query of the same model."""
    store = world.scratch
    entry = store.pop(model, None)
    if not isinstance(entry, KinematicScratch):
        entry = KinematicScratch(
            model,
            mujoco.MjData(model),
            mink.Configuration(model),
            mink.ConfigurationLimit(model),
            RobotIndices.of(model),
        )
    store[model] = entry  # the most recently used last
    while len(store) > SCRATCH_MODELS:
        store.pop(next(iter(store)))
    return entry
