"""The study's regrasp (``--regrasp``): a grasp the hand cannot take sends the controller back to
contacts the hand holds, as the task cycle's Wrench Closure does (section 5: "back to Posture
Control when a contact is unreachable").

In the task cycle the grasp controller starts from the fingertips' own contacts (Fine Reach put
them on the block) and every few steps checks that the hand still reaches its contacts. The
study draws its initial contacts uniformly in theta instead, so some of its grasps ask for a
finger arrangement the hand does not have (docs/physics_study.md, "What it finds"). With
the regrasp, such a grasp is synthesized once more, by the same controller and its generator,
from where the best-ranked seed posture's pre-shaped fingertips touch the block (the
:func:`~experiments.physics.hand_placement.ranked_starts` pair first in rank for the grasp that
failed): the contacts Fine Reach would have given it. The grasp tested is then that second one,
marked :attr:`~experiments.physics.study.GraspOutcome.regrasped`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from controllers.reach.coarse import ReachTarget
from controllers.reach.fine import project_to_surface
from experiments.physics.compare import held_share
from experiments.physics.hand_placement import HandPosture, ranked_starts


def regrasp_start(
    target: ReachTarget,
    postures: list[HandPosture],
    theta: NDArray[np.float64],
    table_z: float,
    heights: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Contact coordinates (4,) and world heights (4,) of the pre-shaped fingertips of the seed
    posture ranked first for contacts ``theta`` (``heights``: their world z in 3-D, None for a
    planar grasp), projected onto the block's side faces at the fingertips' own heights."""
    if not postures:
        raise ValueError("no seed posture to regrasp from")
    posture = ranked_starts(target, theta, postures, table_z, heights)[0][0]
    # depth 0: keep each fingertip's own height (the pre-shape put it on the face already)
    surface = project_to_surface(target, posture.tips, depth=0.0, table_z=table_z)
    return surface.theta, surface.points[:, 2]


def regrasp_section(results: list[dict]) -> list[str]:
    """Markdown lines: per model, the grasps the hand could not take as synthesized and what
    their regrasps gave (reached, tested, held with its Wilson 95 % interval), beside the
    grasps taken as synthesized. Empty when no grasp was regrasped."""
    if not any(r.get("regrasped") for r in results):
        return []
    lines = [
        "### Regrasps (`--regrasp`)",
        "",
        "A grasp the hand cannot take as synthesized is synthesized once more by the same "
        "controller from where the hand's best seed posture touches the block; the tables above "
        "count the grasp tested (the second one where there was a regrasp).",
        "",
        "| model | grasps | taken as synthesized | held (of tested) | regrasped | reached "
        "after the regrasp | held (of tested) | unreachable after both |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]

    for m in sorted({r.get("model", "planar") for r in results}):
        rs = [r for r in results if r.get("model", "planar") == m]
        first = [r for r in rs if not r.get("regrasped")]
        again = [r for r in rs if r.get("regrasped")]
        reached = [r for r in again if r["result"] != "unreachable"]
        lines.append(
            f"| {m} | {len(rs)} | {sum(r['result'] != 'unreachable' for r in first)} "
            f"| {held_share(first)} | {len(again)} | {len(reached)} | {held_share(again)} "
            f"| {len(again) - len(reached)} |"
        )
    return [*lines, ""]
