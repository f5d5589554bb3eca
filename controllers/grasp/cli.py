"""Command line of the grasp core: ``python -m controllers.grasp {trials,score,table1,reproduce}``.

Results go to stdout as one-line summaries and, with ``--json``, to a JSON file other programs can
check. Bad input is one line on stderr and exit status 2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from controllers.grasp.errors import GraspError, PolygonError
from controllers.grasp.experiments import (
    PAPER_TABLE1_AVERAGE,
    PAPER_TABLE1_KB,
    table1_rows,
    trial_summary,
)
from controllers.grasp.objects import PAPER_LABELS, PAPER_OBJECTS, paper_object
from controllers.grasp.polygon import Polygon, centroid_of, parse_points
from controllers.grasp.registry import COMPOSERS, DEFAULT_MODEL_DIR, make_composer
from controllers.grasp.score import grasp_score
from controllers.grasp.trials import GAIN, MAX_STEPS, N_CONTACTS, PolygonBatch, run_trials

#: A contact point given to ``score`` may be this far (fraction of the diameter) off the outline.
ON_BOUNDARY_TOLERANCE = 0.01


def _polygon_arg(args: argparse.Namespace) -> Polygon:
    if args.polygon:
        return Polygon.from_vertices(parse_points(args.polygon), name="user")
    return paper_object(args.object)


def _write_json(path: str | None, payload: dict) -> None:
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(json.dumps(payload, indent=1))


def cmd_trials(args: argparse.Namespace) -> int:
    poly = _polygon_arg(args)
    if args.rotate:
        poly = poly.rotated(np.deg2rad(args.rotate))
    composer = make_composer(args.controller, Path(args.models), gain=args.gain)
    rng = np.random.default_rng(args.seed)
    batch = PolygonBatch.of([poly])
    start = time.perf_counter()
    result = run_trials(
        [poly],
        np.zeros(args.trials, dtype=int),
        composer,
        rng,
        n_contacts=args.contacts,
        max_steps=args.max_steps,
        gain=args.gain,
        batch=batch,
    )
    elapsed = time.perf_counter() - start
    summary = trial_summary(result, elapsed)
    summary.update(
        object=poly.name,
        controller=args.controller,
        seed=args.seed,
        contacts=args.contacts,
        rotate_deg=args.rotate,
        gain=args.gain,
    )
    print(
        f"{poly.name}: {args.trials} trials, {args.controller}: "
        f"failure {100 * summary['failure_rate']:.2f} %, "
        f"mean S_G {summary['mean_s_g']:.3f}, mean steps {summary['mean_steps']:.1f}, "
        f"{summary['trials_per_s']:.0f} trials/s"
    )
    unit = batch.polygons[0]
    scale = poly.diameter / unit.diameter  # unit-moment frame -> the polygon's own units
    per_trial = [
        {
            "theta_initial": result.theta_initial[i].tolist(),
            "theta_final": result.theta_final[i].tolist(),
            "points": (result.points[i] * scale).tolist(),
            "s_g": None if not result.feasible[i] else float(result.s_g[i]),
            "feasible": bool(result.feasible[i]),
            "success": bool(result.success[i]),
            "steps": int(result.steps[i]),
            "converged": bool(result.converged[i]),
        }
        for i in range(args.trials)
    ]
    _write_json(
        args.json, {"summary": summary, "vertices": poly.vertices.tolist(), "trials": per_trial}
    )
    return 0


def cmd_score(args: argparse.Namespace) -> int:
    raw = parse_points(args.polygon)
    poly = Polygon.from_vertices(raw, name="user")
    centroid = centroid_of(raw)
    points = parse_points(args.points, what="points") - centroid
    theta = poly.theta_of(points)
    frames = poly.locate(theta)
    off = np.linalg.norm(frames.point - points, axis=1)
    bad = np.flatnonzero(off > ON_BOUNDARY_TOLERANCE * poly.diameter)
    if bad.size:
        i = int(bad[0])
        raise PolygonError(
            f"point {i} {tuple(float(c) for c in points[i] + centroid)} "
            f"is {off[i]:.3g} away from the polygon outline: give points on its edges"
        )
    scale = 1.0 / poly.max_moment
    task = None if args.task is None else [float(x) for x in args.task.split(",")]
    score = grasp_score(frames.point * scale, frames.normal, task)
    if score.feasible:
        print(f"S_G = {score.s_g:.4f} ({'success' if score.success else 'failure'}: threshold 0.4)")
    else:
        print("infeasible: no contact forces satisfy the constraints (a failure)")
    _write_json(
        args.json,
        {
            "feasible": score.feasible,
            "s_g": score.s_g if score.feasible else None,
            "success": score.success,
            "normal_forces": score.normal_forces.tolist(),
            "tangential_forces": score.tangential_forces.tolist(),
        },
    )
    return 0


def cmd_table1(args: argparse.Namespace) -> int:
    start = time.perf_counter()
    rows = table1_rows(args.trials, args.seed, gain=args.gain)
    elapsed = time.perf_counter() - start
    print(
        f"Table 1, knowledge-based composition: {args.trials} trials per object, seed {args.seed}"
    )
    print(f"{'Object':18s} {'ours (%)':>9s} {'paper (%)':>10s} {'mean S_G':>9s} {'steps':>6s}")
    for r in rows:
        print(
            f"{PAPER_LABELS[r['object']]:18s} {100 * r['failure_rate']:9.2f} "
            f"{PAPER_TABLE1_KB[r['object']]:10.2f} {r['mean_s_g']:9.3f} {r['mean_steps']:6.1f}"
        )
    avg = float(np.mean([r["failure_rate"] for r in rows]))
    paper_avg = PAPER_TABLE1_AVERAGE["kb"]
    print(f"{'Average':18s} {100 * avg:9.2f} {paper_avg:10.2f}")
    print(f"({len(rows) * args.trials} trials in {elapsed:.2f} s)")
    _write_json(args.json, {"rows": rows, "average_failure_rate": avg, "seconds": elapsed})
    return 0


def cmd_reproduce(args: argparse.Namespace) -> int:
    from controllers.grasp.reproduce import ReproduceConfig, reproduce

    cfg = ReproduceConfig.quick_run() if args.quick else ReproduceConfig.paper()
    res = reproduce(Path(args.out), seed=args.seed, config=cfg)
    avg = {k: f"{v['average_failure']:.2f}" for k, v in res["table2"].items()}
    print(
        f"average failure (%): kb {avg['kb']}, ql {avg['ql']}, pi {avg['pi']}, "
        f"pi (5 objects) {avg['pi5']}; report: {Path(args.out) / 'report.md'}"
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m controllers.grasp", description=__doc__.splitlines()[0]
    )
    sub = p.add_subparsers(dest="command", required=True)

    t = sub.add_parser("trials", help="run grasp trials on one object")
    t.add_argument("--object", default="square", help=f"paper object: {', '.join(PAPER_OBJECTS)}")
    t.add_argument("--polygon", help="your own convex polygon 'x,y;x,y;...' (overrides --object)")
    t.add_argument("--controller", default="kb", help=f"composer: {', '.join(COMPOSERS)}")
    t.add_argument("--trials", type=_positive_int, default=200)
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--contacts", type=_contacts, default=N_CONTACTS)
    t.add_argument("--rotate", type=float, default=0.0, help="rotate the object by DEG degrees")
    t.add_argument("--max-steps", type=_positive_int, default=MAX_STEPS)
    t.add_argument("--gain", type=float, default=GAIN, help="gradient step (rad per unit gradient)")
    t.add_argument("--models", default=str(DEFAULT_MODEL_DIR), help="directory of trained models")
    t.add_argument("--json", help="write per-trial results and the summary to this JSON file")
    t.set_defaults(func=cmd_trials)

    s = sub.add_parser("score", help="grasp score S_G (Eq. 13) of contact points on a polygon")
    s.add_argument("--polygon", required=True, help="convex polygon 'x,y;x,y;...'")
    s.add_argument("--points", required=True, help="contact points on its outline 'x,y;x,y;...'")
    s.add_argument("--task", help="task wrench 'fx,fy,mz' (default: null grasp)")
    s.add_argument("--json", help="write the result to this JSON file")
    s.set_defaults(func=cmd_score)

    tb = sub.add_parser("table1", help="knowledge-based column of Table 1 beside the paper's")
    tb.add_argument("--trials", type=_positive_int, default=200)
    tb.add_argument("--seed", type=int, default=0)
    tb.add_argument("--gain", type=float, default=GAIN)
    tb.add_argument("--json", help="write the rows to this JSON file")
    tb.set_defaults(func=cmd_table1)

    r = sub.add_parser(
        "reproduce", help="train and test every learned controller; write report, figures, models"
    )
    r.add_argument(
        "--out", required=True, help="output directory (report.md, results.json, PNGs, models)"
    )
    r.add_argument(
        "--quick", action="store_true", help="reduced sizes for CI (well under a minute)"
    )
    r.add_argument("--seed", type=int, default=0)
    r.set_defaults(func=cmd_reproduce)
    return p


def _positive_int(text: str) -> int:
    v = int(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return v


def _contacts(text: str) -> int:
    v = int(text)
    if v < 2:
        raise argparse.ArgumentTypeError(f"a grasp needs at least 2 contacts, got {text}")
    return v


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (GraspError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
