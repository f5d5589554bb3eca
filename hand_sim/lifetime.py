""":class:`ClosesOnExit`: the ``with`` protocol of the objects that hold a resource until
``close()`` (a camera's renderer, a recording)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import TracebackType
from typing import Self


class ClosesOnExit(ABC):
    """``with obj:`` gives ``obj`` and, leaving the block, calls :meth:`_exit` with the exception
    that ended it (None when it finished), which closes ``obj``; a subclass that records the
    exception first overrides :meth:`_exit`."""

    @abstractmethod
    def close(self) -> None:
        """Release what the object holds (idempotent)."""

    def _exit(self, exc_type: type[BaseException] | None, exc: BaseException | None) -> None:
        self.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._exit(exc_type, exc)
