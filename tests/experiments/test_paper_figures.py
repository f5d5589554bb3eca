"""The paper report's figure building blocks (:mod:`experiments.paper.figures`): each draws on a
matplotlib Axes, a figure is written as a PNG of its size, the same figure gives the same bytes,
and no OpenCV is involved."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np
from matplotlib.image import imread

from controllers.grasp.objects import paper_object
from experiments.paper import figures as fig
from experiments.paper.paper_figures import configurations


def draw_every_block(path: Path) -> None:
    f = fig.new_figure((10.0, 4.0), "every block")
    line, heat, panel, inset, empty = f.subplots(1, 5)
    t = np.linspace(0.0, 1.0, 50)
    fig.line_plot(
        line,
        [fig.Series("a", t, t**2), fig.Series("b", t, (t > 0.5).astype(float), step=True)],
        "title",
        "x",
        "y",
        hlines=[(0.5, "half")],
    )
    grid = np.arange(900.0).reshape(30, 30)
    grid[3, 4] = np.nan
    path_states = np.array([[0.0, 0.0], [10.0, 12.0], [np.nan, 1.0], [20.0, 25.0]])
    fig.state_heatmap(heat, grid, "map", paths=[("KB: fail", path_states)])
    square = paper_object("square").unit_moment()
    points = square.point_at(np.array([0.1, 1.7, 3.3]))
    fig.grasp_panel(panel, square, points, "S_G 0.10", start=points * 0.9, good=False)
    fig.square_activation_inset(inset, t * 2 * np.pi, (t > 0.3).astype(float), 0.0)
    fig.blank(empty)
    fig.save_png(f, path)


def test_every_block_draws_and_the_png_is_deterministic(tmp_path: Path) -> None:
    a, b = tmp_path / "a.png", tmp_path / "b.png"
    draw_every_block(a)
    draw_every_block(b)
    assert a.read_bytes() == b.read_bytes()
    img = imread(a)
    assert img.shape[:2] == (4 * fig.DPI, 10 * fig.DPI)
    assert img[..., :3].std() > 0.05  # not blank


def test_figures_are_drawn_with_matplotlib_not_opencv() -> None:
    tree = ast.parse(inspect.getsource(fig))
    modules = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    modules |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    roots = {m.split(".")[0] for m in modules}
    assert "cv2" not in roots and "matplotlib" in roots


def test_configurations_group_contacts_and_count_them() -> None:
    square = paper_object("square")
    theta = np.array([[0.1, 1.7, 3.3]] * 3 + [[0.2, 2.0, 4.0]])
    tops = configurations(square, theta, np.array([0.1, 0.1, 0.1, 0.5]), 2)
    assert [frac for _, frac, _ in tops] == [0.75, 0.25]
    assert [s for _, _, s in tops] == [0.1, 0.5]
