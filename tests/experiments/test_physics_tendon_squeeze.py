"""The tendon hand's squeeze regulates each finger's estimated force into its face, not the
size of the estimated force (issue 24): a squeeze that curls the fingers drags the pads down the
faces, and the tangential force that drag makes is not pressing. Judged by the touch pads, the
ground truth the tendon hand never reads."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.grasp.objects import PAPER_OBJECTS
from controllers.grasp.registry import make_composer
from experiments.physics.outcome import GraspOutcome
from experiments.physics.study import Job, StudyWorld, initial_contacts
from experiments.physics.study import test_grasp as take_and_test

#: Every pad presses at least this share of the force the squeeze settled on for it.
PAD_SHARE = 0.85
#: The drag: some finger's estimated force exceeds its pad's normal force by this much (N).
DRAG = 1.0


@pytest.mark.e2e
def test_the_tendon_squeeze_presses_each_face_and_the_block_is_held() -> None:
    """Seed 1, square, QL grasp 9 (dropped when the squeeze regulated the size of the estimate:
    the thumb pad pressed 3.0 N under a 5.8 N estimate): at the end of the squeeze the pads drag
    along the faces (the size of some finger's estimate exceeds its pad by more than 1 N), every
    pad presses at least 85 % of the force into its face the squeeze settled on, and the grasp
    holds through the physical test."""
    obj, controller, index, seed = "square", "ql", 9, 1
    sw = StudyWorld.of(obj, "3d", "tendon")
    job = Job(obj, PAPER_OBJECTS.index(obj), controller, 1, (index,), seed, "3d", hand="tendon")
    seen: dict[str, np.ndarray] = {}

    def at_squeeze(stage: str, world) -> None:
        if stage == "grasp":
            seen["pads"] = world.touch_sensors()
            seen["size"] = world.contact_estimate().normal

    theta0, rng = initial_contacts(job, index)
    out = GraspOutcome(obj, controller, index, theta0, model="3d")
    take_and_test(sw, make_composer(controller), rng, out, at_squeeze, regrasp=False)
    assert out.squeeze_settled
    pads, into_face = seen["pads"], np.asarray(out.grip_force)
    assert np.max(seen["size"] - pads) > DRAG, (seen["size"], pads)
    assert np.all(pads >= PAD_SHARE * into_face), (pads, into_face)
    assert out.result == "held", out.reason
