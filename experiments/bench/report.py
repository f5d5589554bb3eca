"""``report.md`` and its PNG figures for a bench folder, from ``results.jsonl`` alone (so that a
report can be rebuilt from the results at any time, and an interrupted bench reports what it did).

Figures (matplotlib, Agg canvas, no pyplot state): ``success.png`` (success rate overall and per
block count, Wilson 95 % intervals), ``failures.png`` (episodes per failure reason),
``place_error.png`` (histogram of the judged deliveries' place error with its percentiles and the
judge's tolerance), ``wall_per_state.png`` (mean wall seconds per episode spent in each state).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from experiments.bench.stats import (
    BenchSummary,
    FailureRow,
    seed_ranges,
    summarize,
    wilson_interval,
)
from fsm.judge import PLACE_TOLERANCE
from graspsim_base.files import atomic_path, write_text

REPORT_FILE = "report.md"
FIGURES = {
    "success": "success.png",
    "failures": "failures.png",
    "place_error": "place_error.png",
    "wall_per_state": "wall_per_state.png",
}
#: Figure size (inches) and resolution of every PNG.
FIG_SIZE = (7.0, 4.0)
DPI = 100
#: Seeds listed per failure reason in the table (the rest are counted).
SEEDS_SHOWN = 12


def _figure(size: tuple[float, float] = FIG_SIZE) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Any, path: Path) -> None:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")


@contextmanager
def _plot(path: Path, title: str) -> Iterator[Any]:
    """Axes of a new figure to draw on; the figure gets ``title`` and is saved to ``path``
    (written whole) when the block ends."""
    fig = _figure()
    ax = fig.add_subplot()
    yield ax
    ax.set_title(title)
    _save(fig, path)


def _no_data(ax: Any, text: str) -> None:
    """An empty plot: ``text`` in the middle, no axes."""
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes)
    ax.set_axis_off()


def _knocked_cell(row: FailureRow) -> str:
    """How many of a reason's failures knocked their block over, and of how many judged."""
    if row.judged == 0:
        return "not judged"
    if row.judged < row.episodes:
        return f"{row.knocked_over} of {row.judged} judged"
    return str(row.knocked_over)


def _pct(x: float) -> str:
    return f"{100.0 * x:.1f} %"


def plot_success(s: BenchSummary, path: Path) -> None:
    with _plot(path, f"Success rate with Wilson 95 % interval ({s.episodes} episodes)") as ax:
        labels = [f"all\n(n = {s.episodes})"]
        rates = [s.rate]
        for blocks, n, k in s.by_blocks:
            labels.append(f"{blocks} blocks\n(n = {n})" if blocks is not None else f"(n = {n})")
            rates.append(wilson_interval(k, n))
        x = np.arange(len(rates))
        est = np.array([100 * r.estimate for r in rates])
        err = np.array(
            [
                [100 * (r.estimate - r.low) for r in rates],
                [100 * (r.high - r.estimate) for r in rates],
            ]
        )
        ax.errorbar(x, est, yerr=err, fmt="o", capsize=6, color="tab:blue")
        ax.set_xticks(x, labels)
        ax.set_ylim(0, 105)
        ax.set_xlim(-0.5, len(rates) - 0.5)
        ax.set_ylabel("episodes delivered (%)")
        ax.grid(axis="y", alpha=0.3)


def plot_failures(s: BenchSummary, path: Path) -> None:
    failed = s.episodes - s.successes - s.elsewhere
    with _plot(path, f"Failure reasons ({failed} of {s.episodes} episodes)") as ax:
        if s.failures:
            reasons = [f.reason for f in s.failures][::-1]
            counts = [f.episodes for f in s.failures][::-1]
            bars = ax.barh(reasons, counts, color="tab:red")
            ax.bar_label(bars, padding=3)
            ax.set_xlim(0, max(counts) * 1.12)  # room for the longest bar's label
            ax.set_xlabel("episodes")
            ax.xaxis.get_major_locator().set_params(integer=True)
        else:
            _no_data(ax, "no failed episode")


def plot_place_error(s: BenchSummary, path: Path) -> None:
    with _plot(path, f"Place error of the judged deliveries (n = {len(s.place_error_mm)})") as ax:
        tolerance = 1000.0 * PLACE_TOLERANCE
        if s.place_error_mm:
            errors = np.asarray(s.place_error_mm)
            top = max(tolerance, float(errors.max())) * 1.05
            ax.hist(errors, bins=np.linspace(0.0, top, 30), color="tab:blue", alpha=0.8)
            styles = (":", "--", "-.", (0, (1, 4)))
            for (q, value), style in zip(s.place_percentiles, styles, strict=False):
                ax.axvline(value, color="black", ls=style, lw=1, label=f"p{q} {value:.1f} mm")
            ax.axvline(
                tolerance, color="tab:red", lw=1.5, label=f"judge's tolerance {tolerance:g} mm"
            )
            ax.yaxis.get_major_locator().set_params(integer=True)
            ax.legend(loc="upper right")
            ax.set_xlabel("place error (mm)")
            ax.set_ylabel("deliveries")
        else:
            _no_data(ax, "no delivery was judged")


def plot_wall_per_state(s: BenchSummary, path: Path) -> None:
    with _plot(path, f"Wall time per state ({s.episodes} episodes)") as ax:
        names = [r.state for r in s.states][::-1]
        means = [r.mean_per_episode for r in s.states][::-1]
        bars = ax.barh(names, means, color="tab:green")
        ax.bar_label(bars, labels=[f"{m:.1f}" for m in means], padding=3)
        ax.set_xlabel("wall seconds per episode (mean)")


def _command(settings: dict[str, Any], seeds: Sequence[int]) -> str:
    lo, hi = min(seeds), max(seeds) + 1
    parts = ["python -m experiments.bench", f"--scene {settings['scene']}", f"--seeds {lo}:{hi}"]
    if settings.get("blocks"):
        parts.append(f"--blocks {settings['blocks']}")
    parts += [f"--controller {settings['controller']}", f"--approach {settings['approach']}"]
    # always written, so that the command runs the same model whatever the default
    parts.append(f"--model {settings.get('grasp_model', 'planar')}")
    if settings.get("cycles", "1") != "1":
        parts.append(f"--cycles {settings['cycles']}")
    if settings.get("place_fallback", "none") != "none":
        parts.append(f"--place-fallback {settings['place_fallback']}")
    if settings.get("models"):
        parts.append(f"--models {settings['models']}")
    if settings.get("lateral_gate", 0.4) != 0.4:
        parts.append(f"--lateral-gate {settings['lateral_gate']}")
    rule = settings.get("lateral_gate_rule", "paper")  # a folder without the setting ran "paper"
    if rule != "opposition":
        parts.append(f"--lateral-gate-rule {rule}")
    # always written, so that the command runs the same hand whatever the default
    parts.append(f"--hand {settings.get('hand', 'servo')}")
    if settings.get("perturb") is not None:
        parts.append(f"--perturb {settings['perturb']}")
    return " ".join(parts)


def _cycles_text(settings: dict[str, Any]) -> str:
    cycles = settings.get("cycles", "1")
    if cycles == "1":
        return "one pick and place"
    if cycles == "all":
        return "clearing the table block after block (`--cycles all`)"
    return f"up to {cycles} picks and places one after another (`--cycles {cycles}`)"


def _cycles_section(s: BenchSummary) -> list[str]:
    """``## Cycles``: blocks delivered, delivered elsewhere and failed per cycle, and the share
    of tables cleared."""
    out = [
        "## Cycles",
        "",
        "Per cycle (0 is the block asked for; later ones are chosen by the task cycle): the "
        "episodes that reached it, and its block delivered, delivered elsewhere, or failed "
        "(the episode ends there).",
        "",
        "| cycle | reached | delivered | delivered elsewhere | failed |",
        "|---|---|---|---|---|",
    ]
    for r in s.cycles:
        out.append(f"| {r.cycle} | {r.reached} | {r.delivered} | {r.elsewhere} | {r.failed} |")
    share = s.tables_cleared / s.episodes if s.episodes else 0.0
    out += [
        "",
        f"Blocks delivered: {sum(r.delivered for r in s.cycles)}, delivered elsewhere: "
        f"{sum(r.elsewhere for r in s.cycles)}, failed: {sum(r.failed for r in s.cycles)}. "
        f"Tables cleared (every block of the scene delivered): {s.tables_cleared} of "
        f"{s.episodes} ({_pct(share)}).",
        "",
    ]
    return out


def markdown(s: BenchSummary, settings: dict[str, Any]) -> str:
    """The text of ``report.md``."""
    out = [
        "# Task-cycle benchmark",
        "",
        f"`{_command(settings, s.seeds)}`: {s.episodes} episodes, seeds {seed_ranges(s.seeds)}, "
        f"controller `{settings['controller']}`, approach `{settings['approach']}`. "
        f"An episode is {_cycles_text(settings)} on a fresh scene, judged physically "
        "(fsm.judge) at the place point asked for (later cycles: the point the task cycle "
        "chose). A block the hand could only set down at another point "
        "(`--place-fallback nearest`) is *delivered elsewhere*: counted apart, never in the "
        "success rate.",
        "",
        "## Success rate",
        "",
        "| blocks | episodes | delivered where asked | success rate | Wilson 95 % interval |",
        "|---|---|---|---|---|",
    ]
    rows = (
        [("all", s.episodes, s.successes)]
        + [(str(b) if b is not None else "scene file", n, k) for b, n, k in s.by_blocks]
        + [
            (f"{a} approach" if a != "none" else "no approach chosen", n, k)
            for a, n, k in s.by_approach
        ]
    )
    for label, n, k in rows:
        r = wilson_interval(k, n)
        out.append(
            f"| {label} | {n} | {k} | {_pct(r.estimate)} | [{_pct(r.low)}, {_pct(r.high)}] |"
        )
    failed = s.episodes - s.successes - s.elsewhere
    out += [
        "",
        f"Delivered {s.successes} of {s.episodes}: {_pct(s.rate.estimate)}, Wilson 95 % interval "
        f"[{_pct(s.rate.low)}, {_pct(s.rate.high)}] (lower bound {_pct(s.rate.low)}). "
        f"Delivered elsewhere: {s.elsewhere}. Failed: {failed}. The rows by approach split "
        "the episodes by the approach their first cycle took (none chosen: it failed before Coarse "
        "Reach chose one).",
        "",
        f"![success rate]({FIGURES['success']})",
        "",
        *(_cycles_section(s) if settings.get("cycles", "1") != "1" else []),
        "## Failure reasons",
        "",
    ]
    if s.failures:
        out += [
            "| reason | episodes | share of episodes | block knocked over | seeds |",
            "|---|---|---|---|---|",
        ]
        for f in s.failures:
            shown = ", ".join(str(x) for x in f.seeds[:SEEDS_SHOWN])
            more = f" and {len(f.seeds) - SEEDS_SHOWN} more" if len(f.seeds) > SEEDS_SHOWN else ""
            out.append(
                f"| {f.reason} | {f.episodes} | {_pct(f.episodes / s.episodes)} | "
                f"{_knocked_cell(f)} | {shown}{more} |"
            )
        out += [
            "",
            "*Block knocked over*: of those episodes, how many left the block they had picked "
            "tilted 10 deg or more when they failed, judged from the simulation (the summary's "
            "`block_at_failure`; no state reads it); *not judged* where the results were written "
            "before the judge existed. The recording of every failed episode is in "
            "`rrd/seed-NNNNNN.rrd`.",
        ]
        if s.replayed:
            differs = ", ".join(str(x) for x in s.replay_differs) or "none"
            out += [
                "",
                f"{s.replayed} failed episodes ran unrecorded, then again recorded for their "
                f"`.rrd`; replays that ended differently from the counted run: {differs}.",
            ]
    else:
        out.append("No episode failed.")
    out += ["", f"![failure reasons]({FIGURES['failures']})", "", "## Place error", ""]
    if s.place_percentiles:
        head = " | ".join(f"p{q}" for q, _ in s.place_percentiles)
        vals = " | ".join(f"{v:.1f}" for _, v in s.place_percentiles)
        out += [
            f"Horizontal distance (mm) of the placed block from the place point, over the "
            f"{len(s.place_error_mm)} judged deliveries (the judge accepts up to "
            f"{1000 * PLACE_TOLERANCE:g} mm).",
            "",
            f"| deliveries | {head} | max |",
            f"|---|{'---|' * len(s.place_percentiles)}---|",
            f"| {len(s.place_error_mm)} | {vals} | {max(s.place_error_mm):.1f} |",
        ]
    else:
        out.append("No delivery was judged.")
    out += [
        "",
        f"![place error]({FIGURES['place_error']})",
        "",
        "## Wall time per state",
        "",
        "Seconds of wall-clock time (noisy on shared cores); per episode is the total over the "
        "bench's episodes divided by their number. "
        + (
            f"{s.recorded} of the {s.episodes} counted runs recorded an `.rrd` (its rendering "
            "and logging are in their times); the others ran unrecorded."
            if s.recorded
            else "The counted runs were not recorded (no rendering or logging in these times)."
        ),
        "",
        "| state | visits | episodes | mean per visit | p95 per visit | mean per episode |",
        "|---|---|---|---|---|---|",
    ]
    for r in s.states:
        out.append(
            f"| {r.state} | {r.visits} | {r.episodes} | {r.mean_per_visit:.2f} | "
            f"{r.p95_per_visit:.2f} | {r.mean_per_episode:.2f} |"
        )
    wall, sim = np.asarray(s.wall_per_episode), np.asarray(s.sim_per_episode)
    out += [
        "",
        f"Per episode: wall {wall.mean():.1f} s (median {np.median(wall):.1f} s, max "
        f"{wall.max():.1f} s), simulated {sim.mean():.1f} s; {wall.sum() / 60:.1f} worker-minutes "
        "in all.",
        "",
        f"![wall time per state]({FIGURES['wall_per_state']})",
        "",
    ]
    return "\n".join(out)


def write_report(folder: Path, lines: Sequence[dict[str, Any]], settings: dict[str, Any]) -> Path:
    """Write ``report.md`` and the figures into ``folder`` (each file atomically); return the
    report's path."""
    s = summarize(lines)
    plot_success(s, folder / FIGURES["success"])
    plot_failures(s, folder / FIGURES["failures"])
    plot_place_error(s, folder / FIGURES["place_error"])
    plot_wall_per_state(s, folder / FIGURES["wall_per_state"])
    path = folder / REPORT_FILE
    write_text(path, markdown(s, settings))
    return path
