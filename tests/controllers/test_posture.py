"""Tests of mink posture control (controllers.posture.solver) on the simulated hand."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from controllers.errors import PostureError
from controllers.posture.manipulability import finger_manipulability, world_log_manipulability
from controllers.posture.solver import apply_posture, solve_posture
from hand_sim.indices import RobotIndices


@pytest.fixture(scope="module")
def hovering_world(hovering):
    """clutter3 with the arm driven (in simulation) to the coarse-reach goal above the target."""
    return hovering[0]


def test_manipulability_matches_a_finite_difference_jacobian(hovering_world):
    model = hovering_world.model
    data = mujoco.MjData(model)
    data.qpos[:] = hovering_world.data.qpos
    mujoco.mj_forward(model, data)
    idx = RobotIndices.of(model)
    w = finger_manipulability(model, data, idx)
    h = 1e-6
    for f in range(4):
        J = np.empty((3, 4))
        for k, adr in enumerate(idx.finger_qpos[f]):
            d2 = mujoco.MjData(model)
            d2.qpos[:] = data.qpos
            d2.qpos[adr] += h
            mujoco.mj_kinematics(model, d2)
            J[:, k] = (d2.site_xpos[idx.tip_sites[f]] - data.site_xpos[idx.tip_sites[f]]) / h
        np.testing.assert_allclose(w[f], np.sqrt(np.linalg.det(J @ J.T)), rtol=1e-4)


def test_posture_control_raises_manipulability_and_holds_fingertips_in_simulation(hovering_world):
    world = hovering_world
    tips_before = world.fingertip_positions()
    m_before = world_log_manipulability(world)
    result = solve_posture(world)
    assert result.reachable
    assert result.log_manipulability_end > result.log_manipulability_start + 1.0
    assert np.abs(result.arm_q - world.arm_qpos()).max() > 1e-3  # the arm was reconfigured
    tips_after = apply_posture(world, result)
    assert np.linalg.norm(tips_after - tips_before, axis=1).max() < 2e-3
    assert world_log_manipulability(world) > m_before + 1.0
    for q, ranges in (
        (world.arm_qpos(), world.arm_ctrlrange()),
        (world.hand_qpos(), world.hand_ctrlrange()),
    ):
        assert np.all(q >= ranges[:, 0] - 1e-3) and np.all(q <= ranges[:, 1] + 1e-3)


def test_unreachable_fingertip_targets_are_reported(hovering_world):
    world = hovering_world
    tips = world.fingertip_positions()
    far = solve_posture(world, tips + np.array([2.0, 0.0, 0.0]), optimize=False)
    assert not far.reachable
    assert set(far.unreachable) == {"ff", "mf", "rf", "th"}
    one = tips.copy()
    one[0] += np.array([0.0, 0.0, 0.08])  # first finger 8 cm up: beyond it with the arm frozen
    res = solve_posture(world, one, optimize=False, joints="hand")
    assert res.unreachable == ("ff",)
    assert res.tip_error[1:].max() < 1e-3
    with pytest.raises(PostureError, match="joint set"):
        solve_posture(world, joints="wrist")
    with pytest.raises(PostureError, match="targets"):
        solve_posture(world, np.zeros((3, 3)))
