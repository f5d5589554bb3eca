"""Command line of the grasp core: ``python -m controllers.grasp {trials,score}``.

Results go to stdout as one-line summaries and, with ``--json``, to a JSON file other programs can
check. Bad input is one line on stderr and exit status 2 (:mod:`graspsim_base.cli`).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from controllers.grasp.errors import GraspError, PolygonError
from controllers.grasp.objects import PAPER_OBJECTS, paper_object
from controllers.grasp.polygon import MAX_COORDINATE, Polygon, centroid_of, parse_points
from controllers.grasp.prism3d import prism_contacts
from controllers.grasp.registry import COMPOSERS, make_composer
from controllers.grasp.run_folder import REPRODUCE, check_finished_run
from controllers.grasp.score import GraspScore, grasp_score
from controllers.grasp.score3d import GraspScore3D, grasp_score_3d
from controllers.grasp.trials import (
    GAIN,
    MAX_STEPS,
    N_CONTACTS,
    DescentSettings,
    PolygonBatch,
    run_trials,
    trial_summary,
)
from controllers.grasp.trials3d import HeightBand, PrismBatch, run_trials_3d
from graspsim_base import cli
from graspsim_base.files import write_text

PROG = "python -m controllers.grasp"
#: A contact point given to ``score`` may be this far (fraction of the diameter) off the outline.
ON_BOUNDARY_TOLERANCE = 0.01
#: Command-line limits. Trials: about 700/s, so the largest run takes a few minutes; contacts: a
#: four-fingered hand needs 4, the planar controllers work for any number >= 2; the gain has no
#: natural upper bound (the README's gain study goes to 1.0), 10 only refuses typing mistakes.
MAX_TRIALS = 100_000
MAX_CONTACTS = 16
MAX_STEPS_LIMIT = 10_000
MAX_GAIN = 10.0
#: Task wrench components (unit-moment frame, in units of the unit contact force).
MAX_TASK = 1e6
#: Default prism height of ``trials --model 3d`` (the simulated blocks' 20 cm, section 5.1).
DEFAULT_HEIGHT = 0.20
#: Controllers that read trained models from ``--models``.
LEARNED = ("ql", "pi", "pi9", "pi5")
#: Errors the grasp commands report as bad input (one line, exit status 2).
ERRORS: tuple[type[BaseException], ...] = (GraspError,)
#: Argument types of a number of trials and of the gradient step (``--gain``), and its help.
trials_type = cli.integer(1, MAX_TRIALS)
gain_type = cli.number(0.0, MAX_GAIN, lo_open=True)
GAIN_HELP = f"gradient step, rad per unit gradient, in (0, {MAX_GAIN:g}]"


def _user_polygon(text: str, flag: str) -> tuple[np.ndarray, Polygon]:
    """The vertices written in ``text`` and their polygon; errors name ``flag``."""
    raw = parse_points(text, what=flag)
    try:
        return raw, Polygon.from_vertices(raw, name="user")
    except PolygonError as e:
        raise PolygonError(f"{flag}: {e}") from e


def _polygon_arg(args: argparse.Namespace) -> Polygon:
    if args.polygon is not None:
        return _user_polygon(args.polygon, "--polygon")[1]
    return paper_object(args.object)


def prepare_json(args: argparse.Namespace) -> None:
    """Check, before the work starts, that the ``--json`` file can be written."""
    if args.json is not None:
        cli.prepare_file(args.json, "--json")


def write_json(path: Path | None, payload: dict) -> None:
    if path is not None:
        write_text(path, json.dumps(payload, indent=1) + "\n")


def cmd_trials(args: argparse.Namespace) -> int:
    poly = _polygon_arg(args)
    if args.rotate:
        poly = poly.rotated(np.deg2rad(args.rotate))
    if args.models is not None and args.controller in LEARNED:
        check_finished_run(args.models, "--models")
        composer = make_composer(args.controller, args.models, gain=args.gain)
    else:
        composer = make_composer(args.controller, gain=args.gain)
    if args.model == "planar" and (args.height is not None or args.depths is not None):
        raise GraspError("--height and --depths describe the prism: use them with --model 3d")
    prism = None
    if args.model == "3d":
        height = DEFAULT_HEIGHT if args.height is None else args.height
        lo, hi = (0.0, height) if args.depths is None else args.depths
        prism = PrismBatch.of([poly], [height], [HeightBand.below_top(height, lo, hi)])
    prepare_json(args)
    rng = np.random.default_rng(args.seed)
    batch = PolygonBatch.of([poly])
    start = time.perf_counter()
    settings = {"n_contacts": args.contacts, "max_steps": args.max_steps, "gain": args.gain}
    index = np.zeros(args.trials, dtype=int)
    if prism is None:
        result = run_trials([poly], index, composer, rng, batch=batch, **settings)
    else:
        result = run_trials_3d(prism, index, composer, rng, DescentSettings(**settings))
    elapsed = time.perf_counter() - start
    summary = trial_summary(result, elapsed)
    summary.update(
        object=poly.name,
        controller=args.controller,
        seed=args.seed,
        contacts=args.contacts,
        rotate_deg=args.rotate,
        gain=args.gain,
        model=args.model,
    )
    if prism is not None:
        summary.update(height=float(prism.half_height[0] * prism.scale[0] * 2.0), depths=[lo, hi])
    print(
        f"{poly.name}{' (3d)' if prism is not None else ''}: {args.trials} trials, "
        f"{args.controller}: "
        f"failure {100 * summary['failure_rate']:.2f} %, "
        f"mean S_G {summary['mean_s_g']:.3f}, mean steps {summary['mean_steps']:.1f}, "
        f"{summary['trials_per_s']:.0f} trials/s"
    )
    unit = batch.polygons[0]
    scale = poly.diameter / unit.diameter  # unit-moment frame -> the polygon's own units
    # 3-D points: the prism's frame (centroid at the origin), z above its base
    lift = 0.0 if prism is None else float(prism.half_height[0] * prism.scale[0])
    per_trial = [
        {
            "theta_initial": result.theta_initial[i].tolist(),
            "theta_final": result.theta_final[i].tolist(),
            "points": (result.points[i] * scale + [0.0, 0.0, lift][: result.points.shape[-1]])
            .round(9)
            .tolist(),
            "s_g": None if not result.feasible[i] else float(result.s_g[i]),
            "feasible": bool(result.feasible[i]),
            "success": bool(result.success[i]),
            "steps": int(result.steps[i]),
            "converged": bool(result.converged[i]),
        }
        for i in range(args.trials)
    ]
    write_json(
        args.json, {"summary": summary, "vertices": poly.vertices.tolist(), "trials": per_trial}
    )
    return 0


def _report_score(args: argparse.Namespace, score: GraspScore | GraspScore3D) -> int:
    """Print S_G and its verdict; write the ``--json`` file."""
    if score.feasible:
        shown = round(score.s_g, 4) + 0.0  # + 0.0: the LP's -1e-12 prints as 0.0000, not -0.0000
        print(f"S_G = {shown:.4f} ({'success' if score.success else 'failure'}: threshold 0.4)")
    else:
        print("infeasible: no contact forces satisfy the constraints (a failure)")
    write_json(
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


def _score_3d(args: argparse.Namespace, raw: np.ndarray, poly: Polygon, points: np.ndarray) -> int:
    """``score`` with points x,y,z: contacts on the prism of ``--polygon`` extruded to
    ``--height`` (z above its base; a point with z = H on the top face), scored by the 3-D S_G
    (Eq. 13 with 6-D wrenches, :mod:`controllers.grasp.score3d`) in the unit-moment frame."""
    if args.height is None:
        raise PolygonError(
            "--height: points with three numbers need the prism's height (--height H)"
        )
    task = args.task
    if task is not None and len(task) != 6:
        raise PolygonError("--task: the 3-D model takes 6 numbers FX,FY,FZ,MX,MY,MZ")
    h, tol = args.height, ON_BOUNDARY_TOLERANCE * poly.diameter
    xy = points[:, :2] - centroid_of(raw)
    z = points[:, 2]
    on, _, off = poly.nearest_on_outline(xy)
    inside = np.all(xy @ _edge_normals(poly).T - poly.offset[None, :] <= tol, axis=1)
    top = (np.abs(z - h) <= tol) & inside
    side = ~top & (off <= tol) & (z >= -tol) & (z <= h + tol)
    _refuse_first(
        ~(top | side),
        points,
        f"is not on the prism's sides (on the outline, 0 <= z <= {h:g}) or top face "
        f"(inside, z = {h:g})",
    )
    prepare_json(args)
    theta = np.array([poly.theta_of(p) for p in on[side]])
    p3, n3 = prism_contacts(poly, theta, np.clip(z[side], 0.0, h), h, top=xy[top], unit_moment=True)
    order = np.concatenate([np.flatnonzero(side), np.flatnonzero(top)])
    p3[order], n3[order] = p3.copy(), n3.copy()
    return _report_score(args, grasp_score_3d(p3, n3, task))


def _refuse_first(bad: np.ndarray, points: np.ndarray, problem: str) -> None:
    """Raise :class:`PolygonError` naming the first point marked ``bad`` and its ``problem``."""
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise PolygonError(f"--points: point {i} {tuple(float(c) for c in points[i])} {problem}")


def _edge_normals(poly: Polygon) -> np.ndarray:
    """Outward unit normals (k, 2) of the polygon's edges."""
    return np.stack([np.cos(poly.normal_angle), np.sin(poly.normal_angle)], axis=1)


def cmd_score(args: argparse.Namespace) -> int:
    raw, poly = _user_polygon(args.polygon, "--polygon")
    centroid = centroid_of(raw)
    points = parse_points(args.points, what="--points", dims=(2, 3))
    if points.shape[1] == 3:
        return _score_3d(args, raw, poly, points)
    if args.height is not None:
        raise PolygonError("--height: applies to points with three numbers (x,y,z) only")
    if args.task is not None and len(args.task) != 3:
        raise PolygonError("--task: points with two numbers take 3 numbers FX,FY,MZ")
    points = points - centroid
    on, edge, off = poly.nearest_on_outline(points)
    far = off > ON_BOUNDARY_TOLERANCE * poly.diameter
    if far.any():
        gap = off[np.flatnonzero(far)[0]]
        _refuse_first(
            far,
            points + centroid,
            f"is {gap:.3g} away from the polygon outline: give points on its edges",
        )
    prepare_json(args)
    scale = 1.0 / poly.max_moment
    task = None if args.task is None else list(args.task)
    normals = _edge_normals(poly)[edge]
    return _report_score(args, grasp_score(on * scale, normals, task))


def build_parser() -> cli.ArgumentParser:
    p, sub = cli.command_parser(
        PROG,
        "The grasp controller of Coelho & Grupen on planar polygons: grasp trials and the S_G "
        "score of contact points (the paper's experiments: python -m experiments.paper).",
    )
    t = cli.add_command(sub, "trials", "run grasp trials on one object")
    t.add_argument("--object", default="square", help=f"paper object: {', '.join(PAPER_OBJECTS)}")
    t.add_argument(
        "--polygon",
        metavar="X,Y;X,Y;...",
        help="your own convex polygon, any unit (overrides --object); quote it, and write "
        'negative values as they are: --polygon "-1,-1;1,-1;0,1"',
    )
    t.add_argument("--controller", default="kb", help=f"composer: {', '.join(COMPOSERS)}")
    t.add_argument(
        "--trials", type=trials_type, default=200, help=f"number of trials, 1..{MAX_TRIALS}"
    )
    cli.add_seed_argument(t)
    t.add_argument(
        "--contacts",
        type=cli.integer(2, MAX_CONTACTS),
        default=N_CONTACTS,
        help=f"contacts per grasp, 2..{MAX_CONTACTS}",
    )
    t.add_argument(
        "--rotate",
        type=cli.number(-360.0, 360.0),
        default=0.0,
        metavar="DEG",
        help="rotate the object by DEG degrees, -360..360",
    )
    t.add_argument(
        "--max-steps",
        type=cli.integer(1, MAX_STEPS_LIMIT),
        default=MAX_STEPS,
        help=f"control steps per trial, 1..{MAX_STEPS_LIMIT}",
    )
    t.add_argument("--gain", type=gain_type, default=GAIN, help=GAIN_HELP)
    t.add_argument(
        "--models",
        type=Path,
        metavar="DIR",
        help=f"folder of a finished `{REPRODUCE} DIR` run whose models --controller "
        "ql|pi|pi9|pi5 use (default: the models shipped in the package)",
    )
    t.add_argument(
        "--model",
        choices=("planar", "3d"),
        default="planar",
        help="planar: the paper's controllers with phi = 0 (its tables); 3d: contacts with "
        'heights on the sides of a prism (docs/grasp.md, "The 3-D model")',
    )
    t.add_argument(
        "--height",
        type=cli.number(0.0, MAX_COORDINATE, lo_open=True),
        metavar="H",
        help=f"3d: prism height, the polygon's unit (default {DEFAULT_HEIGHT:g}: the simulated "
        "blocks' 20 cm for the paper objects, which are in metres)",
    )
    t.add_argument(
        "--depths",
        type=cli.numbers(2, "LO,HI", 0.0, MAX_COORDINATE),
        metavar="LO,HI",
        help="3d: contacts between LO and HI below the top (default: the whole side)",
    )
    cli.add_json_argument(t, "write per-trial results and the summary here")
    t.set_defaults(func=cmd_trials)

    s = cli.add_command(sub, "score", "grasp score S_G (Eq. 13) of contact points on a polygon")
    s.add_argument(
        "--polygon", required=True, metavar="X,Y;X,Y;...", help="convex polygon, any unit"
    )
    s.add_argument(
        "--points",
        required=True,
        metavar="X,Y;X,Y;...",
        help="contact points on its outline; three numbers a point (X,Y,Z;...) select the 3-D "
        "model: contacts on the prism of --height H, Z above its base, Z = H on the top face",
    )
    s.add_argument(
        "--height",
        type=cli.number(0.0, MAX_COORDINATE, lo_open=True),
        metavar="H",
        help="prism height, the polygon's unit (3-D points only)",
    )
    s.add_argument(
        "--task",
        type=cli.numbers((3, 6), "FX,FY,MZ or FX,FY,FZ,MX,MY,MZ", -MAX_TASK, MAX_TASK),
        metavar="FX,FY,MZ",
        help="task wrench in the unit-moment frame (3-D points: FX,FY,FZ,MX,MY,MZ, moments "
        "about the centre of mass; default: the null grasp)",
    )
    cli.add_json_argument(s, "write the result to this JSON file")
    s.set_defaults(func=cmd_score)

    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the exit status."""
    return cli.run_command(build_parser, argv, prog=PROG, errors=ERRORS)
