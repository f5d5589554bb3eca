"""Errors of the vision package (section 5.2, Select/Model).

Every error names the bad value and says what to do; the CLIs turn them into one line on stderr
and exit status 2.
"""

from __future__ import annotations


class VisionError(Exception):
    """Base of every error raised by :mod:`vision`."""


class NotABlockError(VisionError):
    """A selection (pixel, name or world point) does not land on a block."""


class ExtractionError(VisionError):
    """A block was found but no trustworthy polygon could be extracted from it."""
