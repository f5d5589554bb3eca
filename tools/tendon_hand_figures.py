"""The figures of docs/models.md's tendon-driven hand section, drawn from
models/utah_mit_hand/scene.xml:

* ``docs/models/utah_mit_hand_views.png``: the hand in a half-closed posture from the front (the
  fingertips' side), the side (+x) and the top (the grasping face), rendered with
  ``mujoco.Renderer`` (run with ``MUJOCO_GL=egl`` on a machine without a display);
* ``docs/models/utah_mit_hand_tensions.png``: the first finger's eight tendon tensions (measured
  by the tension sensors, and as commanded) while
  :class:`controllers.hand.tendon_control.TendonHandController` closes the hand (palm up, with
  gravity) over 1 s, holds 0.5 s and opens it over 1 s.

Usage: MUJOCO_GL=egl .venv/bin/python -m tools.tendon_hand_figures [--out docs/models]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from types import ModuleType

import mujoco
import numpy as np

from controllers.hand.tendon_control import TendonHandController
from hand_sim import robot

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "models" / "utah_mit_hand" / "scene.xml"
OUT = REPO / "docs" / "models"
#: Half-closed posture of every digit (j0, j1, j2, j3; rad) for the pictures and the closed
#: target of the motion.
HALF_CLOSED = (0.0, 0.7, 0.6, 0.45)
CLOSED = (0.0, 1.3, 1.2, 0.9)
#: Free-camera views (azimuth, elevation in degrees) of the hand frame: +y fingers, +z palm normal.
VIEWS = {
    "front (from the fingertips)": (-90.0, -12.0),
    "side (from +x)": (180.0, -12.0),
    "top (the grasping face, fingers up)": (90.0, -89.0),
}
#: The motion: close over CLOSE_TIME, hold HOLD_TIME, open over CLOSE_TIME (s).
CLOSE_TIME, HOLD_TIME = 1.0, 0.5


def _pyplot() -> ModuleType:
    """matplotlib.pyplot on the Agg backend (no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _posture(model: mujoco.MjModel, data: mujoco.MjData, q: tuple[float, ...]) -> None:
    for finger in robot.FINGERS:
        for i, value in enumerate(q):
            data.qpos[model.joint(f"{finger}j{i}").qposadr[0]] = value
    mujoco.mj_forward(model, data)


def render_views(path: Path, size: int = 480) -> None:
    """The three views side by side, titled, into ``path``."""
    model = mujoco.MjModel.from_xml_path(str(SCENE))
    data = mujoco.MjData(model)
    _posture(model, data, HALF_CLOSED)
    renderer = mujoco.Renderer(model, size, size)
    camera = mujoco.MjvCamera()
    camera.lookat[:] = (0.0, 0.02, 0.04)
    camera.distance = 0.36
    images = []
    try:
        for azimuth, elevation in VIEWS.values():
            camera.azimuth, camera.elevation = azimuth, elevation
            renderer.update_scene(data, camera)
            images.append(renderer.render())
    finally:
        renderer.close()
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(12, 4.3))
    for ax, title, image in zip(axes, VIEWS, images, strict=True):
        ax.imshow(image)
        ax.set_title(title)
        ax.axis("off")
    fig.suptitle("models/utah_mit_hand: tendon-driven Utah/MIT hand, half closed")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def close_and_open(t: float) -> np.ndarray:
    """Joint targets (16) of the motion at time ``t``: smooth close, hold, smooth open."""
    closed = np.tile(CLOSED, len(robot.FINGERS))
    if t < CLOSE_TIME:
        s = 0.5 - 0.5 * np.cos(np.pi * t / CLOSE_TIME)
    elif t < CLOSE_TIME + HOLD_TIME:
        s = 1.0
    else:
        s = 0.5 + 0.5 * np.cos(np.pi * min(1.0, (t - CLOSE_TIME - HOLD_TIME) / CLOSE_TIME))
    return s * closed


def plot_tensions(path: Path) -> None:
    """The first finger's eight tensions during :func:`close_and_open`, into ``path``."""
    model = mujoco.MjModel.from_xml_path(str(SCENE))
    data = mujoco.MjData(model)
    ctrl = TendonHandController.for_model(model)
    log = ctrl.run(data, close_and_open, 2 * CLOSE_TIME + HOLD_TIME + 0.3).arrays()
    time = log["time"]
    plt = _pyplot()
    names = ("j0 abduction", "j1 MCP", "j2 PIP", "j3 DIP")
    fig, axes = plt.subplots(4, 2, figsize=(10, 8), sharex=True)
    for i, name in enumerate(names):
        for side, column in (("flex", 0), ("ext", 1)):
            ax = axes[i, column]
            k = 2 * i + column  # ff's joints come first in the layout, flexor then extensor
            ax.plot(time, log["measured"][:, k], label="measured (sensor)")
            ax.plot(time, log["commanded"][:, k], "--", lw=0.8, label="commanded")
            ax.set_title(f"ff{name[:2]}_{side} ({name})", fontsize=9)
            ax.set_ylabel("tension (N)")
            ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(
        "First finger's tendon tensions: close 1 s, hold 0.5 s, open 1 s (palm up, gravity); "
        f"pretension {ctrl.pretension:g} N"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Write both figures into ``--out``."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=OUT, help="folder of the PNG files")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    render_views(args.out / "utah_mit_hand_views.png")
    plot_tensions(args.out / "utah_mit_hand_tensions.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
