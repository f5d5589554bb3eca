"""The physical grasp study end to end: grasps on a process pool, the ROC of S_G as a predictor of
a physical hold (:mod:`experiments.physics.roc`), the report and its figures
(``python -m experiments.physics``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from contextlib import closing
from pathlib import Path

import numpy as np

from controllers.grasp.objects import PAPER_OBJECTS
from controllers.grasp.task_height import HEIGHT_TRIES
from experiments.physics.compare import measures_figure, measures_section
from experiments.physics.heights import height_section
from experiments.physics.regrasp import regrasp_section
from experiments.physics.roc import Roc, rates_at, roc
from experiments.physics.study import (
    DIRECTIONS,
    FORCE_TIME,
    LIFT_HEIGHT,
    MAX_SHIFT,
    MAX_TURN,
    PAPER_THRESHOLD,
    Job,
    run_job,
)
from graspsim_base.files import write_bytes, write_text
from graspsim_base.pool import map_unordered
from hand_sim.assembly import DEFAULT_HAND

#: Controllers of the study (section 3.6.1, 3.6.2, section 4 with the general predictor).
CONTROLLERS: tuple[str, ...] = ("kb", "ql", "pi")
#: Grasps per process task (one world and one set of hand postures per task).
CHUNK = 10
#: The quick version (tests): two objects, few grasps.
QUICK_OBJECTS = ("trapezoid", "irregular_hexagon")
QUICK_GRASPS = 4
#: Pictures of grasps S_G calls good that physics drops.
PICTURES = 4


def jobs_for(
    objects: Sequence[str],
    grasps: int,
    seed: int,
    models: Sequence[str] = ("planar",),
    depth: float | None = None,
    hand: str = DEFAULT_HAND,
    height_tries: int = HEIGHT_TRIES,
    regrasp: bool = True,
    perturb: str | None = None,
) -> list[Job]:
    """The study's chunks: per model, object and controller (the same starts for every model),
    with the ``hand`` on the arm and, in 3-D, up to ``height_tries`` common heights tried;
    ``regrasp``: an unreachable grasp is synthesized once more (``--regrasp``); ``perturb``:
    each grasp's world perturbed so (``--perturb``)."""
    out = []
    for model in models:
        for obj in objects:
            o_index = PAPER_OBJECTS.index(obj)
            for ci, ctrl in enumerate(CONTROLLERS):
                for start in range(0, grasps, CHUNK):
                    idx = tuple(range(start, min(grasps, start + CHUNK)))
                    out.append(
                        Job(
                            obj,
                            o_index,
                            ctrl,
                            ci,
                            idx,
                            seed,
                            model=model,
                            depth=depth,
                            hand=hand,
                            height_tries=height_tries,
                            regrasp=regrasp,
                            perturb=perturb,
                        )
                    )
    return out


def run_study(
    objects: Sequence[str],
    grasps: int,
    seed: int,
    workers: int = 2,
    progress=None,
    models: Sequence[str] = ("planar",),
    depth: float | None = None,
    hand: str = DEFAULT_HAND,
    height_tries: int = HEIGHT_TRIES,
    regrasp: bool = True,
    perturb: str | None = None,
) -> list[dict]:
    """Every grasp, in a fixed order (model, object, controller, index) whatever the workers,
    taken by the ``hand`` ("servo" or "tendon"); ``height_tries`` and ``perturb`` as in
    :func:`jobs_for`."""
    jobs = jobs_for(objects, grasps, seed, models, depth, hand, height_tries, regrasp, perturb)
    results: list[list[dict]] = [[] for _ in jobs]
    with closing(map_unordered(run_job, jobs, workers)) as finished:
        for k, res in finished:
            results[k] = res
            if progress is not None:
                progress(len(res))
    return [r for chunk in results for r in chunk]


def _pct(a: int, b: int) -> str:
    return f"{a} / {b} ({100.0 * a / b:.0f} %)" if b else "0 / 0"


def summary_tables(results: list[dict], objects: Sequence[str]) -> str:
    """Markdown tables: outcomes per controller, held rate per controller and object."""
    lines = [
        "| controller | grasps | S_G <= 0.4 | unreachable | not closed | sim error | tested "
        "| held (of tested) | held among S_G <= 0.4 |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for c in CONTROLLERS:
        rs = [r for r in results if r["controller"] == c]
        if not rs:
            continue
        tested = [r for r in rs if r["result"] in ("held", "dropped")]
        good = [r for r in tested if r["s_g"] is not None and r["s_g"] <= PAPER_THRESHOLD]
        ok = sum(r["s_g"] is not None and r["s_g"] <= PAPER_THRESHOLD for r in rs)
        lines.append(
            f"| {c} | {len(rs)} | {ok} | {sum(r['result'] == 'unreachable' for r in rs)} "
            f"| {sum(r['result'] == 'not closed' for r in rs)} "
            f"| {sum(r['result'] == 'sim error' for r in rs)} | {len(tested)} "
            f"| {_pct(sum(r['result'] == 'held' for r in tested), len(tested))} "
            f"| {_pct(sum(r['result'] == 'held' for r in good), len(good))} |"
        )
    lines += ["", "Held / tested per object and controller (unreachable in brackets):", ""]
    lines += ["| object | " + " | ".join(CONTROLLERS) + " |", "|---|" + "---:|" * len(CONTROLLERS)]
    for o in objects:
        cells = []
        for c in CONTROLLERS:
            rs = [r for r in results if r["controller"] == c and r["object"] == o]
            tested = [r for r in rs if r["result"] in ("held", "dropped")]
            held = sum(r["result"] == "held" for r in tested)
            unr = sum(r["result"] in ("unreachable", "not closed") for r in rs)
            cells.append(f"{held} / {len(tested)} ({unr})")
        lines.append(f"| {o} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def roc_figure(r: Roc, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 4.5), dpi=110)
    ax.plot(r.fpr, r.tpr, drawstyle="steps-post", label=f"S_G, AUC {r.auc:.3f}")
    ax.plot([0, 1], [0, 1], color="grey", lw=0.8, ls="--", label="chance")
    ax.set_xlabel("false positive rate (dropped, S_G <= t)")
    ax.set_ylabel("true positive rate (held, S_G <= t)")
    ax.set_title(
        f"S_G as a predictor of a physical hold\n{r.positives} held, {r.negatives} dropped"
    )
    ax.legend(loc="lower right")
    fig.tight_layout()
    tmp = path.with_name(path.name + ".tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)


def sg_histogram(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tested = [r for r in results if r["result"] in ("held", "dropped")]
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=110)
    bins = np.linspace(0, 1.0, 41)
    for label, colour in (("held", "tab:green"), ("dropped", "tab:red")):
        s = [min(r["s_g"], 1.0) for r in tested if r["result"] == label and r["s_g"] is not None]
        ax.hist(s, bins=bins, alpha=0.6, color=colour, label=f"{label} ({len(s)})")
    ax.axvline(PAPER_THRESHOLD, color="k", ls="--", lw=0.8, label="paper's 0.4")
    ax.set_xlabel("S_G (Eq. 13; 1.0 = 1.0 or more)")
    ax.set_ylabel("grasps")
    ax.legend()
    fig.tight_layout()
    tmp = path.with_name(path.name + ".tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)


def render_grasp(
    entry: dict,
    seed: int,
    path: Path,
    hand: str = DEFAULT_HAND,
    height_tries: int = HEIGHT_TRIES,
    perturb: str | None = None,
) -> bool:
    """Re-run one grasp (deterministic, with the ``hand``, ``height_tries`` and ``perturb`` of
    its run) and save a picture: the grasp after the squeeze beside the moment the test lost it.
    False when the re-run does not reproduce the drop."""
    import mujoco

    frames: dict[str, np.ndarray] = {}
    job = Job(
        entry["object"],
        PAPER_OBJECTS.index(entry["object"]),
        entry["controller"],
        CONTROLLERS.index(entry["controller"]),
        (entry["index"],),
        seed,
        entry.get("model", "planar"),
        entry.get("depth"),
        hand=hand,
        height_tries=height_tries,
        # a regrasped grasp came from a run with --regrasp; any other was taken first time
        regrasp=bool(entry.get("regrasped")),
        perturb=perturb,
    )
    renderer: list = []

    def snap(stage: str, world) -> None:
        if not renderer:
            renderer.append(mujoco.Renderer(world.model, 360, 480))
        cam = mujoco.MjvCamera()
        b = world.block_body_id(world.scene.target)
        cam.lookat[:] = world.data.xpos[b]
        cam.distance, cam.azimuth, cam.elevation = 0.42, 135.0, -30.0
        renderer[0].update_scene(world.data, camera=cam)
        frames[stage] = renderer[0].render().copy()

    try:
        again = run_job(job, snapshot=snap)[0]
    finally:
        if renderer:
            renderer[0].close()
    if again["result"] != entry["result"] or "grasp" not in frames or len(frames) < 2:
        return False
    import cv2

    lost = next(k for k in frames if k != "grasp")
    left = cv2.putText(
        frames["grasp"][:, :, ::-1].copy(),
        "squeezed",
        (10, 25),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.7,
        (255, 255, 255),
        2,
    )
    right = cv2.putText(
        frames[lost][:, :, ::-1].copy(),
        f"lost under {lost}",
        (10, 25),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.7,
        (255, 255, 255),
        2,
    )
    ok, png = cv2.imencode(".png", np.hstack([left, right]))
    if ok:
        write_bytes(path, png.tobytes())
    return bool(ok)


def write_report(
    out: Path,
    results: list[dict],
    objects: Sequence[str],
    grasps: int,
    seed: int,
    command: str,
    seconds: float,
    pictures: int = PICTURES,
    models: Sequence[str] = ("planar",),
    hand: str = DEFAULT_HAND,
    height_tries: int = HEIGHT_TRIES,
    perturb: str | None = None,
) -> dict:
    """results.jsonl, summary.json, report.md, roc.png, sg_hist.png and a few pictures; the
    summary and the report name the ``hand`` that took the grasps (``height_tries`` and
    ``perturb``: the run's, for re-running the pictured grasps)."""
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "results.jsonl", "".join(json.dumps(r) + "\n" for r in results))
    tested = [r for r in results if r["result"] in ("held", "dropped")]
    s_g = [r["s_g"] for r in tested]
    held = [r["result"] == "held" for r in tested]
    curve = roc(s_g, held)
    tpr04, fpr04 = rates_at(s_g, held, PAPER_THRESHOLD)
    tprb, fprb = rates_at(s_g, held, curve.best_threshold)
    if tested:
        roc_figure(curve, out / "roc.png")
        sg_histogram(results, out / "sg_hist.png")
    false_pos = [
        r
        for r in tested
        if r["result"] == "dropped" and r["s_g"] is not None and r["s_g"] <= PAPER_THRESHOLD
    ]
    drawn = []
    for m in models:  # up to ``pictures`` of each model
        for r in [r for r in false_pos if r.get("model", "planar") == m][:pictures]:
            prefix = "" if m == "planar" else f"{m}_"
            name = f"dropped_{prefix}{r['object']}_{r['controller']}_{r['index']}.png"
            if render_grasp(r, seed, out / name, hand, height_tries, perturb):
                drawn.append((name, r))
    summary = {
        "command": command,
        "objects": list(objects),
        "grasps": grasps,
        "seed": seed,
        "seconds": round(seconds, 1),
        "tested": len(tested),
        "held": int(sum(held)),
        "auc": curve.auc,
        "best_threshold": curve.best_threshold,
        "best_j": curve.best_j,
        "tpr_fpr_at_0.4": [tpr04, fpr04],
        "tpr_fpr_at_best": [tprb, fprb],
        "false_positives": len(false_pos),
        "models": list(models),
        "hand": hand,
        "perturb": perturb,
    }
    compare_md, summary["measures"] = measures_section(results, tuple(models))
    if tested:
        measures_figure(results, out / "roc_measures.png")
    write_text(out / "summary.json", json.dumps(summary, indent=1) + "\n")
    stages = ", ".join(f"{d}" for d, _ in DIRECTIONS)
    md = [
        "# The physical grasp study: S_G against MuJoCo",
        "",
        f"Command: `{command}` ({seconds:.0f} s wall). Seed {seed}; {grasps} grasps per object "
        f"and controller; the {hand} hand."
        + (
            f" Each grasp's world perturbed: `--perturb {perturb}`, drawn from the grasp's "
            "seed (docs/robustness.md); the controllers' task is set from the block's nominal "
            "weight, the test's pushes from its true one."
            if perturb
            else ""
        ),
        "",
        f"Test: block hanging in the hand (table collisions off), m*g along {stages}, "
        f"{FORCE_TIME:g} s each, then a {LIFT_HEIGHT * 100:.0f} cm lift; held = the block stays "
        f"within {MAX_SHIFT * 100:.0f} cm and {np.degrees(MAX_TURN):.0f} deg of its pose in the "
        "palm's frame throughout.",
        "",
        *(
            f"### Model: {m}\n\n"
            + summary_tables([r for r in results if r["model"] == m], objects)
            + "\n"
            for m in models
        ),
        "",
        *height_section(results),
        *regrasp_section(results),
        *compare_md,
        "",
        "## S_G of the synthesized contacts as a predictor (tested grasps, all models)",
        "",
        f"AUC {curve.auc:.3f} ({curve.positives} held, {curve.negatives} dropped). "
        f"Best-separating threshold (Youden J = {curve.best_j:.3f}): S_G <= "
        f"{curve.best_threshold:.3f}, TPR {tprb:.3f}, FPR {fprb:.3f}; the paper's 0.4: "
        f"TPR {tpr04:.3f}, FPR {fpr04:.3f}.",
        "",
        "![ROC](roc.png)",
        "",
        "![S_G of held and dropped grasps](sg_hist.png)",
        "",
        f"## Grasps S_G calls good (<= 0.4) that physics drops: {len(false_pos)}",
        "",
    ]
    md += [
        "| model | object | controller | grasp | S_G | lost under | shift (cm) | turn (deg) |",
        "|---|---|---|---:|---:|---|---:|---:|",
    ]
    for r in false_pos:
        st = r["failed_stage"]
        md.append(
            f"| {r['model']} | {r['object']} | {r['controller']} | {r['index']} | {r['s_g']:.3f} "
            f"| {st} "
            f"| {r['shift'].get(st, float('nan')) * 100:.1f} "
            f"| {np.degrees(r['turn'].get(st, float('nan'))):.1f} |"
        )
    for name, r in drawn:
        md += ["", f"![{r['model']} {r['object']} {r['controller']} {r['index']}]({name})"]
    write_text(out / "report.md", "\n".join(md) + "\n")
    return summary
