"""The common heights the hand took in the 3-D study: how many grasps the hand placed at the
task's best height and at each next-best one (:data:`controllers.grasp.task_height.HEIGHT_TRIES`),
and how often those held."""

from __future__ import annotations

import numpy as np

from experiments.physics.compare import held_share


def height_section(results: list[dict]) -> list[str]:
    """Markdown lines: per height rank (0 = the task's best common height), the 3-D grasps the
    hand placed there, tested, held (Wilson 95 %) and the median raise of the contacts above the
    task's best height (mm); then the grasps no height reached. Empty without 3-D grasps."""
    rs = [r for r in results if r.get("model") == "3d"]
    if not rs:
        return []
    placed = [r for r in rs if r["result"] != "unreachable"]
    lines = [
        "### 3-D: the common height the hand took",
        "",
        "Rank 0 is the task's best common height (the least worst-task S_G); when the hand cannot "
        "take the contacts there, it tries the next-best common heights, 5 mm or more apart, in "
        "turn (`--height-tries`).",
        "",
        "| height rank | placed | tested | held (of tested, Wilson 95 %) | median raise (mm) |",
        "|---:|---:|---:|---:|---:|",
    ]
    for k in sorted({int(r.get("height_rank", 0)) for r in placed}):
        at = [r for r in placed if int(r.get("height_rank", 0)) == k]
        tested = [r for r in at if r["result"] in ("held", "dropped")]
        raise_mm = [
            1000.0 * float(r["height_raise"]) for r in at if r.get("height_raise") is not None
        ]
        median = f"{np.median(raise_mm):.1f}" if raise_mm else "-"
        lines.append(f"| {k} | {len(at)} | {len(tested)} | {held_share(at)} | {median} |")
    unreachable = len(rs) - len(placed)
    lines += ["", f"Reached at no height: {unreachable} of {len(rs)} 3-D grasps.", ""]
    return lines
