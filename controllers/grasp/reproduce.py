"""``python -m controllers.grasp reproduce --out DIR``: every experiment of the paper in one run.

For each seed (default 0, 1, 2) it trains the Q-learning composer (section 3.6.2), the F/S
predictors of the PI controller on the nine objects and on the five-object subset (section 4.3),
a general F/S predictor on random convex polygons (beyond the paper), the atomic-action controller
(section 2), and tests them: Tables 1 and 2, every reading of the pre-image noise, polygons never
seen in training. Appendix A is solved once. Tables are reported as mean and standard deviation
over the seeds (``report.md``, ``results.json``); figures and models come from the first seed.

The work is cut into independent tasks (one experiment of one seed each) run by a pool of
``workers`` processes (spawn context); results are assembled in a fixed order, so the outputs do
not depend on the pool. Wall-clock times go to ``timings.json`` and the run's provenance (command,
commit, date) to ``provenance.json``; with the same seeds every other file is byte-identical.
Every file is written atomically; ``results.json`` is written last and marks the run finished
(:mod:`controllers.grasp.run_folder`), so ``trials --models DIR`` refuses an interrupted run.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import multiprocessing
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch

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
    train_atomic,
)
from controllers.grasp.composition import Composer, KnowledgeBased
from controllers.grasp.experiments import (
    FAMILY_TRIALS,
    PAPER_TABLE1_KB,
    PAPER_TABLE1_QL,
    TrialSet,
    average_failure,
    object_rows,
    over_seeds,
    trial_set,
)
from controllers.grasp.experiments import TEST_TRIALS as TABLE_TRIALS
from controllers.grasp.files import write_text
from controllers.grasp.objects import (
    FAMILY_SIZE,
    PAPER_OBJECTS,
    ObjectSet,
    paper_object,
    polygon_set,
    polygon_set_seeds,
)
from controllers.grasp.optimal_control import PAPER_THETA_T, solve_time_optimal
from controllers.grasp.predictor import PREDICTOR_EPOCHS, train_predictor
from controllers.grasp.preimaging import (
    NOISE_READINGS,
    PI_GENERAL_MODEL_FILE,
    PI_MODEL_FILE,
    PI_SUBSET_MODEL_FILE,
    PreImaging,
)
from controllers.grasp.qlearning import (
    EPOCHS,
    QL_MODEL_FILE,
    TRIALS_PER_OBJECT,
    QLearningComposer,
    save_q_table,
    train_qlearning,
)
from controllers.grasp.run_folder import finished_mark, mark_started, write_results
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
#: Seeds of a default run: tables are means and standard deviations over them.
DEFAULT_SEEDS: tuple[int, ...] = (0, 1, 2)
#: Epochs per batch when running the (non-learning) KB and PI failure curves.
CURVE_CHUNK = 10
#: How often the parent looks at the pool's tasks (s); it stays responsive to Ctrl-C.
POLL_SECONDS = 0.2
#: Trials on the square for Figures 10 and 11.
FIGURE10_TRIALS = 200
#: Noise scales of the sensitivity sweep (literal reading; 1 = the paper's noise as radians).
NOISE_SCALES: tuple[float, ...] = (2.0, 4.0, 6.0)
#: The general PI controller (beyond the paper): F/S predictor trained on random convex polygons
#: (``polygon_set("train")``), noise read as a fraction of a turn, failure predicted when the
#: output exceeds -0.5. Reading and threshold were chosen on the "validation" polygons (never on
#: the held-out ones) over seeds 0-2, among {literal, turn, perimeter} x {0, -0.25, -0.5, -0.75};
#: every run reports the untuned setting (turn, threshold 0) beside it.
GENERAL_SETTINGS = {"reading": "turn", "threshold": -0.5}
#: Knowledge-based training trials per epoch of the general predictor (each on a new polygon).
GENERAL_TRIALS_PER_EPOCH = 90
#: Independent random streams of one seed (SeedSequence children), each used for one purpose.
STREAMS = {
    name: i
    for i, name in enumerate(
        (
            "ql", "pi9", "pi5", "test", "test_noise", "kb_curve", "pi_curve", "atomic",
            "atomic_test", "general", "fig10", "fig10_noise", "heldout", "heldout_noise",
            "validation", "validation_noise",
        )
    )
}  # fmt: skip
CONTROLLER_LABELS = {
    "kb": "Knowledge-based (a)",
    "ql": "Q-learning (b)",
    "pi": "PI, 9 objects (c)",
    "pi5": "PI, 5 objects (d)",
}
Progress = Callable[[str], None]


@dataclass(frozen=True)
class ReproduceConfig:
    """Experiment sizes; :meth:`paper` is the paper's, :meth:`quick_run` a reduced one for CI."""

    seeds: tuple[int, ...] = DEFAULT_SEEDS
    workers: int = 2
    ql_epochs: int = EPOCHS
    trials_per_object: int = TRIALS_PER_OBJECT
    predictor_epochs: int = PREDICTOR_EPOCHS
    test_trials: int = TABLE_TRIALS
    family_size: int = FAMILY_SIZE
    family_trials: int = FAMILY_TRIALS
    curve_epochs: int = EPOCHS
    atomic_epochs: int = ATOMIC_EPOCHS
    atomic_trials: int = ATOMIC_TRIALS
    atomic_test_trials: int = TEST_TRIALS
    general_trials: int = GENERAL_TRIALS_PER_EPOCH
    validation_polygons: int = 300
    heldout_polygons: int = 200
    heldout_trials: int = 10
    noise_sweep: bool = True
    validation_sweep: bool = True
    quick: bool = False
    command: str = field(default="", compare=False)

    @classmethod
    def paper(cls, **kwargs) -> ReproduceConfig:
        return cls(**kwargs)

    @classmethod
    def quick_run(cls, **kwargs) -> ReproduceConfig:
        small = dict(
            seeds=(0,),
            ql_epochs=30,
            predictor_epochs=4,
            test_trials=40,
            family_size=3,
            family_trials=10,
            curve_epochs=20,
            atomic_epochs=30,
            atomic_trials=60,
            atomic_test_trials=60,
            general_trials=30,
            validation_polygons=20,
            heldout_polygons=30,
            heldout_trials=4,
            noise_sweep=False,
            validation_sweep=False,
            quick=True,
        )
        return cls(**{**small, **kwargs})


def _streams(seed: int) -> dict[str, np.random.SeedSequence]:
    children = np.random.SeedSequence(seed).spawn(len(STREAMS))
    return {name: children[i] for name, i in STREAMS.items()}


def _rng(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng(_streams(seed)[name])


def _objects(cfg: ReproduceConfig, names: Sequence[str] = PAPER_OBJECTS) -> ObjectSet:
    return ObjectSet.paper(names, cfg.family_size)


def _tables_set(cfg: ReproduceConfig, seed: int) -> TrialSet:
    return trial_set(_objects(cfg), _rng(seed, "test"), cfg.test_trials, cfg.family_trials)


def _nine(cfg: ReproduceConfig, seed: int):
    return train_predictor(
        _rng(seed, "pi9"), _objects(cfg), cfg.predictor_epochs, cfg.trials_per_object
    )


def _representative(result: TrialBatch, ts: TrialSet) -> dict:
    """The trials on each object's member 0 (for Figure 12), as plain arrays."""
    keep = np.isin(ts.polygon_index, ts.objects.first)
    return {
        "object": ts.object_index[keep],
        "theta": result.theta_final[keep],
        "s_g": result.s_g[keep],
    }


# --- tasks: one experiment of one seed each; run in worker processes ---------------------------
def task_ql(cfg: ReproduceConfig, seed: int) -> dict:
    """Section 3.6.2: train Q-learning, test it greedily (Table 1 and 2, column (b))."""
    ql = train_qlearning(_rng(seed, "ql"), _objects(cfg), cfg.ql_epochs, cfg.trials_per_object)
    ts = _tables_set(cfg, seed)
    r = ts.run(QLearningComposer(q=ql.q.copy()), _rng(seed, "test_noise"))
    return {
        "q": ql.q,
        "curve": ql.failure_per_epoch,
        "temperature": ql.temperature,
        "rows": {"ql": object_rows(r, ts)},
        "fig12": {"ql": _representative(r, ts)},
    }


def task_tables(cfg: ReproduceConfig, seed: int) -> dict:
    """Section 4.3-4.4: train the nine- and five-object predictors; test KB and PI (c), (d) with
    the literal noise, PI (c) with every other reading and the noise sweep, and PI (c) with a
    predictor trained on each epoch's states only (the other reading of the training set)."""
    pred = _nine(cfg, seed)
    last = train_predictor(
        _rng(seed, "pi9"), _objects(cfg), cfg.predictor_epochs, cfg.trials_per_object,
        cumulative=False,
    )  # fmt: skip
    five = _objects(cfg, FIVE_OBJECTS)
    pred5 = train_predictor(_rng(seed, "pi5"), five, cfg.predictor_epochs, cfg.trials_per_object)
    ts = _tables_set(cfg, seed)
    comps: dict[str, Composer] = {
        "kb": KnowledgeBased(),
        "pi": PreImaging(pred.predictor),
        "pi5": PreImaging(pred5.predictor),
        "pi_last_epoch": PreImaging(last.predictor),
    }
    for reading in NOISE_READINGS:
        if reading != "literal":
            comps[f"pi_{reading}"] = PreImaging(pred.predictor, reading=reading)
    for scale in NOISE_SCALES if cfg.noise_sweep else ():
        comps[f"pi_x{scale:g}"] = PreImaging(pred.predictor, noise_scale=scale)
    rows, fig12 = {}, {}
    for key, comp in comps.items():
        r = ts.run(comp, _rng(seed, "test_noise"))
        rows[key] = object_rows(r, ts)
        if key in ("kb", "pi"):
            fig12[key] = _representative(r, ts)
    return {
        "predictor": pred.predictor,
        "predictor5": pred5.predictor,
        "predictor_curve": pred.failure_per_epoch,
        "rows": rows,
        "fig12": fig12,
    }


def general_training_set(cfg: ReproduceConfig) -> ObjectSet:
    """The general predictor's training polygons: one family of ``predictor_epochs *
    general_trials`` random convex polygons from the "train" seeds (each trial a new polygon)."""
    n = cfg.predictor_epochs * cfg.general_trials
    return ObjectSet(("random",), (tuple(polygon_set("train", n)),))


def task_general(cfg: ReproduceConfig, seed: int) -> dict:
    """Beyond the paper: train the general predictor on random polygons; test KB, nine-object PI
    and general PI (and the predictor-gradient action) on validation and held-out polygons."""
    nine = _nine(cfg, seed).predictor
    train = general_training_set(cfg)
    gen = train_predictor(
        _rng(seed, "general"), train, cfg.predictor_epochs, cfg.general_trials
    ).predictor
    out: dict = {"predictor": gen, "validation": {}, "heldout": {}}
    for kind, count, trials in (
        ("validation", cfg.validation_polygons, cfg.heldout_trials),
        ("heldout", cfg.heldout_polygons, cfg.heldout_trials),
    ):
        polys = polygon_set(kind, count)
        objects = ObjectSet((kind,), (tuple(polys),))
        ts = trial_set(objects, _rng(seed, kind), trials_per_member=trials)
        comps: dict[str, Composer] = {"kb": KnowledgeBased()}
        if kind == "heldout":
            comps["nine_literal"] = PreImaging(nine)
            comps["nine_turn"] = PreImaging(nine, reading="turn")
            comps["general_literal"] = PreImaging(gen)
            comps["general_predictor_action"] = PreImaging(gen, action="predictor")
        sweep = kind == "validation" and cfg.validation_sweep
        for reading in ("literal", "turn", "perimeter") if sweep else ("turn",):
            for th in (0.0, -0.25, -0.5, -0.75) if sweep else (0.0,):
                comps[f"general_{reading}_{th:g}"] = PreImaging(gen, reading=reading, threshold=th)
        comps["general"] = PreImaging(gen, **GENERAL_SETTINGS)
        for key, comp in comps.items():
            r = ts.run(comp, _rng(seed, f"{kind}_noise"))
            feas = r.s_g[r.feasible]
            fail = ~r.success
            out[kind][key] = {
                "failure": 100.0 * float(fail.mean()),
                "mean_s_g": float(feas.mean()) if feas.size else float("nan"),
                "failed_converged": int((fail & r.converged).sum()),
                "failed_unconverged": int((fail & ~r.converged).sum()),
                "mean_steps": float(r.steps.mean()),
            }
    return out


def task_atomic(cfg: ReproduceConfig, seed: int) -> dict:
    """Section 2: atomic actions on the irregular triangle, tested as trained and rotated."""
    tri = paper_object("irregular_triangle")
    atomic = train_atomic(
        tri, _rng(seed, "atomic"), cfg.atomic_epochs, cfg.atomic_trials, ScoreTable(tri)
    )
    tests = [
        evaluate_atomic(
            atomic.q, tri, _rng(seed, "atomic_test"), rot, cfg.atomic_test_trials, label
        )
        for label, rot in (("trained", 0.0), ("rotated", TEST_ROTATION_DEG))
    ]
    return {"q": atomic.q, "curve": atomic.failure_per_epoch, "tests": tests}


def failure_curve(
    polys: Sequence,
    batch: PolygonBatch,
    composer: Composer,
    rng: np.random.Generator,
    epochs: int,
    trials_per_object: int,
    objects: ObjectSet,
) -> np.ndarray:
    """Failure rate per epoch of a controller that does not learn (Figure 9 (a) after the predictor
    is trained, (b)); epochs run CURVE_CHUNK at a time, each chunk one batch."""
    from controllers.grasp.qlearning import epoch_objects, epoch_trials

    obj = epoch_objects(len(objects.names), trials_per_object, rng)
    out = []
    for start in range(0, epochs, CURVE_CHUNK):
        k = min(CURVE_CHUNK, epochs - start)
        idx = np.concatenate([epoch_trials(objects, obj, start + e, trials_per_object)
                              for e in range(k)])  # fmt: skip
        r = run_trials(polys, idx, composer, rng, batch=batch)
        out.append(1.0 - r.success.reshape(k, obj.size).mean(axis=1))
    return np.concatenate(out)


def task_curves(cfg: ReproduceConfig, seed: int) -> dict:
    """Figures 9, 10 and 11 (first seed only): KB and PI failure curves, and KB and PI paths on
    the square from the same initial contacts."""
    objects = _objects(cfg)
    polys = objects.polygons
    batch = PolygonBatch.of(polys)
    pred = _nine(cfg, seed)
    e_pi = max(cfg.curve_epochs - cfg.predictor_epochs, 1)
    tpo = cfg.trials_per_object
    kb = failure_curve(
        polys, batch, KnowledgeBased(), _rng(seed, "kb_curve"), cfg.curve_epochs, tpo, objects
    )
    pi = failure_curve(
        polys, batch, PreImaging(pred.predictor), _rng(seed, "pi_curve"), e_pi, tpo, objects
    )
    square = [paper_object("square")]
    theta0 = _rng(seed, "fig10").uniform(0, 2 * np.pi, (FIGURE10_TRIALS, N_CONTACTS))
    idx = np.zeros(FIGURE10_TRIALS, dtype=np.int64)
    runs = {
        key: run_trials(
            square, idx, comp, _rng(seed, "fig10_noise"), theta_initial=theta0, record_states=True
        )
        for key, comp in (("kb", KnowledgeBased()), ("pi", PreImaging(pred.predictor)))
    }
    return {
        "kb": kb,
        "pi": np.concatenate([pred.failure_per_epoch, pi]),
        "square": runs,
        "square_theta0": theta0,
    }


TASKS: dict[str, Callable[[ReproduceConfig, int], dict]] = {
    "qlearning": task_ql,
    "tables": task_tables,
    "general": task_general,
    "curves": task_curves,
    "atomic": task_atomic,
}


def _run_task(name: str, cfg: ReproduceConfig, seed: int) -> tuple[dict, float, float]:
    torch.set_num_threads(1)
    t0, c0 = time.perf_counter(), time.process_time()
    out = TASKS[name](cfg, seed)
    return out, time.perf_counter() - t0, time.process_time() - c0


def _stderr(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def run_tasks(
    cfg: ReproduceConfig, progress: Progress = _stderr
) -> tuple[dict[tuple[str, int], dict], dict[str, float]]:
    """Every task of the run, longest first, on ``cfg.workers`` processes (in this process when
    1). Returns results keyed by (task, seed) and each task's wall and CPU seconds (the CPU
    seconds, unlike the wall ones, do not grow when other jobs share the cores)."""
    # longest first (CPU seconds of a full run: tables ~100, curves ~80, qlearning ~70,
    # general ~60, atomic ~6), so that two workers finish together
    jobs = [("tables", s) for s in cfg.seeds] + [("curves", cfg.seeds[0])]
    jobs += [(name, s) for name in ("qlearning", "general", "atomic") for s in cfg.seeds]
    results: dict[tuple[str, int], dict] = {}
    seconds: dict[str, float] = {}

    def done(job: tuple[str, int], value: tuple[dict, float, float]) -> None:
        results[job], secs, cpu = value
        seconds[f"{job[0]}_seed{job[1]}"] = round(secs, 2)
        seconds[f"{job[0]}_seed{job[1]}_cpu"] = round(cpu, 2)
        progress(f"[reproduce] {job[0]} (seed {job[1]}) done in {secs:.1f} s ({cpu:.1f} s CPU)")

    if cfg.workers <= 1:
        for job in jobs:
            done(job, _run_task(job[0], cfg, job[1]))
        return results, seconds
    ctx = multiprocessing.get_context("spawn")
    pool = ctx.Pool(min(cfg.workers, len(jobs)), initializer=_ignore_sigint)
    try:
        pending = [(job, pool.apply_async(_run_task, (job[0], cfg, job[1]))) for job in jobs]
        while pending:
            ready = [p for p in pending if p[1].ready()]
            for job, res in ready:
                done(job, res.get())
            pending = [p for p in pending if p not in ready]
            if pending and not ready:
                pending[0][1].wait(POLL_SECONDS)
    except BaseException:
        pool.terminate()  # Ctrl-C or a failed task: stop the other workers now
        pool.join()
        raise
    pool.close()
    pool.join()
    return results, seconds


def _ignore_sigint() -> None:
    """In a worker: Ctrl-C goes to the parent alone, which stops the pool (no worker tracebacks)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def git_commit() -> str:
    """The repository's commit (with ``-dirty`` if it has uncommitted changes), or "unknown"."""
    root = Path(__file__).resolve().parents[2]
    git = ["git", "-C", str(root)]
    try:
        head = subprocess.run(
            [*git, "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            [*git, "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("-dirty" if dirty else "")


def source_hash() -> str:
    """SHA-256 of the grasp core's Python sources (file names and bytes, sorted): identifies the
    code that made the models even where a commit was later rewritten."""
    digest = hashlib.sha256()
    for path in sorted(Path(__file__).resolve().parent.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def reproduce(
    out: Path, config: ReproduceConfig | None = None, progress: Progress = _stderr
) -> dict:
    """Run every experiment, write the report, results, figures and models into ``out``.

    Returns the results dictionary (also written to ``out/results.json``).
    """
    from controllers.grasp.paper_figures import write_figures
    from controllers.grasp.report import write_report
    from controllers.grasp.shipped import check_figures

    cfg = config or ReproduceConfig.paper()
    if not cfg.seeds or len(set(cfg.seeds)) != len(cfg.seeds) or min(cfg.seeds) < 0:
        raise ValueError(f"seeds must be distinct non-negative integers, got {cfg.seeds}")
    torch.set_num_threads(1)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    mark_started(out, cfg.seeds[0])
    t_all = time.perf_counter()
    results, timings = run_tasks(cfg, progress)
    seeds = list(cfg.seeds)
    first = seeds[0]
    res: dict = {
        "seeds": seeds,
        "config": {k: v for k, v in asdict(cfg).items() if k not in ("workers", "command")},
        "gain": GAIN,
        "families": {"size": cfg.family_size, "trials_per_member": cfg.family_trials},
    }
    # Tables 1 and 2, readings and sweep: per seed, then over seeds.
    keys = [*results[("tables", first)]["rows"], "ql"]
    per_seed = {
        k: [
            {**results[("tables", s)]["rows"], **results[("qlearning", s)]["rows"]}[k]
            for s in seeds
        ]
        for k in keys
    }
    res["per_seed"] = {k: dict(zip(map(str, seeds), v, strict=True)) for k, v in per_seed.items()}
    res["tables"] = {k: over_seeds(v) for k, v in per_seed.items()}
    gen_keys = {kind: list(results[("general", first)][kind]) for kind in ("validation", "heldout")}
    res["general"] = {
        kind: {
            k: _spread([results[("general", s)][kind][k] for s in seeds]) for k in gen_keys[kind]
        }
        for kind in ("validation", "heldout")
    }
    h = polygon_set_seeds("heldout", cfg.heldout_polygons)
    v = polygon_set_seeds("validation", cfg.validation_polygons)
    t = polygon_set_seeds("train", cfg.predictor_epochs * cfg.general_trials)
    res["general"]["sets"] = {
        "train_seeds": [t.start, t.stop - 1],
        "validation_seeds": [v.start, v.stop - 1],
        "heldout_seeds": [h.start, h.stop - 1],
        "heldout_trials_per_polygon": cfg.heldout_trials,
        "settings": GENERAL_SETTINGS,
    }
    res["section2"] = {
        str(s): {
            tt.label: {
                "failure": 100.0 * tt.failure_rate,
                "configurations": tt.configurations,
                "satisfactory": tt.satisfactory,
            }
            for tt in results[("atomic", s)]["tests"]
        }
        for s in seeds
    }
    opt = solve_time_optimal()
    res["appendix_a"] = {
        "theta_T": opt.theta_final,
        "paper_theta_T": PAPER_THETA_T,
        "error": abs(opt.theta_final - PAPER_THETA_T),
        "T": float(opt.t[-1]),
        "switches": opt.switches,
        "converged": opt.converged,
    }
    res["curves"] = {
        "ql": results[("qlearning", first)]["curve"].tolist(),
        "kb": results[("curves", first)]["kb"].tolist(),
        "pi": results[("curves", first)]["pi"].tolist(),
        "atomic": results[("atomic", first)]["curve"].tolist(),
    }
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
    t0 = time.perf_counter()
    save_models(out, results, first, cfg)
    write_figures(out, results, first, cfg, opt)
    write_text(out / "report.md", write_report(res, cfg))
    checks = check_figures(out)
    write_text(out / "provenance.json", json.dumps(provenance(res, cfg, checks), indent=1) + "\n")
    timings["models_figures_report_checks"] = round(time.perf_counter() - t0, 2)
    timings["total"] = round(time.perf_counter() - t_all, 2)
    timings["tasks_cpu"] = round(sum(v for k, v in timings.items() if k.endswith("_cpu")), 2)
    write_text(out / "timings.json", json.dumps(timings, indent=1) + "\n")
    res["run"] = finished_mark(out, first, MODEL_FILES)
    write_results(out, res)  # last: marks the run finished
    progress(f"[reproduce] all done in {timings['total']:.1f} s; report: {out / 'report.md'}")
    return res


def _spread(values: Sequence[dict]) -> dict:
    f = np.array([v["failure"] for v in values])
    sg = np.array([v["mean_s_g"] for v in values])
    return {
        "failure": {"mean": float(f.mean()), "sd": float(f.std(ddof=1)) if f.size > 1 else 0.0},
        "mean_s_g": float(sg.mean()),
        "failed_converged": int(sum(v["failed_converged"] for v in values)),
        "failed_unconverged": int(sum(v["failed_unconverged"] for v in values)),
        "mean_steps": float(np.mean([v["mean_steps"] for v in values])),
    }


#: Model files written by :func:`save_models` (from the run's first seed).
MODEL_FILES = (
    QL_MODEL_FILE,
    PI_MODEL_FILE,
    PI_SUBSET_MODEL_FILE,
    PI_GENERAL_MODEL_FILE,
    ATOMIC_MODEL_FILE,
)


def save_models(out: Path, results: dict, seed: int, cfg: ReproduceConfig) -> None:
    """The first seed's models: the Q-table, the three F/S predictors (each with the PI settings
    it is meant to be used with) and the atomic-action Q-table."""
    save_q_table(results[("qlearning", seed)]["q"], out / QL_MODEL_FILE)
    tables = results[("tables", seed)]
    meta = {"seed": seed, "epochs": cfg.predictor_epochs, "family_size": cfg.family_size}
    literal = {"reading": "literal", "threshold": 0.0}
    tables["predictor"].save(
        out / PI_MODEL_FILE, {**meta, "objects": list(PAPER_OBJECTS), "settings": literal}
    )
    tables["predictor5"].save(
        out / PI_SUBSET_MODEL_FILE, {**meta, "objects": list(FIVE_OBJECTS), "settings": literal}
    )
    t = polygon_set_seeds("train", cfg.predictor_epochs * cfg.general_trials)
    gen_meta = {**meta, "train_seeds": [t.start, t.stop - 1], "settings": GENERAL_SETTINGS}
    results[("general", seed)]["predictor"].save(out / PI_GENERAL_MODEL_FILE, gen_meta)
    save_atomic_q(results[("atomic", seed)]["q"], out / ATOMIC_MODEL_FILE)


def provenance(res: dict, cfg: ReproduceConfig, checks: dict) -> dict:
    """How the models of this run were made, the figures they gave, and their check figures."""
    seed = res["seeds"][0]
    heldout = res["general"]["heldout"]
    model_seed = {k: res["per_seed"][k][str(seed)] for k in ("ql", "pi", "pi5")}
    sets = res["general"]["sets"]
    return {
        "command": cfg.command or "python -m controllers.grasp reproduce",
        "seed": seed,
        "run_seeds": res["seeds"],
        "git_commit": git_commit(),
        "source_sha256": source_hash(),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "quick": cfg.quick,
        "models": {
            QL_MODEL_FILE: {
                "composer": "ql",
                "table2_average_failure": average_failure(model_seed["ql"]),
            },
            PI_MODEL_FILE: {
                "composer": "pi9",
                "table2_average_failure": average_failure(model_seed["pi"]),
                "heldout_failure_run_mean": heldout["nine_literal"]["failure"]["mean"],
            },
            PI_SUBSET_MODEL_FILE: {
                "composer": "pi5",
                "table2_average_failure": average_failure(model_seed["pi5"]),
            },
            PI_GENERAL_MODEL_FILE: {
                "composer": "pi",
                "train_seeds": sets["train_seeds"],
                "settings": GENERAL_SETTINGS,
                "heldout_failure_run_mean": heldout["general"]["failure"]["mean"],
                "heldout_seeds": sets["heldout_seeds"],
            },
            ATOMIC_MODEL_FILE: {"composer": None, "section2": res["section2"][str(seed)]},
        },
        "checks": checks,
    }
