"""Figures of the paper's experiments, drawn with matplotlib (Agg canvas, no pyplot state).

Building blocks that each draw on one matplotlib ``Axes`` (a line plot, a state-space heat map, a
grasp configuration on a polygon, Figure 18's square inset), a figure to lay them out on and its
PNG; :mod:`experiments.paper.paper_figures` assembles them into Figures 1, 2, 7, 9, 10, 11, 12, 17
and 18. matplotlib is imported when a figure is made, not with this module.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.polygon import Polygon
from graspsim_base.files import atomic_path

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Resolution of every PNG (pixels per inch of the figure sizes below).
DPI = 100
#: Size (inches) of one line plot, and of one grasp configuration panel.
PLOT_SIZE = (7.6, 4.4)
PANEL_SIZE = 1.9
#: Fill of a satisfactory grasp's polygon (S_G at most the success threshold) and of another.
GOOD_FILL, BAD_FILL = "#d2e1eb", "#f0d7d7"
#: Colour of the force arrows, and their length as a fraction of the polygon's largest vertex
#: coordinate.
ARROW_COLOUR = "#c81e1e"
ARROW_LENGTH = 0.35
#: Colours of the paths drawn over a state map, in order (the first stands out on viridis).
PATH_COLOURS = ("white", "#ff3c3c")


def moving_average(x: NDArray[np.float64], window: int = 10) -> NDArray[np.float64]:
    """Average over a sliding window of ``window`` epochs (shorter at the start), as the paper's
    10-epoch smoothing of Figures 1, 7 and 9."""
    c = np.cumsum(np.insert(np.asarray(x, dtype=float), 0, 0.0))
    n = np.arange(1, len(x) + 1)
    lo = np.maximum(0, n - window)
    return (c[n] - c[lo]) / (n - lo)


@dataclass(frozen=True)
class Series:
    label: str
    x: NDArray[np.float64]
    y: NDArray[np.float64]
    step: bool = False  #: draw as a step function (activations): y[i] holds from x[i] to x[i+1]


def new_figure(size: tuple[float, float] = PLOT_SIZE, title: str = "") -> Figure:
    """An empty figure of ``size`` inches on an Agg canvas, laid out by matplotlib's constrained
    layout, with an optional title over all its panels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    if title:
        fig.suptitle(title, x=0.01, ha="left")
    return fig


def save_png(fig: Figure, path: Path) -> None:
    """Write ``fig`` as a PNG (the same bytes for the same figure), atomically."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", metadata={"Software": None})


def _fmt(v: float) -> str:
    if abs(v) < 1e-9:
        return "0"
    return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.0f}"


def blank(ax: Axes) -> None:
    """An empty panel (a grid cell with nothing to show)."""
    ax.set_axis_off()


def line_plot(
    ax: Axes,
    series: Sequence[Series],
    title: str,
    xlabel: str,
    ylabel: str,
    ylim: tuple[float, float] | None = None,
    hlines: Sequence[tuple[float, str]] = (),
) -> None:
    """Lines (or steps) of ``series`` with a legend, and dashed reference values ``hlines``
    (value, label) labelled at the right end."""
    for s in series:
        x, y = np.asarray(s.x, float), np.asarray(s.y, float)
        if s.step:
            ax.step(x, y, where="post", label=s.label, linewidth=2)
        else:
            ax.plot(x, y, label=s.label, linewidth=2)
    for value, label in hlines:
        ax.axhline(value, color="grey", linestyle="--", linewidth=1)
        ax.annotate(
            label,
            (1.0, value),
            xycoords=("axes fraction", "data"),
            xytext=(-4, 3),
            textcoords="offset points",
            ha="right",
            va="bottom",
            color="grey",
            fontsize=8,
        )
    if ylim is not None:
        ax.set_ylim(*ylim)
    ax.set_xmargin(0)
    ax.grid(color="0.92")
    ax.set_title(title, loc="left")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(loc="best")


def state_heatmap(
    ax: Axes,
    grid: NDArray[np.float64],
    title: str,
    vmin: float | None = None,
    vmax: float | None = None,
    paths: Sequence[tuple[str, NDArray[np.float64]]] = (),
    colorbar: tuple[str, str] = ("low", "high"),
) -> None:
    """A 30 x 30 state-space map, grid[fc_bin, mc_bin]; x = eps'_FC, y = eps'_MC (Eq. 14), with a
    colour bar whose ends are named ``colorbar`` (low, high). Cells without a value take the low
    end's colour.

    ``paths`` are (label, (k, 2) Eq. 14 states) drawn over the map, with the start marked by a
    dot, a failure end by an X and a success end by an O (Figure 10); a label ending in "fail"
    gets the X.
    """
    from matplotlib import patheffects

    g = np.asarray(grid, dtype=float)
    n = g.shape[0]
    lo = float(np.nanmin(g)) if vmin is None else vmin
    hi = float(np.nanmax(g)) if vmax is None else vmax
    if hi <= lo:
        hi = lo + 1.0
    shown = np.where(np.isnan(g), lo, g)
    im = ax.imshow(shown.T, origin="lower", extent=(0, n, 0, n), cmap="viridis", vmin=lo, vmax=hi)
    ticks = np.arange(0, n + 1, 5)
    ax.set_xticks(ticks)
    ax.set_yticks(ticks)
    ax.set_xlabel(r"$\epsilon'_{FC}$ (Eq. 14)")
    ax.set_ylabel(r"$\epsilon'_{MC}$")
    ax.set_title(title, loc="left", fontsize=10)
    bar = ax.figure.colorbar(im, ax=ax, ticks=[lo, hi], fraction=0.05)
    bar.ax.set_yticklabels([f"{colorbar[0]} {_fmt(lo)}", f"{colorbar[1]} {_fmt(hi)}"])
    outline = [patheffects.Stroke(linewidth=4, foreground="black"), patheffects.Normal()]
    for i, (label, pts) in enumerate(paths):
        p = np.asarray(pts, float)
        p = p[np.isfinite(p).all(axis=1)]
        if not len(p):
            continue
        q = np.clip(p, 0.5, n - 0.5)  # eps' <= 0.5 drawn in the middle of bin 0, visible
        colour = PATH_COLOURS[min(i, len(PATH_COLOURS) - 1)]
        ax.plot(q[:, 0], q[:, 1], color=colour, linewidth=2, label=label, path_effects=outline)
        ax.plot(*q[0], "o", color=colour, markersize=5, path_effects=outline)
        end = "X" if label.endswith("fail") else "o"
        face = colour if end == "X" else "none"
        ax.plot(*q[-1], end, markersize=10, markeredgewidth=2, color=colour, mfc=face)
    if paths:
        ax.legend(loc="upper left", fontsize=8)
    ax.set_xlim(0, n)
    ax.set_ylim(0, n)


def grasp_panel(
    ax: Axes,
    polygon: Polygon,
    points: NDArray[np.float64],
    caption: str,
    start: NDArray[np.float64] | None = None,
    good: bool = True,
) -> None:
    """One grasp configuration (Figures 2, 10, 12): the polygon (filled by ``good``), its
    contacts (dots with inward force arrows) and a caption. ``points`` in the polygon's frame;
    ``start`` optional hollow circles for the initial contacts."""
    from matplotlib.patches import Polygon as PolygonPatch

    v = polygon.vertices
    reach = float(np.abs(v).max())
    ax.add_patch(
        PolygonPatch(v, closed=True, facecolor=GOOD_FILL if good else BAD_FILL, edgecolor="black")
    )
    if start is not None:
        s = np.asarray(start, float)
        ax.plot(s[:, 0], s[:, 1], "o", mfc="none", mec="grey", markersize=8)
    frames = polygon.locate(np.arctan2(points[:, 1], points[:, 0]))
    for p, nrm in zip(points, frames.normal, strict=True):
        tail = p + nrm * (ARROW_LENGTH * reach)  # outward normal: the arrow ends on the contact
        ax.annotate(
            "",
            xy=p,
            xytext=tail,
            arrowprops={"arrowstyle": "-|>", "color": ARROW_COLOUR, "linewidth": 1.5},
        )
    ax.plot(points[:, 0], points[:, 1], "o", color="black", markersize=5)
    half = reach / 0.72  # the polygon fills 72 % of the panel
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    for side in ax.spines.values():
        side.set_visible(False)
    ax.set_xlabel(caption, fontsize=8)


def square_activation_inset(
    ax: Axes, theta: NDArray[np.float64], alpha: NDArray[np.float64], beta: float
) -> None:
    """Figure 18's inset: the unit square with the moving contact's path along its outline grey
    where the MC controller was selected (alpha = 0) and white where FC was (alpha = 1); the
    fixed contact at ``beta`` (black), the path's start (hollow) and end (filled)."""
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Rectangle

    def boundary(t: NDArray[np.float64]) -> NDArray[np.float64]:
        r = 1.0 / np.maximum(np.abs(np.cos(t)), np.abs(np.sin(t)))
        return np.stack([r * np.cos(t), r * np.sin(t)], axis=-1)

    ax.add_patch(Rectangle((-1, -1), 2, 2, facecolor="0.98", edgecolor="black", linewidth=1))
    pts = boundary(np.asarray(theta, float))
    ax.plot(pts[:, 0], pts[:, 1], color="black", linewidth=9, solid_capstyle="round")
    segments = np.stack([pts[:-1], pts[1:]], axis=1)
    colours = ["0.45" if a < 0.5 else "white" for a in np.asarray(alpha)[: len(segments)]]
    ax.add_collection(LineCollection(segments, colors=colours, linewidths=5))
    fixed = boundary(np.array([beta]))[0]
    ax.plot(*fixed, "o", color="black", markersize=8)
    ax.plot(*pts[0], "o", mfc="none", mec="#1450c8", mew=2, markersize=9)
    ax.plot(*pts[-1], "o", color="#dc1e1e", markersize=9)
    ax.set_xlim(-1.25, 1.25)
    ax.set_ylim(-1.25, 1.25)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    for side in ax.spines.values():
        side.set_visible(False)
    ax.set_xlabel("grey: MC, white: FC\nblack: fixed contact", fontsize=8)
