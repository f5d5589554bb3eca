"""Select/Model from the command line (section 5.2): render a scene's overhead view and model the
block under a mouse click (``--pick-pixel U,V``), a named block (``--name``) or the block
nearest a world point (``--near X,Y``).

    python -m vision --scene clutter3 --pick-pixel 960,720 [--overlay out.png]

Prints the model; errors are one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import numpy as np

from vision.errors import VisionError
from vision.model import ObjectModel
from vision.observation import DEFAULT_HEIGHT, DEFAULT_WIDTH, Observation, overhead_camera
from vision.select import analyze


def _pair(text: str, what: str) -> tuple[float, float]:
    try:
        a, b = (float(c) for c in text.split(","))
    except ValueError as e:
        raise VisionError(f"{what} must be two numbers 'a,b', got {text!r}") from e
    return a, b


def describe(model: ObjectModel) -> str:
    """Human-readable summary of a model (metres, degrees)."""
    verts = "; ".join(f"{x:+.4f},{y:+.4f}" for x, y in model.polygon.vertices)
    cx, cy, cz = model.centroid
    return (
        f"block {model.name}: {model.n_edges} edges, centroid ({cx:+.4f}, {cy:+.4f}, {cz:.4f}) m, "
        f"yaw {np.degrees(model.yaw):+.2f} deg, height {model.height:.4f} m\n"
        f"  polygon (object frame, m): {verts}"
    )


#: Overlay drawing: colour (BGR) and the image width at which lines are 1 px thick.
OVERLAY_COLOUR = (255, 0, 255)
OVERLAY_REFERENCE_WIDTH = 640


def write_overlay(path: str, obs: Observation, model: ObjectModel) -> None:
    """The overhead image with the model's contour drawn on it (PNG)."""
    import cv2

    img = np.ascontiguousarray(obs.rgb[:, :, ::-1])
    scale = max(1, round(img.shape[1] / OVERLAY_REFERENCE_WIDTH))  # thicker lines on big images
    pts = np.rint(model.pixel_contour * 16).astype(np.int32)  # 4 fractional bits
    cv2.polylines(img, [pts], True, OVERLAY_COLOUR, scale, cv2.LINE_AA, 4)
    for p in pts:
        cv2.circle(
            img, tuple(int(c) for c in p), 16 * 2 * scale, OVERLAY_COLOUR, -1, cv2.LINE_AA, 4
        )
    u, v = np.rint(model.pixel_contour.max(axis=0)).astype(int)
    cv2.putText(
        img,
        f"{model.name}: {model.n_edges} edges",
        (int(u) + 6 * scale, int(v)),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.35 * scale,
        OVERLAY_COLOUR,
        scale,
        cv2.LINE_AA,
    )
    if not cv2.imwrite(path, img):
        raise VisionError(f"could not write the overlay image {path!r}")


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m vision", description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="clutter3", help="scene name or file (hand_sim.scene)")
    p.add_argument("--seed", type=int, default=None, help="seed of the random scene")
    p.add_argument("--blocks", type=int, default=None, help="blocks of the random scene")
    how = p.add_mutually_exclusive_group(required=True)
    how.add_argument("--pick-pixel", metavar="U,V", help="the mouse click: image pixel (u, v)")
    how.add_argument("--name", help="the block's name in the scene")
    how.add_argument("--near", metavar="X,Y", help="world point (m): the nearest block")
    p.add_argument("--width", type=int, default=DEFAULT_WIDTH)
    p.add_argument("--height", type=int, default=DEFAULT_HEIGHT)
    p.add_argument("--overlay", metavar="PNG", help="write the image with the contour drawn")
    a = p.parse_args(argv)
    try:
        from hand_sim.errors import HandSimError
        from hand_sim.scene import load_scene
        from hand_sim.world import World

        try:
            scene = load_scene(a.scene, seed=a.seed, blocks=a.blocks)
            world = World.build(scene)
            camera = overhead_camera(world, a.width, a.height)
        except HandSimError as e:
            raise VisionError(str(e)) from e
        try:
            obs = Observation.capture(camera)
        finally:
            camera.close()
        positions = {b.name: b.position for b in scene.blocks}
        sel = analyze(obs, positions)
        if a.pick_pixel is not None:
            model = sel.select_pixel(_pair(a.pick_pixel, "--pick-pixel"))
        elif a.name is not None:
            model = sel.select_name(a.name)
        else:
            model = sel.select_near(_pair(a.near, "--near"))
        print(describe(model))
        if a.overlay:
            write_overlay(a.overlay, obs, model)
    except VisionError as e:
        print(f"python -m vision: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
