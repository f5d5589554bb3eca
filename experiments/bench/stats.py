"""The numbers of a bench report, from the lines of ``results.jsonl`` alone: the success rate with
its Wilson score interval, the failure reasons, the place error of the judged deliveries and the
wall time each state of the task cycle (section 5.2, Figure 14) took.

An episode is *delivered* when every block it asked for went where it was asked (the success
rate counts these only), *delivered elsewhere* when it succeeded only because
``--place-fallback nearest`` took a block to another point than the one asked for (its own
count, never in the success rate), and *failed* otherwise. With ``--cycles N|all`` the report
also counts, per cycle, the blocks delivered, delivered elsewhere and failed, and the share of
tables cleared (every block of the scene delivered)."""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import ndtri

from fsm.states import State

#: Two-sided 95 % normal quantile (1.95996...).
Z95 = float(ndtri(0.975))
#: Percentiles of the place error the report gives.
PLACE_PERCENTILES = (50, 90, 95, 99)
#: Label of a failed episode without a named reason (should not happen; shown if it does).
NO_REASON = "(no reason given)"
#: An episode's outcome (:func:`outcome`).
DELIVERED, ELSEWHERE, FAILED = "delivered", "delivered elsewhere", "failed"


def outcome(line: dict[str, Any]) -> str:
    """DELIVERED, ELSEWHERE (a success only because a block went to another point than the one
    asked for) or FAILED, of one results line (a line without ``delivered_elsewhere`` counts as
    delivered where asked: its judge knew no other point)."""
    if not line.get("success"):
        return FAILED
    moved = any(c.get("delivered_elsewhere") for c in line.get("cycles") or [])
    return ELSEWHERE if moved else DELIVERED


@dataclass(frozen=True)
class CycleRow:
    """Blocks of cycle ``cycle`` (0-based) over the episodes: how many reached it (entered its
    Select/Model and picked or failed), were delivered, delivered elsewhere, or failed."""

    cycle: int
    reached: int
    delivered: int
    elsewhere: int
    failed: int


def cycle_rows(eps: Sequence[dict[str, Any]]) -> tuple[CycleRow, ...]:
    """Per-cycle counts (:class:`CycleRow`): a cycle's block is delivered (or elsewhere) when its
    record succeeded; an episode that failed failed in the cycle after its last success."""
    counts: dict[int, list[int]] = defaultdict(lambda: [0, 0, 0, 0])
    for e in eps:
        good = [c for c in e.get("cycles") or [] if c.get("success")]
        for k, c in enumerate(good):
            row = counts[k]
            row[0] += 1
            row[2 if c.get("delivered_elsewhere") else 1] += 1
        if not e.get("success"):
            row = counts[len(good)]
            row[0] += 1
            row[3] += 1
    return tuple(CycleRow(k, *counts[k]) for k in sorted(counts))


def table_cleared(line: dict[str, Any]) -> bool:
    """Whether every block of the episode's scene was delivered (where asked or elsewhere)."""
    delivered = sum(1 for c in line.get("cycles") or [] if c.get("success"))
    return (
        bool(line.get("success"))
        and line.get("blocks") is not None
        and (delivered >= int(line["blocks"]))
    )


@dataclass(frozen=True)
class Interval:
    """A proportion and its confidence interval (all in [0, 1])."""

    estimate: float
    low: float
    high: float


def wilson_interval(successes: int, trials: int, z: float = Z95) -> Interval:
    """Wilson score interval of a binomial proportion (Wilson 1927; Agresti & Coull 1998):
    centre (p + z^2/2n) / (1 + z^2/n), half-width z sqrt(p(1-p)/n + z^2/4n^2) / (1 + z^2/n)."""
    if trials <= 0 or not 0 <= successes <= trials:
        raise ValueError(f"need 0 <= successes <= trials and trials > 0, got {successes}/{trials}")
    n, p = float(trials), successes / trials
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2.0 * n)) / denom
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n)) / denom
    # the interval contains p: at p = 0 or 1, rounding could leave it a hair short of it
    return Interval(p, max(0.0, min(p, centre - half)), min(1.0, max(p, centre + half)))


@dataclass(frozen=True)
class FailureRow:
    reason: str
    episodes: int
    seeds: tuple[int, ...]
    #: of them, episodes whose failed cycle left its block knocked over (judged from the
    #: simulation, ``block_at_failure`` of the summary)
    knocked_over: int = 0
    #: of them, episodes whose summary has that judgement at all (older results have none:
    #: their count is unknown, not zero)
    judged: int = 0


def block_at_failure(episode: dict[str, Any]) -> dict[str, Any] | None:
    """The judged state of a failed episode's block (its last cycle's), or None."""
    cycles = episode.get("cycles") or []
    state = cycles[-1].get("block_at_failure") if cycles else None
    return state if isinstance(state, dict) else None


def knocked_over(episode: dict[str, Any]) -> bool:
    """Whether a failed episode's last cycle left its block knocked over (judged)."""
    state = block_at_failure(episode)
    return bool(state and state.get("knocked_over"))


@dataclass(frozen=True)
class StateRow:
    """Wall time of one state over the episodes (seconds)."""

    state: str
    visits: int
    episodes: int  #: episodes that entered it
    total: float
    mean_per_visit: float
    p95_per_visit: float
    mean_per_episode: float  #: total over all the bench's episodes


@dataclass(frozen=True)
class BenchSummary:
    """Everything the report shows."""

    episodes: int
    successes: int  #: delivered where asked (DELIVERED)
    rate: Interval
    by_blocks: tuple[tuple[int | None, int, int], ...]  #: (blocks, episodes, successes)
    failures: tuple[FailureRow, ...]  #: most frequent first
    place_error_mm: tuple[float, ...]  #: every judged delivery, in seed order
    place_percentiles: tuple[tuple[int, float], ...]  #: (percentile, mm); empty if none judged
    states: tuple[StateRow, ...]  #: in the order of the task cycle
    wall_per_episode: tuple[float, ...]  #: s
    sim_per_episode: tuple[float, ...]  #: s
    seeds: tuple[int, ...]
    elsewhere: int = 0  #: episodes delivered elsewhere (ELSEWHERE), not in the success rate
    cycles: tuple[CycleRow, ...] = ()
    tables_cleared: int = 0
    #: (approach of the first cycle, episodes, successes); "none" when no coarse path was found
    by_approach: tuple[tuple[str, int, int], ...] = ()
    #: failed episodes run again, recorded, for their .rrd, and the seeds whose replay ended
    #: differently (see :func:`experiments.bench.jobs.run_job`)
    replayed: int = 0
    replay_differs: tuple[int, ...] = ()
    recorded: int = 0  #: episodes whose wall times include recording


def first_approach(line: dict[str, Any]) -> str:
    """The approach (top, lateral) the episode's first cycle took, ``none`` when it took none
    (it failed before Coarse Reach chose one)."""
    cycles = line.get("cycles") or []
    return (cycles[0].get("approach") if cycles else None) or "none"


def tally(keys: Sequence[Any], ok: Sequence[bool]) -> dict[Any, list[int]]:
    """Per key: [episodes, successes]."""
    rows: dict[Any, list[int]] = defaultdict(lambda: [0, 0])
    for key, good in zip(keys, ok, strict=True):
        rows[key][0] += 1
        rows[key][1] += good
    return rows


def _state_order(names: set[str]) -> list[str]:
    known = [s.value for s in State if s.value in names]
    return known + sorted(names - set(known))


def summarize(lines: Sequence[dict[str, Any]]) -> BenchSummary:
    """The report's numbers from ``results.jsonl`` lines (one per episode; a seed's first line
    counts if it appears twice)."""
    unique: dict[int, dict[str, Any]] = {}
    for line in lines:
        unique.setdefault(int(line["seed"]), line)
    eps = [unique[s] for s in sorted(unique)]
    if not eps:
        raise ValueError("no episode to summarize")
    kinds = [outcome(e) for e in eps]
    ok = [k == DELIVERED for k in kinds]
    blocks = tally([e.get("blocks") for e in eps], ok)
    approaches = tally([first_approach(e) for e in eps], ok)
    by_blocks = tuple(
        (b, n, k) for b, (n, k) in sorted(blocks.items(), key=lambda kv: (kv[0] is None, kv[0]))
    )
    failed: dict[str, list[int]] = defaultdict(list)
    knocked: dict[str, int] = defaultdict(int)
    judged: dict[str, int] = defaultdict(int)
    for e, kind in zip(eps, kinds, strict=True):
        if kind == FAILED:
            reason = e.get("failure") or NO_REASON
            failed[reason].append(int(e["seed"]))
            knocked[reason] += knocked_over(e)
            judged[reason] += block_at_failure(e) is not None
    failures = tuple(
        FailureRow(reason, len(seeds), tuple(seeds), knocked[reason], judged[reason])
        for reason, seeds in sorted(failed.items(), key=lambda kv: (-len(kv[1]), kv[0]))
    )
    errors = [
        float(c["judgement"]["place_error_mm"])
        for e in eps
        for c in e.get("cycles") or []
        if isinstance(c.get("judgement"), dict) and c["judgement"].get("place_error_mm") is not None
    ]
    percentiles = (
        tuple((q, float(np.percentile(errors, q))) for q in PLACE_PERCENTILES) if errors else ()
    )
    per_visit: dict[str, list[float]] = defaultdict(list)
    entered: Counter[str] = Counter()
    for e in eps:
        seen = set()
        for v in e.get("visits") or []:
            per_visit[v["state"]].append(float(v["wall_seconds"]))
            seen.add(v["state"])
        entered.update(seen)
    states = tuple(
        StateRow(
            state=name,
            visits=len(per_visit[name]),
            episodes=entered[name],
            total=float(np.sum(per_visit[name])),
            mean_per_visit=float(np.mean(per_visit[name])),
            p95_per_visit=float(np.percentile(per_visit[name], 95)),
            mean_per_episode=float(np.sum(per_visit[name])) / len(eps),
        )
        for name in _state_order(set(per_visit))
    )
    k = sum(ok)
    return BenchSummary(
        episodes=len(eps),
        successes=k,
        rate=wilson_interval(k, len(eps)),
        by_blocks=by_blocks,
        failures=failures,
        place_error_mm=tuple(errors),
        place_percentiles=percentiles,
        states=states,
        wall_per_episode=tuple(float(e.get("wall_time", 0.0)) for e in eps),
        sim_per_episode=tuple(float(e.get("sim_time", 0.0)) for e in eps),
        seeds=tuple(sorted(unique)),
        elsewhere=kinds.count(ELSEWHERE),
        cycles=cycle_rows(eps),
        replayed=sum("replay" in e for e in eps),
        replay_differs=tuple(
            int(e["seed"]) for e in eps if "replay" in e and not e["replay"].get("same")
        ),
        recorded=sum(bool((e.get("options") or {}).get("record", True)) for e in eps),
        tables_cleared=sum(table_cleared(e) for e in eps),
        by_approach=tuple((a, n, k) for a, (n, k) in sorted(approaches.items())),
    )


def seed_ranges(seeds: Sequence[int]) -> str:
    """Sorted seeds as compact ranges: ``0-4, 7, 9-10``."""
    parts: list[str] = []
    ordered = sorted(set(seeds))
    i = 0
    while i < len(ordered):
        j = i
        while j + 1 < len(ordered) and ordered[j + 1] == ordered[j] + 1:
            j += 1
        parts.append(str(ordered[i]) if i == j else f"{ordered[i]}-{ordered[j]}")
        i = j + 1
    return ", ".join(parts)
