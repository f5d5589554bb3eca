"""The tendon hand's fingertip forces estimated from its tendon tensions
(hand_sim.contact_estimate, issue 24), checked against the touch pads the model keeps as ground
truth: on a real grip (the balanced top and lateral grasps of the square that
tests/models/test_utah_mit_hand.py lifts), each pressing pad's estimate is within 15 % or 0.5 N of
its touch sensor while the hand squeezes, lifts and holds the block; a finger off the block is
not taken for a touching one; a finger moving freely reads about 0 N; the world's touch() reads
the estimate for the tendon hand and the pads, unchanged, for the servo hand."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.optimize import lsq_linear

from benchmarks import hand_reachability as reach
from benchmarks.fingertip_contacts import HandSamples
from benchmarks.lift_rig import TENDON_HAND as HAND
from benchmarks.lift_rig import tendon_lift
from experiments.physics.cli import DEFAULT_HAND as STUDY_DEFAULT_HAND
from experiments.physics.cli import HANDS as STUDY_HANDS
from experiments.physics.report import jobs_for
from hand_sim import robot
from hand_sim.assembly import DEFAULT_HAND, HAND_KINDS
from hand_sim.contact_estimate import (
    DETECTION_THRESHOLD,
    ContactEstimate,
    ContactEstimator,
    least_force,
    least_pressing,
)
from hand_sim.errors import HandSimError
from hand_sim.scene import load_scene
from hand_sim.telemetry import ESTIMATE_PATH, series_names
from hand_sim.world import TIMESTEP, TOUCH_PADS, TOUCH_TENDONS, World

#: The estimate must match a pressing pad's touch sensor within this fraction or this many N.
REL_TOL, ABS_TOL = 0.15, 0.5
#: A pad pressing harder than this (N) is compared; one at 0 N is "off the block".
PRESSING = 1.0
#: A pad pressing harder than this (N) must be felt by the guards (``ContactEstimate.least``).
FELT = 2.0
#: A freely moving finger's estimate stays below this (N) once its joints slide.
FREE_TOL = 0.5


def _touch(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    return np.array([data.sensor(f"hand/{f}_touch").data[0] for f in robot.FINGERS])


def _links_touching(model: mujoco.MjModel, data: mujoco.MjData) -> set[str]:
    """Fingers any of whose links touches something (the pads feel only their own zone)."""
    out = set()
    for c in data.contact[: data.ncon]:
        for g in (c.geom1, c.geom2):
            name = model.body(model.geom_bodyid[g]).name
            if name.startswith("hand/") and name[5:7] in robot.FINGERS:
                out.add(name[5:7])
    return out


@pytest.fixture(scope="module")
def hand_samples() -> HandSamples:
    return reach.sample_hand(3000, np.random.default_rng(0), HAND)


@pytest.mark.parametrize("kind", ["top", "lateral"])
def test_the_estimate_matches_the_touch_pads_on_a_grip(hand_samples, kind: str) -> None:
    """Squeeze 0.5 s, lift 8 cm, hold 1 s; every 0.1 s each pressing pad's estimate is within
    15 % or 0.5 N of its sensor, a pad pressing 2 N or more is felt (the least force its tensions
    allow is above the detection threshold, however its stuck joints' friction lies), a finger
    touching nothing is not, and the least force never exceeds the estimate."""
    _, found = reach.evaluate("square", kind, hand_samples, np.array([0.0]))
    assert found is not None
    compared, checked_free, felt = 0, 0, 0

    def check(model: mujoco.MjModel, data: mujoco.MjData, e: ContactEstimate) -> None:
        nonlocal compared, checked_free, felt
        pads = _touch(model, data)
        touching = _links_touching(model, data)
        for f, name in enumerate(robot.FINGERS):
            assert e.least is not None and e.least[f] <= e.normal[f] + 1e-9
            if pads[f] > PRESSING:
                tol = max(REL_TOL * pads[f], ABS_TOL)
                assert abs(e.normal[f] - pads[f]) <= tol, (kind, name, data.time, e.normal, pads)
                compared += 1
                if pads[f] > FELT:
                    assert e.least[f] > DETECTION_THRESHOLD, (kind, name, data.time, e.least, pads)
                    felt += 1
            elif name not in touching:
                assert e.least[f] <= DETECTION_THRESHOLD, (kind, name, data.time, e.least)
                checked_free += 1

    tendon_lift(found, 0.1, check)
    assert compared >= 3 * 20  # at least three pads at every sample
    assert felt >= 2 * 20
    assert kind == "top" or checked_free > 0  # the lateral grasp leaves the thumb off


def test_the_four_fingers_fitted_at_once_give_the_finger_by_finger_numbers(hand_samples) -> None:
    """The estimate fits the four fingers in one batch when no joint is at a limit (the
    recording asks for it at every control step): on the states of a real grip, squeeze, lift
    and hold, its forces, contact points and fits equal the finger-by-finger ones to the bit,
    with and without the faces' normals."""
    _, found = reach.evaluate("square", "top", hand_samples, np.array([0.0]))
    assert found is not None
    free = np.zeros(len(robot.HAND_JOINTS), dtype=bool)
    checked = 0

    def check(model: mujoco.MjModel, data: mujoco.MjData, e: ContactEstimate) -> None:
        nonlocal checked
        est = ContactEstimator.for_model(model, "hand/")
        outward = -e.force / np.maximum(np.linalg.norm(e.force, axis=1, keepdims=True), 1e-9)
        for faces in (None, outward):
            batch = est._fit_all(model, data, e.external_torque, faces)
            each = est._fit_each(model, data, e.external_torque, free, faces)
            for a, b in zip(batch, each, strict=True):
                np.testing.assert_array_equal(a, np.asarray(b))
        assert np.abs(batch[0]).max() > 1.0  # a state with force on the pads
        checked += 1

    tendon_lift(found, 0.1, check)
    assert checked >= 20


@pytest.fixture(scope="module")
def tendon_world() -> World:
    return World.build(load_scene("clutter3"), hand="tendon")


def test_a_freely_moving_finger_reads_about_zero(tendon_world: World) -> None:
    """Each finger flexes and extends (0.8 Hz) in free space with the hand's joint loop; once
    its joints slide, its estimate stays below 0.5 N (the touch pads read 0 throughout)."""
    world = tendon_world
    world.reset()
    q0 = world.hand_qpos()
    wave = np.tile([0.0, 0.5, 0.5, 0.4], len(robot.FINGERS))
    worst = np.zeros(len(robot.FINGERS))
    steps = round(0.02 / TIMESTEP)
    for k in range(round(2.0 / 0.02)):
        t = (k + 1) * 0.02
        world.set_hand_targets(q0 + wave * 0.5 * (1.0 - np.cos(2 * np.pi * 0.8 * t)))
        world.step(steps)
        assert np.all(world.touch_sensors() == 0.0)
        if t > 0.3:
            sliding = np.abs(world.hand_qvel()).reshape(4, 4)[:, 1:].min(axis=1) > 0.05
            worst = np.where(sliding, np.maximum(worst, world.touch()), worst)
    assert np.all(worst < FREE_TOL), worst


def test_the_world_reads_the_estimate_for_the_tendon_hand_only(tendon_world: World) -> None:
    world = tendon_world
    world.reset()
    world.step(50)
    assert world.touch_source == TOUCH_TENDONS
    np.testing.assert_array_equal(world.touch(), world.contact_estimate().normal)
    assert world.touch_floor == DETECTION_THRESHOLD
    assert not world.touch_felt(0.0).any()  # a hand at rest in free space feels nothing
    servo = World.build(load_scene("single_square"), hand="servo")
    servo.step(10)
    assert servo.touch_source == TOUCH_PADS and servo.touch_floor == 0.0
    np.testing.assert_array_equal(servo.touch(), servo.touch_sensors())
    np.testing.assert_array_equal(servo.touch_felt(0.05), servo.touch_sensors() > 0.05)
    np.testing.assert_array_equal(servo.touch_felt(1.0, forces=np.full(4, 2.0)), np.ones(4, bool))
    with pytest.raises(HandSimError, match="no tendons"):
        servo.contact_estimate()


def test_the_recording_logs_the_estimate_beside_the_pads_for_the_tendon_hand() -> None:
    tendon, servo = series_names("tendon"), series_names("servo")
    for f in robot.FINGERS:
        assert f"{ESTIMATE_PATH}/{f}" in tendon and f"{ESTIMATE_PATH}/{f}" not in servo
        assert f"touch/{f}" in tendon and f"touch/{f}" in servo


def test_the_physics_study_carries_the_hand_it_is_given() -> None:
    assert STUDY_HANDS == HAND_KINDS and STUDY_DEFAULT_HAND == DEFAULT_HAND
    jobs = jobs_for(("square",), 2, 0, hand="tendon")
    assert jobs and {j.hand for j in jobs} == {"tendon"}
    assert {j.hand for j in jobs_for(("square",), 2, 0)} == {DEFAULT_HAND}


def test_the_least_force_is_the_least_over_the_friction_band() -> None:
    """least_force against an independent minimisation (bounded linear least squares, scipy's
    BVLS: min ||A_free t + A_stuck centre_stuck|| over the band) on 200 random fits and bands;
    0 when the band holds torques the fit maps to no force; the fit of the centre when no joint
    is stuck."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        solver = rng.normal(size=(3, 4)) * rng.uniform(10.0, 200.0)
        centre = rng.normal(size=4) * 0.05
        band = np.where(rng.random(4) < 0.7, rng.uniform(0.0, 0.06, 4), 0.0)
        ours = least_force(solver, centre, band)
        free = band > 0
        rest = solver[:, ~free] @ centre[~free]
        if free.any():
            found = lsq_linear(
                solver[:, free],
                -rest,
                bounds=(centre[free] - band[free], centre[free] + band[free]),
                method="bvls",
                tol=1e-14,
            )
            best = float(np.linalg.norm(solver[:, free] @ found.x + rest))
        else:
            best = float(np.linalg.norm(rest))
        assert ours == pytest.approx(best, rel=1e-6, abs=1e-9)
        assert ours <= np.linalg.norm(solver @ centre) + 1e-12
    solver = rng.normal(size=(3, 4))
    assert least_force(solver, np.full(4, 0.01), np.full(4, 0.02)) == pytest.approx(0, abs=1e-12)
    centre = np.array([0.1, -0.2, 0.05, 0.0])
    exact = np.linalg.norm(solver @ centre)
    assert least_force(solver, centre, np.zeros(4)) == pytest.approx(exact)


def test_the_least_force_into_a_face_is_the_least_over_the_box_corners() -> None:
    """least_pressing against every corner of the friction box (a linear function's minimum
    over a box is at a corner; joints with no band fixed at their centre), floored at 0, on 200
    random fits and bands."""
    import itertools

    rng = np.random.default_rng(11)
    for _ in range(200):
        into = rng.normal(size=4) * rng.uniform(10.0, 200.0)
        centre = rng.normal(size=4) * 0.05
        band = np.where(rng.random(4) < 0.7, rng.uniform(0.0, 0.06, 4), 0.0)
        corners = [
            into @ (centre + np.array(signs) * band)
            for signs in itertools.product((-1.0, 1.0), repeat=4)
        ]
        assert least_pressing(into, centre, band) == pytest.approx(
            max(0.0, min(corners)), abs=1e-12
        )
