"""Errors raised by ``controllers.grasp``: one base class, messages that name the bad value."""


class GraspError(Exception):
    """Base class of every error raised by ``controllers.grasp``."""


class PolygonError(GraspError, ValueError):
    """A polygon given by a user is malformed (too few vertices, non-convex, zero area...)."""


class TrialSettingsError(GraspError, ValueError):
    """Trial settings that cannot run (fewer than 2 contacts, no step)."""


class UnknownNameError(GraspError, KeyError):
    """An object, controller or experiment name is not one of the known ones."""

    def __init__(self, kind: str, name: str, valid: list[str]) -> None:
        self.kind, self.name, self.valid = kind, name, sorted(valid)
        super().__init__(f"unknown {kind} {name!r}; valid: {', '.join(self.valid)}")

    def __str__(self) -> str:  # KeyError would quote the whole message otherwise
        return str(self.args[0])


class ModelNotTrainedError(GraspError, FileNotFoundError):
    """A learned controller was asked for before its model file was trained."""


class RunFolderError(GraspError, ValueError):
    """A folder given for trained models does not hold one finished ``reproduce`` run."""
