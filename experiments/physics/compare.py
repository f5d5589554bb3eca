"""Planar against 3-D in the physical study: held rates per model, and how well each grasp
measure (:mod:`experiments.physics.measures`) predicts a hold.

For every tested grasp (held or dropped) with measures, each measure's ROC and AUC
(:func:`experiments.physics.roc.roc`, lower = predicts a hold), pooled and per model, and its
Spearman rank correlation with the block's worst turn and worst shift over the test's stages
(the 10-degree limit cuts a continuum: held grasps turn too). Wilson 95 % intervals on held
rates.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from experiments.physics.roc import Roc, roc

#: The measures, as keys of ``GraspOutcome.measures`` and their labels.
MEASURES: dict[str, str] = {
    "planar_sg": "planar S_G",
    "sg3d": "3-D S_G (null grasp)",
    "worst_sg3d": "3-D S_G, worst test task",
    "predicted_turn": "grasp compliance, worst predicted turn",
    "force_demand": "measured-force demand, worst test load",
}


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval of k successes in n trials (0, 0 for n = 0)."""
    if n == 0:
        return 0.0, 0.0
    p = k / n
    d = 1.0 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return float(c - h), float(c + h)


def held_share(results: list[dict]) -> str:
    """ "held / tested (lo-hi %)" of ``results``' tested grasps, with the Wilson 95 % interval
    ("0 / 0" when none was tested)."""
    tested = [r for r in results if r["result"] in ("held", "dropped")]
    if not tested:
        return "0 / 0"
    held = sum(r["result"] == "held" for r in tested)
    lo, hi = wilson(held, len(tested))
    return f"{held} / {len(tested)} ({100 * lo:.0f}-{100 * hi:.0f} %)"


def _scored(results: list[dict]) -> list[dict]:
    return [r for r in results if r["result"] in ("held", "dropped") and r.get("measures")]


def measure_rocs(results: list[dict]) -> dict[str, Roc]:
    """Each measure's ROC over the tested grasps that have measures."""
    rs = _scored(results)
    held = [r["result"] == "held" for r in rs]
    return {k: roc([r["measures"].get(k) for r in rs], held) for k in MEASURES}


def spearman(results: list[dict]) -> dict[str, dict[str, float]]:
    """Each measure's Spearman correlation with the worst turn and worst shift (infeasible
    scores rank last)."""
    from scipy.stats import spearmanr

    rs = _scored(results)
    turn = [max(r["turn"].values()) for r in rs]
    shift = [max(r["shift"].values()) for r in rs]
    out = {}
    for k in MEASURES:
        v = [np.inf if r["measures"].get(k) is None else r["measures"][k] for r in rs]
        v = np.where(np.isfinite(v), v, np.nanmax(np.where(np.isfinite(v), v, np.nan)) * 10)
        out[k] = {
            "turn": float(spearmanr(v, turn).statistic) if len(rs) > 2 else float("nan"),
            "shift": float(spearmanr(v, shift).statistic) if len(rs) > 2 else float("nan"),
        }
    return out


def model_table(results: list[dict], models: tuple[str, ...]) -> list[str]:
    """Markdown: per model, grasps, unreachable, tested, held (Wilson interval), square."""
    lines = [
        "| model | grasps | unreachable | not closed | tested | held (of tested, 95 % CI) "
        "| square held |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for m in models:
        rs = [r for r in results if r.get("model", "planar") == m]
        tested = [r for r in rs if r["result"] in ("held", "dropped")]
        held = sum(r["result"] == "held" for r in tested)
        lo, hi = wilson(held, len(tested))
        sq = [r for r in tested if r["object"] == "square"]
        sq_held = sum(r["result"] == "held" for r in sq)
        lines.append(
            f"| {m} | {len(rs)} | {sum(r['result'] == 'unreachable' for r in rs)} "
            f"| {sum(r['result'] == 'not closed' for r in rs)} | {len(tested)} "
            f"| {held} ({100 * held / max(len(tested), 1):.0f} %, {100 * lo:.0f}-{100 * hi:.0f} %) "
            f"| {sq_held} / {len(sq)} |"
        )
    return lines


def measures_section(results: list[dict], models: tuple[str, ...]) -> tuple[list[str], dict]:
    """The report's comparison section (markdown lines) and its summary numbers."""
    md = ["## Planar and 3-D grasps, and the measures that predict a hold", ""]
    md += model_table(results, models)
    md += [
        "",
        "Each grasp is scored as the hand holds it at the end of the squeeze (the fingers' real "
        "contact points): AUC (lower measure predicts a hold) and Spearman correlation with the "
        "block's worst turn and shift.",
        "",
        "| measure | grasps | AUC pooled | "
        + " | ".join(f"AUC {m}" for m in models)
        + " | Spearman turn | Spearman shift |",
        "|---|---:|---:|" + "---:|" * len(models) + "---:|---:|",
    ]
    pooled = measure_rocs(results)
    per = {m: measure_rocs([r for r in results if r.get("model", "planar") == m]) for m in models}
    rank = spearman(results)
    summary = {}
    for k, label in MEASURES.items():
        r = pooled[k]
        md.append(
            f"| {label} | {r.positives + r.negatives} | {r.auc:.3f} | "
            + " | ".join(f"{per[m][k].auc:.3f}" for m in models)
            + f" | {rank[k]['turn']:+.2f} | {rank[k]['shift']:+.2f} |"
        )
        summary[k] = {
            "auc": r.auc,
            **{f"auc_{m}": per[m][k].auc for m in models},
            "spearman_turn": rank[k]["turn"],
            "spearman_shift": rank[k]["shift"],
        }
    md += ["", "![ROC of the measures](roc_measures.png)", ""]
    return md, summary


def measures_figure(results: list[dict], path: Path) -> None:
    """The measures' pooled ROC curves in one plot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.0, 4.8), dpi=110)
    rocs = measure_rocs(results)
    for k, label in MEASURES.items():
        r = rocs[k]
        ax.plot(r.fpr, r.tpr, drawstyle="steps-post", label=f"{label}, AUC {r.auc:.3f}")
    ax.plot([0, 1], [0, 1], color="grey", lw=0.8, ls="--", label="chance")
    ax.set_xlabel("false positive rate (dropped, measure <= t)")
    ax.set_ylabel("true positive rate (held, measure <= t)")
    any_roc = next(iter(rocs.values()))
    ax.set_title(
        f"Grasp measures as predictors of a hold\n{any_roc.positives} held, "
        f"{any_roc.negatives} dropped (all models)"
    )
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    tmp = path.with_name(path.name + ".tmp.png")
    fig.savefig(tmp)
    plt.close(fig)
    os.replace(tmp, path)
