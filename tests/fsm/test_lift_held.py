"""The lift's held test (fsm.handlers.deliver.lift_held): the wrist weighs the block and the pads
still feel it. Cases from the bench's lateral episodes (random 14's second grasp: the wrist held
1.48 N of 1.48 N with two pads at 4.4 and 10.8 N and the two others off the block)."""

import dataclasses

import numpy as np
import pytest

from fsm.config import DEFAULT_CONFIG
from fsm.handlers.deliver import lift_held
from hand_sim.contact_estimate import DETECTION_THRESHOLD

FLOOR = DETECTION_THRESHOLD  # the tendon hand's touch floor, 0.5 N
EVEN = np.array([3.1, 3.9, 3.2, 2.1])  # a squeeze's targets, every finger carrying


@pytest.mark.parametrize(
    ("load", "touch", "forces", "lateral", "held"),
    [
        # random 14: the wrist weighs the block, two pads feel it, two are off it
        (1.48, [0.07, 4.4, 10.83, 0.1], EVEN, True, True),
        # the same pads in a top grasp: two lost pads are a slip
        (1.48, [0.07, 4.4, 10.83, 0.1], EVEN, False, False),
        # random 62: the wrist weighs it, but only one pad is above the floor
        (1.51, [0.46, 2.96, 0.48, 0.01], EVEN, True, False),
        # the wrist feels nothing: slipped, whatever the pads say (random 85)
        (0.0, [4.35, 0.78, 6.46, 2.89], EVEN, True, False),
        # the wrist weighs it but only one pad feels it, and two carrying pads are lost
        (1.48, [0.0, 0.1, 6.71, 0.1], EVEN, True, False),
        # a light finger of a balanced squeeze may let go; the three others hold
        (1.48, [4.0, 0.0, 5.0, 2.0], np.array([6.0, 0.3, 3.5, 2.4]), True, True),
        # every pad on the block
        (1.48, [4.0, 1.0, 5.0, 2.0], EVEN, False, True),
        # a block lighter than wood (half its density) is held: the density is not known
        (0.70, [4.0, 1.0, 5.0, 2.0], EVEN, True, True),
        (0.70, [4.0, 1.0, 5.0, 2.0], EVEN, False, True),
        # below the floor the wrist holds nothing, whatever the pads say
        (0.15, [4.0, 1.0, 5.0, 2.0], EVEN, False, False),
    ],
)
def test_the_lift_is_held_when_the_wrist_weighs_the_block_and_pads_still_feel_it(
    load, touch, forces, lateral, held
) -> None:
    assert lift_held(load, 1.48, np.asarray(touch), FLOOR, forces, lateral, DEFAULT_CONFIG) is held


def test_a_check_by_the_nominal_weight_calls_a_light_block_slipped() -> None:
    """With the sensed weight off, the lift's check expects the block's nominal weight and calls
    a block at half wood's density slipped while the hand holds it (section 5.3's "imprecise
    object models")."""
    before = dataclasses.replace(
        DEFAULT_CONFIG,
        closed_loop=dataclasses.replace(DEFAULT_CONFIG.closed_loop, sensed_weight=False),
    )
    touch = np.array([4.0, 1.0, 5.0, 2.0])
    assert not lift_held(0.70, 1.48, touch, FLOOR, EVEN, False, before)
    assert lift_held(0.70, 1.48, touch, FLOOR, EVEN, False, DEFAULT_CONFIG)
