"""Tests of the Select/Model vision (section 5.2): real scenes rendered through MuJoCo by hand_sim,
checked against the scene's true footprints."""

from __future__ import annotations

import re

import numpy as np
import pytest

from controllers.grasp import (
    PAPER_OBJECTS,
    KnowledgeBased,
    grasp_score,
    paper_object,
    run_trials,
)
from hand_sim.camera import OverheadCamera
from hand_sim.scene import COLOURS, BlockSpec, Scene, TableSpec, load_scene
from hand_sim.world import World
from vision import (
    ExtractionError,
    NotABlockError,
    ObjectModel,
    Observation,
    VisionError,
    analyze,
    bench,
    overhead_camera,
    select,
)
from vision.__main__ import main as vision_cli
from vision.bench import BlockResult, add_noise, change_lighting, evaluate_scene, summarize
from vision.bench import main as bench_main
from vision.metrics import model_error

WIDTH, HEIGHT = 1280, 960
#: Acceptance per block (issue 5): centroid (mm), vertex (mm), yaw (deg).
MAX_CENTROID_MM = 1.0
MAX_VERTEX_MM = 3.0
MAX_YAW_DEG = 1.0
#: What the vision achieves here, with a margin: the acceptance above is ten times looser. Worst
#: measured over the blocks of these tests: vertex 0.38 mm, area 1.3 % (a pixel is ~0.8 mm).
#: Edge points half a pixel outward give vertex errors of 0.5-0.9 mm and areas 3.6-5.9 % too big.
ACHIEVED_VERTEX_MM = 0.7
ACHIEVED_AREA_PCT = 2.5
#: An arm posture (waist, shoulder, elbow, wrist pitch, roll) that holds the hand over the
#: table near (-0.1, 0.075), above the blocks' tops.
ARM_OVER_TABLE = (0.0, -0.07, 2.29, -0.4, 0.0)


def _render(world: World, rng: np.random.Generator | None = None) -> Observation:
    if rng is not None:
        change_lighting(world.model, world.data, rng)
    with overhead_camera(world, WIDTH, HEIGHT) as cam:
        return Observation.capture(cam)


def _nine_scene() -> Scene:
    """The nine paper objects on a 3 x 3 grid at seeded random yaws."""
    rng = np.random.default_rng(5)
    colours = list(COLOURS.values())
    blocks = []
    for i, name in enumerate(PAPER_OBJECTS):
        xy = (-0.15 + 0.17 * (i % 3), -0.2 + 0.2 * (i // 3))
        blocks.append(
            BlockSpec(
                name,
                paper_object(name),
                xy,
                float(rng.uniform(-np.pi, np.pi)),
                rgba=colours[i % len(colours)],
            )
        )
    return Scene("nine", TableSpec(), tuple(blocks), blocks[0].name, (0.35, 0.35))


@pytest.fixture(scope="module")
def nine() -> tuple[Scene, Observation]:
    scene = _nine_scene()
    return scene, _render(World.build(scene))


@pytest.fixture(scope="module")
def nine_noisy() -> tuple[Scene, Observation]:
    scene = _nine_scene()
    rng = np.random.default_rng(11)
    return scene, add_noise(_render(World.build(scene), rng), rng)


def _positions(scene: Scene) -> dict[str, tuple[float, float]]:
    return {b.name: b.position for b in scene.blocks}


def _check_block(model: ObjectModel, block: BlockSpec) -> None:
    err = model_error(model, block.polygon.vertices, block.position, block.yaw)
    assert err.edges_right, f"{block.name}: {model.n_edges} edges, true {block.polygon.n_edges}"
    assert err.centroid_mm < MAX_CENTROID_MM, f"{block.name}: centroid off {err.centroid_mm:.2f} mm"
    assert err.vertex_mm.max() < MAX_VERTEX_MM, f"{block.name}: vertices off {err.vertex_mm} mm"
    assert err.yaw_deg < MAX_YAW_DEG, f"{block.name}: rotated {err.yaw_deg:.2f} deg"
    assert err.vertex_mm.max() < ACHIEVED_VERTEX_MM, f"{block.name}: vertices {err.vertex_mm} mm"
    area_pct = 100.0 * (model.polygon.area / block.polygon.area - 1.0)
    assert abs(area_pct) < ACHIEVED_AREA_PCT, f"{block.name}: area off {area_pct:.2f} %"


def test_camera_geometry_agrees_with_hand_sim() -> None:
    world = World.build(load_scene("clutter3"), with_robot=False)
    cam = OverheadCamera(world, 320, 240)
    try:
        obs = Observation.capture(cam)
        uv = np.array([[3.0, 7.0], [160.0, 120.0], [300.5, 200.25]])
        for z in (0.75, 0.95):
            np.testing.assert_allclose(
                obs.geometry.pixel_to_plane(uv, z), cam.pixel_to_world(uv, z), atol=1e-9
            )
        xyz = np.array([[0.1, -0.2, 0.95], [-0.3, 0.25, 0.75]])
        np.testing.assert_allclose(
            obs.geometry.world_to_pixel(xyz), cam.world_to_pixel(xyz), atol=1e-9
        )
    finally:
        cam.close()


def test_segmentation_finds_every_block_table_and_height(nine: tuple[Scene, Observation]) -> None:
    scene, obs = nine
    sel = analyze(obs, _positions(scene))
    seg = sel.segmentation
    assert abs(seg.table_z - scene.table.height) < 1e-3
    on_table = [b for b in sel.blocks if sel.names[b.index] is not None]
    assert sorted(sel.names[b.index] for b in on_table) == sorted(PAPER_OBJECTS)
    for b in on_table:
        assert abs(b.z_top - scene.table.height - 0.20) < 1e-3


@pytest.mark.parametrize("noisy", [False, True], ids=["clean", "noise+lighting"])
def test_nine_paper_objects_are_modelled(
    nine: tuple[Scene, Observation], nine_noisy: tuple[Scene, Observation], noisy: bool
) -> None:
    scene, obs = nine_noisy if noisy else nine
    sel = analyze(obs, _positions(scene))
    area_pct = []
    for block in scene.blocks:
        model = sel.select_name(block.name)
        assert model.name == block.name
        assert abs(model.height - 0.20) < 2e-3
        _check_block(model, block)
        area_pct.append(100.0 * (model.polygon.area / block.polygon.area - 1.0))
        # the object frame: polygon vertices map back onto the world vertices
        np.testing.assert_allclose(
            model.to_world(model.polygon.vertices), model.world_vertices, atol=1e-9
        )
    # no bias: the mean area error is -0.08 % (clean) and +0.15 % (noisy); +4.7 % if the edge
    # points were half a pixel outward
    assert abs(np.mean(area_pct)) < 0.75


def test_select_by_pixel_name_and_world_point_agree(nine: tuple[Scene, Observation]) -> None:
    scene, obs = nine
    block = scene.blocks[7]
    pixel = obs.geometry.world_to_pixel([*block.position, scene.table.height + block.height])
    by_pixel = select(obs, pixel=pixel, block_positions=_positions(scene))
    by_name = select(obs, name=block.name, block_positions=_positions(scene))
    by_point = select(obs, world_point=np.add(block.position, 0.01))
    for model in (by_pixel, by_name, by_point):
        assert np.linalg.norm(model.centroid[:2] - block.position) < 1e-3
    assert by_pixel.name == by_name.name == block.name


def test_a_click_on_a_side_face_selects_its_block(nine: tuple[Scene, Observation]) -> None:
    scene, obs = nine
    sel = analyze(obs, _positions(scene))
    block = scene.blocks[8]  # far from the image centre: its side faces show
    # the ray to a point inside the block near its base enters through a side face
    base = obs.geometry.world_to_pixel([*block.position, scene.table.height + 0.02])
    u, v = np.rint(base).astype(int)
    label = sel.segmentation.labels[v, u]
    assert label > 0 and not sel.blocks[label - 1].top_mask[v, u]  # a side face, not the top
    assert sel.names[sel.index_at_pixel((u, v))] == block.name


def test_a_click_on_the_table_is_a_clear_error(nine: tuple[Scene, Observation]) -> None:
    scene, obs = nine
    table_px = obs.geometry.world_to_pixel([0.4, -0.4, scene.table.height])
    with pytest.raises(NotABlockError, match=r"on the table.*blocks in the 1280x960 image are at"):
        select(obs, pixel=table_px)
    with pytest.raises(NotABlockError, match="outside the 1280x960 image"):
        select(obs, pixel=(5000, 3))
    with pytest.raises(VisionError, match="exactly one"):
        select(obs, pixel=table_px, world_point=(0.0, 0.0))
    with pytest.raises(NotABlockError, match="no visible block is named 'nope'"):
        select(obs, name="nope", block_positions=_positions(scene))


def test_touching_blocks_of_different_colours_are_split() -> None:
    square = paper_object("square")  # 4 cm wide: side by side they touch
    blocks = (
        BlockSpec("left", square, (0.0, 0.1), 0.0, rgba=COLOURS["red"]),
        BlockSpec("right", square, (0.04, 0.1), 0.0, rgba=COLOURS["blue"]),
    )
    scene = Scene("touching", TableSpec(), blocks, "left", (0.3, 0.3))
    obs = _render(World.build(scene, with_robot=False))
    sel = analyze(obs, _positions(scene))
    for block in blocks:
        _check_block(sel.select_name(block.name), block)


def test_blocks_nearly_touching_in_perspective_are_separate() -> None:
    """Far from the image centre a block's side faces reach towards its neighbour in the image."""
    rng = np.random.default_rng(3)
    names = ("hexagon", "trapezoid", "irregular_pentagon")
    blocks = tuple(
        BlockSpec(
            n,
            paper_object(n),
            (0.38, -0.36 + 0.065 * i),
            float(rng.uniform(-np.pi, np.pi)),
            rgba=COLOURS["green"],
        )
        for i, n in enumerate(names)
    )
    scene = Scene("near_edge", TableSpec(), blocks, names[0], (0.0, 0.0))
    obs = _render(World.build(scene, with_robot=False))
    sel = analyze(obs, _positions(scene))
    for block in blocks:
        _check_block(sel.select_name(block.name), block)


def test_a_block_partly_hidden_by_the_arm_is_refused_with_the_reason() -> None:
    block = BlockSpec("hidden", paper_object("pentagon"), (-0.12, 0.075), 0.3, rgba=COLOURS["red"])
    scene = Scene("occluded", TableSpec(), (block,), "hidden", (0.3, 0.3))
    world = World.build(scene)
    world.set_arm_targets(ARM_OVER_TABLE)
    world.step(1000)
    obs = _render(world)
    sel = analyze(obs, _positions(scene))
    with pytest.raises(ExtractionError, match=r"block 'hidden' at pixel .*(hidden|missing)"):
        sel.select_name("hidden")


def test_a_block_next_to_the_arm_is_still_modelled() -> None:
    block = BlockSpec("beside", paper_object("pentagon"), (-0.05, 0.075), 0.3, rgba=COLOURS["red"])
    scene = Scene("beside_arm", TableSpec(), (block,), "beside", (0.3, 0.3))
    world = World.build(scene)
    world.set_arm_targets(ARM_OVER_TABLE)
    world.step(1000)
    pos, quat = world.block_pose("beside")
    moved = BlockSpec(
        "beside", block.polygon, (pos[0], pos[1]), 2.0 * float(np.arctan2(quat[3], quat[0]))
    )
    obs = _render(world)
    _check_block(select(obs, world_point=pos[:2]), moved)


def _theta_on_true(model: ObjectModel, block: BlockSpec, theta_model: np.ndarray) -> np.ndarray:
    """Contact angles on the model's polygon mapped onto the true polygon (through the world)."""
    pts = model.polygon.point_at(theta_model)  # object frame of the model, metres
    world = model.to_world(pts) - np.asarray(block.position)
    c, s = np.cos(block.yaw), np.sin(block.yaw)
    local = world @ np.array([[c, -s], [s, c]])
    return np.arctan2(local[..., 1], local[..., 0])


def test_grasps_on_extracted_and_true_polygons_agree(nine: tuple[Scene, Observation]) -> None:
    """Section 5.2 feeds the vision's polygon to the grasp controller: on every paper object, the
    grasps it reaches score the same S_G, on the true polygon, as grasps planned on the truth."""
    scene, obs = nine
    sel = analyze(obs, _positions(scene))
    n = 40
    for block in scene.blocks:
        model = sel.select_name(block.name)
        rng = np.random.default_rng(17)
        theta0 = rng.uniform(0.0, 2.0 * np.pi, size=(n, 4))  # true object frame
        dyaw = block.yaw - model.yaw
        truth = run_trials(
            [block.polygon],
            np.zeros(n, int),
            KnowledgeBased(),
            np.random.default_rng(1),
            theta_initial=theta0,
        )
        seen = run_trials(
            [model.polygon],
            np.zeros(n, int),
            KnowledgeBased(),
            np.random.default_rng(1),
            theta_initial=theta0 + dyaw,
        )
        unit = block.polygon.unit_moment()
        frames = unit.locate(_theta_on_true(model, block, seen.theta_final))
        s_g = np.array([grasp_score(frames.point[i], frames.normal[i]).s_g for i in range(n)])
        success = s_g <= 0.4
        assert np.mean(success == truth.success) >= 0.95, block.name
        finite = np.isfinite(s_g) & np.isfinite(truth.s_g)
        assert np.median(np.abs(s_g[finite] - truth.s_g[finite])) < 0.02, block.name


def test_bench_runs_and_reports(capsys: pytest.CaptureFixture[str]) -> None:
    status = bench_main(["--trials", "2", "--shapes", "paper", "--width", "640", "--height", "480"])
    out = capsys.readouterr().out
    assert status == 0, out  # 0 only when both acceptance checks pass
    assert "edges ok" in out and "acceptance (noiseless)" in out and "acceptance (noisy)" in out
    assert out.count(": PASS") == 2


def _result(noisy: bool, n_edges: int, vertex_mm: float) -> BlockResult:
    return BlockResult("paper", noisy, 4, n_edges, "", 0.1, np.full(4, vertex_mm), 0.1, 5.0)


def test_bench_acceptance_fails_and_exits_1_when_a_target_is_missed(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    good = [_result(False, 4, 0.1) for _ in range(100)] + [_result(True, 4, 0.1)] * 100
    text, ok = summarize(good)
    assert ok and text.count(": PASS") == 2
    # 2 % of the noiseless edge counts wrong (acceptance: >= 99 %); noisy still fine
    wrong = [_result(False, 3, 0.1)] * 2 + good[2:]
    text, ok = summarize(wrong)
    assert not ok and "(noiseless)" in text and text.count(": FAIL") == 1
    # vertex p95 above 3 mm with noise
    far = good[:100] + [_result(True, 4, 3.5)] * 10 + good[110:]
    assert not summarize(far)[1]
    monkeypatch.setattr(bench, "run", lambda *args: wrong)
    assert bench_main(["--trials", "2", "--shapes", "paper"]) == 1
    assert "FAIL" in capsys.readouterr().out


def test_bench_rejects_bad_trials(capsys: pytest.CaptureFixture[str]) -> None:
    assert bench_main(["--trials", "0"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_evaluate_scene_counts_a_missing_block() -> None:
    scene = load_scene("clutter3")
    world = World.build(scene, with_robot=False)
    obs = _render(world)
    ghost = BlockSpec("ghost", paper_object("square"), (0.3, 0.3), 0.0)
    results = evaluate_scene(
        Scene("x", scene.table, (*scene.blocks, ghost), scene.target, scene.place),
        obs,
        "paper",
        False,
    )
    assert [r.failure for r in results[:3]] == ["", "", ""]
    assert results[3].failure == "not found" and results[3].n_edges == 0


def test_observation_refuses_mismatched_images() -> None:
    world = World.build(load_scene("clutter3"), with_robot=False)
    cam = OverheadCamera(world, 160, 120)
    try:
        obs = Observation.capture(cam)
    finally:
        cam.close()
    with pytest.raises(VisionError, match=r"depth shape \(120, 159\) differs"):
        Observation(obs.rgb, obs.depth[:, :-1], obs.geometry)
    with pytest.raises(VisionError, match="uint8"):
        Observation(obs.rgb.astype(float), obs.depth, obs.geometry)


def test_cli_models_a_named_block_and_refuses_a_table_click(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert vision_cli(["--scene", "clutter3", "--name", "pentagon"]) == 0
    out = capsys.readouterr().out
    assert "block pentagon: 5 edges" in out and "height 0.2000 m" in out
    assert vision_cli(["--scene", "clutter3", "--pick-pixel", "10,10"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "on the table" in err[0]
    # the message lists the three blocks, by name, and not the parked arm's base at the image's
    # left edge (its flat top is a plateau at block height, off the table)
    listed = re.findall(r"\((\d+), (\d+)\)( \w+)?", err[0].split("are at pixels ")[1])
    assert sorted(name.strip() for _, _, name in listed) == ["pentagon", "rectangle", "triangle"]
