"""Cost and size of an episode recording (:class:`fsm.recording.EpisodeRecorder`): wall time per
``tick`` (one per 20 ms control period) and megabytes per simulated second, on a stand-in for a
task cycle on clutter3 that exercises every kind of record: the vision of the target block, a
coarse reach to it, a Wrench Closure run of the knowledge-based controller on the perceived
polygon, the hand closing on the block (contacts and force arrows) and transitions and a verdict
in the event log. It is not the task cycle (``python -m fsm.run``): it only feeds the recorder.

Run: ``.venv/bin/python -m benchmarks.bench_recording [--out DIR] [--hold SECONDS]``. Prints
figures and writes ``DIR/episode.rrd`` (open it with ``rerun DIR/episode.rrd``).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from controllers.deliver.carry import move_palm
from controllers.grasp.composition import KnowledgeBased
from controllers.grasp.synthesis import GraspSynthesis
from controllers.hand.grip import move_hand
from controllers.planning.cspace import CollisionChecker
from controllers.reach.arm_path import execute_path
from controllers.reach.coarse import ReachTarget, plan_coarse_reach
from fsm.recorder_protocol import SynthesisRecord, VisionView
from fsm.recording import EpisodeRecorder
from hand_sim.contacts import robot_contacts
from hand_sim.scene import load_scene
from hand_sim.world import World
from vision import Observation, overhead_camera, select

#: Simulated seconds of the settle; the task cycle lasts 25-40 s of simulated time, so the size
#: is also extrapolated to EPISODE_S.
SETTLE_S, EPISODE_S = 0.5, 40.0
#: Stand-in for Grasp Object: the fingers curl to this fraction of their flexion range over
#: CURL_S, the palm descends (at most MAX_DESCENT m over DESCENT_S) until the hand touches the
#: block and then presses PRESS m further over PRESS_S (s).
CURL_FRACTION, CURL_S = 0.9, 0.5
MAX_DESCENT, DESCENT_S = 0.2, 2.0
PRESS, PRESS_S = 0.001, 0.3
#: Controller steps of the Wrench Closure run (the kb controller usually converges sooner).
SYNTHESIS_STEPS = 150
SEED = 0


def run(out: Path, hold: float) -> None:
    world = World.build(load_scene("clutter3"))
    scene = world.scene
    target = scene.target
    rrd = out / "episode.rrd"
    control_steps = 10  # 20 ms control period at the 2 ms physics step
    wall0 = time.perf_counter()
    with EpisodeRecorder(rrd, world) as rec:
        world.on_step = rec.tick
        rec.log_transition("Start", "Select/Model", f"scene {scene.name}, pick {target}")
        for _ in range(round(SETTLE_S / 0.02)):
            world.step(control_steps)
        with overhead_camera(world) as cam:
            obs = Observation.capture(cam)
        positions = {b.name: world.block_pose(b.name)[0][:2] for b in scene.blocks}
        model = select(obs, name=target, block_positions=positions)
        rec.log_vision(
            VisionView(
                obs.rgb,
                obs.geometry.K,
                obs.geometry.cam_to_world,
                model.world_vertices,
                model.pixel_contour,
                float(model.centroid[2]),
            )
        )
        rec.set_target(target)
        rec.log_transition("Select/Model", "Coarse Reach", f"{model.n_edges}-gon modelled")
        plan = plan_coarse_reach(world, ReachTarget.from_object_model(model))
        if plan.found and plan.path is not None:
            rec.log_transition("Coarse Reach", "Wrench Closure", f"{plan.approach} approach")
            execute_path(world, plan.path.path, hand_q=plan.hand_q)
        else:
            rec.log_transition("Coarse Reach", "Wrench Closure", plan.reason, level="WARN")
        rng = np.random.default_rng(SEED)
        theta0 = np.linspace(0.0, 2 * np.pi, 4, endpoint=False) + 0.3
        synth = GraspSynthesis(model.polygon, KnowledgeBased(), theta0, rng)
        z_grasp = float(model.centroid[2]) - 0.5 * model.height
        while not synth.done and synth.steps < SYNTHESIS_STEPS:
            s = synth.step()
            xy = model.to_world(np.array([model.polygon.point_at(t) for t in s.theta]))
            contacts = np.column_stack([xy, np.full(len(xy), z_grasp)])
            rec.log_synthesis(
                SynthesisRecord(s.step, s.eps_fc, s.eps_mc, s.predicted_failure, contacts)
            )
        score = synth.finish()
        rec.log_reachability(1, True, f"S_G = {score.s_g:.3f} after {synth.steps} steps")
        rec.log_transition("Wrench Closure", "Grasp Object", "contacts reachable")
        # Stand-in for Grasp Object: curl the fingers and lower the palm until the hand
        # touches the block, then press PRESS m further.
        lo, hi = world.hand_ctrlrange().T
        curled = np.array(plan.hand_q, dtype=float)
        curled[1::4], curled[2::4], curled[3::4] = (
            (lo + CURL_FRACTION * (hi - lo))[j::4] for j in (1, 2, 3)
        )
        move_hand(world, curled, CURL_S)
        checker = CollisionChecker(world, hand_q=curled)
        body = world.block_body_id(target)
        move_palm(
            world,
            checker,
            (0.0, 0.0, -MAX_DESCENT),
            DESCENT_S,
            stop=lambda w: len(robot_contacts(w, body)) > 0,
        )
        move_palm(world, checker, (0.0, 0.0, -PRESS), PRESS_S)
        for _ in range(round(hold / 0.02)):
            world.step(control_steps)
        rec.log_verdict(
            False, "stand-in episode: the hand pressed on the block, nothing was delivered"
        )
        stats = rec.stats
    wall = time.perf_counter() - wall0
    size = rrd.stat().st_size / 1e6
    sim = world.time
    print(f"wrote {rrd}: {size:.2f} MB for {sim:.2f} s simulated ({wall:.1f} s wall in all)")
    print(
        f"ticks {stats.ticks}: {1e3 * stats.seconds_per_tick:.2f} ms per tick "
        f"({stats.body_frames} body frames, {stats.scalar_rows} scalar rows, {stats.images} "
        f"images, {stats.contact_frames} contact frames; {stats.tick_seconds:.2f} s in tick)"
    )
    print(
        f"{size / sim:.3f} MB per simulated second -> about {EPISODE_S * size / sim:.1f} MB for "
        f"a {EPISODE_S:.0f} s episode (limit 50 MB)"
    )


def main(argv: Sequence[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("runs/bench_recording"))
    p.add_argument("--hold", type=float, default=2.0, help="simulated seconds held at the end")
    args = p.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    run(args.out, args.hold)


if __name__ == "__main__":
    main()
