"""``python -m fsm.run``: one pick-and-place task cycle (section 5.2) on a scene, recorded.

Exit status: 0 every asked block delivered (at the place point asked for, or, with
``--place-fallback nearest``, at the nearest free slot, reported as delivered elsewhere), 1 the
task failed (the named reason is printed; an exception no state names is ``internal error``), 2
bad input (one line on stderr saying what is wrong), 130 interrupted (Ctrl-C).
``DIR/summary.json`` and ``DIR/episode.rrd`` are written in every case but bad input;
``--live`` / ``--connect`` stream the recording to the rerun viewer as well while the episode runs
(:mod:`fsm.live`).
"""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from fsm.config import DEFAULT_CONFIG, LATERAL_GATE_RULES
from fsm.context import (
    APPROACH_CHOICES,
    CONTROLLERS,
    DEFAULT_GRASP_MODEL,
    DEFAULT_HAND,
    GRASP_MODELS,
    HANDS,
    PLACE_FALLBACKS,
    EpisodeOptions,
    out_paths,
)
from fsm.layout import ASKED_CLEARANCE, episode_scene, place_is_free
from fsm.live import DEFAULT_LIVE_PORT, LiveStream, connect_stream, serve_stream
from hand_sim.clitools import (
    ERRORS,
    ArgumentParser,
    CommandLineError,
    add_perturb_argument,
    first_paragraph,
    integer,
    numbers,
    out_dir,
    partial_results_in,
    prepare_dir,
    run_main,
    seed,
)
from hand_sim.scene import Scene, scene_names
from vision import DEFAULT_HEIGHT as IMAGE_HEIGHT
from vision import DEFAULT_WIDTH as IMAGE_WIDTH

PROG = "python -m fsm.run"
#: Horizontal reach (m) of the arm from its waist axis that a place point must be within.
PLACE_REACH = (0.35, 0.95)
#: Most blocks ``--cycles`` may ask for (``all`` clears the table whatever their number).
MAX_CYCLES = 50
#: ``--live`` serves the stream on the loopback address only.
LIVE_HOST = "127.0.0.1"


def add_scene(ap: argparse.ArgumentParser) -> None:
    """``--scene``, ``--seed`` and ``--blocks``: the table an episode runs on."""
    ap.add_argument(
        "--scene",
        default="clutter3",
        help=f"scene name ({', '.join(scene_names())}) or a .toml path",
    )
    ap.add_argument(
        "--seed",
        type=seed,
        default=0,
        help="draws a random scene; jitters a scene file's layout when > 0; seeds the noise",
    )
    ap.add_argument(
        "--blocks",
        type=integer(1, 12),
        default=None,
        help="number of blocks of --scene random (default from scenes/random.toml)",
    )


def add_models(ap: argparse.ArgumentParser) -> None:
    """``--models``: the grasp controllers' trained models."""
    ap.add_argument(
        "--models",
        default=None,
        help="trained models folder from `python -m experiments.paper reproduce --out DIR` "
        "(default: the shipped ones)",
    )


def add_controller_and_approach(ap: argparse.ArgumentParser) -> None:
    """``--controller`` and ``--approach``, as ``fsm.run`` and ``experiments.bench`` take them."""
    ap.add_argument(
        "--controller",
        default="pi",
        choices=CONTROLLERS,
        help="grasp controller: pre-imaging (section 4), knowledge-based (3.6.1), "
        "Q-learning (3.6.2)",
    )
    ap.add_argument(
        "--approach",
        default="auto",
        choices=APPROACH_CHOICES,
        help="auto: the coarse planner chooses top or lateral; or force one",
    )
    ap.add_argument(
        "--model",
        default=DEFAULT_GRASP_MODEL,
        choices=GRASP_MODELS,
        help="grasp model of a top grasp: planar (the paper's controllers, contacts at the "
        "fingertips' height) or 3d (contacts with heights, set by moment closure and the task); "
        'docs/findings.md, "Which grasp model by default"',
    )


def add_place_fallback(ap: argparse.ArgumentParser) -> None:
    """``--place-fallback``, as ``fsm.run`` and ``experiments.bench`` take it."""
    ap.add_argument(
        "--place-fallback",
        default="none",
        choices=PLACE_FALLBACKS,
        help="when the block cannot be set down at the place point asked for (--place, "
        "--place-pixel or the scene's): none fails the episode there; nearest delivers to the "
        "nearest free slot and reports the block as delivered elsewhere",
    )


def add_hand(ap: argparse.ArgumentParser) -> None:
    """``--hand``, as ``fsm.run`` and ``experiments.bench`` take it."""
    ap.add_argument(
        "--hand",
        default=DEFAULT_HAND,
        choices=HANDS,
        help="the hand on the arm: tendon (default; the Utah/MIT hand's tendon model, "
        "models/utah_mit_hand/: every joint turned by two pull-only tendons of its own, a joint "
        "PD loop every physics step) or servo (models/hand.xml, 16 position servos); "
        "docs/models.md",
    )


def lateral_gate(text: str) -> float:
    """``--lateral-gate S_G``: a positive, finite S_G (Eq. 13)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (np.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(
            f"must be a positive S_G (Eq. 13; the paper's, the default, is "
            f"{DEFAULT_CONFIG.lateral_gate}), e.g. 0.6, got {text!r}"
        )
    return value


def add_lateral_gate(ap: argparse.ArgumentParser) -> None:
    """``--lateral-gate``, as ``fsm.run`` and ``experiments.bench`` take it."""
    ap.add_argument(
        "--lateral-gate",
        type=lateral_gate,
        default=DEFAULT_CONFIG.lateral_gate,
        metavar="S_G",
        help="S_G (Eq. 13) a lateral grasp must reach, as --lateral-gate-rule counts it; the "
        "default is the paper's. "
        "A study setting: above it, a lateral pre-shape scoring up to the gate "
        "is taken only where none scores the paper's (docs/findings.md, \"Eq. 13's gate bounds "
        'the lateral grasp")',
    )
    ap.add_argument(
        "--lateral-gate-rule",
        choices=LATERAL_GATE_RULES,
        default=DEFAULT_CONFIG.lateral_gate_rule,
        help="how the gate applies to a lateral grasp of n contacts: opposition (default), "
        "counted from Eq. 13's floor for the thumb against the other n-1 fingers, "
        "(n-2)/n, after every grasp within the gate itself; paper, the gate itself "
        "(docs/findings.md, \"Eq. 13's gate counted from the thumb's opposition\")",
    )


def parse_cycles(text: str) -> int | None:
    """``--cycles N|all``: N blocks one after another (1..MAX_CYCLES), or None for all."""
    if text == "all":
        return None
    try:
        cycles = int(text)
    except ValueError:
        cycles = 0
    if not 1 <= cycles <= MAX_CYCLES:
        raise CommandLineError("--cycles", f"must be 1-{MAX_CYCLES} or 'all', got {text!r}")
    return cycles


#: Argument type of a pixel (column, row) of the overhead image.
pixel = numbers(2, "U,V")


def parser() -> ArgumentParser:
    ap = ArgumentParser(prog=PROG, description=first_paragraph(__doc__))
    add_scene(ap)
    pick = ap.add_mutually_exclusive_group()
    pick.add_argument(
        "--pick", default=None, help="name of the block to pick first (default: the scene's target)"
    )
    image = f"{IMAGE_WIDTH}x{IMAGE_HEIGHT} overhead image"
    pick.add_argument(
        "--pick-pixel",
        type=pixel,
        metavar="U,V",
        help=f"pick the block at this pixel of the {image} (u column, v row)",
    )
    place = ap.add_mutually_exclusive_group()
    place.add_argument(
        "--place",
        type=numbers(2, "X,Y"),
        default=None,
        metavar="X,Y",
        help="world point (m) to place the block at (default: the scene's place point)",
    )
    place.add_argument(
        "--place-pixel",
        type=pixel,
        metavar="U,V",
        help=f"place at the table point seen at this pixel of the {image}",
    )
    add_place_fallback(ap)
    add_controller_and_approach(ap)
    ap.add_argument(
        "--cycles",
        default="1",
        help=f"blocks to pick and place one after another (1-{MAX_CYCLES}), "
        "or 'all' to clear the table",
    )
    ap.add_argument(
        "--out", type=out_dir, default=None, help="output folder (default runs/<scene>-<seed>)"
    )
    add_models(ap)
    add_hand(ap)
    add_lateral_gate(ap)
    add_perturb_argument(ap)
    ap.add_argument("--no-record", action="store_true", help="skip the .rrd recording (faster)")
    add_live(ap)
    return ap


def add_live(ap: argparse.ArgumentParser) -> None:
    """``--live [PORT]`` and ``--connect URL``: the recording streamed to the rerun viewer while
    the episode runs (:mod:`fsm.live`)."""
    live = ap.add_mutually_exclusive_group()
    live.add_argument(
        "--live",
        nargs="?",
        const=DEFAULT_LIVE_PORT,
        default=None,
        type=integer(0, 65535),
        metavar="PORT",
        help=f"serve the recording live on {LIVE_HOST}:PORT while the episode runs (PORT "
        f"{DEFAULT_LIVE_PORT} when omitted, 0 any free port) and print the `rerun --connect "
        "URL` line that opens it; the .rrd is written the same",
    )
    live.add_argument(
        "--connect",
        default=None,
        metavar="URL",
        help="stream the recording live to a rerun viewer already running (its URL, e.g. "
        "rerun+http://127.0.0.1:9876/proxy, or its port); the .rrd is written the same",
    )


def live_from_args(argv: Sequence[str] | None) -> LiveStream | None:
    """The live stream ``--live`` or ``--connect`` asks for, checked before any work (the port
    free, the viewer listening), or None. It is not an episode option: nothing simulated
    changes, and the recording is the same."""
    args = parser().parse_args(argv)
    if args.live is None and args.connect is None:
        return None
    flag = "--live" if args.live is not None else "--connect"
    if args.no_record:
        raise CommandLineError(flag, "streams the recording: it cannot go with --no-record")
    if args.live is not None:
        return serve_stream(LIVE_HOST, args.live, flag)
    return connect_stream(args.connect, flag)


def _check_place(
    scene: Scene, place: tuple[float, float], radius: float, target: str, flag: str
) -> None:
    t = scene.table
    if not t.contains(np.array([place]), margin=radius):
        raise CommandLineError(
            flag,
            f"place point {list(place)} is off the table (top {list(t.size_xy)} m centred at "
            f"{list(t.position_xy)}); choose a point on it",
        )
    base = np.array([-0.60, 0.0])
    d = float(np.linalg.norm(np.asarray(place) - base))
    if not PLACE_REACH[0] <= d <= PLACE_REACH[1]:
        raise CommandLineError(
            flag,
            f"place point {list(place)} is {d:.2f} m from the arm's waist axis at "
            f"{base.tolist()}; the arm places within {PLACE_REACH[0]}-{PLACE_REACH[1]} m",
        )
    footprints = [b.footprint() for b in scene.blocks if b.name != target]
    if not place_is_free(np.asarray(place), radius, footprints, t, ASKED_CLEARANCE):
        raise CommandLineError(flag, f"place point {list(place)} is occupied by another block")


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
            raise CommandLineError("--pick-pixel", str(e)) from None
        name = sel.names[index]
        if name is None:
            raise CommandLineError("--pick-pixel", f"{list(pick_pixel)} is not on a block")
        target = name
    if place_pixel is not None:
        point = obs.geometry.pixel_to_plane(np.asarray(place_pixel, float), scene.table.height)
        place = (float(point[0]), float(point[1]))
    return target, place


def options_from_args(argv: Sequence[str] | None) -> EpisodeOptions:
    """Parse and check every flag before any work starts (:class:`CommandLineError` otherwise)."""
    args = parser().parse_args(argv)
    cycles = parse_cycles(args.cycles)
    scene = episode_scene(args.scene, args.seed, args.blocks)
    pick = args.pick
    if pick is not None and pick not in scene.block_names:
        raise CommandLineError(
            "--pick",
            f"{pick!r} is not a block of {scene.name}; valid: {', '.join(scene.block_names)}",
        )
    for pixel, flag in ((args.pick_pixel, "--pick-pixel"), (args.place_pixel, "--place-pixel")):
        if pixel is not None and not (0 <= pixel[0] < IMAGE_WIDTH and 0 <= pixel[1] < IMAGE_HEIGHT):
            raise CommandLineError(
                flag,
                f"{list(pixel)} is outside the {IMAGE_WIDTH}x{IMAGE_HEIGHT} overhead image "
                f"(u in 0..{IMAGE_WIDTH - 1}, v in 0..{IMAGE_HEIGHT - 1})",
            )
    target, place = pick or scene.target, args.place
    if args.pick_pixel is not None or args.place_pixel is not None:
        target, place = _resolve_pixels(scene, args.pick_pixel, args.place_pixel, target, place)
    if place is not None:
        radius = float(np.linalg.norm(scene.block(target).polygon.vertices, axis=1).max())
        flag = "--place" if args.place is not None else "--place-pixel"
        _check_place(scene, place, radius, target, flag)
    stem = Path(args.scene).stem if args.scene.endswith(".toml") else args.scene
    out = prepare_dir(args.out or Path("runs") / f"{stem}-{args.seed}", "--out")
    return EpisodeOptions(
        scene=args.scene,
        seed=args.seed,
        blocks=args.blocks,
        pick=target if (pick or args.pick_pixel is not None) else None,
        pick_pixel=None,
        place=place,
        place_fallback=args.place_fallback,
        cycles=cycles,
        out=out,
        record=not args.no_record,
        **task_settings(args),
    )


def task_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The episode options the task cycle's flags set (:func:`add_controller_and_approach`,
    :func:`add_models`, :func:`add_hand`, :func:`add_lateral_gate`, ``--perturb``), as keywords
    of :class:`~fsm.context.EpisodeOptions`."""
    return {
        "controller": args.controller,
        "approach": args.approach,
        "grasp_model": args.model,
        "models": None if args.models is None else Path(args.models),
        "hand": args.hand,
        "config": replace(
            DEFAULT_CONFIG,
            lateral_gate=args.lateral_gate,
            lateral_gate_rule=args.lateral_gate_rule,
        ),
        "perturb": args.perturb,
    }


def run(argv: Sequence[str] | None) -> int:
    live = live_from_args(argv)
    options = options_from_args(argv)
    from fsm.judge import block_state_text
    from fsm.machine import run_episode

    rrd, summary = out_paths(options.out)
    factory = None
    if live is not None:
        from fsm.recording import EpisodeRecorder

        factory = functools.partial(EpisodeRecorder, live=live.sink())
        how = "served" if live.serve else "sent to the viewer at"
        print(f"live: the recording is {how} {live.url}; open it with: {live.viewer_command}")
    with partial_results_in(options.out):
        result = run_episode(
            options, announce=lambda line: print(line, flush=True), recorder_factory=factory
        )
    if result.success:
        for c in result.cycles:
            j = c["judgement"]
            used = [round(v, 3) for v in c["place_used"]]
            where = f"the place point {used} ({c['place_chosen_by']})"
            if c["delivered_elsewhere"]:
                asked = [round(v, 3) for v in c["place_asked"]]
                where = (
                    f"the free slot {used}: delivered ELSEWHERE, {c['place_moved_mm']:.0f} mm "
                    f"from the place point asked for {asked} ({c['place_chosen_by']})"
                )
            print(
                f"delivered {c['block']} ({c['approach']} grasp, S_G {c['s_g']:.3f}): "
                f"{j['place_error_mm']:.1f} mm from {where}, tilt {j['tilt_deg']:.1f} deg"
            )
    else:
        failed = result.cycles[-1] if result.cycles else {}
        judged = block_state_text(failed.get("block_at_failure"), failed.get("block"))
        print(
            f"FAILED: {result.failure}: {result.failure_detail}" + (f"; {judged}" if judged else "")
        )
    written = f"{summary}" + (f" and {rrd}" if options.record else "")
    print(f"sim {result.sim_time:.1f} s, wall {result.wall_time:.1f} s; wrote {written}")
    return 0 if result.success else 1


def main(argv: Sequence[str] | None = None) -> int:
    """Run the task cycle; see the module docstring for the exit status."""
    return run_main(lambda: run(argv), prog=PROG, errors=ERRORS)


if __name__ == "__main__":
    sys.exit(main())
