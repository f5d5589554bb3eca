"""``python -m controllers.grasp reproduce --out DIR``: every experiment of the paper in one run.

Trains the Q-learning composer (section 3.6.2), the F/S predictors of the PI controller on all nine
objects and on the five-object subset (section 4.3), the atomic-action controller (section 2),
solves Appendix A, tests everything, and writes ``DIR/report.md`` (our numbers beside the paper's),
``DIR/results.json``, the figures (PNG) and the trained models. Wall-clock times go to
``DIR/timings.json`` only, so the same seed reproduces every other file byte for byte. Every file
is written atomically; ``results.json`` is written last and marks the run finished
(:mod:`controllers.grasp.run_folder`), so ``trials --models DIR`` refuses an interrupted run.
"""

from __future__ import annotations

import json
import sys
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from numpy.typing import NDArray

from controllers.grasp import figures as fig
from controllers.grasp.atomic import (
    ATOMIC_EPOCHS,
    ATOMIC_MODEL_FILE,
    ATOMIC_TRIALS,
    PAPER_ATOMIC,
    TEST_ROTATION_DEG,
    TEST_TRIALS,
    ScoreTable,
    evaluate_atomic,
    save_atomic_q,
    sector_angle,
    train_atomic,
)
from controllers.grasp.composition import Composer, KnowledgeBased
from controllers.grasp.experiments import PAPER_TABLE1_AVERAGE, PAPER_TABLE1_KB, PAPER_TABLE1_QL
from controllers.grasp.files import write_text
from controllers.grasp.objects import (
    PAPER_LABELS,
    PAPER_OBJECTS,
    paper_object,
    random_convex_polygon,
)
from controllers.grasp.optimal_control import BETA, PAPER_THETA_T, solve_time_optimal
from controllers.grasp.polygon import Polygon
from controllers.grasp.predictor import PREDICTOR_EPOCHS, FSPredictor, train_predictor
from controllers.grasp.preimaging import (
    NOISE_BOUND,
    NOISE_SIGMA,
    PI_MODEL_FILE,
    PI_SUBSET_MODEL_FILE,
    PREIMAGE_NOISE_GAIN,
    PreImaging,
)
from controllers.grasp.qlearning import (
    EPOCHS,
    QL_MODEL_FILE,
    TRIALS_PER_OBJECT,
    QLearningComposer,
    save_q_table,
    scaled_error,
    state_bin,
    train_qlearning,
)
from controllers.grasp.run_folder import finished_mark, mark_started, write_results
from controllers.grasp.score import SUCCESS_THRESHOLD
from controllers.grasp.trials import GAIN, N_CONTACTS, PolygonBatch, TrialBatch, run_trials

#: Table 2 of the paper: PI trained on all nine objects (c) and on five of them (d), failure (%).
PAPER_TABLE2_PI_ALL: dict[str, float] = {
    "triangle": 0.00, "square": 0.00, "pentagon": 0.00, "hexagon": 0.00,
    "irregular_triangle": 2.50, "rectangle": 0.00, "trapezoid": 0.50,
    "irregular_pentagon": 0.00, "irregular_hexagon": 0.00,
}  # fmt: skip
PAPER_TABLE2_PI_FIVE: dict[str, float] = {
    "triangle": 1.00, "square": 0.00, "pentagon": 0.00, "hexagon": 0.00,
    "irregular_triangle": 2.50, "rectangle": 0.00, "trapezoid": 0.00,
    "irregular_pentagon": 0.50, "irregular_hexagon": 0.00,
}  # fmt: skip
PAPER_TABLE2_AVERAGE = {"kb": 10.06, "ql": 8.33, "pi": 0.33, "pi5": 0.44}
#: Mean grasp score over the objects (section 4.5).
PAPER_MEAN_SG = {"kb": 0.172, "ql": 0.189, "pi": 0.138}
#: The five objects of Table 2 (d).
FIVE_OBJECTS: tuple[str, ...] = (
    "triangle", "square", "trapezoid", "irregular_pentagon", "irregular_hexagon",
)  # fmt: skip
#: Width of the sliding window of the learning curves (Figures 1, 7, 9).
SMOOTHING = 10
#: Two final contacts are "the same configuration" (Figure 12) when on the same edge with surface
#: coordinates (unit-moment frame) in the same bin of this width.
CONFIG_RESOLUTION = 0.1
#: Independent random streams of a run (SeedSequence children; each used for one purpose).
N_STREAMS = 13
#: Trials on the square for Figures 10 and 11 (at least this many).
FIGURE10_TRIALS = 100
#: Epochs per batch when running the (non-learning) KB and PI failure curves.
CURVE_CHUNK = 10
#: Pre-image noise gains reported in the sensitivity table (1 = the paper's literal noise).
NOISE_GAINS = (1.0, 2.0, 4.0, PREIMAGE_NOISE_GAIN)
CONTROLLERS = ("kb", "ql", "pi", "pi5")
#: The trained models a run writes (recorded, with their hashes, in results.json).
MODEL_FILES = (QL_MODEL_FILE, PI_MODEL_FILE, PI_SUBSET_MODEL_FILE, ATOMIC_MODEL_FILE)
QUICK_NOTE = " (QUICK run: reduced sizes, not comparable with the paper)"
CONTROLLER_LABELS = {
    "kb": "Knowledge-based (a)",
    "ql": "Q-learning (b)",
    "pi": "PI, 9 objects (c)",
    "pi5": "PI, 5 objects (d)",
}


@dataclass(frozen=True)
class ReproduceConfig:
    """Experiment sizes; :meth:`paper` is the paper's, :meth:`quick` a reduced one for CI."""

    ql_epochs: int = EPOCHS
    trials_per_object: int = TRIALS_PER_OBJECT
    predictor_epochs: int = PREDICTOR_EPOCHS
    test_trials: int = 200
    curve_epochs: int = EPOCHS
    atomic_epochs: int = ATOMIC_EPOCHS
    atomic_trials: int = ATOMIC_TRIALS
    atomic_test_trials: int = TEST_TRIALS
    random_polygons: int = 200
    random_trials: int = 10
    noise_sweep: bool = True
    quick: bool = False

    @classmethod
    def paper(cls) -> ReproduceConfig:
        return cls()

    @classmethod
    def quick_run(cls) -> ReproduceConfig:
        return cls(
            ql_epochs=30,
            predictor_epochs=4,
            test_trials=40,
            curve_epochs=20,
            atomic_epochs=30,
            atomic_trials=60,
            atomic_test_trials=60,
            random_polygons=30,
            random_trials=4,
            noise_sweep=False,
            quick=True,
        )


Progress = Callable[[str], None]


def _stderr(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def object_rows(result: TrialBatch, names: Sequence[str]) -> dict[str, dict]:
    """Per object: failure rate (%), mean S_G over feasible grasps, infeasible count, mean steps."""
    rows = {}
    for i, name in enumerate(names):
        sub = result.subset(result.object_index == i)
        feas = sub.s_g[sub.feasible]
        rows[name] = {
            "failure": 100.0 * sub.failure_rate,
            "mean_s_g": float(feas.mean()) if feas.size else float("nan"),
            "infeasible": int((~sub.feasible).sum()),
            "mean_steps": float(sub.steps.mean()),
        }
    return rows


def mean_score(rows: dict[str, dict]) -> float:
    """S_G-bar of section 4.5: the frequency-weighted S_G of the generated configurations of each
    object (its mean S_G), averaged over the objects (infeasible grasps have no S_G: left out)."""
    return float(np.mean([r["mean_s_g"] for r in rows.values()]))


def configurations(
    polygons: Sequence[Polygon], result: TrialBatch, i: int, top: int
) -> list[tuple[NDArray[np.float64], float, float]]:
    """The ``top`` most frequent final configurations on object ``i``: (points in the unit-moment
    frame, fraction of trials, S_G), contacts grouped as in :data:`CONFIG_RESOLUTION`."""
    unit = polygons[i].unit_moment()
    m = np.flatnonzero(result.object_index == i)
    frames = unit.locate(result.theta_final[m])
    keys = [
        tuple(
            sorted(
                zip(
                    frames.edge[j].tolist(),
                    np.round(frames.surface[j] / CONFIG_RESOLUTION).astype(int).tolist(),
                    strict=True,
                )
            )
        )
        for j in range(len(m))
    ]
    counts = Counter(keys)
    out = []
    for key, n in counts.most_common(top):
        j = keys.index(key)
        out.append((frames.point[j], n / len(m), float(result.s_g[m[j]])))
    return out


def failure_curve(
    polys: Sequence[Polygon],
    batch: PolygonBatch,
    composer: Composer,
    rng: np.random.Generator,
    epochs: int,
    trials_per_object: int,
) -> NDArray[np.float64]:
    """Failure rate per epoch of a controller that does not learn (Figure 9 (a) after the predictor
    is trained, (b)): the epochs run in chunks of CURVE_CHUNK epochs, each chunk one batch (a
    batch runs until its slowest trial ends, so smaller batches waste fewer steps)."""
    one = np.repeat(np.arange(len(polys)), trials_per_object)
    out = []
    for start in range(0, epochs, CURVE_CHUNK):
        k = min(CURVE_CHUNK, epochs - start)
        r = run_trials(polys, np.tile(one, k), composer, rng, batch=batch)
        out.append(1.0 - r.success.reshape(k, one.size).mean(axis=1))
    return np.concatenate(out)


def _table(
    rows_by: dict[str, dict[str, dict]], paper: dict[str, dict[str, float]], names: Sequence[str]
) -> list[str]:
    keys = list(rows_by)
    head = "| Object | " + " | ".join(f"{CONTROLLER_LABELS[k]} ours / paper" for k in keys) + " |"
    lines = [head, "|---|" + "---:|" * len(keys)]
    for n in names:
        cells = [f"{rows_by[k][n]['failure']:.2f} / {paper[k][n]:.2f}" for k in keys]
        lines.append(f"| {PAPER_LABELS[n]} | " + " | ".join(cells) + " |")
    avg = [
        f"**{np.mean([rows_by[k][n]['failure'] for n in names]):.2f}** / "
        f"{PAPER_TABLE2_AVERAGE[k]:.2f}"
        for k in keys
    ]
    lines.append("| Average | " + " | ".join(avg) + " |")
    return lines


def reproduce(
    out: Path, seed: int = 0, config: ReproduceConfig | None = None, progress: Progress = _stderr
) -> dict:
    """Run every experiment, write the report, results, figures and models into ``out``.

    Returns the results dictionary (also written to ``out/results.json``).
    """
    cfg = config or ReproduceConfig.paper()
    torch.set_num_threads(1)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    mark_started(out, seed)
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    streams = np.random.SeedSequence(seed).spawn(N_STREAMS)
    rngs = [np.random.default_rng(s) for s in streams]
    names = list(PAPER_OBJECTS)
    polys = [paper_object(n) for n in names]
    batch = PolygonBatch.of(polys)
    res: dict = {"seed": seed, "config": asdict(cfg), "gain": GAIN}

    def clock(key: str, t0: float) -> None:
        timings[key] = round(time.perf_counter() - t0, 2)
        progress(f"[reproduce] {key} done in {timings[key]:.1f} s")

    # 1. Q-learning composition (section 3.6.2).
    t0 = time.perf_counter()
    every = max(1, cfg.ql_epochs // 10)

    def ql_progress(e: int, f: float) -> None:
        if (e + 1) % every == 0:
            progress(
                f"[reproduce] Q-learning epoch {e + 1}/{cfg.ql_epochs}: failure {100 * f:.1f} %"
            )

    ql = train_qlearning(rngs[0], polys, cfg.ql_epochs, cfg.trials_per_object, progress=ql_progress)
    save_q_table(ql.q, out / QL_MODEL_FILE)
    clock("qlearning", t0)

    # 2. F/S predictors (section 4.3): all nine objects (c) and the five-object subset (d).
    t0 = time.perf_counter()
    pred = train_predictor(rngs[1], polys, cfg.predictor_epochs, cfg.trials_per_object)
    five = [paper_object(n) for n in FIVE_OBJECTS]
    pred5 = train_predictor(rngs[2], five, cfg.predictor_epochs, cfg.trials_per_object)
    meta = {"objects": list(pred.objects), "epochs": cfg.predictor_epochs, "seed": seed}
    pred.predictor.save(out / PI_MODEL_FILE, meta)
    pred5.predictor.save(out / PI_SUBSET_MODEL_FILE, {**meta, "objects": list(pred5.objects)})
    clock("predictors", t0)

    # 3. Tables 1 and 2: every controller from the same initial contacts.
    t0 = time.perf_counter()
    idx = np.repeat(np.arange(len(polys)), cfg.test_trials)
    theta0 = rngs[3].uniform(0.0, 2.0 * np.pi, size=(idx.size, N_CONTACTS))
    composers: dict[str, Composer] = {
        "kb": KnowledgeBased(),
        "ql": QLearningComposer(q=ql.q.copy()),
        "pi": PreImaging(pred.predictor),
        "pi5": PreImaging(pred5.predictor),
    }
    results: dict[str, TrialBatch] = {}
    rows: dict[str, dict[str, dict]] = {}
    for key, comp in composers.items():
        results[key] = run_trials(
            polys,
            idx,
            comp,
            np.random.default_rng(streams[4]),
            theta_initial=theta0,
            batch=batch,
        )
        rows[key] = object_rows(results[key], names)
        progress(
            f"[reproduce] {CONTROLLER_LABELS[key]}: average failure "
            f"{np.mean([r['failure'] for r in rows[key].values()]):.2f} %"
        )
    res["table2"] = {
        k: {
            "rows": v,
            "average_failure": float(np.mean([r["failure"] for r in v.values()])),
            "mean_s_g": mean_score(v),
        }
        for k, v in rows.items()
    }
    clock("tables", t0)

    # 4. Sensitivity of PI to the pre-image noise gain.
    t0 = time.perf_counter()
    sweep = {}
    for g in NOISE_GAINS if cfg.noise_sweep else (1.0, PREIMAGE_NOISE_GAIN):
        r = run_trials(
            polys,
            idx,
            PreImaging(pred.predictor, noise_gain=g),
            np.random.default_rng(streams[4]),
            theta_initial=theta0,
            batch=batch,
        )
        rr = object_rows(r, names)
        sweep[str(g)] = {
            "average_failure": float(np.mean([x["failure"] for x in rr.values()])),
            "mean_s_g": mean_score(rr),
            "per_object": {n: x["failure"] for n, x in rr.items()},
        }
    res["noise_gain_sweep"] = sweep
    clock("noise_sweep", t0)

    # 5. Learning curves (Figure 9): KB and PI do not learn (PI after its 10 training epochs).
    t0 = time.perf_counter()
    e_pi = max(cfg.curve_epochs - cfg.predictor_epochs, 1)
    tpo = cfg.trials_per_object
    kb_curve = failure_curve(polys, batch, KnowledgeBased(), rngs[5], cfg.curve_epochs, tpo)
    pi_rest = failure_curve(polys, batch, PreImaging(pred.predictor), rngs[6], e_pi, tpo)
    pi_curve = np.concatenate([pred.failure_per_epoch, pi_rest])
    res["curves"] = {
        "ql": ql.failure_per_epoch.tolist(),
        "kb": kb_curve.tolist(),
        "pi": pi_curve.tolist(),
        "ql_temperature": ql.temperature.tolist(),
    }
    clock("curves", t0)

    # 6. Section 2: atomic actions on the irregular triangle.
    t0 = time.perf_counter()
    tri = paper_object("irregular_triangle")
    ev = max(1, cfg.atomic_epochs // 5)
    atomic = train_atomic(
        tri,
        rngs[7],
        cfg.atomic_epochs,
        cfg.atomic_trials,
        ScoreTable(tri),
        progress=lambda e, f: (
            progress(
                f"[reproduce] atomic epoch {e + 1}/{cfg.atomic_epochs}: failure {100 * f:.1f} %"
            )
            if (e + 1) % ev == 0
            else None
        ),
    )
    save_atomic_q(atomic.q, out / ATOMIC_MODEL_FILE)
    tests = [
        evaluate_atomic(
            atomic.q,
            tri,
            np.random.default_rng(streams[8]),
            rot,
            cfg.atomic_test_trials,
            label,
        )
        for label, rot in (("trained", 0.0), ("rotated", TEST_ROTATION_DEG))
    ]
    res["section2"] = {
        t.label: {
            "failure": 100.0 * t.failure_rate,
            "configurations": t.configurations,
            "satisfactory": t.satisfactory,
            "most_frequent": [
                {"sectors": list(c), "count": n, "s_g": s} for c, n, s in t.most_frequent
            ],
            "most_frequent_failures": [
                {"sectors": list(c), "count": n, "s_g": s} for c, n, s in t.most_frequent_failures
            ],
        }
        for t in tests
    }
    res["section2"]["curve"] = atomic.failure_per_epoch.tolist()
    clock("section2", t0)

    # 7. Appendix A.
    t0 = time.perf_counter()
    opt = solve_time_optimal()
    res["appendix_a"] = {
        "theta_T": opt.theta_final,
        "paper_theta_T": PAPER_THETA_T,
        "error": abs(opt.theta_final - PAPER_THETA_T),
        "T": float(opt.t[-1]),
        "switches": opt.switches,
        "converged": opt.converged,
    }
    clock("appendix_a", t0)

    # 8. Random convex polygons (generalization of PI).
    t0 = time.perf_counter()
    rand = [random_convex_polygon(rngs[9]) for _ in range(cfg.random_polygons)]
    r_idx = np.repeat(np.arange(len(rand)), cfg.random_trials)
    r_theta = rngs[9].uniform(0.0, 2.0 * np.pi, size=(r_idx.size, N_CONTACTS))
    rbatch = PolygonBatch.of(rand)
    rand_res = {}
    for key in ("kb", "pi"):
        r = run_trials(
            rand,
            r_idx,
            composers[key],
            np.random.default_rng(streams[12]),
            theta_initial=r_theta,
            batch=rbatch,
        )
        feas = r.s_g[r.feasible]
        rand_res[key] = {"failure": 100.0 * r.failure_rate, "mean_s_g": float(feas.mean())}
    sides = Counter(p.n_edges for p in rand)
    res["random_polygons"] = {
        **rand_res,
        "polygons": len(rand),
        "trials_per_polygon": cfg.random_trials,
        "sides": {str(k): sides[k] for k in sorted(sides)},
    }
    clock("random_polygons", t0)

    # 9. Figures and the report.
    t0 = time.perf_counter()
    _figures(out, polys, names, ql, pred, results, atomic, tests, tri, opt, res, cfg, streams)
    res["paper"] = {
        "table1_kb": PAPER_TABLE1_KB,
        "table1_ql": PAPER_TABLE1_QL,
        "table2_pi_all": PAPER_TABLE2_PI_ALL,
        "table2_pi_five": PAPER_TABLE2_PI_FIVE,
        "averages": PAPER_TABLE2_AVERAGE,
        "mean_s_g": PAPER_MEAN_SG,
        "section2": PAPER_ATOMIC,
        "appendix_a_theta_T": PAPER_THETA_T,
    }
    write_text(out / "report.md", _report(res, names, cfg))
    clock("figures_report", t0)
    timings["total"] = round(time.perf_counter() - t_all, 2)
    write_text(out / "timings.json", json.dumps(timings, indent=1) + "\n")
    res["run"] = finished_mark(out, seed, MODEL_FILES)
    write_results(out, res)  # last: marks the run finished
    progress(f"[reproduce] all done in {timings['total']:.1f} s; report: {out / 'report.md'}")
    return res


def _figures(
    out, polys, names, ql, pred, results, atomic, tests, tri, opt, res, cfg, streams
) -> None:
    sm = fig.moving_average
    ep = np.arange(1, cfg.ql_epochs + 1)
    fig.save_png(
        out / "fig01_atomic_learning.png",
        fig.line_plot(
            [
                fig.Series(
                    "atomic Q-learning (irregular triangle)",
                    np.arange(1, cfg.atomic_epochs + 1),
                    100 * sm(atomic.failure_per_epoch),
                )
            ],
            "Figure 1: failure rate during training (10-epoch smoothing)",
            "epoch",
            "failure rate (%)",
            ylim=(0, 100 * max(0.05, float(sm(atomic.failure_per_epoch).max()) * 1.1)),
        ),
    )
    fig.save_png(
        out / "fig07_ql_learning.png",
        fig.line_plot(
            [fig.Series("Q-learning composition, 9 objects", ep, 100 * sm(ql.failure_per_epoch))],
            "Figure 7: failure rate during training (10-epoch smoothing)",
            "epoch",
            "failure rate (%)",
            hlines=[(PAPER_TABLE1_AVERAGE["ql"], "paper QL test 8.33 %")],
        ),
    )
    c = res["curves"]
    fig.save_png(
        out / "fig09_failure_curves.png",
        fig.line_plot(
            [
                fig.Series(
                    "(a) PI (predictor used after epoch 10)",
                    np.arange(1, len(c["pi"]) + 1),
                    100 * sm(np.array(c["pi"])),
                ),
                fig.Series(
                    "(b) knowledge-based",
                    np.arange(1, len(c["kb"]) + 1),
                    100 * sm(np.array(c["kb"])),
                ),
                fig.Series("(c) Q-learning", ep, 100 * sm(ql.failure_per_epoch)),
            ],
            "Figure 9: failure rate per epoch (10-epoch smoothing)",
            "epoch",
            "failure rate (%)",
        ),
    )
    _figure10_11(out, polys, names, pred.predictor, cfg, streams)
    _figure12(out, polys, names, results)
    trained, rotated = tests
    unit_t = tri.unit_moment()
    unit_r = tri.rotated(np.deg2rad(TEST_ROTATION_DEG)).unit_moment()
    rows = [(trained, unit_t, trained.most_frequent), (rotated, unit_r, rotated.most_frequent),
            (rotated, unit_r, rotated.most_frequent_failures)]  # fmt: skip
    panels = []
    for t, unit, configs in rows:
        row = [
            fig.grasp_panel(
                unit,
                unit.point_at(sector_angle(np.array(sectors))),
                f"{t.label}: {n}x, " + (f"S_G {s:.2f}" if np.isfinite(s) else "infeasible"),
                good=s <= SUCCESS_THRESHOLD,
            )
            for sectors, n, s in configs
        ]
        panels += row + [np.full((220, 190, 3), 255, np.uint8)] * (4 - len(row))
    fig.save_png(
        out / "fig02_atomic_configurations.png",
        fig.grid_of(
            panels,
            4,
            "Figure 2: as trained; rotated 30 deg, satisfactory; rotated, unsatisfactory",
        ),
    )
    fig.save_png(
        out / "fig17_theta.png",
        fig.line_plot(
            [fig.Series("theta(t)", opt.t, opt.theta)],
            f"Figure 17: theta(t), theta(T) = {opt.theta_final:.4f} rad (paper 3.6052)",
            "t",
            "theta (rad)",
            hlines=[(PAPER_THETA_T, "3.6052")],
        ),
    )
    plot = fig.line_plot(
        [fig.Series("alpha (1: FC, 0: MC)", opt.t, opt.alpha, step=True)],
        "Figure 18: time-optimal activation",
        "t",
        "alpha",
        ylim=(-0.1, 1.1),
    )
    inset = fig.square_activation_inset(opt.theta, opt.alpha, BETA)
    fig.save_png(out / "fig18_activation.png", fig.hstack([plot, inset]))


def _figure10_11(out, polys, names, predictor: FSPredictor, cfg, streams) -> None:
    """Figure 10 (KB vs PI paths from one start on the square) and Figure 11 (F/S map, visits)."""
    sq = names.index("square")
    n = max(cfg.test_trials, FIGURE10_TRIALS)
    theta0 = np.random.default_rng(streams[10]).uniform(0, 2 * np.pi, (n, N_CONTACTS))
    idx = np.full(n, sq)
    kb = run_trials(
        polys,
        idx,
        KnowledgeBased(),
        np.random.default_rng(streams[11]),
        theta_initial=theta0,
        record_states=True,
    )
    pi = run_trials(
        polys,
        idx,
        PreImaging(predictor),
        np.random.default_rng(streams[11]),
        theta_initial=theta0,
        record_states=True,
    )
    fs = predictor.fs_map()
    both = np.flatnonzero(~kb.success & pi.success)
    j = int(both[0]) if both.size else 0

    def path(r: TrialBatch) -> NDArray[np.float64]:
        s = r.states[j]
        s = s[np.isfinite(s[:, 0])]
        return np.stack([scaled_error(s[:, 0]), scaled_error(s[:, 1])], axis=1)

    tag = {True: "success", False: "fail"}
    m10 = fig.state_heatmap(
        fs,
        "Figure 10: paths on the square over the F/S map",
        -1,
        1,
        paths=[
            (f"KB: {tag[bool(kb.success[j])]}", path(kb)),
            (f"PI: {tag[bool(pi.success[j])]}", path(pi)),
        ],
        colorbar=("success", "failure"),
    )
    unit = polys[sq].unit_moment()
    start = unit.point_at(theta0[j])
    cfgs = [
        fig.grasp_panel(
            unit, r.points[j], f"{k}: S_G {r.s_g[j]:.2f}", start=start, good=bool(r.success[j])
        )
        for k, r in (("KB", kb), ("PI", pi))
    ]
    fig.save_png(out / "fig10_state_paths.png", fig.hstack([m10, fig.grid_of(cfgs, 1)]))

    def visits(r: TrialBatch) -> NDArray[np.float64]:
        s = r.states[np.isfinite(r.states[..., 0])]
        h = np.zeros((30, 30))
        np.add.at(h, (state_bin(s[:, 0]), state_bin(s[:, 1])), 1.0)
        return np.log10(1.0 + 1e4 * h / h.sum())

    a = fig.state_heatmap(fs, "(a) F/S predictor output", -1, 1, colorbar=("success", "failure"))
    b = fig.state_heatmap(
        visits(kb),
        f"(b) KB visits, square ({100 * kb.failure_rate:.0f}% fail)",
        colorbar=("rare", "log freq"),
    )
    c = fig.state_heatmap(
        visits(pi),
        f"(c) PI visits, square ({100 * pi.failure_rate:.0f}% fail)",
        colorbar=("rare", "log freq"),
    )
    att = []
    for ok in (False, True):
        k = np.flatnonzero(kb.success == ok)
        if k.size:
            att.append(
                fig.grasp_panel(
                    unit,
                    kb.points[k[0]],
                    f"KB {'success' if ok else 'failure'} S_G {kb.s_g[k[0]]:.2f}",
                    good=ok,
                )
            )
    fig.save_png(
        out / "fig11_fs_map_visits.png", fig.grid_of([a, b, c, fig.grid_of(att, 1)], 4, "Figure 11")
    )


def _figure12(out, polys, names, results: dict[str, TrialBatch]) -> None:
    """Figure 12: the two most frequent configurations per object for KB, QL and PI."""
    panels = []
    for i in range(len(polys)):
        unit = polys[i].unit_moment()
        for key in ("kb", "ql", "pi"):
            tops = configurations(polys, results[key], i, 2)
            for k in range(2):
                if k < len(tops):
                    pts, frac, s = tops[k]
                    panels.append(
                        fig.grasp_panel(
                            unit,
                            pts,
                            f"{key} {100 * frac:.0f}% S_G {s:.2f}",
                            size=150,
                            good=s <= 0.4,
                        )
                    )
                else:
                    panels.append(np.full((180, 150, 3), 255, np.uint8))
    fig.save_png(
        out / "fig12_configurations.png",
        fig.grid_of(
            panels, 6, "Figure 12: most frequent configurations per object (rows): KB | QL | PI"
        ),
    )


def _report(res: dict, names: Sequence[str], cfg: ReproduceConfig) -> str:
    t2 = res["table2"]
    rp = res["random_polygons"]
    paper = {
        "kb": PAPER_TABLE1_KB,
        "ql": PAPER_TABLE1_QL,
        "pi": PAPER_TABLE2_PI_ALL,
        "pi5": PAPER_TABLE2_PI_FIVE,
    }
    rows = {k: t2[k]["rows"] for k in CONTROLLERS}
    lines = [
        "# Coelho & Grupen, reproduced: learning-derived composition and pre-imaging",
        "",
        f"Seed {res['seed']}{QUICK_NOTE if cfg.quick else ''}; "
        f"{cfg.test_trials} test trials per object; gain {res['gain']}. Failure rates in %, "
        "ours / paper. Generated by `python -m controllers.grasp reproduce`.",
        "",
        "## Table 1: knowledge-based and Q-learning composition",
        "",
        *_table({k: rows[k] for k in ("kb", "ql")}, paper, names),
        "",
        "## Table 2: adding the PI controller, trained on all nine objects (c) and on five (d)",
        "",
        *_table(rows, paper, names),
        "",
        "## Mean grasp score S_G-bar (section 4.5)",
        "",
        "| Controller | ours | paper |",
        "|---|---:|---:|",
        *[
            f"| {CONTROLLER_LABELS[k]} | {t2[k]['mean_s_g']:.3f} | "
            f"{f'{PAPER_MEAN_SG[k]:.3f}' if k in PAPER_MEAN_SG else '-'} |"
            for k in CONTROLLERS
        ],
        "",
        "## Pre-image noise gain (our choice; 1 = the paper's noise taken literally as radians)",
        "",
        "| noise gain | sigma on theta (rad) | PI (c) average failure | S_G-bar |",
        "|---:|---:|---:|---:|",
        *[
            f"| {float(g):g} | {float(g) * NOISE_SIGMA:.4f} (bound {float(g) * NOISE_BOUND:.2f}) | "
            f"{v['average_failure']:.2f} | {v['mean_s_g']:.3f} |"
            for g, v in res["noise_gain_sweep"].items()
        ],
        "",
        "## Section 2: atomic actions on the irregular triangle",
        "",
        "| test | failure ours / paper | configurations ours / paper | satisfactory ours / paper |",
        "|---|---:|---:|---:|",
        *[
            f"| {k} | {res['section2'][k]['failure']:.1f} / {PAPER_ATOMIC[k]['failure']:.1f} | "
            f"{res['section2'][k]['configurations']} / {PAPER_ATOMIC[k]['configurations']} | "
            f"{res['section2'][k]['satisfactory']} / {PAPER_ATOMIC[k]['satisfactory']} |"
            for k in ("trained", "rotated")
        ],
        "",
        "## Appendix A: time-optimal activation",
        "",
        f"theta(T) = {res['appendix_a']['theta_T']:.5f} rad (paper {PAPER_THETA_T}); "
        f"|difference| = {res['appendix_a']['error']:.5f} rad; T = {res['appendix_a']['T']:.2f}, "
        f"{res['appendix_a']['switches']} switches.",
        "",
        "## Random convex polygons (never seen in training)",
        "",
        f"{rp['polygons']} polygons (sides: {rp['sides']}), "
        f"{res['random_polygons']['trials_per_polygon']} trials each, same initial contacts: "
        f"knowledge-based {res['random_polygons']['kb']['failure']:.2f} % failure "
        f"(mean S_G {res['random_polygons']['kb']['mean_s_g']:.3f}), "
        f"PI {res['random_polygons']['pi']['failure']:.2f} % "
        f"(mean S_G {res['random_polygons']['pi']['mean_s_g']:.3f}).",
        "",
        "## Figures",
        "",
        *[
            f"- `{p}`"
            for p in (
                "fig01_atomic_learning.png",
                "fig02_atomic_configurations.png",
                "fig07_ql_learning.png",
                "fig09_failure_curves.png",
                "fig10_state_paths.png",
                "fig11_fs_map_visits.png",
                "fig12_configurations.png",
                "fig17_theta.png",
                "fig18_activation.png",
            )
        ],
        "",
        f"Models: `{QL_MODEL_FILE}`, `{PI_MODEL_FILE}`, `{PI_SUBSET_MODEL_FILE}`, "
        f"`{ATOMIC_MODEL_FILE}` "
        "(use with `python -m controllers.grasp trials --controller ql|pi --models DIR`).",
        "",
    ]
    return "\n".join(lines)
