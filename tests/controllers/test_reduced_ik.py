"""controllers.posture.reduced_ik: mink's differential-IK step solved on the moving joints only
gives mink's own step (mink.solve_ik with the other joints frozen by equality constraints)."""

from __future__ import annotations

import mink
import numpy as np
import pytest

from controllers.posture.reduced_ik import ReducedStep
from controllers.posture.solver import (
    IK_DAMPING,
    IK_DT,
    PAD_CENTRE_COST,
    QP_SOLVER,
    TIP_COST,
    _frozen_dofs,
    _point_tasks,
    avoidance_limits,
    mink_velocity,
    moving_dofs,
)
from hand_sim import robot
from hand_sim.indices import RobotIndices


def _problem(world, joints: str, avoid: bool, qpos=None):
    """A configuration at ``qpos`` (default the world's), tip and pad-centre tasks 1-2 cm off
    the fingertips, the limits, and mink's freezing constraint of the joints not in ``joints``."""
    model = world.model
    cfg = mink.Configuration(model)
    cfg.update((world.data.qpos if qpos is None else qpos).copy())
    idx = RobotIndices.of(model)
    tips = cfg.data.site_xpos[idx.tip_sites] + np.array([0.012, -0.006, -0.015])
    tasks = _point_tasks(robot.FINGERTIP_SITES, tips, TIP_COST) + _point_tasks(
        robot.PAD_CENTRE_SITES, tips + np.array([0.0, 0.01, 0.0]), PAD_CENTRE_COST
    )
    limits: list[mink.Limit] = [mink.ConfigurationLimit(model)]
    if avoid:
        target = model.geom_bodyid == world.block_body_id(world.scene.target)
        touchable = model.geom(int(np.flatnonzero(target)[0])).name
        limits += avoidance_limits(model, touchable, fingers_may_touch=True)
    frozen = _frozen_dofs(model, idx, joints)
    constraints = [mink.DofFreezingTask(model, dof_indices=frozen)]
    step = ReducedStep(
        model, tasks, moving_dofs(model, frozen), limits, damping=IK_DAMPING, solver=QP_SOLVER
    )
    return cfg, tasks, limits, constraints, step


@pytest.mark.parametrize(("joints", "avoid"), [("hand", False), ("arm+hand", True)])
def test_fifty_steps_follow_minks_steps(hovering, joints, avoid):
    world, _ = hovering
    cfg, tasks, limits, constraints, step = _problem(world, joints, avoid)
    mink_cfg = mink.Configuration(world.model)
    mink_cfg.update(cfg.q.copy())
    moved = 0.0
    for _ in range(50):
        ours = step.velocity(cfg, IK_DT)
        theirs = mink_velocity(mink_cfg, tasks, limits, constraints)
        assert ours is not None
        np.testing.assert_allclose(ours, theirs, atol=1e-9)
        cfg.integrate_inplace(ours, IK_DT)
        mink_cfg.integrate_inplace(theirs, IK_DT)
        moved += float(np.abs(ours).max()) * IK_DT
    np.testing.assert_allclose(cfg.q, mink_cfg.q, atol=1e-9)
    assert moved > 0.05  # the steps moved the joints: the comparison is not of zeros


def test_a_joint_at_its_limit_is_held_there_as_mink_holds_it(hovering):
    world, _ = hovering
    model = world.model
    idx = RobotIndices.of(model)
    qpos = world.data.qpos.copy()
    adr = idx.finger_qpos[0][1]  # ff's MCP flexion at its upper limit
    qpos[adr] = model.jnt_range[model.jnt(robot.hand_name("ffj1")).id, 1]
    cfg, tasks, limits, constraints, step = _problem(world, "hand", False, qpos)
    ours = step.velocity(cfg, IK_DT)
    theirs = mink_velocity(cfg, tasks, limits, constraints)
    np.testing.assert_allclose(ours, theirs, atol=1e-9)
    dof = model.jnt_dofadr[model.jnt(robot.hand_name("ffj1")).id]
    assert ours[dof] <= 1e-12  # the bound binds


def test_a_frozen_joint_beyond_its_limit_has_no_step_as_in_mink(hovering):
    world, _ = hovering
    model = world.model
    qpos = world.data.qpos.copy()
    arm = int(robot.arm_qpos_addresses(model)[1])
    joint = model.jnt_qposadr.tolist().index(arm)
    qpos[arm] = model.jnt_range[joint, 1] + 0.01
    cfg, tasks, limits, constraints, step = _problem(world, "hand", False, qpos)
    assert step.velocity(cfg, IK_DT) is None
    with pytest.raises(mink.NoSolutionFound):
        mink_velocity(cfg, tasks, limits, constraints)


def test_only_position_targets_on_sites_are_taken(hovering):
    world, _ = hovering
    task = mink.FrameTask(robot.qualified(robot.FINGERTIP_SITES[0]), "site", 1.0, 1.0)
    with pytest.raises(ValueError, match="position-only"):
        ReducedStep(
            world.model,
            [task],
            np.arange(3),
            [mink.ConfigurationLimit(world.model)],
            damping=IK_DAMPING,
            solver=QP_SOLVER,
        )
    with pytest.raises(ValueError, match="daqp"):
        ReducedStep(
            world.model,
            [],
            np.arange(3),
            [mink.ConfigurationLimit(world.model)],
            damping=IK_DAMPING,
            solver="osqp",
        )
