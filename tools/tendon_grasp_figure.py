"""docs/models.md's figure of a finger's tendon tensions during a grasp:
``docs/models/utah_mit_hand_grasp_tensions.png``.

The tendon-driven hand takes one grasp of the physical study (``python -m experiments.physics``,
3-D model, ``--hand tendon``: the square, the knowledge-based controller, study seed 0, the first
grasp index that holds), closes and squeezes it, then goes through the study's test (the block
hangs with the table gone, is pushed by its weight along +-x, +-y, +-z in turn, and is lifted).
Every control period the first finger's eight tendon tensions (its four joints' flexor and
extensor, read by the tension sensors), its pad-force estimate from those tensions
(``World.touch``) and the push on the block are logged and plotted against simulated time.

Usage: MUJOCO_GL=egl .venv/bin/python -m tools.tendon_grasp_figure [--out docs/models]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from controllers.grasp.objects import PAPER_OBJECTS
from controllers.grasp.registry import make_composer
from controllers.hand.grip import GRIP_FORCE
from experiments.physics.report import CONTROLLERS
from experiments.physics.study import (
    GraspOutcome,
    Job,
    StudyWorld,
    initial_contacts,
    out_name,
    test_grasp,
)
from hand_sim.world import World
from tools.tendon_hand_figures import OUT, _pyplot

#: The grasp shown: object, controller, study seed, and how many grasp indices to try for one
#: that holds (the first that does is drawn).
OBJECT, CONTROLLER, SEED, INDICES = "square", "kb", 0, 6
#: Joint names of a digit's four joints, in the tension layout's order.
JOINTS = ("j0 abduction", "j1 MCP", "j2 PIP", "j3 DIP")


@dataclass
class TensionLog:
    """What :func:`record` keeps at every control period of the grasp's world."""

    time: list[float] = field(default_factory=list)
    tensions: list[np.ndarray] = field(default_factory=list)  #: (4, 2) ff: flexor, extensor
    pad_force: list[float] = field(default_factory=list)  #: ff's estimate (N)
    push: list[np.ndarray] = field(default_factory=list)  #: force on the block (N, world)
    squeezed_at: float | None = None  #: time the squeeze ended (the test starts)

    def record(self, world: World) -> None:
        """``World.on_step``: log the first finger's tensions, its pad force and the push."""
        body = world.block_body_id(out_name(world))
        self.time.append(world.time)
        self.tensions.append(world.hand_tensions()[:4].copy())
        self.pad_force.append(float(world.touch()[0]))
        self.push.append(world.data.xfrc_applied[body, :3].copy())


def held_grasp() -> tuple[GraspOutcome, TensionLog]:
    """The first of :data:`INDICES` grasps of the chosen object and controller that the tendon
    hand holds, with its log (the last tried when none holds)."""
    sw = StudyWorld.of(OBJECT, "3d", hand="tendon")
    composer = make_composer(CONTROLLER)
    job = Job(
        OBJECT,
        PAPER_OBJECTS.index(OBJECT),
        CONTROLLER,
        CONTROLLERS.index(CONTROLLER),
        tuple(range(INDICES)),
        SEED,
        "3d",
        hand="tendon",
    )
    for index in job.indices:
        log = TensionLog()
        theta0, rng = initial_contacts(job, index)
        out = GraspOutcome(OBJECT, CONTROLLER, index, theta0, model="3d")

        def squeezed(stage: str, world: World, log: TensionLog = log) -> None:
            if stage == "grasp":
                log.squeezed_at = world.time

        sw.world.on_step = log.record
        try:
            test_grasp(sw, composer, rng, out, squeezed, regrasp=False)
        finally:
            sw.world.on_step = None
        if out.result == "held":
            break
    return out, log


def push_spans(t: np.ndarray, push: np.ndarray) -> list[tuple[float, float, str]]:
    """(start, end, label) of each run of one push on the block (``+x`` ... ``-z``, the
    direction of the force's largest component)."""
    spans: list[tuple[float, float, str]] = []
    start = None
    for k in range(len(t) + 1):
        on = k < len(t) and np.linalg.norm(push[k]) > 0
        same = on and start is not None and np.allclose(push[k], push[start])
        if start is not None and not same:
            axis = int(np.argmax(np.abs(push[start])))
            sign = "+" if push[start][axis] > 0 else "-"
            spans.append((float(t[start]), float(t[k - 1]), sign + "xyz"[axis]))
            start = None
        if on and start is None:
            start = k
    return spans


def plot_grasp_tensions(path: Path) -> GraspOutcome:
    """Draw :func:`held_grasp`'s log into ``path``; the grasp's outcome."""
    out, log = held_grasp()
    t = np.asarray(log.time)
    T = np.asarray(log.tensions)  # (n, 4, 2)
    pushes = np.asarray(log.push)
    push = np.linalg.norm(pushes, axis=1)
    spans = push_spans(t, pushes)
    plt = _pyplot()
    fig, axes = plt.subplots(5, 1, figsize=(10, 11), sharex=True)
    top = axes[0]
    top.plot(t, log.pad_force, label="ff pad force, estimated from its tensions (N)")
    top.plot(t, push, label="push on the block (N)")
    top.set_ylabel("N")
    top.legend(fontsize=8, loc="center left", framealpha=0.9)
    for i, name in enumerate(JOINTS):
        ax = axes[i + 1]
        ax.plot(t, T[:, i, 0], label="flexor")
        ax.plot(t, T[:, i, 1], "--", label="extensor")
        ax.set_ylabel("tension (N)")
        ax.set_title(f"ff {name}", fontsize=9)
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=8, loc="center right", framealpha=0.9)
    for ax in axes:
        if log.squeezed_at is not None:
            ax.axvline(log.squeezed_at, color="k", lw=0.8, ls=":")
        for k, (a, b, _) in enumerate(spans):
            ax.axvspan(a, b, color="0.85" if k % 2 else "0.93", zorder=0)
    for a, b, label in spans:
        top.text(
            0.5 * (a + b),
            0.9,
            f"push {label}",
            ha="center",
            fontsize=8,
            transform=top.get_xaxis_transform(),
        )
    if spans:
        top.text(spans[-1][1] + 0.2, 0.9, "lift", fontsize=8, transform=top.get_xaxis_transform())
    axes[-1].set_xlabel(
        "simulated time (s); dotted: the squeeze ends and the test starts (hang, pushes, lift)"
    )
    fig.suptitle(
        f"Tendon hand, first finger (ff), one grasp of the {OBJECT}: {CONTROLLER}, 3-D, study "
        f"seed {SEED}, grasp {out.index}\nclose and squeeze to {GRIP_FORCE:g} N, then the "
        f"physical test; {out.result}"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> int:
    """Write the figure into ``--out`` and print the grasp's outcome."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=OUT, help="folder of the PNG file")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    out = plot_grasp_tensions(args.out / "utah_mit_hand_grasp_tensions.png")
    print(
        f"{OBJECT} {CONTROLLER} grasp {out.index}: {out.result}; grip force "
        f"{out.grip_force} N; worst turn {max(out.turn.values(), default=0):.3f} rad"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
