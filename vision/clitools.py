"""Command-line plumbing of ``vision`` (``python -m vision``, ``python -m vision.bench``): the
toolkit of :mod:`hand_sim.clitools` plus the errors a vision command reports as bad input and the
checks of values that need the scene or the image (a pixel inside the image, a point on the
table)."""

from __future__ import annotations

from collections.abc import Sequence

from hand_sim import clitools
from hand_sim.scene import TableSpec
from vision.errors import VisionError

#: Errors a vision command reports as bad input: its own, and hand_sim's (scenes, image sizes).
ERRORS: tuple[type[BaseException], ...] = (VisionError, *clitools.ERRORS)


def check_pixel(uv: Sequence[float], width: int, height: int, flag: str) -> tuple[float, float]:
    """``uv`` when it lies in a ``width`` x ``height`` image (pixel (u, v) = (column, row),
    integers at pixel centres); :class:`~hand_sim.clitools.CommandLineError` otherwise."""
    u, v = float(uv[0]), float(uv[1])
    if not (-0.5 <= u < width - 0.5 and -0.5 <= v < height - 0.5):
        raise clitools.CommandLineError(
            flag,
            f"({u:g}, {v:g}) is outside the {width}x{height} image: u (column) must be in "
            f"0..{width - 1} and v (row) in 0..{height - 1}; the image size is --width x --height",
        )
    return u, v


def check_on_table(xy: Sequence[float], table: TableSpec, flag: str) -> tuple[float, float]:
    """``xy`` (world, metres) when it lies on the table top; CommandLineError otherwise."""
    x, y = float(xy[0]), float(xy[1])
    (cx, cy), (sx, sy) = table.position_xy, table.size_xy
    if not table.contains(xy, margin=0.0):
        raise clitools.CommandLineError(
            flag,
            f"({x:g}, {y:g}) is off the table top: x must be in [{cx - sx / 2:g}, {cx + sx / 2:g}] "
            f"and y in [{cy - sy / 2:g}, {cy + sy / 2:g}] (world metres)",
        )
    return x, y
