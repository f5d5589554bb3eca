"""``python -m experiments.paper reproduce --out DIR``: every experiment of the paper in one run.

For each seed (default 0, 1, 2) it trains the Q-learning composer (section 3.6.2), the F/S
predictors of the PI controller on the nine objects and on the five-object subset (section 4.3),
a general F/S predictor on random convex polygons (beyond the paper), the atomic-action controller
(section 2), and tests them: Tables 1 and 2, every reading of the pre-image noise, polygons never
seen in training. Appendix A is solved once. Tables are reported as mean and standard deviation
over the seeds (``report.md``, ``results.json``); figures and models come from the first seed.

The work is cut into independent tasks (:mod:`experiments.paper.tasks`) run by a pool of ``workers``
processes (:mod:`graspsim_base.pool`); results are assembled in a fixed order, so the outputs do not
depend on the pool. Wall-clock times go to ``timings.json`` and the run's provenance (command,
commit, date) to ``provenance.json``; with the same seeds every other file is byte-identical. Every
file is written atomically; ``results.json`` is written last and marks the run finished
(:mod:`controllers.grasp.run_folder`), so ``trials --models DIR`` refuses an interrupted run."""

from __future__ import annotations

import datetime
import hashlib
import json
import subprocess
import sys
import time
from collections.abc import Sequence
from contextlib import closing
from dataclasses import asdict
from pathlib import Path

import numpy as np

import controllers.grasp
from controllers.grasp.atomic import (
    ATOMIC_MODEL_FILE,
    PAPER_ATOMIC,
    save_atomic_q,
)
from controllers.grasp.objects import (
    PAPER_OBJECTS,
    polygon_set_seeds,
)
from controllers.grasp.optimal_control import PAPER_THETA_T, solve_time_optimal
from controllers.grasp.preimaging import (
    PI_GENERAL_MODEL_FILE,
    PI_MODEL_FILE,
    PI_SUBSET_MODEL_FILE,
)
from controllers.grasp.qlearning import (
    QL_MODEL_FILE,
    save_q_table,
)
from controllers.grasp.run_folder import (
    REPRODUCE_COMMAND,
    finished_mark,
    mark_started,
    write_results,
)
from controllers.grasp.trials import GAIN
from experiments.paper.tables import (
    PAPER_TABLE1_KB,
    PAPER_TABLE1_QL,
    average_failure,
    over_seeds,
)
from experiments.paper.tasks import (
    FIVE_OBJECTS,
    GENERAL_SETTINGS,
    PAPER_MEAN_SG,
    PAPER_TABLE2_AVERAGE,
    PAPER_TABLE2_PI_ALL,
    PAPER_TABLE2_PI_FIVE,
    TASKS,
    Progress,
    ReproduceConfig,
)
from graspsim_base.files import write_text
from graspsim_base.pool import map_unordered


def _run_task(task: tuple[str, ReproduceConfig, int]) -> tuple[dict, float, float]:
    """Run one task (name, config, seed); its result, wall and CPU seconds."""
    name, cfg, seed = task
    import torch  # here, not at the top: a command that fails on its input does not pay for it

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

    tasks = [(name, cfg, seed) for name, seed in jobs]
    with closing(map_unordered(_run_task, tasks, cfg.workers)) as finished:
        for k, value in finished:
            done(jobs[k], value)
    return results, seconds


def git_commit() -> str:
    """The repository's commit (with ``-dirty`` if it has uncommitted changes), or "unknown"."""
    root = Path(controllers.grasp.__file__).resolve().parents[2]
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
    for path in sorted(Path(controllers.grasp.__file__).resolve().parent.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def reproduce(
    out: Path, config: ReproduceConfig | None = None, progress: Progress = _stderr
) -> dict:
    """Run every experiment, write the report, results, figures and models into ``out``.

    Returns the results dictionary (also written to ``out/results.json``).
    """
    from controllers.grasp.shipped import check_figures
    from experiments.paper.paper_figures import write_figures
    from experiments.paper.report import write_report

    cfg = config or ReproduceConfig.paper()
    if not cfg.seeds or len(set(cfg.seeds)) != len(cfg.seeds) or min(cfg.seeds) < 0:
        raise ValueError(f"seeds must be distinct non-negative integers, got {cfg.seeds}")
    import torch

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
        "command": cfg.command or REPRODUCE_COMMAND,
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
