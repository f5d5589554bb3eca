"""Errors raised by ``hand_sim``: one base class, messages that name the bad value."""


class HandSimError(Exception):
    """Base class of every error raised by ``hand_sim``."""


class SceneError(HandSimError, ValueError):
    """A scene file or scene name is malformed: the message names the file, field and problem."""


class SimulationError(HandSimError, RuntimeError):
    """The physics went wrong (NaN state, MuJoCo instability warning) or a model cannot be built."""
