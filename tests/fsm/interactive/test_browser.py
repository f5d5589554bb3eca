"""The interactive page in a real browser (headless Chromium), served by ``python -m
fsm.interactive`` as a user starts it. The page is displayed at another size than the camera's
image, so every click goes through the page's mapping of the displayed size to the image's
pixels. Timings are printed (``-s``), not asserted."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import numpy as np
import pytest

from fsm.layout import episode_scene
from tests.fsm.interactive.browser import (
    browser_page,
    camera_geometry,
    click_pixel,
    need_chromium,
    pixel_of,
    served_run,
    wait_status,
)


@pytest.mark.e2e
def test_a_click_on_the_bare_table_says_so_and_closing_the_page_ends_the_run(
    tmp_path: Path,
) -> None:
    need_chromium()
    g = camera_geometry("clutter3")
    z = episode_scene("clutter3", 0, None).table.height
    out = tmp_path / "run"
    with served_run(out, "--scene", "clutter3") as run:
        with browser_page(900, 700) as page:
            page.goto(run.url)
            page.wait_for_function("() => document.getElementById('overhead').naturalWidth > 0")
            shown = time.perf_counter()
            wait_status(page, "waiting for a block", 60)
            assert page.evaluate("document.getElementById('overhead').naturalWidth") == 1920
            assert page.locator("#overhead").bounding_box()["width"] < 1920
            print(f"first image {shown - run.started:.2f} s after the server's start")
            click_pixel(page, *pixel_of(g, (0.3, -0.3, z)))
            page.wait_for_function(
                "() => document.getElementById('message').textContent.includes('no block there')"
            )
            assert "no block there: click on a block" in page.locator("#message").inner_text()
            assert "refused: no block there" in page.locator("#status").inner_text()
        # the page is closed: the run ends by itself, nothing written (no block was clicked)
        assert run.process.wait(60) == 0
        assert any("the page was closed" in line for line in run.output())
        assert not list(out.glob("cycle-*"))


@pytest.mark.e2e
def test_click_a_block_and_a_place_point_and_ctrl_c_keeps_every_cycles_files(
    tmp_path: Path,
) -> None:
    """clutter3's target at its true pixel, then a free table point: delivered, judged
    physically within 20 mm of the point clicked; then Ctrl-C in the middle of the next cycle
    keeps both cycles' files."""
    need_chromium()
    scene = episode_scene("clutter3", 0, None)
    g = camera_geometry("clutter3")
    z = scene.table.height
    target = scene.block(scene.target)
    pick = pixel_of(g, (*target.position, z + target.height))
    place = pixel_of(g, (-0.05, -0.25, z))
    clicked = g.pixel_to_plane(np.asarray(place, dtype=float), z)[:2]
    out = tmp_path / "run"
    with served_run(out, "--scene", "clutter3") as run, browser_page(1100, 760) as page:
        page.goto(run.url)
        wait_status(page, "waiting for a block", 60)
        click_pixel(page, *pick)
        t0 = time.perf_counter()
        page.wait_for_selector("#overlay polygon.poly", state="attached", timeout=60_000)
        print(f"click to polygon on the page: {time.perf_counter() - t0:.2f} s")
        points = page.locator("#overlay polygon.poly").get_attribute("points")
        outline = np.array([[float(c) for c in p.split(",")] for p in points.split()])
        assert len(outline) == 5 and np.linalg.norm(outline.mean(axis=0) - pick) < 15.0
        busy = time.perf_counter()
        frames0 = page.evaluate("frames")
        wait_status(page, "waiting for a place point")
        frames = page.evaluate("frames") - frames0
        print(f"{frames} live frames in {time.perf_counter() - busy:.1f} s of the grasp")
        assert frames >= 10
        click_pixel(page, *place)
        wait_status(page, "delivered")
        summary = json.loads((out / "cycle-001" / "summary.json").read_text())
        assert summary["success"], summary["failure_detail"]
        (cycle,) = summary["cycles"]
        assert cycle["block"] == scene.target and cycle["place_chosen_by"] == "user"
        final = np.array(cycle["judgement"]["final_position"])[:2]
        assert np.linalg.norm(final - clicked) < 0.020  # judged physically, at the point clicked
        assert page.locator("#cycles a", has_text="summary.json").count() == 1

        # the next cycle, interrupted by Ctrl-C while the robot is busy
        wait_status(page, "waiting for a block")
        triangle = scene.block("triangle")
        click_pixel(page, *pixel_of(g, (*triangle.position, z + triangle.height)))
        wait_status(page, "busy: Coarse Reach")
        time.sleep(1.0)
        run.process.send_signal(signal.SIGINT)
        assert run.process.wait(120) == 130
        assert "interrupted; partial results in" in run.process.stderr.read()
    first = json.loads((out / "cycle-001" / "summary.json").read_text())
    second = json.loads((out / "cycle-002" / "summary.json").read_text())
    assert first["success"] and second["failure"] == "interrupted"
    assert second["cycles"][0]["block"] == "triangle"
    for folder in ("cycle-001", "cycle-002"):
        assert (out / folder / "episode.rrd").stat().st_size > 10_000
    assert not list(out.glob("cycle-*/.*"))  # no half-written file left
