"""The robustness report: how often the task cycle delivers on random scenes when the simulated
world differs from the robot's model (section 5.3's woes; docs/robustness.md), per perturbation
and scale, with the failures by name, read from the folders ``python -m experiments.bench
--perturb NAME=SCALE`` wrote (``results.jsonl`` and ``bench.json``).

Writes ``report.md`` (one table row per perturbation and scale: delivered, Wilson 95 %
interval, place error median and 95th percentile, the failures by name and seed) and
``success_vs_scale.png`` (the success rate against the scale, one line per perturbation, the
interval as error bars). The experiments do not import one another: the results are read as
files.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import binomtest

from graspsim_base.files import atomic_path, write_text
from hand_sim.perturb import KINDS, WOES, PerturbSpec

#: The unperturbed run's name in the report.
NOMINAL = "none"


@dataclass
class Row:
    """One bench folder: a perturbation at a scale."""

    name: str  #: a perturbation of hand_sim.perturb.NAMES, or NOMINAL
    scale: float
    folder: Path
    episodes: int = 0
    delivered: int = 0
    place_errors: list[float] = field(default_factory=list)
    failures: Counter = field(default_factory=Counter)
    failure_seeds: dict[str, list[int]] = field(default_factory=dict)

    @property
    def rate(self) -> float:
        return self.delivered / self.episodes if self.episodes else math.nan


def wilson(successes: int, trials: int) -> tuple[float, float]:
    """Wilson score 95 % interval (low, high) of a binomial proportion (Wilson 1927), scipy's."""
    if trials <= 0:
        return math.nan, math.nan
    ci = binomtest(successes, trials).proportion_ci(confidence_level=0.95, method="wilson")
    return float(ci.low), float(ci.high)


def name_and_scale(perturb: str | None) -> tuple[str, float]:
    """The perturbation a bench ran (its ``--perturb``): one kind, ``woes`` (every kind at one
    scale), or NOMINAL."""
    spec = PerturbSpec() if perturb in (None, "none") else PerturbSpec.parse(perturb)
    scales = dict(spec.scales)
    if not scales or not any(scales.values()):
        return NOMINAL, 0.0
    if set(scales) == set(KINDS) and len(set(scales.values())) == 1:
        return WOES, next(iter(scales.values()))
    if len(scales) == 1:
        return next(iter(scales.items()))
    return spec.text(), 1.0


def read_row(folder: Path) -> Row:
    """One bench folder's row."""
    settings = json.loads((folder / "bench.json").read_text())
    name, scale = name_and_scale(settings.get("perturb"))
    row = Row(name, scale, folder)
    for raw in (folder / "results.jsonl").read_text().splitlines():
        if not raw.strip():
            continue
        line = json.loads(raw)
        row.episodes += 1
        cycles = line.get("cycles") or []
        elsewhere = any(c.get("delivered_elsewhere") for c in cycles)
        if line.get("success") and not elsewhere:
            row.delivered += 1
            row.place_errors += [c["judgement"]["place_error_mm"] for c in cycles]
            continue
        reason = "delivered elsewhere" if line.get("success") else str(line.get("failure"))
        row.failures[reason] += 1
        row.failure_seeds.setdefault(reason, []).append(int(line["seed"]))
    return row


def _order(row: Row) -> tuple[int, float]:
    names = (NOMINAL, *KINDS, WOES)
    return (names.index(row.name) if row.name in names else len(names), row.scale)


def table(rows: list[Row]) -> str:
    """The report's table (markdown)."""
    out = [
        "| perturbation | scale | episodes | delivered | rate | Wilson 95 % | place error p50 / "
        "p95 mm | failures (seeds) |",
        "|---|---:|---:|---:|---:|---|---|---|",
    ]
    for r in sorted(rows, key=_order):
        lo, hi = wilson(r.delivered, r.episodes)
        errors = np.asarray(r.place_errors)
        err = f"{np.median(errors):.1f} / {np.percentile(errors, 95):.1f}" if errors.size else "-"
        fails = "; ".join(
            f"{reason} {n} ({', '.join(map(str, sorted(r.failure_seeds[reason])[:8]))}"
            + (", ..." if n > 8 else "")
            + ")"
            for reason, n in r.failures.most_common()
        )
        out.append(
            f"| {r.name} | {r.scale:g} | {r.episodes} | {r.delivered} | {100 * r.rate:.1f} % "
            f"| {100 * lo:.1f}-{100 * hi:.1f} % | {err} | {fails or '-'} |"
        )
    return "\n".join(out)


def figure(rows: list[Row], path: Path) -> None:
    """Success rate against scale, one line per perturbation (the unperturbed run at scale 0
    of every line), Wilson intervals as error bars."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nominal = [r for r in rows if r.name == NOMINAL]
    fig, ax = plt.subplots(figsize=(7.0, 4.2), dpi=100)
    names = [n for n in (*KINDS, WOES) if any(r.name == n for r in rows)]
    for k, name in enumerate(names):
        line = sorted(nominal + [r for r in rows if r.name == name], key=lambda r: r.scale)
        x = np.array([r.scale for r in line]) + 0.012 * (k - len(names) / 2)
        y = np.array([100 * r.rate for r in line])
        bounds = np.array([wilson(r.delivered, r.episodes) for r in line]) * 100
        yerr = np.vstack([y - bounds[:, 0], bounds[:, 1] - y])
        style = {"lw": 2.5, "color": "black"} if name == WOES else {"lw": 1.4}
        ax.errorbar(x, y, yerr=yerr, marker="o", ms=4, capsize=2, label=name, **style)
    ax.set_xlabel("scale (1: the magnitudes of docs/robustness.md)")
    ax.set_ylabel("delivered (%)")
    ax.set_ylim(bottom=max(0.0, ax.get_ylim()[0]), top=101)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2, loc="lower left")
    ax.set_title("Task cycle on random scenes: success against the perturbations' scale")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp)
    plt.close(fig)


def write_report(folders: list[Path], out: Path, command: str, notes: str = "") -> list[Row]:
    """Read every bench folder of ``folders`` and write ``out/report.md`` and
    ``out/success_vs_scale.png``; ``command`` and ``notes`` head the report."""
    rows = [read_row(f) for f in folders]
    figure(rows, out / "success_vs_scale.png")
    text = [
        "# Robustness: the task cycle when the world differs from the robot's model",
        "",
        f"Made with `{command}`. Each row is one `python -m experiments.bench --scene random "
        "--perturb NAME=SCALE` run (folder named in the last column's source); an episode is "
        "judged physically on the simulated world (fsm.judge), delivered only at the place "
        "point asked for.",
        "",
        *([notes, ""] if notes else []),
        table(rows),
        "",
        "![success against scale](success_vs_scale.png)",
        "",
        "Runs: " + ", ".join(f"`{r.folder.name}`" for r in sorted(rows, key=_order)),
        "",
    ]
    write_text(out / "report.md", "\n".join(text))
    return rows


def as_json(rows: list[Row]) -> list[dict[str, Any]]:
    """The rows as JSON-ready dicts (summary.json)."""
    return [
        {
            "perturbation": r.name,
            "scale": r.scale,
            "episodes": r.episodes,
            "delivered": r.delivered,
            "wilson95": list(wilson(r.delivered, r.episodes)),
            "place_error_p50_mm": float(np.median(r.place_errors)) if r.place_errors else None,
            "failures": dict(r.failures),
            "failure_seeds": r.failure_seeds,
        }
        for r in sorted(rows, key=_order)
    ]
