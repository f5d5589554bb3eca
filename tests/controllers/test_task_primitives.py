"""The controllers the task cycle sequences, each on its own (issue 9's breakages, fixed in their
modules): the perceived planning model, posture control that keeps clear of the block, fine
reach's touch guard and perceived obstacles, the reachability criterion, the trapezoidal carry
profile and the wrist's load sensing."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from controllers.deliver.carry import held_load, timed_path
from controllers.hand.finger_geometry import PerceivedPrism
from controllers.hand.reachability import MIN_PAD_SPACING, check_reach
from controllers.planning.belief import PERCEIVED_GEOM, planning_model
from controllers.planning.cspace import CollisionChecker
from controllers.planning.harmonic import GridSpec
from controllers.posture.solver import CLEARANCE_SLACK, apply_posture, solve_posture
from controllers.preshape.moves import BlockSite, approach_touches, move_backed_out
from controllers.reach.coarse import PRESHAPE, ReachTarget
from controllers.reach.fine import fine_reach, obstacle_grid
from hand_sim import robot
from hand_sim.scene import load_scene
from hand_sim.world import World
from tests.controllers.conftest import hover_over_target


def shifted(target: ReachTarget, dx: float) -> ReachTarget:
    return dataclasses.replace(
        target, position_xy=(target.position_xy[0] + dx, target.position_xy[1])
    )


def test_planning_model_holds_the_perceived_block_not_the_true_one() -> None:
    world = World.build(load_scene("single_square"))
    truth = ReachTarget.from_world(world, "square")
    seen = shifted(truth, 0.20)  # perceived 20 cm away from where it stands
    model = planning_model(world, "square", seen.polygon, seen.yaw, seen.position_xy, seen.top_z)
    data = mujoco.MjData(model)
    data.qpos[:] = world.data.qpos
    mujoco.mj_forward(model, data)
    probe = model.geom(PERCEIVED_GEOM).id
    assert data.geom_xpos[probe][0] == pytest.approx(seen.position_xy[0], abs=1e-6)
    true_geom = model.geom("square_geom").id
    assert model.geom_contype[true_geom] == 0 and model.geom_conaffinity[true_geom] == 0
    # the planner's collision checks see the perceived block: a palm over the perceived block's
    # place collides, one over the true block's place does not
    checker = CollisionChecker(world, model=model, clearance=0.0, hand_q=PRESHAPE)
    base = checker.data.xpos[model.body(robot.arm_name("arm_base")).id]
    down = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    hits = []
    for xy in (seen.position_xy, truth.position_xy):
        goal = np.array([*xy, seen.top_z - 0.005])  # the palm 5 mm into the top, fingers around
        waist = np.arctan2(goal[1] - base[1], goal[0] - base[0])
        ik = checker.solve_ik(goal, down, [waist, 0.3, 1.5, 1.3, 0.0])
        assert ik.found
        hits.append(checker.collides(ik.q))
    assert hits == [True, False]


def test_posture_control_keeps_the_palm_and_links_off_the_block(hovering) -> None:
    """Breakage 2: posture control over arm and hand pushed the block by 5 cm; with collision
    avoidance in the perceived world it raises manipulability and the block stays put."""
    world, target = hovering
    name = world.scene.target
    before = world.block_pose(name)[0]
    model = planning_model(
        world, name, target.polygon, target.yaw, target.position_xy, target.top_z
    )
    sol = solve_posture(world, model=model, avoid_collisions=True, touchable=PERCEIVED_GEOM)
    assert sol.reachable
    assert sol.log_manipulability_end > sol.log_manipulability_start
    assert sol.path is not None and len(sol.path) >= 2
    apply_posture(world, sol)
    assert np.linalg.norm(world.block_pose(name)[0] - before) < 1e-3
    free = solve_posture(world, model=model, avoid_collisions=False)
    assert free.reachable  # the same problem without avoidance: a different posture
    assert np.abs(free.arm_q - sol.arm_q).max() > 1e-3


def test_fine_reach_guards_touch_and_uses_the_perceived_block(hovering) -> None:
    world, target = hovering
    name = world.scene.target
    # obstacles: the perceived block, not the true one
    spec = GridSpec((-0.1, -0.1, 0.8), (0.1, 0.1, 0.96), (41, 41, 17))
    seen = shifted(target, 0.03)
    free_true = obstacle_grid(world, target, spec, None)
    free_seen = obstacle_grid(world, seen, spec, name)
    centre = np.array(spec.nearest_cell(np.array([*seen.position_xy, 0.85])))
    assert free_true[tuple(centre)] and not free_seen[tuple(centre)]
    # the reach itself: every finger ends near its target or stopped by its guard, and the
    # block is not shoved
    before = world.block_pose(name)[0]
    result = fine_reach(world, name, seen=target, standoff=0.008, tolerance=0.006)
    # three fingers projected onto one face crowd each other (the task cycle spreads their
    # targets first): they end within a pad's width of their targets, the block unmoved
    assert result.tip_error.max() < 0.015, result.tip_error
    assert result.max_penetration < 0.002
    assert np.linalg.norm(world.block_pose(name)[0][:2] - before[:2]) < 5e-3


def _pad_distances(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Each pad's signed distance (m) to the perceived block in ``model`` at ``qpos``."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    block, fromto = model.geom(PERCEIVED_GEOM).id, np.zeros(6)
    pads = [model.geom(robot.hand_name(f"{f}_pad")).id for f in robot.FINGERS]
    return np.array([mujoco.mj_geomDistance(model, data, g, block, 0.05, fromto) for g in pads])


def test_the_hold_posture_keeps_the_pads_from_pressing_into_the_block() -> None:
    """Posture Control after Fine Reach holds the fingertip sites; turning a finger about its
    tip swings the pad into the face (clutter3: 5-9 mm into it, which pushed tall triangles
    over on the tendon hand). With ``pads_press=False`` the pads may touch, not press in, the
    manipulability still rises, and the block stays where it stands."""
    world, target = hover_over_target()
    name = world.scene.target
    model = planning_model(
        world, name, target.polygon, target.yaw, target.position_xy, target.top_z
    )
    fine_reach(world, name, seen=target, model=model, touchable=PERCEIVED_GEOM)
    before = world.block_pose(name)[0]

    def planned(pads_press: bool) -> tuple[object, np.ndarray]:
        sol = solve_posture(
            world,
            model=model,
            avoid_collisions=True,
            touchable=PERCEIVED_GEOM,
            pads_press=pads_press,
        )
        q = world.data.qpos.copy()
        q[robot.arm_qpos_addresses(model)] = sol.arm_q
        q[robot.hand_qpos_addresses(model)] = sol.hand_q
        return sol, _pad_distances(model, q)

    _, pressed = planned(True)
    assert pressed.min() < -0.003  # the unguarded hold does press a pad in
    sol, kept = planned(False)
    assert sol.reachable
    assert sol.log_manipulability_end > sol.log_manipulability_start
    assert kept.min() > -CLEARANCE_SLACK, kept
    apply_posture(world, sol)
    assert np.linalg.norm(world.block_pose(name)[0][:2] - before[:2]) < 1e-3


def test_reachability_refuses_pads_too_close_and_unreachable_contacts(hovering) -> None:
    world, target = hovering
    prism = PerceivedPrism.of(target, world.scene.table.height)
    theta = np.array([0.0, 0.05, 2.0, -2.0])  # two contacts 1-2 mm apart
    frames = target.polygon.locate(theta)
    c, s = np.cos(target.yaw), np.sin(target.yaw)
    xy = frames.point @ np.array([[c, s], [-s, c]]) + np.asarray(target.position_xy)
    nxy = frames.normal @ np.array([[c, s], [-s, c]])
    z = np.full(4, target.top_z - 0.04)
    points = np.column_stack([xy, z])
    normals = np.column_stack([nxy, np.zeros(4)])
    verdict = check_reach(world, prism, points, normals)
    assert not verdict.reachable and "apart" in verdict.reason
    assert verdict.min_spacing < MIN_PAD_SPACING
    # contacts free to slide up and down their faces, the two close ones given above the top
    # and below the bottom: the pads' spacing is measured where the fingers take them, at the
    # heights taken (a lateral hand's fingers stack on one face), not at the heights given
    given = np.column_stack([xy, [prism.top + 0.03, prism.bottom - 0.02, z[2], z[3]]])
    slid = check_reach(world, prism, given, normals, slide=True)
    assert slid.heights is not None
    assert np.all((slid.heights > prism.bottom) & (slid.heights < prism.top))
    pads = np.column_stack([xy, slid.heights]) + robot.PAD_RADIUS * normals
    gaps = np.linalg.norm(pads[:, None] - pads[None, :], axis=-1)
    assert slid.min_spacing == pytest.approx(gaps[np.triu_indices(4, 1)].min())
    far = points + np.array([0.3, 0.0, 0.0])  # 30 cm away: no finger reaches with the arm held
    verdict = check_reach(world, prism, far, normals, check_spacing=False)
    assert not verdict.reachable and "cannot reach" in verdict.reason


def test_carry_profile_is_trapezoidal_and_ends_on_the_path() -> None:
    line = np.array([[0.0, 0.0], [1.5, 0.5]])
    q = timed_path(line, 0.4, 0.6, 0.02)
    np.testing.assert_allclose(q[-1], line[-1])
    speed = np.abs(np.diff(np.vstack([line[:1], q]), axis=0)).max(axis=1) / 0.02
    assert speed.max() <= 0.4 + 1e-9 and speed.max() > 0.39  # cruises at the top speed
    accel = np.abs(np.diff(speed)) / 0.02
    assert accel.max() <= 0.6 + 1e-6
    assert speed[0] < 0.05 and speed[-1] < 0.05  # starts and ends at rest
    # a polyline is followed through its corner, every posture on it
    corner = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    q = timed_path(corner, 0.4, 0.6, 0.02)
    on_path = np.minimum(np.abs(q[:, 1]) * (q[:, 0] <= 1.0), np.abs(q[:, 0] - 1.0))
    assert on_path.max() < 1e-9


def test_wrist_load_ignores_the_arms_own_acceleration() -> None:
    """The held load is the wrist force over the accelerometer's reading less the hand's mass:
    an empty hand shaken up and down reads about zero load."""
    world = World.build(load_scene("single_square"))
    world.step(round(1.0 / world.model.opt.timestep))
    empty = world.wrist_wrench()[0]
    loads, raw = [], []
    q0 = world.arm_qpos()
    for k in range(150):
        q = q0.copy()
        q[1] += 0.15 * np.sin(2 * np.pi * k / 50)  # the shoulder swings the hand up and down
        world.set_arm_targets(q)
        world.step(10)
        loads.append(held_load(world, empty))
        raw.append(world.wrist_wrench()[0][2] - empty[2])
    assert np.max(np.abs(raw)) > 1.0  # the raw force swings by more than a newton
    assert np.max(np.abs(loads)) < 0.2 * np.max(np.abs(raw))


def test_approach_touches_names_a_neighbour_on_the_straight_approach_and_never_the_target() -> None:
    """controllers.preshape.moves.approach_touches: the pre-shaped hand's straight 8 cm approach to
    a
    palm pose just above single_square's block meets a post standing where a fingertip passes
    (a neighbour it would push) and nothing else; without the post it meets nothing (the block
    itself, perceived or true, and the table are not neighbours)."""
    base_scene = load_scene("single_square")
    found = {}
    for with_post in (False, True):
        scene = base_scene
        world = World.build(scene)
        truth = ReachTarget.from_world(world, "square")
        model = planning_model(
            world, "square", truth.polygon, truth.yaw, truth.position_xy, truth.top_z
        )
        checker = CollisionChecker(world, model=model, clearance=0.0, hand_q=PRESHAPE)
        base = checker.data.xpos[model.body(robot.arm_name("arm_base")).id]
        down = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
        goal = np.array([*truth.position_xy, truth.top_z + 0.08])
        waist = np.arctan2(goal[1] - base[1], goal[0] - base[0])
        ik = checker.solve_ik(goal, down, [waist, 0.3, 1.5, 1.3, 0.0])
        assert ik.found
        if with_post:
            # a slender post under the first finger's tip, clear of the block
            tip = checker.data.site_xpos[model.site(robot.qualified("ff_tip")).id][:2]
            post = dataclasses.replace(
                scene.block("square"),
                name="post",
                polygon=scene.block("square").polygon.scaled(0.3),
                position=(float(tip[0]), float(tip[1])),
            )
            scene = dataclasses.replace(scene, blocks=(*scene.blocks, post))
            world = World.build(scene)
            model = planning_model(
                world, "square", truth.polygon, truth.yaw, truth.position_xy, truth.top_z
            )
        site = BlockSite(
            world, model, truth, world.block_body_id("square"), np.array([0.0, 0.0, -1.0])
        )
        found[with_post] = approach_touches(site, ik.q, np.asarray(PRESHAPE))
    assert found == {False: (), True: ("post",)}


def test_the_arm_moves_between_backed_out_postures_straight_when_clear_else_harmonic() -> None:
    """controllers.preshape.moves.move_backed_out, above clutter3's target: a small turn of the
    waist
    and the wrist, well clear of everything, is taken in a straight joint-space line; with a
    clearance no line can keep (19 cm: the block below is nearer), the way back is planned as a
    harmonic path instead. Both end at their goal posture and push no block."""
    world, target = hover_over_target()
    name = world.scene.target
    model = planning_model(
        world, name, target.polygon, target.yaw, target.position_xy, target.top_z
    )
    site = BlockSite(world, model, target, world.block_body_id(name), np.array([0.0, 0.0, -1.0]))
    blocks = [b.name for b in world.scene.blocks]
    before = {b: world.block_pose(b)[0].copy() for b in blocks}
    start = world.arm_qpos().copy()
    goal = start + np.array([0.05, 0.0, 0.0, 0.0, 0.5])
    assert move_backed_out(site, goal) == "straight"
    assert np.abs(world.arm_qpos() - goal).max() < 0.02
    far = dataclasses.replace(site.params, direct_clearance=0.19)
    assert move_backed_out(dataclasses.replace(site, params=far), start) == "harmonic"
    assert np.abs(world.arm_qpos() - start).max() < 0.02
    for b in blocks:
        assert np.linalg.norm(world.block_pose(b)[0] - before[b]) < 1e-3, b
