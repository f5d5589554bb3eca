"""The paper's figures from a ``reproduce`` run (first seed): Figures 1, 2, 7, 9, 10, 11, 12, 17
and 18, assembled from the building blocks of :mod:`experiments.paper.figures`."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.atomic import TEST_ROTATION_DEG, sector_angle
from controllers.grasp.objects import PAPER_OBJECTS, paper_object
from controllers.grasp.optimal_control import BETA, PAPER_THETA_T, OptimalPath
from controllers.grasp.polygon import Polygon
from controllers.grasp.qlearning import scaled_error, state_bin
from controllers.grasp.score import SUCCESS_THRESHOLD
from controllers.grasp.trials import TrialBatch
from experiments.paper import figures as fig
from experiments.paper.tables import PAPER_TABLE1_AVERAGE

#: Two final contacts are "the same configuration" (Figure 12) when on the same edge with surface
#: coordinates (unit-moment frame) in the same bin of this width.
CONFIG_RESOLUTION = 0.1
FIGURES = (
    "fig01_atomic_learning.png",
    "fig02_atomic_configurations.png",
    "fig07_ql_learning.png",
    "fig09_failure_curves.png",
    "fig10_state_paths.png",
    "fig11_fs_map_visits.png",
    "fig12_configurations.png",
    "fig17_theta.png",
    "fig18_activation.png",
)


def configurations(
    polygon: Polygon, theta: NDArray[np.float64], s_g: NDArray[np.float64], top: int
) -> list[tuple[NDArray[np.float64], float, float]]:
    """The ``top`` most frequent final configurations of trials on ``polygon`` (final contact
    coordinates ``theta`` (T, n), scores ``s_g``): (points in the unit-moment frame, fraction of
    trials, S_G), contacts grouped as in :data:`CONFIG_RESOLUTION`."""
    unit = polygon.unit_moment()
    frames = unit.locate(theta)
    keys = [
        tuple(
            sorted(
                zip(
                    frames.edge[j].tolist(),
                    np.round(frames.surface[j] / CONFIG_RESOLUTION).astype(int).tolist(),
                    strict=True,
                )
            )
        )
        for j in range(len(theta))
    ]
    out = []
    for key, n in Counter(keys).most_common(top):
        j = keys.index(key)
        out.append((frames.point[j], n / len(theta), float(s_g[j])))
    return out


def _line_figure(path: Path, series: list[fig.Series], title: str, ylabel: str, **kw) -> None:
    """One line plot (:func:`experiments.paper.figures.line_plot`) as a PNG."""
    f = fig.new_figure()
    fig.line_plot(f.add_subplot(), series, title, kw.pop("xlabel", "epoch"), ylabel, **kw)
    fig.save_png(f, path)


def write_figures(out: Path, results: dict, seed: int, cfg, opt: OptimalPath) -> None:
    """Every figure of the paper from the tasks' ``results`` of ``seed``."""
    sm = fig.moving_average
    ql = results[("qlearning", seed)]
    atomic = results[("atomic", seed)]
    curves = results[("curves", seed)]
    _line_figure(
        out / "fig01_atomic_learning.png",
        [
            fig.Series(
                "atomic Q-learning (irregular triangle)",
                np.arange(1, cfg.atomic_epochs + 1),
                100 * sm(atomic["curve"]),
            )
        ],
        "Figure 1: failure rate during training (10-epoch smoothing)",
        "failure rate (%)",
        ylim=(0, 100 * max(0.05, float(sm(atomic["curve"]).max()) * 1.1)),
    )
    ep = np.arange(1, cfg.ql_epochs + 1)
    _line_figure(
        out / "fig07_ql_learning.png",
        [fig.Series("Q-learning composition, 9 objects", ep, 100 * sm(ql["curve"]))],
        "Figure 7: failure rate during training (10-epoch smoothing)",
        "failure rate (%)",
        hlines=[(PAPER_TABLE1_AVERAGE["ql"], "paper QL test 8.33 %")],
    )
    _line_figure(
        out / "fig09_failure_curves.png",
        [
            fig.Series(
                "(a) PI (predictor used after epoch 10)",
                np.arange(1, len(curves["pi"]) + 1),
                100 * sm(curves["pi"]),
            ),
            fig.Series(
                "(b) knowledge-based",
                np.arange(1, len(curves["kb"]) + 1),
                100 * sm(curves["kb"]),
            ),
            fig.Series("(c) Q-learning", ep, 100 * sm(ql["curve"])),
        ],
        "Figure 9: failure rate per epoch (10-epoch smoothing)",
        "failure rate (%)",
    )
    _figure10_11(out, results[("tables", seed)]["predictor"], curves)
    _figure12(out, {**results[("tables", seed)]["fig12"], **ql["fig12"]})
    _figure2(out, atomic["tests"])
    _line_figure(
        out / "fig17_theta.png",
        [fig.Series("theta(t)", opt.t, opt.theta)],
        f"Figure 17: theta(t), theta(T) = {opt.theta_final:.4f} rad (paper 3.6052)",
        "theta (rad)",
        xlabel="t",
        hlines=[(PAPER_THETA_T, "3.6052")],
    )
    f = fig.new_figure((fig.PLOT_SIZE[0] + 2.4, fig.PLOT_SIZE[1]))
    plot, inset = f.subplots(1, 2, width_ratios=(fig.PLOT_SIZE[0], 2.4))
    fig.line_plot(
        plot,
        [fig.Series("alpha (1: FC, 0: MC)", opt.t, opt.alpha, step=True)],
        "Figure 18: time-optimal activation",
        "t",
        "alpha",
        ylim=(-0.1, 1.1),
    )
    fig.square_activation_inset(inset, opt.theta, opt.alpha, BETA)
    fig.save_png(f, out / "fig18_activation.png")


def _figure2(out: Path, tests) -> None:
    """Figure 2: the most frequent atomic-action configurations (at most four per row), as
    trained, rotated and satisfactory, rotated and unsatisfactory."""
    tri = paper_object("irregular_triangle")
    trained, rotated = tests
    unit_t = tri.unit_moment()
    unit_r = tri.rotated(np.deg2rad(TEST_ROTATION_DEG)).unit_moment()
    rows = [(trained, unit_t, trained.most_frequent), (rotated, unit_r, rotated.most_frequent),
            (rotated, unit_r, rotated.most_frequent_failures)]  # fmt: skip
    side = fig.PANEL_SIZE
    f = fig.new_figure(
        (4 * side, 3 * side + 0.4),
        "Figure 2: as trained; rotated 30 deg, satisfactory; rotated, unsatisfactory",
    )
    axes = f.subplots(3, 4, squeeze=False)
    for (t, unit, configs), row in zip(rows, axes, strict=True):
        for ax in row[len(configs) :]:
            fig.blank(ax)
        for ax, (sectors, n, s) in zip(row, configs, strict=False):
            fig.grasp_panel(
                ax,
                unit,
                unit.point_at(sector_angle(np.array(sectors))),
                f"{t.label}: {n}x, " + (f"S_G {s:.2f}" if np.isfinite(s) else "infeasible"),
                good=s <= SUCCESS_THRESHOLD,
            )
    fig.save_png(f, out / "fig02_atomic_configurations.png")


def _figure10_11(out: Path, predictor, curves: dict) -> None:
    """Figure 10 (KB vs PI paths from one start on the square) and Figure 11 (F/S map, visits)."""
    kb: TrialBatch = curves["square"]["kb"]
    pi: TrialBatch = curves["square"]["pi"]
    theta0 = curves["square_theta0"]
    fs = predictor.fs_map()
    both = np.flatnonzero(~kb.success & pi.success)
    j = int(both[0]) if both.size else 0

    def path(r: TrialBatch) -> NDArray[np.float64]:
        s = r.states[j]
        s = s[np.isfinite(s[:, 0])]
        return np.stack([scaled_error(s[:, 0]), scaled_error(s[:, 1])], axis=1)

    tag = {True: "success", False: "fail"}
    side = fig.PANEL_SIZE
    f = fig.new_figure((5.6 + side, 2 * side + 0.3))
    grid = f.add_gridspec(2, 2, width_ratios=(5.6, side))
    fig.state_heatmap(
        f.add_subplot(grid[:, 0]),
        fs,
        "Figure 10: paths on the square over the F/S map",
        -1,
        1,
        paths=[
            (f"KB: {tag[bool(kb.success[j])]}", path(kb)),
            (f"PI: {tag[bool(pi.success[j])]}", path(pi)),
        ],
        colorbar=("success", "failure"),
    )
    unit = paper_object("square").unit_moment()
    start = unit.point_at(theta0[j])
    for row, (k, r) in enumerate((("KB", kb), ("PI", pi))):
        fig.grasp_panel(
            f.add_subplot(grid[row, 1]),
            unit,
            r.points[j],
            f"{k}: S_G {r.s_g[j]:.2f}",
            start=start,
            good=bool(r.success[j]),
        )
    fig.save_png(f, out / "fig10_state_paths.png")

    def visits(r: TrialBatch) -> NDArray[np.float64]:
        s = r.states[np.isfinite(r.states[..., 0])]
        h = np.zeros((30, 30))
        np.add.at(h, (state_bin(s[:, 0]), state_bin(s[:, 1])), 1.0)
        return np.log10(1.0 + 1e4 * h / h.sum())

    f = fig.new_figure((3 * 4.6 + side, 2 * side + 0.6), "Figure 11")
    grid = f.add_gridspec(2, 4, width_ratios=(4.6, 4.6, 4.6, side))
    fig.state_heatmap(
        f.add_subplot(grid[:, 0]),
        fs,
        "(a) F/S predictor output",
        -1,
        1,
        colorbar=("success", "failure"),
    )
    for col, (r, name) in enumerate(((kb, "KB"), (pi, "PI")), start=1):
        fig.state_heatmap(
            f.add_subplot(grid[:, col]),
            visits(r),
            f"({'bc'[col - 1]}) {name} visits, square ({100 * r.failure_rate:.0f}% fail)",
            colorbar=("rare", "log freq"),
        )
    for row, ok in enumerate((False, True)):
        ax = f.add_subplot(grid[row, 3])
        k = np.flatnonzero(kb.success == ok)
        if not k.size:
            fig.blank(ax)
            continue
        fig.grasp_panel(
            ax,
            unit,
            kb.points[k[0]],
            f"KB {'success' if ok else 'failure'} S_G {kb.s_g[k[0]]:.2f}",
            good=ok,
        )
    fig.save_png(f, out / "fig11_fs_map_visits.png")


def _figure12(out: Path, runs: dict[str, dict]) -> None:
    """Figure 12: the two most frequent configurations per object (member 0 of a family) for KB,
    QL and PI, one object a row."""
    side = 1.5
    f = fig.new_figure(
        (6 * side, len(PAPER_OBJECTS) * side + 0.4),
        "Figure 12: most frequent configurations per object (rows): KB | QL | PI",
    )
    axes = f.subplots(len(PAPER_OBJECTS), 6, squeeze=False)
    for o, (name, row) in enumerate(zip(PAPER_OBJECTS, axes, strict=True)):
        poly = paper_object(name)
        unit = poly.unit_moment()
        for c, key in enumerate(("kb", "ql", "pi")):
            m = runs[key]["object"] == o
            tops = configurations(poly, runs[key]["theta"][m], runs[key]["s_g"][m], 2)
            for k in range(2):
                ax = row[2 * c + k]
                if k >= len(tops):
                    fig.blank(ax)
                    continue
                pts, frac, s = tops[k]
                fig.grasp_panel(
                    ax,
                    unit,
                    pts,
                    f"{key} {100 * frac:.0f}% S_G {s:.2f}",
                    good=s <= SUCCESS_THRESHOLD,
                )
    fig.save_png(f, out / "fig12_configurations.png")
