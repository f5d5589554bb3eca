"""The interactive page as a user meets it, timed: ``python -m fsm.interactive`` started as a
process with headless Chromium already open, then blocks and place points clicked on the page
one cycle after another, every click through the page's mapping of its displayed size.

Prints when the server listened (from the command's start), when the page showed its first
overhead image (from the server's start), how long each click took to draw its block's polygon,
the live view's frames per second of wall time while the arm moved, and each cycle's physical
judgement (the block's distance from the point clicked). ``--screenshots DIR`` saves the page at
four stages of the first cycle (waiting for a block, busy, waiting for a place point,
delivered) as small PNGs. Needs Debian's chromium (``apt-get install chromium``) and Playwright
(the ``test`` extra).

Usage: python -m benchmarks.bench_interactive [--scene clutter3] [--picks pentagon]
[--places -0.05,-0.25] [--screenshots DIR]
(two cycles on clutter5: --scene clutter5 --picks square,hexagon --places 0.05,0.25:-0.06,0.25)
"""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fsm.layout import episode_scene
from hand_sim.clitools import ERRORS, ArgumentParser, CommandLineError, first_paragraph, run_main
from hand_sim.world import World
from vision import DEFAULT_HEIGHT, DEFAULT_WIDTH, overhead_camera
from vision.observation import geometry_of

PROG = "python -m benchmarks.bench_interactive"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--headless=new",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
#: The page's size in the browser (the image is shown smaller than its 1920x1440).
VIEWPORT = {"width": 1100, "height": 720}
#: Screenshots larger than this (bytes) are reduced to a 256-colour palette (docs/img keeps each
#: under 150 kB).
SCREENSHOT_BYTES = 100_000
#: Milliseconds allowed for a cycle's wait.
CYCLE_MS = 900_000


def parser() -> ArgumentParser:
    ap = ArgumentParser(prog=PROG, description=first_paragraph(__doc__))
    ap.add_argument("--scene", default="clutter3", help="the scene the run serves")
    ap.add_argument("--picks", default=None, help="blocks to click, in order (the scene's target)")
    ap.add_argument(
        "--places",
        default=None,
        help="place points X,Y (m) to click, one per pick, separated by ':' (-0.05,-0.25)",
    )
    ap.add_argument("--screenshots", default=None, help="folder for the first cycle's four PNGs")
    return ap


def save_screenshot(page: object, path: Path) -> int:
    """The page as a PNG at ``path``, reduced to 256 colours above :data:`SCREENSHOT_BYTES`;
    returns its size."""
    from PIL import Image

    png = page.screenshot()
    if len(png) > SCREENSHOT_BYTES:
        image = Image.open(io.BytesIO(png)).convert("RGB")
        out = io.BytesIO()
        image.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(out, "PNG", optimize=True)
        png = out.getvalue()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png)
    return len(png)


def click_pixel(page: object, u: int, v: int) -> None:
    """Click the middle of pixel (u, v) of ``#overhead`` at the size it is displayed."""
    img = page.locator("#overhead")
    box = img.bounding_box()
    w, h = page.evaluate("() => [overhead.naturalWidth, overhead.naturalHeight]")
    img.click(position={"x": (u + 0.5) * box["width"] / w, "y": (v + 0.5) * box["height"] / h})


def wait_status(page: object, text: str) -> float:
    page.wait_for_function(
        "(t) => document.getElementById('status').textContent.includes(t)",
        arg=text,
        timeout=CYCLE_MS,
        polling=20,
    )
    return time.perf_counter()


def moving_rate(page: object, since_ms: float) -> tuple[float, float]:
    """The live view's frames per second of wall time while the arm moved, since page time
    ``since_ms``: the median and the slowest tenth of the gaps between frames across which
    simulated time went on (no frame comes while a planner thinks and nothing moves)."""
    log = np.array(page.evaluate("(t) => frameLog.filter((f) => f[0] >= t)", since_ms))
    if len(log) < 3:
        return 0.0, 0.0
    gaps = np.diff(log[:, 0])[np.diff(log[:, 1]) > 0] / 1000.0
    if len(gaps) == 0:
        return 0.0, 0.0
    return 1.0 / float(np.median(gaps)), 1.0 / float(np.percentile(gaps, 90))


def run(argv: list[str] | None) -> int:
    args = parser().parse_args(argv)
    scene = episode_scene(args.scene, 0, None)
    picks = args.picks.split(",") if args.picks else [scene.target]
    places = [
        tuple(float(c) for c in p.split(",")) for p in (args.places or "-0.05,-0.25").split(":")
    ]
    if len(places) != len(picks) or any(name not in scene.block_names for name in picks):
        raise CommandLineError("--picks", "one place point per pick, each a block of the scene")
    z = scene.table.height
    with overhead_camera(World.build(scene, with_robot=False)) as cam:
        g = geometry_of(cam, (DEFAULT_HEIGHT, DEFAULT_WIDTH))

    def pixel(x: float, y: float, height: float = 0.0) -> tuple[int, int]:
        u, v = np.floor(g.world_to_pixel([x, y, z + height]) + 0.5)
        return int(u), int(v)

    from playwright.sync_api import sync_playwright

    shots = Path(args.screenshots) if args.screenshots else None
    out = Path(tempfile.mkdtemp(prefix="bench-interactive-")) / "run"
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport=VIEWPORT)
        env = {**os.environ, "MUJOCO_GL": "egl", "PYTHONUNBUFFERED": "1"}
        cmd = [sys.executable, "-m", "fsm.interactive", "--scene", args.scene, "--out", str(out)]
        t_launch = time.perf_counter()
        proc = subprocess.Popen(
            [*cmd, "--port", "0", "--rerun-port", "0"], stdout=subprocess.PIPE, text=True, env=env
        )
        line = proc.stdout.readline()
        t_server = time.perf_counter()
        page.goto(line.split()[2])
        page.wait_for_function("() => overhead.naturalWidth > 0", polling=20)
        t_image = time.perf_counter()
        print(f"server listening {t_server - t_launch:.2f} s after the command started")
        print(f"first overhead image on the page {t_image - t_server:.2f} s after that")
        for k, (name, place) in enumerate(zip(picks, places, strict=True)):
            block = scene.block(name)
            wait_status(page, "waiting for a block")
            if k == 0 and shots is not None:
                click_pixel(page, *pixel(0.3, -0.3))  # the bare table: refused, said so
                page.wait_for_function(
                    "() => document.getElementById('message').textContent.includes('no block')"
                )
                save_screenshot(page, shots / "interactive_1_waiting_for_a_block.png")
            before = page.evaluate("() => document.querySelectorAll('#log li').length")
            click_pixel(page, *pixel(*block.position, block.height))
            t_click = time.perf_counter()
            page.wait_for_function(
                "(n) => document.querySelectorAll('#log li').length > n"
                " && overlay.querySelector('polygon.poly')",
                arg=before,
                polling=20,
            )
            t_poly = time.perf_counter()
            frames0 = page.evaluate("() => frames")
            clock0 = page.evaluate("() => performance.now()")
            if k == 0 and shots is not None:
                wait_status(page, "busy: Fine Reach")
                time.sleep(1.5)
                save_screenshot(page, shots / "interactive_2_busy.png")
            t_place = wait_status(page, "waiting for a place point")
            grasp_fps = (page.evaluate("() => frames") - frames0) / (t_place - t_poly)
            grasp_moving = moving_rate(page, clock0)
            if k == 0 and shots is not None:
                save_screenshot(page, shots / "interactive_3_waiting_for_a_place_point.png")
            u, v = pixel(*place)
            clicked = g.pixel_to_plane(np.array([u, v], dtype=float), z)[:2]
            frames1 = page.evaluate("() => frames")
            clock1 = page.evaluate("() => performance.now()")
            click_pixel(page, u, v)
            t0 = time.perf_counter()
            wait_status(page, f"delivered {name}")
            deliver_fps = (page.evaluate("() => frames") - frames1) / (time.perf_counter() - t0)
            deliver_moving = moving_rate(page, clock1)
            summary = json.loads((out / f"cycle-{k + 1:03d}" / "summary.json").read_text())
            cycle = summary["cycles"][0]
            final = np.array(cycle["judgement"]["final_position"])[:2]
            print(
                f"cycle {k + 1}: {name}: polygon {t_poly - t_click:.2f} s after the click; live "
                f"view, frames/s of wall time: reach and grasp {grasp_fps:.1f} on average, "
                f"{grasp_moving[0]:.1f} (median) / {grasp_moving[1]:.1f} (slowest tenth) while "
                f"the arm moved; deliver {deliver_fps:.1f}, {deliver_moving[0]:.1f} / "
                f"{deliver_moving[1]:.1f}; success {summary['success']}, "
                f"{np.linalg.norm(final - clicked) * 1000:.1f} mm "
                f"from the point clicked, tilt {cycle['judgement']['tilt_deg']:.1f} deg"
            )
            if k == 0 and shots is not None:
                wait_status(page, "waiting for a block")
                page.wait_for_function("() => overhead.complete", polling=20)
                save_screenshot(page, shots / "interactive_4_delivered.png")
        page.locator("#stop").click()
        status = proc.wait(120)
        print(f"stopped from the page: exit status {status}; files in {out}")
        browser.close()
    if shots is not None:
        for f in sorted(shots.glob("interactive_*.png")):
            print(f"{f}: {f.stat().st_size / 1000:.0f} kB")
    return 0


def main(argv: list[str] | None = None) -> int:
    return run_main(lambda: run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    sys.exit(main())
