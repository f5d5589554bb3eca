"""The measured-force demand recomputed from a study's ``results.jsonl``, with variants: what in
the measure predicts the hold (docs/physics_study.md; docs/findings.md, "Measured-force demand").

``python -m experiments.physics.demand_variants runs/physics3d/results.jsonl`` prints, per
variant, the AUC (pooled and per model) over the tested grasps that have contact points:
- ``registered``: the measure as the study computes it (measured forces, the pads' torsion);
- ``no torsion``: the pads' torsional friction left out;
- ``grip target``: every finger's normal force bounded by the grip's target
  (:data:`controllers.hand.grip.GRIP_FORCE`) instead of what its pad measured.
The stored points and forces are rounded (0.01 mm, 1 mN), so ``registered`` reproduces the
study's values to about 1e-3, not bit for bit.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from controllers.hand.grip import GRIP_FORCE
from controllers.reach.coarse import ReachTarget
from experiments.physics.force_demand import PAD_TORSION, ForceDemand, held_force_demand
from experiments.physics.roc import roc
from hand_sim.scene import load_scene
from hand_sim.world import World


@dataclass(frozen=True)
class Variant:
    """How a variant bounds the normal forces and which torsion it gives the pads."""

    name: str
    measured_forces: bool
    torsion: float


VARIANTS: tuple[Variant, ...] = (
    Variant("registered", True, PAD_TORSION),
    Variant("no torsion", True, 0.0),
    Variant("grip target", False, PAD_TORSION),
)


@dataclass(frozen=True)
class BlockFacts:
    """What the measure needs of a study's block: its perceived outline and yaw, its weight."""

    target: ReachTarget
    weight: float  #: m*g (N)

    @classmethod
    def of(cls, obj: str) -> BlockFacts:
        """The block of the study's scene ``single_<obj>``, as :mod:`experiments.physics.study`
        builds it."""
        world = World.build(load_scene(f"single_{obj}"))
        name = world.scene.target
        return cls(ReachTarget.from_world(world, name), world.block_weight(name))


def scored(results: Sequence[dict]) -> list[dict]:
    """The tested grasps (held or dropped) whose contact points were recorded."""
    return [
        r
        for r in results
        if r["result"] in ("held", "dropped") and (r.get("measures") or {}).get("points")
    ]


def recompute(
    results: Sequence[dict], variant: Variant, blocks: dict[str, BlockFacts]
) -> list[ForceDemand]:
    """The demand of each record of ``results`` (all :func:`scored`) under ``variant``."""
    out = []
    for r in results:
        b = blocks[r["object"]]
        forces = r["grip_force"] if variant.measured_forces else [GRIP_FORCE] * 4
        out.append(
            held_force_demand(
                np.asarray(r["measures"]["points"], dtype=float),
                b.target.polygon,
                forces,
                b.weight,
                b.target.yaw,
                torsion=variant.torsion,
            )
        )
    return out


def auc_table(results: Sequence[dict]) -> list[str]:
    """One line per variant: AUC pooled and per model."""
    rs = scored(results)
    blocks = {obj: BlockFacts.of(obj) for obj in sorted({r["object"] for r in rs})}
    held = [r["result"] == "held" for r in rs]
    models = sorted({r.get("model", "planar") for r in rs})
    lines = []
    for v in VARIANTS:
        d = [x.demand for x in recompute(rs, v, blocks)]
        parts = [f"{v.name}: pooled {roc(d, held).auc:.3f}"]
        for m in models:
            idx = [i for i, r in enumerate(rs) if r.get("model", "planar") == m]
            parts.append(f"{m} {roc([d[i] for i in idx], [held[i] for i in idx]).auc:.3f}")
        lines.append(", ".join(parts))
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Print the variants' AUC for one ``results.jsonl``."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1 or not Path(args[0]).is_file():
        print(
            "usage: python -m experiments.physics.demand_variants RESULTS.jsonl "
            "(a physical study's results file)",
            file=sys.stderr,
        )
        return 2
    try:
        results = [json.loads(line) for line in Path(args[0]).read_text().splitlines() if line]
        lines = auc_table(results)
    except (json.JSONDecodeError, KeyError, TypeError) as e:
        print(f"error: {args[0]} is not a physical study's results file ({e})", file=sys.stderr)
        return 2
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
