"""Demo: ``python -m hand_sim.show --scene clutter3 [--seed N] --out DIR``.

Builds a scene (section 5's table of blocks, the arm and the hand; ``--seed`` gives the layout
``python -m fsm.run`` runs for the same ``--scene`` and ``--seed``), lets the blocks settle, saves
the overhead image as ``DIR/overhead.png`` and records to ``DIR/episode.rrd`` the arm moving
through a few joint targets (with the hand closing and opening), so the models can be inspected in
the rerun viewer (``rerun DIR/episode.rrd``). The overhead image is 1920x1440 pixels by default,
the frame ``python -m vision --pick-pixel U,V`` reads pixels in.

Errors print one line on stderr and exit with 2; Ctrl-C stops with one line and exit status 130,
leaving a closed, readable recording of what ran (:mod:`hand_sim.clitools`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from graspsim_base.files import atomic_path
from hand_sim import clitools as cli
from hand_sim.assembly import MAX_RENDER_HEIGHT, MAX_RENDER_WIDTH
from hand_sim.camera import OverheadCamera
from hand_sim.errors import HandSimError
from hand_sim.recorder import Recorder
from hand_sim.robot import ARM_JOINTS, FINGERS
from hand_sim.world import World

PROG = "python -m hand_sim.show"

#: Simulated seconds for the blocks to settle before the overhead picture.
SETTLE_S = 0.5
#: Seconds per move between two joint targets (linear ramp of the servo targets), then hold.
MOVE_S, HOLD_S = 1.5, 0.3
#: Log the 3D scene every this many physics steps (20 ms: 50 frames per simulated second).
LOG_EVERY = 10
#: Arm waypoints (rad, ARM_JOINTS order), each with the hand open (False) or half closed (True):
#: tool pointing down with the flange 0.40-0.45 m above the table top (over its centre, then to
#: either side, rolling the wrist), then back to the ``home`` keyframe (None).
ARM_WAYPOINTS: tuple[tuple[tuple[float, ...] | None, bool], ...] = (
    ((0.0, 0.272, 1.969, 0.9, 0.0), False),
    ((-0.278, 0.451, 1.706, 0.984, 0.8), True),
    ((0.261, 0.479, 1.56, 1.103, -0.8), False),
    (None, False),
)
#: Fraction of each hand joint's range used for the "closed" posture.
HAND_CLOSE_FRACTION = 0.5
#: Default overhead image size: the size ``python -m vision`` renders, so that a pixel read off
#: ``overhead.png`` is the pixel ``--pick-pixel`` expects.
DEFAULT_WIDTH, DEFAULT_HEIGHT = MAX_RENDER_WIDTH, MAX_RENDER_HEIGHT


@dataclass(frozen=True)
class DemoResult:
    """Files written by the demo and what happened in it."""

    rrd: Path  #: the rerun recording
    png: Path  #: the overhead image after settling
    sim_time: float  #: simulated seconds
    max_block_shift: float  #: largest displacement (m) of any block from its scene pose
    min_fingertip_z: float  #: lowest fingertip height (m) seen at the logged frames


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse and check the command line (numbers and the output folder), before any work."""
    p = cli.ArgumentParser(
        prog=PROG,
        description="Build a scene (table, prism blocks, arm and hand), let the blocks settle, "
        "save the overhead image as DIR/overhead.png and record the arm moving through a few "
        "targets to DIR/episode.rrd (open it with `rerun DIR/episode.rrd`).",
    )
    cli.add_scene_arguments(p, "scene name or .toml path", "number of blocks")
    p.add_argument(
        "--out",
        type=cli.out_dir,
        required=True,
        metavar="DIR",
        help="output folder: episode.rrd and overhead.png",
    )
    cli.add_image_size_arguments(p, "overhead image", DEFAULT_WIDTH, DEFAULT_HEIGHT)
    args = p.parse_args(argv)
    cli.check_scene_arguments(args)
    return args


def hand_posture(world: World, fraction: float) -> NDArray[np.float64]:
    """Hand targets at ``fraction`` of the way from each joint's lower to upper limit (0 for
    abduction joints, whose range is symmetric)."""
    lo, hi = world.hand_ctrlrange().T
    q = lo + fraction * (hi - lo)
    q[0::4] = 0.0
    return q


class Watch:
    """The lowest fingertip height and the largest block shift seen so far."""

    def __init__(self, world: World) -> None:
        self.min_fingertip_z = np.inf
        self.max_block_shift = 0.0
        self.update(world)

    def update(self, world: World) -> None:
        self.min_fingertip_z = min(
            self.min_fingertip_z, float(world.fingertip_positions()[:, 2].min())
        )
        shifts = [block_shift(world, b.name) for b in world.scene.blocks]
        self.max_block_shift = max(self.max_block_shift, *shifts)


def run_segment(
    world: World,
    rec: Recorder,
    arm_to: NDArray[np.float64],
    hand_to: NDArray[np.float64],
    watch: Watch,
) -> None:
    """Ramp the servo targets to ``arm_to``/``hand_to`` over MOVE_S, hold HOLD_S, logging as we
    go."""
    dt = world.model.opt.timestep
    arm_from, hand_from = world.arm_targets(), world.hand_targets()
    n_move, n_hold = round(MOVE_S / dt), round(HOLD_S / dt)
    for k in range(0, n_move + n_hold, LOG_EVERY):
        s = min(1.0, (k + LOG_EVERY) / n_move)
        world.set_arm_targets(arm_from + s * (arm_to - arm_from))
        world.set_hand_targets(hand_from + s * (hand_to - hand_from))
        world.step(LOG_EVERY)
        log_state(world, rec)
        watch.update(world)


def block_shift(world: World, name: str) -> float:
    """Distance (m) of block ``name``'s centroid from where the scene put it."""
    b = world.scene.block(name)
    start = np.array([*b.position, world.scene.table.height + 0.5 * b.height])
    return float(np.linalg.norm(world.block_pose(name)[0] - start))


def log_state(world: World, rec: Recorder) -> None:
    """3D scene, arm joint angles and targets, fingertip heights and touch readings."""
    rec.log_world(world)
    for b in world.scene.blocks:
        rec.log_scalar(f"blocks/{b.name}/shift_mm", 1000.0 * block_shift(world, b.name))
    if world.with_robot:
        for name, q, t in zip(ARM_JOINTS, world.arm_qpos(), world.arm_targets(), strict=True):
            rec.log_scalar(f"arm/{name}/qpos", q)
            rec.log_scalar(f"arm/{name}/target", t)
        for name, f, tip in zip(
            FINGERS, world.touch_sensors(), world.fingertip_positions(), strict=True
        ):
            rec.log_scalar(f"touch/{name}", f)
            rec.log_scalar(f"fingertip_z/{name}", tip[2])


def run_demo(args: argparse.Namespace) -> DemoResult:
    """Build, settle, photograph and record."""
    scene = cli.scene_from_arguments(args)
    out: Path = cli.prepare_dir(args.out, "--out")
    world = World.build(scene)
    rrd, png = out / "episode.rrd", out / "overhead.png"
    dt = world.model.opt.timestep
    with OverheadCamera(world, args.width, args.height) as cam, Recorder(rrd, world) as rec:
        rec.log_event(f"scene {scene.name}: {len(scene.blocks)} blocks, target {scene.target}")
        rec.log_camera("overhead", cam.intrinsics, cam.pose, (cam.width, cam.height))
        watch = Watch(world)
        for _ in range(round(SETTLE_S / dt) // LOG_EVERY):
            world.step(LOG_EVERY)
            log_state(world, rec)
            watch.update(world)
        rgb = cam.rgb()
        with atomic_path(png) as tmp:
            if not cv2.imwrite(str(tmp), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)):
                raise HandSimError(f"cannot write {png}")
        rec.log_image("overhead", rgb)
        rec.log_depth("overhead", cam.depth())
        home, open_hand = world.arm_targets(), world.hand_targets()
        closed = hand_posture(world, HAND_CLOSE_FRACTION)
        for i, (waypoint, close) in enumerate(ARM_WAYPOINTS):
            target = home if waypoint is None else np.array(waypoint)
            rec.log_event(
                f"move {i + 1}/{len(ARM_WAYPOINTS)}: arm targets {np.round(target, 3).tolist()}"
            )
            run_segment(world, rec, target, closed if close else open_hand, watch)
        rec.log_image("overhead", cam.rgb())
        rec.log_event(f"done at t = {world.time:.2f} s")
    return DemoResult(rrd, png, world.time, watch.max_block_shift, watch.min_fingertip_z)


def _run(argv: Sequence[str] | None) -> int:
    args = parse_args(argv)
    with cli.partial_results_in(args.out):
        r = run_demo(args)
    print(
        f"wrote {r.rrd} and {r.png} ({args.width}x{args.height} pixels): {r.sim_time:.2f} s "
        f"simulated, blocks moved at most {1000 * r.max_block_shift:.2f} mm, lowest fingertip "
        f"at z = {r.min_fingertip_z:.3f} m"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the demo with the command line ``argv``; returns the exit status."""
    return cli.run_main(lambda: _run(argv), prog=PROG, errors=cli.ERRORS)


if __name__ == "__main__":
    sys.exit(main())
