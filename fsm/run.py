"""``python -m fsm.run``: one pick-and-place task cycle (section 5.2) on a scene, recorded.

Exit status: 0 every asked block delivered, 1 the task failed (the reason is printed), 2 bad
input (one line on stderr saying what is wrong), 130 interrupted (Ctrl-C). ``DIR/summary.json``
and ``DIR/episode.rrd`` are written in every case but bad input.
"""

from __future__ import annotations

import argparse
import math
import re
import shutil
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from controllers.grasp.errors import GraspError
from fsm.context import APPROACH_CHOICES, CONTROLLERS, EpisodeOptions, out_paths
from fsm.layout import ASKED_CLEARANCE, episode_scene, place_is_free
from hand_sim.errors import HandSimError
from hand_sim.scene import Scene, scene_names

#: The overhead image whose pixels --pick-pixel and --place-pixel name (the Select/Model camera).
from vision import DEFAULT_HEIGHT as IMAGE_HEIGHT
from vision import DEFAULT_WIDTH as IMAGE_WIDTH

#: Horizontal reach (m) of the arm from its waist axis that a place point must be within.
PLACE_REACH = (0.35, 0.95)
#: Options whose value may be negative numbers ("-0.1,0.2"): argparse would read them as flags.
_NUMERIC_OPTIONS = ("--place", "--pick-pixel", "--place-pixel")
_NUMBER_LIST = re.compile(r"^-[0-9.]")


class BadInput(Exception):
    """A command-line value that cannot be used: the message says what and what to do."""


def _join_negative_values(argv: Sequence[str]) -> list[str]:
    """``--place -0.1,0.2`` -> ``--place=-0.1,0.2`` (argparse takes "-0.1,0.2" for a flag)."""
    out: list[str] = []
    it = iter(range(len(argv)))
    for i in it:
        arg = argv[i]
        if arg in _NUMERIC_OPTIONS and i + 1 < len(argv) and _NUMBER_LIST.match(argv[i + 1]):
            out.append(f"{arg}={argv[i + 1]}")
            next(it, None)
        else:
            out.append(arg)
    return out


def parse_pair(text: str, flag: str) -> tuple[float, float]:
    """Two finite numbers "A,B"."""
    parts = text.split(",")
    try:
        a, b = (float(p) for p in parts)
    except ValueError:
        raise BadInput(
            f"{flag} takes two numbers as A,B (e.g. {flag} 0.1,-0.2), got {text!r}"
        ) from None
    if not (math.isfinite(a) and math.isfinite(b)):
        raise BadInput(f"{flag} needs finite numbers, got {text!r}")
    return a, b


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="python -m fsm.run",
        description="Pick a block out of the clutter and place it elsewhere, headless (section 5 "
        "of Coelho & Grupen): writes DIR/episode.rrd (open with `rerun`) and DIR/summary.json.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument(
        "--scene",
        default="clutter3",
        help=f"scene name ({', '.join(scene_names())}, random) or a .toml path",
    )
    ap.add_argument(
        "--seed",
        default="0",
        help="seed: draws a random scene; jitters a scene file's layout when > 0; seeds the controller's noise",
    )
    ap.add_argument(
        "--blocks",
        default=None,
        help="number of blocks of --scene random (1-12; default from scenes/random.toml)",
    )
    pick = ap.add_mutually_exclusive_group()
    pick.add_argument(
        "--pick", default=None, help="name of the block to pick first (default: the scene's target)"
    )
    pick.add_argument(
        "--pick-pixel",
        default=None,
        metavar="U,V",
        help=f"pick the block at this pixel of the {IMAGE_WIDTH}x{IMAGE_HEIGHT} overhead image (u = column, v = row)",
    )
    place = ap.add_mutually_exclusive_group()
    place.add_argument(
        "--place",
        default=None,
        metavar="X,Y",
        help="world point (m) to place the block at (default: the scene's place point)",
    )
    place.add_argument(
        "--place-pixel",
        default=None,
        metavar="U,V",
        help=f"place at the table point seen at this pixel of the {IMAGE_WIDTH}x{IMAGE_HEIGHT} overhead image",
    )
    ap.add_argument(
        "--controller",
        default="pi",
        choices=CONTROLLERS,
        help="grasp controller: pre-imaging (section 4), knowledge-based (3.6.1) or Q-learning (3.6.2)",
    )
    ap.add_argument(
        "--approach",
        default="auto",
        choices=APPROACH_CHOICES,
        help="auto: the coarse planner chooses top or lateral; or force one",
    )
    ap.add_argument(
        "--cycles",
        default="1",
        help="blocks to pick and place one after another, or 'all' to clear the table",
    )
    ap.add_argument("--out", default=None, help="output folder (default runs/<scene>-<seed>)")
    ap.add_argument(
        "--models",
        default=None,
        help="folder of trained models from `python -m controllers.grasp reproduce --out DIR` (default: the shipped ones)",
    )
    ap.add_argument("--no-record", action="store_true", help="skip the .rrd recording (faster)")
    return ap


def _int(text: str, flag: str, lo: int, hi: int | None = None) -> int:
    try:
        value = int(text)
    except ValueError:
        raise BadInput(f"{flag} takes a whole number, got {text!r}") from None
    if value < lo or (hi is not None and value > hi):
        bound = f"{lo}..{hi}" if hi is not None else f">= {lo}"
        raise BadInput(f"{flag} must be {bound}, got {value}")
    return value


def _check_out(text: str | None, scene: str, seed: int) -> Path:
    if text is not None and text.strip() in ("", "/"):
        raise BadInput(
            f"--out {text!r} is not a folder to write into; give a folder such as runs/mine"
        )
    stem = Path(scene).stem if scene.endswith(".toml") else scene
    out = Path(text) if text is not None else Path("runs") / f"{stem}-{seed}"
    if out.exists() and not out.is_dir():
        raise BadInput(f"--out {out} is a file, not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".write-test-"):
            pass
    except OSError as e:
        raise BadInput(
            f"--out {out} cannot be written ({e.strerror}); choose another folder"
        ) from None
    return out


def _check_place(
    scene: Scene, place: tuple[float, float], target_radius: float, target: str
) -> None:
    t = scene.table
    if not t.contains(np.array([place]), margin=target_radius):
        raise BadInput(
            f"place point {list(place)} is off the table (top {list(t.size_xy)} m centred at "
            f"{list(t.position_xy)}); choose a point on it"
        )
    base = np.array([-0.60, 0.0])
    d = float(np.linalg.norm(np.asarray(place) - base))
    if not PLACE_REACH[0] <= d <= PLACE_REACH[1]:
        raise BadInput(
            f"place point {list(place)} is {d:.2f} m from the arm's waist axis at {base.tolist()}; "
            f"the arm places within {PLACE_REACH[0]}-{PLACE_REACH[1]} m"
        )
    footprints = [b.footprint() for b in scene.blocks if b.name != target]
    if not place_is_free(np.asarray(place), target_radius, footprints, t, ASKED_CLEARANCE):
        raise BadInput(
            f"place point {list(place)} is occupied: another block is within reach of it"
        )


def options_from_args(argv: Sequence[str] | None) -> EpisodeOptions:
    """Parse and check every flag before any work starts; raises BadInput."""
    args = parser().parse_args(_join_negative_values(list(sys.argv[1:] if argv is None else argv)))
    seed = _int(args.seed, "--seed", 0, 2**31 - 1)
    blocks = None if args.blocks is None else _int(args.blocks, "--blocks", 1, 12)
    if args.cycles == "all":
        cycles = None
    else:
        cycles = _int(args.cycles, "--cycles", 1, 50)
    try:
        scene = episode_scene(args.scene, seed, blocks)
    except (HandSimError, ValueError, GraspError) as e:
        raise BadInput(str(e).rstrip(".")) from None
    pick = args.pick
    if pick is not None and pick not in scene.block_names:
        raise BadInput(
            f"--pick {pick!r} is not a block of {scene.name}; valid: {', '.join(scene.block_names)}"
        )
    pick_pixel = None if args.pick_pixel is None else parse_pair(args.pick_pixel, "--pick-pixel")
    place_pixel = (
        None if args.place_pixel is None else parse_pair(args.place_pixel, "--place-pixel")
    )
    for pixel, flag in ((pick_pixel, "--pick-pixel"), (place_pixel, "--place-pixel")):
        if pixel is not None and not (0 <= pixel[0] < IMAGE_WIDTH and 0 <= pixel[1] < IMAGE_HEIGHT):
            raise BadInput(
                f"{flag} {list(pixel)} is outside the {IMAGE_WIDTH}x{IMAGE_HEIGHT} overhead image "
                f"(u in 0..{IMAGE_WIDTH - 1}, v in 0..{IMAGE_HEIGHT - 1})"
            )
    place = None if args.place is None else parse_pair(args.place, "--place")
    target = pick or scene.target
    if pick_pixel is not None or place_pixel is not None:
        target, place = _resolve_pixels(scene, pick_pixel, place_pixel, target, place)
    if place is not None:
        radius = float(np.linalg.norm(scene.block(target).polygon.vertices, axis=1).max())
        _check_place(scene, place, radius, target)
    out = _check_out(args.out, args.scene, seed)
    return EpisodeOptions(
        scene=args.scene,
        seed=seed,
        blocks=blocks,
        pick=pick,
        pick_pixel=pick_pixel,
        place=place,
        controller=args.controller,
        approach=args.approach,
        cycles=cycles,
        out=out,
        record=not args.no_record,
        models=None if args.models is None else Path(args.models),
    )


def _resolve_pixels(
    scene: Scene,
    pick_pixel: tuple[float, float] | None,
    place_pixel: tuple[float, float] | None,
    target: str,
    place: tuple[float, float] | None,
) -> tuple[str, tuple[float, float] | None]:
    """Look at the scene through the overhead camera: the block under ``pick_pixel`` (refused
    when it is the table) and the table point under ``place_pixel``."""
    from hand_sim.world import World
    from vision import NotABlockError, Observation, analyze, overhead_camera

    world = World.build(scene, with_robot=False)
    with overhead_camera(world) as cam:
        obs = Observation.capture(cam)
    if pick_pixel is not None:
        sel = analyze(obs, {b.name: b.position for b in scene.blocks})
        try:
            index = sel.index_at_pixel(pick_pixel)
        except NotABlockError as e:
            raise BadInput(f"--pick-pixel {list(pick_pixel)}: {e}") from None
        name = sel.names[index]
        if name is None:
            raise BadInput(f"--pick-pixel {list(pick_pixel)} is on something that is not a block")
        target = name
    if place_pixel is not None:
        point = obs.geometry.pixel_to_plane(np.asarray(place_pixel, float), scene.table.height)
        place = (float(point[0]), float(point[1]))
    return target, place


def main(argv: Sequence[str] | None = None) -> int:
    """Run the task cycle; see the module docstring for the exit status."""
    try:
        options = options_from_args(argv)
    except BadInput as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    from fsm.machine import run_episode

    rrd, summary = out_paths(options.out)
    try:
        result = run_episode(options, announce=lambda line: print(line, flush=True))
    except KeyboardInterrupt:
        print(f"interrupted; partial results in {options.out}", file=sys.stderr)
        return 130
    if result.success:
        for c in result.cycles:
            j = c["judgement"]
            print(
                f"delivered {c['block']} ({c['approach']} grasp, S_G {c['s_g']:.3f}): "
                f"{j['place_error_mm']:.1f} mm from the place point, tilt {j['tilt_deg']:.1f} deg"
            )
    else:
        print(f"FAILED: {result.failure}: {result.failure_detail}")
    print(
        f"sim {result.sim_time:.1f} s, wall {result.wall_time:.1f} s; wrote {summary}"
        + (f" and {rrd}" if options.record else "")
    )
    return 0 if result.success else 1


if __name__ == "__main__":
    sys.exit(main())
