"""The finger-span pre-test of the reach test (:mod:`controllers.hand.finger_span`): a bound that
holds in every finger posture, and a pre-test that never refuses contacts the full reach test
(hand IK) accepts."""

from __future__ import annotations

import mujoco
import numpy as np

from controllers.hand.finger_geometry import PerceivedPrism
from controllers.hand.finger_span import FingerSpans
from controllers.hand.reachability import (
    CONTACT_TOLERANCE,
    SQUEEZE_REACH,
    check_reach,
    grip_targets,
)
from hand_sim.indices import RobotIndices


def test_spans_are_the_same_in_every_posture_and_bound_the_fingertips(hovering) -> None:
    world, _ = hovering
    model = world.model
    idx = RobotIndices.of(model)
    lo, hi = model.jnt_range[idx.hand_joints].T
    rng = np.random.default_rng(0)
    data = world.data
    saved = data.qpos.copy()
    try:
        spans, bases = [], []
        for _ in range(200):
            data.qpos[idx.hand_qpos] = rng.uniform(lo, hi)
            mujoco.mj_kinematics(model, data)
            s = FingerSpans.of(model, data)
            tips = data.site_xpos[idx.tip_sites]
            assert (np.linalg.norm(tips - s.base, axis=1) <= s.span + 1e-12).all()
            spans.append(s.span)
            bases.append(s.base)
        np.testing.assert_allclose(spans, np.broadcast_to(spans[0], (len(spans), 4)), atol=1e-9)
        np.testing.assert_allclose(bases, np.broadcast_to(bases[0], (len(bases), 4, 3)), atol=1e-9)
    finally:
        data.qpos[:] = saved
        mujoco.mj_kinematics(model, data)


def test_pre_test_never_refuses_what_the_full_reach_test_accepts(hovering) -> None:
    world, target = hovering
    prism = PerceivedPrism.of(target, world.scene.table.height)
    rng = np.random.default_rng(1)
    c, s = np.cos(target.yaw), np.sin(target.yaw)
    rot = np.array([[c, s], [-s, c]])
    fired = 0
    for shift in (0.0, 0.0, 0.0, 0.02, 0.04, 0.06, 0.1):
        theta = np.sort(rng.uniform(-np.pi, np.pi, 4))
        frames = target.polygon.locate(theta)
        xy = frames.point @ rot + np.asarray(target.position_xy) + [shift, 0.0]
        points = np.column_stack([xy, np.full(4, target.top_z - 0.03)])
        normals = np.column_stack([frames.normal @ rot, np.zeros(4)])
        tips, _ = grip_targets(points, normals, SQUEEZE_REACH)
        out = FingerSpans.of(world.model, world.data).out_of_reach(tips, CONTACT_TOLERANCE)
        full = check_reach(world, prism, points, normals, check_spacing=False)
        quick = check_reach(
            world, prism, points, normals, check_spacing=False, give_up=True, span_test=True
        )
        assert quick.reachable == full.reachable
        if out.any():
            fired += 1
            assert not full.reachable
            # the fingers the pre-test names fall short in the full IK too
            assert (full.tip_error[out] >= CONTACT_TOLERANCE).all()
    assert fired >= 1
