"""PNG figures of the paper's experiments, drawn with OpenCV (imported lazily; no matplotlib).

Small building blocks (a line plot, a state-space heatmap, grasp configurations on polygons) that
:mod:`experiments.paper.reproduce` combines into Figures 1, 7, 9, 10, 11, 12, 17 and 18.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from controllers.grasp.polygon import Polygon
from graspsim_base.files import atomic_path

#: Colours (BGR) of plotted series, in order.
PALETTE = ((200, 80, 20), (30, 30, 220), (40, 150, 40), (150, 50, 150), (0, 140, 230))
WHITE, BLACK, GREY = (255, 255, 255), (0, 0, 0), (150, 150, 150)
FONT_SCALE = 0.5
#: Length of the force arrows drawn at contacts (pixels).
ARROW_PX = 24
#: Margins of a plot panel (pixels): left, right, top, bottom.
MARGIN = (70, 20, 40, 50)


def _cv2():
    import cv2  # lazy: only figure drawing needs OpenCV

    return cv2


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
    step: bool = False  #: draw as a step function (activations)


def _text(img, text: str, org: tuple[int, int], scale: float = FONT_SCALE, color=BLACK, thick=1):
    cv2 = _cv2()
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, color, thick, cv2.LINE_AA)


def _text_width(text: str, scale: float = FONT_SCALE) -> int:
    cv2 = _cv2()
    return cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)[0][0]


def _nice_ticks(lo: float, hi: float, n: int = 6) -> NDArray[np.float64]:
    span = hi - lo if hi > lo else 1.0
    raw = span / n
    mag = 10 ** np.floor(np.log10(raw))
    step = min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw), default=10 * mag)
    return np.arange(np.ceil(lo / step) * step, hi + 1e-9 * span, step)


def _fmt(v: float) -> str:
    if abs(v) < 1e-9:
        return "0"
    return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.0f}"


def line_plot(
    series: Sequence[Series],
    title: str,
    xlabel: str,
    ylabel: str,
    size: tuple[int, int] = (760, 440),
    ylim: tuple[float, float] | None = None,
    hlines: Sequence[tuple[float, str]] = (),
) -> NDArray[np.uint8]:
    """A line plot with axes, ticks, labels and a legend; returns a BGR image."""
    cv2 = _cv2()
    w, h = size
    img = np.full((h, w, 3), 255, np.uint8)
    left, right, top, bottom = MARGIN
    pw, ph = w - left - right, h - top - bottom
    xs = np.concatenate([np.asarray(s.x, float) for s in series])
    ys = np.concatenate(
        [np.asarray(s.y, float) for s in series] + [np.array([v for v, _ in hlines])]
    )
    ys = ys[np.isfinite(ys)]
    x0, x1 = float(xs.min()), float(xs.max())
    y0, y1 = ylim if ylim is not None else (float(ys.min()), float(ys.max()))
    if y1 <= y0:
        y1 = y0 + 1.0
    pad = 0.0 if ylim is not None else 0.05 * (y1 - y0)
    y0, y1 = y0 - pad, y1 + pad

    def px(x, y):
        u = left + (np.asarray(x, float) - x0) / max(x1 - x0, 1e-12) * pw
        v = top + ph - (np.asarray(y, float) - y0) / (y1 - y0) * ph
        return u, v

    for t in _nice_ticks(x0, x1):
        u, _ = px(t, y0)
        cv2.line(img, (int(u), top), (int(u), top + ph), (235, 235, 235), 1)
        cv2.line(img, (int(u), top + ph), (int(u), top + ph + 5), BLACK, 1)
        _text(img, _fmt(t), (int(u) - _text_width(_fmt(t)) // 2, top + ph + 20))
    for t in _nice_ticks(y0, y1):
        _, v = px(x0, t)
        cv2.line(img, (left, int(v)), (left + pw, int(v)), (235, 235, 235), 1)
        cv2.line(img, (left - 5, int(v)), (left, int(v)), BLACK, 1)
        _text(img, _fmt(t), (left - 8 - _text_width(_fmt(t)), int(v) + 5))
    cv2.rectangle(img, (left, top), (left + pw, top + ph), BLACK, 1)
    for value, label in hlines:
        _, v = px(x0, value)
        for u in range(left, left + pw, 12):
            cv2.line(img, (u, int(v)), (min(u + 6, left + pw), int(v)), GREY, 1, cv2.LINE_AA)
        _text(img, label, (left + pw - _text_width(label, 0.4) - 4, int(v) - 4), 0.4, GREY)
    for i, s in enumerate(series):
        x, y = np.asarray(s.x, float), np.asarray(s.y, float)
        if s.step:
            x = np.repeat(x, 2)[1:]
            y = np.repeat(y, 2)[:-1]
        u, v = px(x, y)
        ok = np.isfinite(v)
        pts = np.stack([u[ok], v[ok]], axis=1).round().astype(np.int32)
        cv2.polylines(img, [pts], False, PALETTE[i % len(PALETTE)], 2, cv2.LINE_AA)
    for i, s in enumerate(series):  # legend
        y = top + 18 + 20 * i
        cv2.line(img, (left + 12, y - 4), (left + 40, y - 4), PALETTE[i % len(PALETTE)], 2)
        _text(img, s.label, (left + 46, y))
    _text(img, title, (left, top - 14), 0.6)
    _text(img, xlabel, (left + pw // 2 - _text_width(xlabel) // 2, h - 12))
    label_img = np.full((24, _text_width(ylabel) + 8, 3), 255, np.uint8)
    _text(label_img, ylabel, (4, 17))
    rot = np.ascontiguousarray(np.rot90(label_img))
    y_at = max(0, top + ph // 2 - rot.shape[0] // 2)
    img[y_at : y_at + rot.shape[0], 4 : 4 + rot.shape[1]] = rot[: h - y_at]
    return img


def state_heatmap(
    grid: NDArray[np.float64],
    title: str,
    vmin: float | None = None,
    vmax: float | None = None,
    cell: int = 12,
    paths: Sequence[tuple[str, NDArray[np.float64]]] = (),
    colorbar: tuple[str, str] = ("low", "high"),
) -> NDArray[np.uint8]:
    """A 30 x 30 state-space map, grid[fc_bin, mc_bin]; x = eps'_FC, y = eps'_MC (up).

    ``paths`` are (label, (k, 2) Eq. 14 states) drawn over the map, with the start marked by a
    dot, a failure end by an X and a success end by an O (Figure 10); a label ending in "fail"
    gets the X.
    """
    cv2 = _cv2()
    n = grid.shape[0]
    g = np.asarray(grid, dtype=float)
    lo = np.nanmin(g) if vmin is None else vmin
    hi = np.nanmax(g) if vmax is None else vmax
    norm = np.clip((g - lo) / (hi - lo if hi > lo else 1.0), 0.0, 1.0)
    norm = np.nan_to_num(norm, nan=0.0)
    img8 = (255 * norm.T[::-1]).astype(np.uint8)  # rows: eps'_MC from top (high) to bottom
    cmap = cv2.applyColorMap(
        cv2.resize(img8, (n * cell, n * cell), interpolation=cv2.INTER_NEAREST),
        cv2.COLORMAP_VIRIDIS,
    )
    left, right, top, bottom = 60, 90, 40, 50
    w, h = left + n * cell + right, top + n * cell + bottom
    img = np.full((h, w, 3), 255, np.uint8)
    img[top : top + n * cell, left : left + n * cell] = cmap
    cv2.rectangle(img, (left, top), (left + n * cell, top + n * cell), BLACK, 1)
    for t in range(0, n + 1, 5):
        u = left + t * cell
        v = top + n * cell - t * cell
        cv2.line(img, (u, top + n * cell), (u, top + n * cell + 5), BLACK, 1)
        _text(img, str(t), (u - 6, top + n * cell + 20), 0.45)
        cv2.line(img, (left - 5, v), (left, v), BLACK, 1)
        _text(img, str(t), (left - 30, v + 5), 0.45)
    _text(img, "eps'_FC (Eq. 14)", (left + n * cell // 2 - 60, h - 10))
    _text(img, "eps'_MC", (4, top - 8), 0.45)
    _text(img, title, (left, top - 14), 0.55)
    bar = cv2.applyColorMap(
        np.linspace(255, 0, n * cell).astype(np.uint8)[:, None].repeat(14, 1), cv2.COLORMAP_VIRIDIS
    )
    bx = left + n * cell + 12
    img[top : top + n * cell, bx : bx + 14] = bar
    _text(img, f"{colorbar[1]} {_fmt(hi)}", (bx - 4, top - 4), 0.4)
    _text(img, f"{colorbar[0]} {_fmt(lo)}", (bx - 4, top + n * cell + 16), 0.4)
    for i, (label, pts) in enumerate(paths):
        p = np.asarray(pts, float)
        p = p[np.isfinite(p).all(axis=1)]
        if not len(p):
            continue
        q = np.clip(p, 0.5, n - 0.5)  # eps' <= 0.5 drawn in the middle of bin 0, visible
        u = left + q[:, 0] * cell
        v = top + n * cell - q[:, 1] * cell
        uv = np.stack([u, v], axis=1).round().astype(np.int32)
        color = (255, 255, 255) if i == 0 else (60, 60, 255)
        cv2.polylines(img, [uv], False, color, 2, cv2.LINE_AA)
        cv2.circle(img, tuple(uv[0]), 4, color, -1)
        end = tuple(uv[-1])
        if label.endswith("fail"):
            cv2.drawMarker(img, end, color, cv2.MARKER_TILTED_CROSS, 14, 2)
        else:
            cv2.circle(img, end, 7, color, 2)
        ty = top + 20 + 20 * i
        cv2.rectangle(
            img, (left + 4, ty - 15), (left + 30 + _text_width(label, 0.45), ty + 5), WHITE, -1
        )
        cv2.line(img, (left + 7, ty - 5), (left + 25, ty - 5), BLACK, 5)
        cv2.line(img, (left + 8, ty - 5), (left + 24, ty - 5), color, 3)
        _text(img, label, (left + 28, ty), 0.45)
    return img


def grasp_panel(
    polygon: Polygon,
    points: NDArray[np.float64],
    caption: str,
    size: int = 190,
    start: NDArray[np.float64] | None = None,
    good: bool = True,
) -> NDArray[np.uint8]:
    """One grasp configuration: the polygon, its contacts (dots with inward force arrows) and a
    caption (Figures 2, 10c, 12). ``points`` in the polygon's frame; ``start`` optional hollow
    circles for the initial contacts."""
    cv2 = _cv2()
    img = np.full((size + 30, size, 3), 255, np.uint8)
    v = polygon.vertices
    scale = 0.36 * size / np.abs(v).max()
    c = np.array([size / 2, size / 2])

    def px(p):
        q = np.asarray(p, float) * scale
        return np.stack([c[0] + q[..., 0], c[1] - q[..., 1]], axis=-1).round().astype(np.int32)

    cv2.fillPoly(img, [px(v)], (235, 225, 210) if good else (215, 215, 240))
    cv2.polylines(img, [px(v)], True, BLACK, 2, cv2.LINE_AA)
    if start is not None:
        for p in px(start):
            cv2.circle(img, tuple(p), 6, GREY, 1, cv2.LINE_AA)
    frames = polygon.locate(np.arctan2(points[:, 1], points[:, 0]))
    for p, nrm in zip(points, frames.normal, strict=True):
        a = px(p + nrm * (ARROW_PX / scale))  # inward unit force: arrow from outside to contact
        b = px(p)
        cv2.arrowedLine(img, tuple(a), tuple(b), (30, 30, 200), 2, cv2.LINE_AA, tipLength=0.3)
        cv2.circle(img, tuple(b), 4, BLACK, -1, cv2.LINE_AA)
    _text(img, caption, (max(2, size // 2 - _text_width(caption, 0.45) // 2), size + 20), 0.45)
    return img


def grid_of(images: Sequence[NDArray[np.uint8]], cols: int, title: str = "") -> NDArray[np.uint8]:
    """Tile images (padded to a common size) in rows of ``cols``, with an optional title bar."""
    h = max(i.shape[0] for i in images)
    w = max(i.shape[1] for i in images)
    padded = [
        np.pad(i, ((0, h - i.shape[0]), (0, w - i.shape[1]), (0, 0)), constant_values=255)
        for i in images
    ]
    while len(padded) % cols:
        padded.append(np.full((h, w, 3), 255, np.uint8))
    rows = [np.concatenate(padded[r : r + cols], axis=1) for r in range(0, len(padded), cols)]
    out = np.concatenate(rows, axis=0)
    if title:
        bar = np.full((34, out.shape[1], 3), 255, np.uint8)
        _text(bar, title, (8, 23), 0.6)
        out = np.concatenate([bar, out], axis=0)
    return out


def hstack(images: Sequence[NDArray[np.uint8]]) -> NDArray[np.uint8]:
    """Images side by side, top-aligned, each keeping its width."""
    h = max(i.shape[0] for i in images)
    return np.concatenate(
        [np.pad(i, ((0, h - i.shape[0]), (0, 0), (0, 0)), constant_values=255) for i in images],
        axis=1,
    )


def square_activation_inset(
    theta: NDArray[np.float64], alpha: NDArray[np.float64], beta: float, size: int = 220
) -> NDArray[np.uint8]:
    """Figure 18's inset: the square with the outline grey where the MC controller was selected
    (alpha = 0) and white where FC was (alpha = 1) along the moving contact's path."""
    cv2 = _cv2()
    img = np.full((size, size, 3), 255, np.uint8)
    c = size / 2
    half = 0.3 * size
    cv2.rectangle(
        img, (int(c - half), int(c - half)), (int(c + half), int(c + half)), (250, 250, 250), -1
    )

    def boundary(t):
        r = half / np.maximum(np.abs(np.cos(t)), np.abs(np.sin(t)))
        return np.stack([c + r * np.cos(t), c - r * np.sin(t)], axis=-1)

    pts = boundary(theta).round().astype(np.int32)
    cv2.polylines(img, [pts], False, BLACK, 13)  # outline, so that white (FC) parts show
    for i in range(len(theta) - 1):
        col = (110, 110, 110) if alpha[i] < 0.5 else WHITE
        cv2.line(img, tuple(pts[i]), tuple(pts[i + 1]), col, 9)
    cv2.rectangle(img, (int(c - half), int(c - half)), (int(c + half), int(c + half)), BLACK, 1)
    fixed = boundary(np.array([beta]))[0].round().astype(int)
    cv2.circle(img, tuple(fixed), 6, BLACK, -1)
    start, end = pts[0].round().astype(int), pts[-1].round().astype(int)
    cv2.circle(img, tuple(start), 6, (200, 80, 20), 2)
    cv2.circle(img, tuple(end), 6, (30, 30, 220), -1)
    _text(img, "grey: MC, white: FC", (6, size - 24), 0.4)
    _text(img, "black: fixed contact", (6, size - 8), 0.4)
    return img


def save_png(path: Path, img: NDArray[np.uint8]) -> None:
    """Write a PNG (deterministic bytes for the same image), atomically."""
    cv2 = _cv2()
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), img):
            raise OSError(f"could not write {path}")
