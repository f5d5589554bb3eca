"""The lift rig for a hand alone (no arm): the hand on a servoed vertical slide, turned so that
the prism :mod:`benchmarks.hand_reachability` placed in its grasp stands upright on a floor as a
free 0.3 kg wooden block, and the lift test's protocol: close every flexion ``SQUEEZE`` past the
contact configuration, then raise the slide ``LIFT`` in ``LIFT_STEPS`` ramps over ``LIFT_TIME``.

Used by the model tests of both hands (``models/hand.xml``'s servos, ``models/utah_mit_hand``'s
tendons), the tendon hand's contact-force validation and its figure.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from benchmarks.hand_reachability import GraspFound
from controllers.grasp import paper_object
from controllers.hand.tendon_control import TendonHandController
from hand_sim import robot
from hand_sim.contact_estimate import ContactEstimate, ContactEstimator, FrictionMemory
from hand_sim.resources import models_dir

#: The two hands' MJCF files.
SERVO_HAND = models_dir() / "hand.xml"
TENDON_HAND = models_dir() / "utah_mit_hand" / "utah_mit_hand.xml"
#: rad added to every flexion target past the contact configuration.
SQUEEZE = 0.15
#: m the slide rises, in LIFT_TIME (s) split into LIFT_STEPS ramps (as an arm trajectory would).
LIFT = 0.08
LIFT_TIME, LIFT_STEPS = 0.5, 25
#: The block: mass (kg) and friction of wood.
BLOCK_MASS = 0.3
BLOCK_FRICTION = 0.8
#: Height (m) of the slide's carriage above the floor's reference.
CARRIAGE_HEIGHT = 1.0


def lift_rig(
    found: GraspFound, hand_xml: Path, poly_name: str = "square"
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The rig with ``hand_xml`` attached (prefix ``hand/``) and its joints at ``found``'s
    configuration, the ``poly_name`` prism in the grasp (nothing commanded yet)."""
    pl = found.placement
    world = mujoco.MjSpec()
    world.option.timestep = 0.002
    world.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    world.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    world.option.impratio = 10
    carriage = world.worldbody.add_body(name="carriage", pos=[0, 0, CARRIAGE_HEIGHT])
    carriage.add_joint(
        name="lift", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1], armature=1.0, damping=50
    )
    carriage.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01, 0, 0], mass=2.0, contype=0, conaffinity=0
    )
    flip = np.diag([1.0, -1.0, -1.0])  # the prism axis points down: the palm faces down
    world_from_hand = flip @ np.stack([pl.e1, pl.e2, pl.axis])
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, world_from_hand.ravel())
    site = carriage.add_site(name="carriage_mount", quat=quat.tolist())
    site.attach_body(mujoco.MjSpec.from_file(str(hand_xml)).body("palm"), "hand/", "")
    lift = world.add_actuator(name="lift", target="lift", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    lift.set_to_position(kp=20000, kv=600)
    z0, z1 = pl.axial_range
    pos = world_from_hand @ (pl.origin + pl.axis * 0.5 * (z0 + z1)) + np.array(
        [0, 0, CARRIAGE_HEIGHT]
    )
    poly, half = paper_object(poly_name), 0.5 * (z1 - z0)
    verts = np.concatenate([np.c_[poly.vertices, np.full(poly.n_edges, z)] for z in (-half, half)])
    world.add_mesh(name="prism", uservert=verts.ravel().tolist())
    mujoco.mju_mat2Quat(quat, flip.ravel())
    block = world.worldbody.add_body(name="block", pos=pos.tolist(), quat=quat.tolist())
    block.add_freejoint()
    block.add_geom(
        type=mujoco.mjtGeom.mjGEOM_MESH,
        meshname="prism",
        mass=BLOCK_MASS,
        friction=[BLOCK_FRICTION, 0.005, 0.0001],
        condim=4,
    )
    world.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_PLANE, size=[1, 1, 0.1], pos=[0, 0, pos[2] - half]
    )
    model = world.compile()
    data = mujoco.MjData(model)
    data.qpos[[model.joint(f"hand/{j}").qposadr[0] for j in robot.HAND_JOINTS]] = found.qpos
    mujoco.mj_forward(model, data)
    return model, data


def tendon_lift(
    found: GraspFound,
    sample_period: float,
    on_sample: Callable[[mujoco.MjModel, mujoco.MjData, ContactEstimate], None],
) -> None:
    """The lift test on the tendon hand: the rig with ``TENDON_HAND`` at ``found``, its joint loop
    holding every flexion ``SQUEEZE`` past contact for 0.5 s, the ``LIFT`` ramp, a 1 s hold;
    every ``sample_period`` s of simulated time ``on_sample(model, data, estimate)`` gets the
    contact forces estimated from the tendon tensions (:mod:`hand_sim.contact_estimate`), with
    the least force the tensions allow."""
    model, data = lift_rig(found, TENDON_HAND)
    drive = TendonHandController.for_model(model, prefix="hand/").drive
    est = ContactEstimator.for_model(model, "hand/")
    memory = FrictionMemory()
    target = found.qpos.copy()
    for f in range(len(robot.FINGERS)):
        target[4 * f + 1 : 4 * f + 4] += SQUEEZE
    lift = model.actuator("lift").id
    dt = model.opt.timestep
    every = round(sample_period / dt)

    def run(seconds: float) -> None:
        for _ in range(round(seconds / dt)):
            drive.step(model, data, target)
            memory.update(data.qvel[est.layout.dof_adr])
            if round(data.time / dt) % every == 0:
                on_sample(model, data, est.estimate(model, data, memory.direction, least=True))

    run(0.5)
    for k in range(1, LIFT_STEPS + 1):
        data.ctrl[lift] = LIFT * k / LIFT_STEPS
        run(LIFT_TIME / LIFT_STEPS)
    run(1.0)
