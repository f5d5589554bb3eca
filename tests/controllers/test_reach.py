"""Tests of coarse reach, arm paths and delivery (controllers.reach.coarse,
controllers.reach.arm_path, controllers.deliver.plan) on the simulated arm in clutter3."""

from __future__ import annotations

import dataclasses
import itertools

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from controllers.deliver.plan import SET_DOWN_HOVER, plan_delivery, reachable_turn
from controllers.errors import ReachError
from controllers.grasp.objects import paper_object
from controllers.planning.cspace import CollisionChecker
from controllers.reach.arm_path import ArmPath, execute_path, plan_arm_path
from controllers.reach.coarse import (
    LATERAL_GOAL_FALLBACKS,
    LATERAL_TILTS,
    PRESHAPE,
    ReachTarget,
    choice_reason,
    goal_poses,
    lateral_fallback_poses,
    lateral_frame,
    plan_coarse_reach,
    solve_goal,
)
from controllers.reach.fine import fine_reach
from fsm.layout import episode_scene
from hand_sim import robot
from hand_sim.scene import load_scene
from hand_sim.world import World

#: Joint step (rad) of the independent check: finer than the verification step of the planner.
CHECK_STEP = 0.005


@pytest.fixture(scope="module", params=[("top", "lateral"), ("top",)], ids=["auto", "top-only"])
def clutter3(request):
    """clutter3 and its coarse-reach plan: best of both approaches, and the top approach alone."""
    world = World.build(load_scene("clutter3"))
    target = ReachTarget.from_world(world, world.scene.target)
    plan = plan_coarse_reach(world, target, approaches=request.param)
    return world, target, plan


def densify(path: np.ndarray, step: float) -> np.ndarray:
    rows = [path[:1]]
    for a, b in itertools.pairwise(path):
        n = max(1, int(np.ceil(np.abs(b - a).max() / step)))
        rows.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
    return np.vstack(rows)


def forbidden_contacts(world: World, arm_q: np.ndarray, hand_q, allowed_body: int) -> list:
    """Robot contacts at a posture, computed from scratch on the world's own model (not the
    planner's copy): robot geom against a non-robot geom other than ``allowed_body``."""
    m = world.model
    d = mujoco.MjData(m)
    d.qpos[:] = world.data.qpos
    adr = [m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.ARM_JOINTS]
    hadr = [m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.HAND_JOINTS]
    d.qpos[hadr] = hand_q
    d.qpos[adr] = arm_q
    mujoco.mj_forward(m, d)
    bad = []
    for c in d.contact[: d.ncon]:
        bodies = [int(m.geom_bodyid[g]) for g in (c.geom1, c.geom2)]
        on_robot = [m.body(b).name.startswith(robot.ARM_PREFIX) for b in bodies]
        if on_robot[0] != on_robot[1] and allowed_body not in bodies and c.dist < 0:
            bad.append((m.geom(c.geom1).name, m.geom(c.geom2).name))
    return bad


def test_clutter3_plan_exists_and_ends_above_the_target(clutter3):
    world, target, plan = clutter3
    assert plan.found, plan.reason
    assert plan.approach in plan.candidates
    assert len(plan.candidates) + len(plan.no_goal) in (1, 2)
    found = {a: p.length for a, p in plan.candidates.items() if p.found}
    assert plan.approach == min(found, key=found.get)  # the shorter existing path wins
    path = plan.path.path
    np.testing.assert_allclose(path[0], world.arm_qpos())
    np.testing.assert_allclose(path[-1], plan.goal.q)
    checker = CollisionChecker(world, hand_q=plan.hand_q)
    pos, rot = checker.palm_pose(path[-1])
    if plan.approach == "top":
        assert np.linalg.norm(pos[:2] - np.asarray(target.position_xy)) < 0.005
        assert pos[2] > target.top_z + 0.1
        assert rot[:, 2] @ np.array([0.0, 0.0, -1.0]) > 0.99  # approach axis points down
    else:  # lateral: approach axis horizontal, pointing at the block, palm beside its faces
        to_block = np.array([*target.position_xy, pos[2]]) - pos
        assert abs(rot[2, 2]) < 0.01
        assert rot[:, 2] @ to_block / np.linalg.norm(to_block) > 0.99
        assert target.top_z - 0.2 < pos[2] < target.top_z
    assert plan.path.length >= plan.path.straight_distance - 1e-9


def test_clutter3_path_has_no_contact_except_the_target_checked_finely(clutter3):
    world, _, plan = clutter3
    target_body = world.block_body_id(world.scene.target)
    dense = densify(plan.path.path, CHECK_STEP)
    assert len(dense) > 3 * len(plan.path.path)
    for q in dense:
        assert forbidden_contacts(world, q, plan.hand_q, target_body) == [], q


def test_clutter3_path_executes_without_contact(clutter3):
    world, _, plan = clutter3
    world.reset()
    run = execute_path(world, plan.path.path, hand_q=plan.hand_q)
    assert run.final_error < 0.01
    assert run.contacts == ()
    # nothing was knocked over: every block is still where the scene put it
    for block in world.scene.blocks:
        pos, _ = world.block_pose(block.name)
        assert np.linalg.norm(pos[:2] - np.asarray(block.position)) < 1e-3


def test_blocked_goal_and_bad_input_are_reported(clutter3):
    world, target, plan = clutter3
    world.reset()
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    start = world.arm_qpos()
    into_table = plan.goal.q.copy()
    into_table[1] += 0.6  # shoulder forward: the hand dives into the table and blocks
    assert checker.collides(into_table)
    res = plan_arm_path(checker, start, into_table)
    assert not res.found
    assert "goal posture is in collision" in res.reason
    with pytest.raises(ReachError, match="approach"):
        plan_coarse_reach(world, target, approaches=("sideways",))
    with pytest.raises(ReachError, match="resolution"):
        plan_arm_path(checker, start, plan.goal.q, resolution=2)


def test_the_wrist_roll_turns_at_the_goal_when_asked_and_the_path_stays_clear(clutter3):
    """plan_arm_path's ``roll_at_goal`` (an empty hand's reposition): the roll keeps its start
    value along the whole path and turns only on the last segment, at the goal's other joints;
    by default it turns first. Both paths are collision-free by the independent fine check."""
    world, _, plan = clutter3
    world.reset()
    checker = CollisionChecker(world, hand_q=plan.hand_q)
    start = world.arm_qpos()
    goal = plan.goal.q.copy()
    goal[4] = start[4] + 0.8
    target_body = world.block_body_id(world.scene.target)
    first = plan_arm_path(checker, start, goal)
    last = plan_arm_path(checker, start, goal, roll_at_goal=True)
    assert first.found and last.found, (first.reason, last.reason)
    for res in (first, last):
        np.testing.assert_allclose(res.path[0], start)
        np.testing.assert_allclose(res.path[-1], goal)
        for q in densify(res.path, CHECK_STEP):
            assert forbidden_contacts(world, q, plan.hand_q, target_body) == [], q
    np.testing.assert_allclose(first.path[1:, 4], goal[4])
    np.testing.assert_allclose(last.path[:-1, 4], start[4])
    np.testing.assert_allclose(last.path[-2, :4], goal[:4])


def test_far_target_plans_both_approaches_and_picks_the_shorter():
    scene = load_scene("single_square")
    block = dataclasses.replace(scene.blocks[0], position=(0.3, 0.1))
    world = World.build(dataclasses.replace(scene, blocks=(block,)))
    target = ReachTarget.from_world(world, "square")
    plan = plan_coarse_reach(world, target)
    assert plan.found
    assert set(plan.candidates) == {"top", "lateral"}
    assert all(p.found for p in plan.candidates.values())
    lengths = {a: p.length for a, p in plan.candidates.items()}
    assert plan.approach == min(lengths, key=lengths.get)
    # the lateral goal puts the approach axis horizontal, pointing at the block, and the finger
    # row (hand x) horizontal: hand y vertical
    lateral = plan_coarse_reach(world, target, approaches=("lateral",))
    checker = CollisionChecker(world, hand_q=plan.hand_q)
    pos, rot = checker.palm_pose(lateral.path.path[-1])
    assert abs(rot[2, 0]) < 0.01 and abs(abs(rot[2, 1]) - 1.0) < 0.01
    to_block = np.array([*target.position_xy, pos[2]]) - pos
    assert abs(rot[2, 2]) < 0.01
    assert rot[:, 2] @ to_block / np.linalg.norm(to_block) > 0.99
    run = execute_path(world, plan.path.path, hand_q=plan.hand_q)
    assert run.contacts == ()
    assert plan.choice.startswith("the shortest path in joint space")
    assert f"top {lengths['top']:.2f} rad" in plan.choice


@pytest.mark.parametrize("scene", ["behind_a_pillar", "tall_neighbours"])
def test_pillars_around_the_target_leave_only_the_lateral_approach(scene: str):
    """The top approach's hand, 4 cm above the target's top, meets the 40 cm pillars behind (and
    beside) it; the lateral one comes from the arm's side, so the path decides."""
    world = World.build(load_scene(scene))
    target = ReachTarget.from_world(world, world.scene.target)
    plan = plan_coarse_reach(world, target)
    assert plan.found and plan.approach == "lateral"
    assert plan.no_goal == ("top",)
    assert plan.choice == ("the only approach with a path (top: no collision-free goal posture)")
    # without the pillar the top approach is the shorter one
    alone = dataclasses.replace(
        world.scene, blocks=tuple(b for b in world.scene.blocks if "pillar" not in b.name)
    )
    free = World.build(alone)
    plan_free = plan_coarse_reach(free, ReachTarget.from_world(free, alone.target))
    assert plan_free.approach == "top"


def carried_contacts(world: World, block: str, path: np.ndarray, lift_gap: float) -> list:
    """Independent check of a delivery path: the block follows the palm rigidly (transform
    taken from the world now); returns forbidden contacts (block or robot against anything but
    the hand-block pair; block-table allowed while the block is within ``lift_gap`` of its
    starting height)."""
    m = world.model
    d = mujoco.MjData(m)
    d.qpos[:] = world.data.qpos
    mujoco.mj_kinematics(m, d)
    site = m.site(robot.hand_name("palm_center")).id
    body = world.block_body_id(block)
    adr = m.jnt_qposadr[m.body_jntadr[body]]
    Rp = d.site_xmat[site].reshape(3, 3)
    p_rel = Rp.T @ (d.xpos[body] - d.site_xpos[site])
    R_rel = Rp.T @ d.xmat[body].reshape(3, 3)
    z0 = d.xpos[body][2]
    arm = [m.jnt_qposadr[m.joint(robot.qualified(j)).id] for j in robot.ARM_JOINTS]
    bad = []
    for q in densify(path, CHECK_STEP):
        d.qpos[arm] = q
        mujoco.mj_kinematics(m, d)
        Rp = d.site_xmat[site].reshape(3, 3)
        d.qpos[adr : adr + 3] = d.site_xpos[site] + Rp @ p_rel
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, (Rp @ R_rel).ravel())
        d.qpos[adr + 3 : adr + 7] = quat
        mujoco.mj_forward(m, d)
        for c in d.contact[: d.ncon]:
            if c.dist >= 0:
                continue
            bodies = [int(m.geom_bodyid[g]) for g in (c.geom1, c.geom2)]
            names = [m.body(b).name for b in bodies]
            hand = [n.startswith(robot.HAND_PREFIX) for n in names]
            robotic = [
                n.startswith(robot.ARM_PREFIX) or b == body
                for n, b in zip(names, bodies, strict=True)
            ]
            if body in bodies and any(hand):
                continue  # the fingers hold the block
            if body in bodies and "table/table" in names and d.xpos[body][2] < z0 + lift_gap:
                continue  # lift-off and set-down
            if robotic[0] != robotic[1]:
                bad.append((m.geom(c.geom1).name, m.geom(c.geom2).name))
    return bad


def _holding_the_pentagon(scene) -> World:
    """clutter3's world with the hand on the pentagon (coarse reach, fingertips on its faces)."""
    world = World.build(scene)
    plan = plan_coarse_reach(world, ReachTarget.from_world(world, "pentagon"))
    execute_path(world, plan.path.path, hand_q=plan.hand_q)
    assert fine_reach(world, "pentagon").reached
    return world


@pytest.fixture(scope="module")
def held_pentagon():
    """clutter3 with the fingertips on the pentagon, and its delivery plan to the scene's place
    point (planning reads the world and leaves it as it is, so the tests share both)."""
    world = _holding_the_pentagon(load_scene("clutter3"))
    return world, plan_delivery(world, "pentagon", world.scene.place)


def test_delivery_carries_the_block_to_the_place_point_without_collision(held_pentagon):
    world, delivery = held_pentagon
    assert delivery.found, delivery.reason
    np.testing.assert_allclose(delivery.block_goal[:2], world.scene.place, atol=2e-3)
    table, height = world.scene.table.height, world.scene.block("pentagon").height
    assert abs(delivery.block_goal[2] - (table + 0.5 * height + SET_DOWN_HOVER)) < 2e-3
    assert carried_contacts(world, "pentagon", delivery.path, 0.02) == []
    with pytest.raises(ReachError, match="place point"):
        plan_delivery(world, "pentagon", [np.nan, 0.0])


def _palm_yaw(world: World, q: np.ndarray) -> float:
    _, rot = CollisionChecker(world).palm_pose(q)
    return float(np.arctan2(rot[1, 0], rot[0, 0]))


#: Width (m) of the post that stands in the held hand's way at the set-down.
POST_WIDTH = 0.015


def test_a_tilted_hand_is_turned_only_where_the_five_joint_arm_can_hold_it() -> None:
    """The arm's tool axis stays in a vertical plane through its waist axis: a hand tilted 14 deg
    off the vertical, moved 3.6 cm and turned 135 deg about a vertical line 5 cm beyond its palm,
    is out of the arm's reach from any IK seed (wrist roll turned either way); the turn
    ``reachable_turn`` gives instead (the hand tilted towards the base) is reached. A hand
    pointing straight down keeps its turn."""
    world = World.build(load_scene("clutter3"))
    checker = CollisionChecker(world)
    q = np.array([0.3, 0.5, 1.9, 0.5, 0.4])
    p0, R0 = checker.palm_pose(q)
    assert np.degrees(np.arccos(-R0[2, 2])) > 10.0
    flange = world.model.body(robot.arm_name("flange")).id
    flange_at, axis = checker.data.xpos[flange].copy(), checker.data.xmat[flange, 2::3].copy()
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id]
    pivot, shift = p0 + 0.05 * R0[:, 2], np.array([0.03, -0.02, 0.0])

    def reached(turn: float) -> bool:
        R = Rotation.from_euler("z", turn).as_matrix() @ R0
        p = pivot + shift + R @ R0.T @ (p0 - pivot)
        seeds = [np.array([*q[:4], q[4] + sign * turn]) for sign in (1.0, -1.0)]
        return any(checker.solve_ik(p, R, seed).found for seed in seeds)

    nominal = np.deg2rad(135.0)
    assert not reached(nominal)
    held = reachable_turn(nominal, pivot, shift, flange_at, axis, base)
    assert abs(held) > np.deg2rad(150.0)  # the nearest turn the arm holds: tilted the other way
    assert reached(held)
    down = np.array([0.0, 0.0, -1.0])
    assert reachable_turn(nominal, pivot, shift, flange_at, down, base) == nominal


def test_a_post_where_the_held_hand_would_set_down_turns_the_hand_about_the_place_point(
    held_pentagon,
):
    """A post stands 3 cm beyond where a fingertip would be at the set-down: the hand as it holds
    the block (and turned with the waist) cannot set it down; turned further about the place
    point it can (controllers.deliver.plan.SET_DOWN_TURNS, each moved to the nearest turn the arm
    can hold the tilted hand at; before them: "no collision-free posture above the place
    point"), and the carried block touches nothing on the way (independent
    check)."""
    world, first = held_pentagon
    scene = world.scene
    assert first.found, first.reason
    m = world.model
    d = mujoco.MjData(m)
    d.qpos[:] = world.data.qpos
    d.qpos[robot.arm_qpos_addresses(m)] = first.path[-1]
    mujoco.mj_kinematics(m, d)
    tips = np.array([d.site_xpos[m.site(robot.hand_name(s)).id] for s in robot.FINGERTIP_SITES])
    place = np.asarray(scene.place)
    far = tips[np.argmax(np.linalg.norm(tips[:, :2] - place, axis=1)), :2]
    spot = far + 0.03 * (far - place) / np.linalg.norm(far - place)
    post = paper_object("square").scaled(POST_WIDTH / np.ptp(paper_object("square").vertices[:, 0]))
    obstacle = dataclasses.replace(
        scene.block("pentagon"), name="post", polygon=post, position=tuple(spot), yaw=0.0
    )
    crowded = dataclasses.replace(scene, blocks=(*scene.blocks, obstacle))
    world = _holding_the_pentagon(crowded)
    second = plan_delivery(world, "pentagon", scene.place)
    assert second.found, second.reason
    assert first.set_down == ""
    assert "deg about the place point beyond the waist" in second.set_down
    np.testing.assert_allclose(second.block_goal[:2], place, atol=2e-3)
    turned = abs(
        np.angle(
            np.exp(1j * (_palm_yaw(world, second.path[-1]) - _palm_yaw(world, first.path[-1])))
        )
    )
    assert turned > np.deg2rad(30.0)
    assert carried_contacts(world, "pentagon", second.path, 0.02) == []


def test_a_lateral_goal_the_forearm_blocks_falls_back_to_a_nearer_or_higher_palm() -> None:
    """Random scene 25 (1 block, 0.54 m from the arm's base): at the nominal lateral goal the
    5-joint arm's wrist pitches so far that the hand hits the arm's own forearm, so no IK seed
    gives a collision-free posture. The fallbacks (palm nearer the block or higher,
    ``LATERAL_GOAL_FALLBACKS``) give one: the plan finds a lateral path ending at one of them,
    collision-free (checked independently here), the palm facing the block along the radial."""
    world = World.build(episode_scene("random", 25, 1))
    target = ReachTarget.from_world(world, "hexagon_0")
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    ((pos, rot),) = goal_poses(target, base)["lateral"]
    assert solve_goal(checker, "lateral", [(pos, rot)], world.arm_qpos()) is None
    # why: the nominal IK solutions exist, and what they hit is the arm itself
    ik = checker.solve_ik(pos, rot, world.arm_qpos())
    assert ik.found and checker.collides(ik.q)
    names = [
        (checker.model.geom(c.geom1).name, checker.model.geom(c.geom2).name)
        for c in checker.data.contact[: checker.data.ncon]
    ]
    assert names and all(a.startswith("arm/") and b.startswith("arm/") for a, b in names)

    plan = plan_coarse_reach(world, target, approaches=("lateral",))
    assert plan.found and plan.approach == "lateral" and plan.goal is not None
    fallbacks = lateral_fallback_poses(target, base)
    assert any(np.allclose(plan.goal.palm_position, p) for p, _ in fallbacks)
    assert not CollisionChecker(world, hand_q=PRESHAPE).collides(plan.goal.q)
    palm, R = checker.palm_pose(plan.goal.q)
    np.testing.assert_allclose(palm, plan.goal.palm_position, atol=0.005)
    radial = np.array([*(np.asarray(target.position_xy) - base), 0.0])
    assert R[:, 2] @ (radial / np.linalg.norm(radial)) > np.cos(np.deg2rad(5.0))


@pytest.mark.parametrize("tilt_deg", [0.0, 15.0, 45.0])
@pytest.mark.parametrize("roll_deg", [0.0, 10.0, -30.0])
def test_a_lateral_frame_faces_along_the_radial_pitched_down_with_the_finger_row_level(
    tilt_deg: float, roll_deg: float
) -> None:
    """``lateral_frame``: a rotation; the approach axis (z) in the vertical plane of the radial,
    ``tilt`` below the horizontal; unrolled, the finger row (x) horizontal and hand y up; rolled,
    hand y turned by ``roll`` about z towards the unrolled x."""
    radial = np.array([np.cos(0.7), np.sin(0.7), 0.0])
    tilt, roll = np.deg2rad(tilt_deg), np.deg2rad(roll_deg)
    R = lateral_frame(radial, tilt, roll)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    z = R[:, 2]
    assert np.degrees(np.arcsin(-z[2])) == pytest.approx(tilt_deg)
    assert np.cross(radial, z) @ np.array([0.0, 0.0, 1.0]) == pytest.approx(0.0, abs=1e-12)
    assert z[:2] @ radial[:2] > 0
    level = lateral_frame(radial, tilt)
    assert level[2, 0] == pytest.approx(0.0, abs=1e-12) and level[2, 1] > 0
    turned = np.degrees(np.arctan2(level[:, 0] @ R[:, 1], level[:, 1] @ R[:, 1]))
    assert turned == pytest.approx(roll_deg)


def test_a_block_too_near_the_base_for_a_level_lateral_goal_is_approached_pitched_down() -> None:
    """Random scene 26 (1 block, 0.49 m from the arm's base): at every level lateral goal (the
    nominal one and the level ``LATERAL_GOAL_FALLBACKS``) the 5-joint arm's hand hits its own
    forearm; pitched down by the first of ``LATERAL_TILTS`` the wrist unfolds, and the plan ends
    there: a collision-free posture (checked independently) with the palm at its goal, the axis
    along the radial pitched 15 deg down."""
    world = World.build(episode_scene("random", 26, 1))
    target = ReachTarget.from_world(world, "irregular_hexagon_0")
    base = world.data.xpos[world.model.body(robot.arm_name("arm_base")).id][:2]
    checker = CollisionChecker(world, hand_q=PRESHAPE)
    level = goal_poses(target, base)["lateral"] + [
        pose
        for pose, (_, _, tilt) in zip(
            lateral_fallback_poses(target, base), LATERAL_GOAL_FALLBACKS, strict=True
        )
        if tilt == 0.0
    ]
    assert solve_goal(checker, "lateral", level, world.arm_qpos()) is None
    plan = plan_coarse_reach(world, target, approaches=("lateral",))
    assert plan.found and plan.approach == "lateral" and plan.goal is not None
    assert not CollisionChecker(world, hand_q=PRESHAPE).collides(plan.goal.q)
    palm, R = checker.palm_pose(plan.goal.q)
    np.testing.assert_allclose(palm, plan.goal.palm_position, atol=0.005)
    radial = np.array([*(np.asarray(target.position_xy) - base), 0.0])
    radial /= np.linalg.norm(radial)
    pitch = np.arcsin(-R[2, 2])
    assert pitch == pytest.approx(LATERAL_TILTS[0], abs=np.deg2rad(2.0))
    horizontal = R[:, 2] - R[2, 2] * np.array([0.0, 0.0, 1.0])
    assert horizontal @ radial / np.linalg.norm(horizontal) > np.cos(np.deg2rad(5.0))


def test_auto_takes_a_level_top_path_over_a_shorter_pitched_lateral_one() -> None:
    """Random scene 26: with ``auto`` both approaches have a path, the lateral one to a goal
    only pitched down; the top approach is taken. Where a pitched lateral path is the shorter,
    the log says the level goal was taken first, not that it was the shortest."""
    world = World.build(episode_scene("random", 26, 1))
    target = ReachTarget.from_world(world, "irregular_hexagon_0")
    plan = plan_coarse_reach(world, target)
    assert plan.found and plan.approach == "top"
    assert plan.candidates["lateral"].found
    assert plan.goal is not None and plan.goal.pitch == pytest.approx(np.pi / 2, abs=0.01)

    def path(length: float) -> ArmPath:
        return ArmPath(True, np.array([np.zeros(5), [length, 0, 0, 0, 0]]), "", None, 0, 0, 0, 0)

    shorter_lateral = {"top": path(2.0), "lateral": path(1.0)}
    reason = choice_reason(("top", "lateral"), shorter_lateral, (), "top")
    assert reason.startswith("a level goal first") and "lateral 1.00 rad" in reason
    longer_lateral = {"top": path(2.0), "lateral": path(3.0)}
    assert choice_reason(("top", "lateral"), longer_lateral, (), "top").startswith("the shortest")
