"""The figure of docs/models.md's "Sensing contact from the tendon tensions": the tendon hand's
fingertip forces estimated from its tension sensors (:mod:`hand_sim.contact_estimate`) beside the
touch pads' readings, while the tendon loop squeezes the balanced top and lateral grasps of the
square (0.15 rad past contact), lifts the 0.3 kg block 8 cm and holds it: the rig of
tests/models/test_utah_mit_hand.py, the validation of tests/hand_sim/test_contact_estimate.py.

Usage: MUJOCO_GL=egl .venv/bin/python -m tools.contact_estimate_figure [--out PATH]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from benchmarks import hand_reachability as reach
from benchmarks.lift_rig import LIFT_TIME, tendon_lift
from benchmarks.lift_rig import TENDON_HAND as HAND
from hand_sim import robot
from tools.tendon_hand_figures import OUT, _pyplot

#: Sampling period (s) of the plotted forces, and the finger colours.
SAMPLE = 0.01
COLOURS = {"ff": "tab:red", "mf": "tab:green", "rf": "tab:blue", "th": "tab:orange"}


def grip_forces(kind: str, hand_samples: object) -> dict[str, np.ndarray]:
    """Time (s), pad readings and estimates (rows of 4, N) through squeeze, lift and hold."""
    _, found = reach.evaluate("square", kind, hand_samples, np.array([0.0]))
    if found is None:
        raise RuntimeError(f"no balanced {kind} grasp of the square found")
    rows: dict[str, list] = {"time": [], "pads": [], "estimate": []}

    def sample(model: object, data: object, estimate: object) -> None:
        rows["time"].append(data.time)
        rows["pads"].append([data.sensor(f"hand/{f}_touch").data[0] for f in robot.FINGERS])
        rows["estimate"].append(estimate.normal)

    tendon_lift(found, SAMPLE, sample)
    return {k: np.asarray(v) for k, v in rows.items()}


def plot(path: Path) -> None:
    """Both grasps side by side into ``path``."""
    hand_samples = reach.sample_hand(3000, np.random.default_rng(0), HAND)
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=False)
    for ax, kind in zip(axes, ("top", "lateral"), strict=True):
        log = grip_forces(kind, hand_samples)
        for f, name in enumerate(robot.FINGERS):
            c = COLOURS[name]
            ax.plot(log["time"], log["pads"][:, f], color=c, label=f"{name} touch pad")
            ax.plot(log["time"], log["estimate"][:, f], "--", color=c, label=f"{name} estimate")
        ax.axvspan(0.5, 0.5 + LIFT_TIME, color="0.9", zorder=0)
        ax.set_title(f"{kind} grasp of the square: squeeze, lift (grey), hold", fontsize=10)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("fingertip normal force (N)")
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=7, ncol=2)
    fig.suptitle("Tendon hand: contact force estimated from the 32 tensions vs the touch pads")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Write the figure."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=OUT / "utah_mit_hand_contact_estimate.png")
    args = ap.parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    plot(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
