"""Benchmark of the Select/Model vision (section 5.2).

    python -m vision.bench --trials 200 --seed 0 [--quick]

Seeded random layouts of prism blocks (the nine paper objects, and random convex polygons) are
rendered through MuJoCo by :mod:`hand_sim` (arm parked at home), once clean and once with the
benchmark's noise: a random lighting change (light intensities and direction), Gaussian colour
noise and Gaussian depth noise. Every block is extracted and compared with its true footprint.
Printed: edge-count accuracy, centroid error, vertex error (median, 95th percentile), yaw error,
and the time per extraction.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from controllers.grasp import PAPER_OBJECTS, Polygon, paper_object, random_convex_polygon
from hand_sim import clitools as cli
from hand_sim.geometry import convex_polygon_distance, place_polygon
from hand_sim.scene import COLOURS, BlockSpec, Scene, TableSpec
from hand_sim.world import World
from vision.clitools import ERRORS
from vision.errors import VisionError
from vision.metrics import match_vertices
from vision.observation import DEFAULT_HEIGHT, DEFAULT_WIDTH, Observation, overhead_camera
from vision.select import analyze

#: Blocks per rendered scene.
BLOCKS_PER_SCENE = 4
#: Region of block centroids (m), as the random scene generator's defaults (scenes/random.toml).
REGION_X = (-0.20, 0.25)
REGION_Y = (-0.30, 0.30)
#: Gap (m) between block footprints: from the scene minimum (blocks nearly touching) up.
GAP_RANGE = (0.005, 0.03)
#: Noise: colour sigma (grey levels), depth sigma (m), light intensity scale range, light tilt.
RGB_NOISE = 4.0
DEPTH_NOISE = 0.001
LIGHT_SCALE = (0.6, 1.3)
LIGHT_TILT_DEG = 30.0
#: Acceptance: edge counts right, centroid median (mm), vertex 95th percentile (mm).
ACCEPT_EDGES = {False: 0.99, True: 0.97}
ACCEPT_CENTROID_MM = 1.0
ACCEPT_VERTEX_P95_MM = 3.0
#: A block counts as found when a segmented face lies this close (m) to its true centroid.
MATCH_RADIUS = 0.03
PROG = "python -m vision.bench"
#: Most blocks per shape set (each costs two renders; 200 take about 2 minutes at 1920x1440).
MAX_TRIALS = 10_000


@dataclass(frozen=True)
class BlockResult:
    """The outcome of one block's extraction."""

    shapes: str  #: "paper" or "random"
    noisy: bool
    true_edges: int
    n_edges: int  #: 0 when extraction failed
    failure: str  #: why extraction failed ("" when it did not)
    centroid_mm: float
    vertex_mm: NDArray[np.float64]  #: empty unless the edge count is right
    yaw_deg: float
    ms: float  #: segmentation share plus the extraction


def _draw_polygon(rng: np.random.Generator, shapes: str) -> Polygon:
    if shapes == "paper":
        return paper_object(PAPER_OBJECTS[int(rng.integers(len(PAPER_OBJECTS)))])
    return random_convex_polygon(rng)


def random_layout(rng: np.random.Generator, shapes: str, n_blocks: int, index: int) -> Scene:
    """A hand_sim Scene with ``n_blocks`` blocks of the shape set at random poses."""
    table = TableSpec()
    palette = list(COLOURS.values())
    colours = [palette[i] for i in rng.permutation(len(palette))]
    blocks: list[BlockSpec] = []
    footprints: list[NDArray] = []
    while len(blocks) < n_blocks:
        poly = _draw_polygon(rng, shapes)
        for _ in range(1000):
            xy = np.array([rng.uniform(*REGION_X), rng.uniform(*REGION_Y)])
            yaw = float(rng.uniform(-np.pi, np.pi))
            fp = place_polygon(poly.vertices, xy, yaw)
            gap = float(rng.uniform(*GAP_RANGE))
            if table.contains(fp) and all(
                convex_polygon_distance(fp, o) >= gap for o in footprints
            ):
                break
        else:
            continue
        name = f"{poly.name}_{len(blocks)}"
        blocks.append(
            BlockSpec(
                name,
                poly,
                (float(xy[0]), float(xy[1])),
                yaw,
                rgba=colours[len(blocks) % len(colours)],
            )
        )
        footprints.append(fp)
    return Scene(
        name=f"vision_bench_{shapes}_{index}",
        table=table,
        blocks=tuple(blocks),
        target=blocks[0].name,
        place=(0.3, 0.35),
    )


def change_lighting(model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.Generator) -> None:
    """Scale every light and the headlight by a random factor and tilt the lights' directions."""
    scale = rng.uniform(*LIGHT_SCALE)
    model.light_diffuse[:] *= scale
    model.light_ambient[:] *= scale
    model.vis.headlight.diffuse[:] = np.asarray(model.vis.headlight.diffuse) * scale
    model.vis.headlight.ambient[:] = np.asarray(model.vis.headlight.ambient) * scale
    tilt = np.deg2rad(rng.uniform(0.0, LIGHT_TILT_DEG))
    az = rng.uniform(0.0, 2.0 * np.pi)
    d = np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), -np.cos(tilt)])
    model.light_dir[:] = d
    mujoco.mj_forward(model, data)


def add_noise(obs: Observation, rng: np.random.Generator) -> Observation:
    """Gaussian colour and depth noise on an observation."""
    rgb = np.clip(obs.rgb + rng.normal(0.0, RGB_NOISE, obs.rgb.shape), 0, 255).astype(np.uint8)
    depth = (obs.depth + rng.normal(0.0, DEPTH_NOISE, obs.depth.shape)).astype(np.float32)
    return Observation(rgb, depth, obs.geometry)


def render(scene: Scene, width: int, height: int, rng: np.random.Generator | None) -> Observation:
    """Render ``scene`` (arm at home) with hand_sim; ``rng`` given: changed lighting."""
    world = World.build(scene)
    if rng is not None:
        change_lighting(world.model, world.data, rng)
    with overhead_camera(world, width, height) as cam:
        return Observation.capture(cam)


def evaluate_scene(scene: Scene, obs: Observation, shapes: str, noisy: bool) -> list[BlockResult]:
    """Extract every block of ``scene`` from ``obs`` and compare with the truth."""
    t0 = time.perf_counter()
    sel = analyze(obs)
    seg_ms = 1000.0 * (time.perf_counter() - t0) / max(1, len(scene.blocks))
    centres = sel.block_centres()[:, :2] if sel.blocks else np.zeros((0, 2))
    results = []
    for block in scene.blocks:
        true = block.footprint()
        k = len(true)
        pos = np.asarray(block.position)
        d = np.linalg.norm(centres - pos, axis=1) if len(centres) else np.zeros(0)
        if d.size == 0 or d.min() > MATCH_RADIUS:
            results.append(
                BlockResult(shapes, noisy, k, 0, "not found", np.nan, np.zeros(0), np.nan, seg_ms)
            )
            continue
        t1 = time.perf_counter()
        try:
            model = sel.model(int(np.argmin(d)))
        except VisionError as e:
            ms = seg_ms + 1000.0 * (time.perf_counter() - t1)
            results.append(
                BlockResult(shapes, noisy, k, 0, str(e), np.nan, np.zeros(0), np.nan, ms)
            )
            continue
        ms = seg_ms + 1000.0 * (time.perf_counter() - t1)
        cen = 1000.0 * float(np.linalg.norm(model.centroid[:2] - pos))
        if model.n_edges == k:
            dv, rot = match_vertices(model.world_vertices, true)
            results.append(
                BlockResult(shapes, noisy, k, k, "", cen, 1000.0 * dv, abs(np.degrees(rot)), ms)
            )
        else:
            results.append(
                BlockResult(shapes, noisy, k, model.n_edges, "", cen, np.zeros(0), np.nan, ms)
            )
    return results


def run(
    trials: int, seed: int, width: int, height: int, shape_sets: Sequence[str]
) -> list[BlockResult]:
    """``trials`` blocks of each shape set, each rendered clean and noisy."""
    rng = np.random.default_rng(seed)
    results: list[BlockResult] = []
    for shapes in shape_sets:
        n_scenes = -(-trials // BLOCKS_PER_SCENE)
        for i in range(n_scenes):
            n = min(BLOCKS_PER_SCENE, trials - i * BLOCKS_PER_SCENE)
            scene = random_layout(rng, shapes, n, i)
            results += evaluate_scene(scene, render(scene, width, height, None), shapes, False)
            noisy = add_noise(render(scene, width, height, rng), rng)
            results += evaluate_scene(scene, noisy, shapes, True)
    return results


def _pct(x: NDArray, q: float) -> float:
    return float(np.percentile(x, q)) if x.size else float("nan")


def summarize(results: Sequence[BlockResult]) -> tuple[str, bool]:
    """The printed table and whether the acceptance criteria hold."""
    lines = [
        f"{'shapes':7} {'noise':5} {'blocks':>6} {'edges ok':>9} {'failed':>6} "
        f"{'centroid mm':>16} {'vertex mm':>16} {'yaw deg':>14} {'ms/block':>8}",
        f"{'':7} {'':5} {'':>6} {'':>9} {'':>6} {'median':>8}{'p95':>8} {'median':>8}{'p95':>8} "
        f"{'median':>7}{'p95':>7} {'median':>8}",
    ]
    ok_all = True
    groups = sorted({(r.shapes, r.noisy) for r in results}, key=lambda g: (g[1], g[0]))
    for noisy in (False, True):
        sel_n = [r for r in results if r.noisy == noisy]
        if not sel_n:
            continue
        for key in [g for g in groups if g[1] == noisy] + [("all", noisy)]:
            rs = sel_n if key[0] == "all" else [r for r in sel_n if r.shapes == key[0]]
            edges_ok = np.mean([r.n_edges == r.true_edges for r in rs])
            failed = sum(1 for r in rs if r.failure)
            cen = np.array([r.centroid_mm for r in rs if np.isfinite(r.centroid_mm)])
            vert = np.concatenate([r.vertex_mm for r in rs]) if rs else np.zeros(0)
            yaw = np.array([r.yaw_deg for r in rs if np.isfinite(r.yaw_deg)])
            ms = np.array([r.ms for r in rs])
            lines.append(
                f"{key[0]:7} {'yes' if noisy else 'no':5} {len(rs):6d} {100 * edges_ok:8.1f}% "
                f"{failed:6d} {_pct(cen, 50):8.3f}{_pct(cen, 95):8.3f} {_pct(vert, 50):8.3f}"
                f"{_pct(vert, 95):8.3f} {_pct(yaw, 50):7.3f}{_pct(yaw, 95):7.3f} "
                f"{_pct(ms, 50):8.1f}"
            )
            if key[0] == "all":
                ok = (
                    edges_ok >= ACCEPT_EDGES[noisy]
                    and _pct(cen, 50) < ACCEPT_CENTROID_MM
                    and _pct(vert, 95) < ACCEPT_VERTEX_P95_MM
                )
                ok_all &= ok
                lines.append(
                    f"  acceptance ({'noisy' if noisy else 'noiseless'}): edges >= "
                    f"{100 * ACCEPT_EDGES[noisy]:.0f}%, centroid median < {ACCEPT_CENTROID_MM} mm, "
                    f"vertex p95 < {ACCEPT_VERTEX_P95_MM} mm: {'PASS' if ok else 'FAIL'}"
                )
    return "\n".join(lines), ok_all


def _run(argv: Sequence[str] | None) -> int:
    p = cli.ArgumentParser(
        prog=PROG,
        description="Benchmark of the Select/Model vision (section 5.2) on seeded random scenes, "
        "clean and with noise; prints accuracy and time per block.",
    )
    p.add_argument(
        "--trials",
        type=cli.integer(1, MAX_TRIALS),
        default=200,
        help=f"blocks per shape set, 1..{MAX_TRIALS}",
    )
    cli.add_seed_argument(p)
    p.add_argument("--quick", action="store_true", help="at most 40 blocks per shape set")
    cli.add_image_size_arguments(p, "rendered image", DEFAULT_WIDTH, DEFAULT_HEIGHT)
    p.add_argument(
        "--shapes",
        choices=["paper", "random", "both"],
        default="both",
        help="paper objects, random convex polygons, or both",
    )
    p.add_argument("--failures", action="store_true", help="list every failed block")
    a = p.parse_args(argv)
    trials = min(a.trials, 40) if a.quick else a.trials
    sets = ["paper", "random"] if a.shapes == "both" else [a.shapes]
    t0 = time.perf_counter()
    results = run(trials, a.seed, a.width, a.height, sets)
    text, ok = summarize(results)
    print(
        f"vision.bench: {trials} blocks per shape set, seed {a.seed}, {a.width}x{a.height}, "
        f"noise: colour sigma {RGB_NOISE:g}, depth sigma {1000 * DEPTH_NOISE:g} mm, lighting "
        f"x{LIGHT_SCALE[0]:g}..{LIGHT_SCALE[1]:g} tilt <= {LIGHT_TILT_DEG:g} deg"
    )
    print(text)
    if a.failures:
        for r in results:
            if r.n_edges != r.true_edges:
                print(
                    f"  {r.shapes} {'noisy' if r.noisy else 'clean'}: {r.true_edges} edges -> "
                    f"{r.n_edges or r.failure}"
                )
    print(f"total {time.perf_counter() - t0:.1f} s")
    return 0 if ok else 1


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark with the command line ``argv``; returns the exit status (1 when the
    acceptance criteria fail)."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    raise SystemExit(main())
