"""What the task cycle asks of its user in interactive mode (:class:`UserChannel`), section 5.1:
"Both the object and the delivery point are specified by the user by clicking a mouse on the
overhead image of the cluttered table. This is the only user intervention in the system that is
otherwise completely autonomous."

The states Wait for Block and Wait for Place (:mod:`fsm.handlers.wait_for_block`,
:mod:`fsm.handlers.wait_for_place`) show the user the overhead image, take the user's clicks one
at a time, and refuse or accept each with a message. The page of :mod:`fsm.interactive` is one
such channel; a batch episode has none (``Episode.user`` is None) and never enters those states.
This module imports neither the page nor the vision, so the machine never loads them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from vision import ObjectModel, Selection

#: A pixel (u column, v row) of the overhead image, integers, row 0 at the top.
Pixel = tuple[int, int]
#: What a wait state waits for (the page's status line says "waiting for a block" / "waiting for
#: a place point").
WAITING_FOR_BLOCK = "a block"
WAITING_FOR_PLACE = "a place point"


@runtime_checkable
class UserChannel(Protocol):
    """The user of an interactive run, as the wait states see it. Every call comes from the
    thread that runs the task cycle."""

    def show_view(self, rgb: NDArray[np.uint8], waiting_for: str) -> None:
        """Show the overhead image ``rgb`` (H, W, 3) the next clicks are read on."""

    def next_click(self, waiting_for: str) -> Pixel | None:
        """Block until the user clicks a pixel of the image last shown; None when the run ends
        (the user stopped it or closed the page). Each click is answered by :meth:`refuse` or
        :meth:`accept` before the next is taken."""

    def refuse(self, message: str) -> None:
        """The last click is refused, with what is wrong and what to do; the state waits on."""

    def accept(self, message: str, contour: NDArray[np.float64] | None = None) -> None:
        """The last click is taken (``contour``: the modelled block's outline (k, 2), pixels of
        the image shown, for the page to draw)."""


@dataclass(frozen=True)
class ClickedBlock:
    """A click Wait for Block took: the view the user clicked on (segmented), the block under
    the click (its index in the view), the vision's model of it, and the pixel."""

    selection: Selection
    index: int
    model: ObjectModel
    pixel: Pixel
