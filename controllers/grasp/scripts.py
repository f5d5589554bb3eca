"""Console scripts that stand for one sub-command of ``python -m controllers.grasp``
(declared in pyproject.toml, ``[project.scripts]``)."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from controllers.grasp.cli import main


def reproduce(argv: Sequence[str] | None = None) -> int:
    """``graspsim-reproduce ARGS`` is ``python -m controllers.grasp reproduce ARGS``: every
    experiment of the paper (Tables 1-2, section 2, Appendix A, figures)."""
    args = sys.argv[1:] if argv is None else list(argv)
    return main(["reproduce", *args])
