"""Select/Model from the command line (section 5.2): render a scene's overhead view and model the
block under a mouse click (``--pick-pixel U,V``), a named block (``--name``) or the block
nearest a world point (``--near X,Y``).

    python -m vision --scene clutter3 [--seed N] --pick-pixel 960,720 [--overlay out.png]

``--scene`` and ``--seed`` give the layout ``python -m fsm.run`` runs for the same flags (a scene
file's block poses jittered for a seed > 0), so a pixel read here is a pixel of that episode.

Pixels are (column, row) of the rendered image, 1920x1440 unless --width/--height say otherwise:
the frame of the ``overhead.png`` that ``python -m hand_sim.show`` writes at its default size.
Prints the model; errors are one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from graspsim_base.files import atomic_path
from hand_sim import clitools as cli
from hand_sim.scene import Scene
from vision.clitools import ERRORS, check_on_table, check_pixel
from vision.errors import VisionError
from vision.model import ObjectModel
from vision.observation import DEFAULT_HEIGHT, DEFAULT_WIDTH, Observation, overhead_camera
from vision.select import analyze

PROG = "python -m vision"
#: Image formats the overlay may be written as (OpenCV picks the format from the suffix).
OVERLAY_SUFFIXES = (".png", ".jpg", ".jpeg")


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


def write_overlay(path: str | Path, obs: Observation, model: ObjectModel) -> None:
    """The overhead image with the model's contour drawn on it (PNG or JPEG, by the suffix),
    written atomically."""
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
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), img):
            raise VisionError(f"could not write the overlay image {str(path)!r}")


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse the command line; every number is checked here (finite, in range)."""
    p = cli.ArgumentParser(prog=PROG, description=cli.first_paragraph(__doc__))
    cli.add_scene_arguments(p, "scene name or .toml file (hand_sim.scene)", "blocks")
    how = p.add_mutually_exclusive_group(required=True)
    how.add_argument(
        "--pick-pixel",
        type=cli.numbers(2, "U,V"),
        metavar="U,V",
        help="the mouse click: pixel (column, row) of the --width x --height image, e.g. 960,720",
    )
    how.add_argument("--name", help="the block's name in the scene")
    how.add_argument(
        "--near",
        type=cli.numbers(2, "X,Y"),
        metavar="X,Y",
        help="a world point on the table (m): the block nearest to it, e.g. 0.1,-0.05",
    )
    cli.add_image_size_arguments(p, "rendered image", DEFAULT_WIDTH, DEFAULT_HEIGHT)
    p.add_argument(
        "--overlay",
        type=cli.out_file(*OVERLAY_SUFFIXES),
        metavar="IMAGE",
        help="write the image with the contour drawn (.png or .jpg)",
    )
    args = p.parse_args(argv)
    cli.check_scene_arguments(args)
    if args.pick_pixel is not None:
        check_pixel(args.pick_pixel, args.width, args.height, "--pick-pixel")
    return args


def _select(args: argparse.Namespace, scene: Scene) -> tuple[Observation, ObjectModel]:
    from hand_sim.world import World

    with overhead_camera(World.build(scene), args.width, args.height) as camera:
        obs = Observation.capture(camera)
    sel = analyze(obs, {b.name: b.position for b in scene.blocks})
    if args.pick_pixel is not None:
        return obs, sel.select_pixel(args.pick_pixel)
    if args.name is not None:
        return obs, sel.select_name(args.name)
    return obs, sel.select_near(args.near)


def _run(argv: Sequence[str] | None) -> int:
    args = parse_args(argv)
    scene = cli.scene_from_arguments(args)
    if args.near is not None:
        check_on_table(args.near, scene.table, "--near")
    if args.overlay is not None:
        cli.prepare_file(args.overlay, "--overlay")
    obs, model = _select(args, scene)
    print(describe(model))
    u, v = model.pixel_contour.mean(axis=0)
    print(f"  in the {args.width}x{args.height} image: contour around pixel ({u:.0f}, {v:.0f})")
    if args.overlay is not None:
        write_overlay(args.overlay, obs, model)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``python -m vision`` with the command line ``argv``; returns the exit status."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    raise SystemExit(main())
