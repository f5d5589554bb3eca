"""Errors raised by the reach and posture controllers of section 5.2
(``controllers.planning.harmonic``, ``controllers.planning.cspace``, ``controllers.reach.coarse``,
``controllers.posture.solver``).

"No path" and "target unreachable" are results (``found`` / ``reachable`` flags), not errors: these
exceptions are for malformed input, and their messages name the bad value.
"""


class ReachError(Exception):
    """Base class of every error raised by the reach/posture controllers."""


class GridError(ReachError, ValueError):
    """A configuration-space grid, obstacle map or goal set is malformed."""


class PostureError(ReachError, ValueError):
    """A posture-control request is malformed (unknown site, wrong target shape...)."""
