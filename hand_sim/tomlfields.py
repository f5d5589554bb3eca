"""Typed, checked access to parsed TOML tables for the scene files (:mod:`hand_sim.scene`): every
error names the file, the dotted field path and the problem, as :class:`SceneError`."""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

from hand_sim.errors import SceneError


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file, turning syntax errors into :class:`SceneError`."""
    try:
        with path.open("rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"{path}: not valid TOML: {e}") from e
    except UnicodeDecodeError as e:
        raise SceneError(
            f"{path}: not UTF-8 text (byte {e.start}: {e.reason}); save the file as UTF-8"
        ) from e
    except OSError as e:
        raise SceneError(f"{path}: cannot read: {e}") from e


def _finite_number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def _short(value: object, limit: int = 80) -> str:
    """``repr(value)``, cut to ``limit`` characters (a message stays one readable line)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


class TomlFields:
    """Typed access to a TOML table, with errors naming ``source`` and the field path."""

    def __init__(self, source: str, path: str, table: Any, allowed: set[str]) -> None:
        self.source, self.path = source, path
        if not isinstance(table, Mapping):
            self.fail("", f"must be a table, got {type(table).__name__}")
        self.table: Mapping[str, Any] = table
        unknown = sorted(set(table) - allowed)
        if unknown:
            self.fail(unknown[0], f"unknown key; valid keys: {', '.join(sorted(allowed))}")

    def field(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path and key else (self.path or key)

    def fail(self, key: str, problem: str) -> NoReturn:
        raise SceneError(f"{self.source}: {self.field(key)}: {problem}")

    def has(self, key: str) -> bool:
        return key in self.table

    def string(self, key: str, default: str | None = None) -> str:
        if key not in self.table:
            if default is None:
                self.fail(key, "missing (required)")
            return str(default)
        value = self.table[key]
        if not isinstance(value, str):
            self.fail(key, f"must be a string, got {_short(value)}")
        return value

    def number(
        self, key: str, default: float | None = None, lo: float = -math.inf, hi: float = math.inf
    ) -> float:
        if key not in self.table:
            if default is None:
                self.fail(key, "missing (required)")
            return float(default)
        value = self.table[key]
        if not _finite_number(value):
            self.fail(key, f"must be a finite number, got {_short(value)}")
        if not lo <= value <= hi:
            self.fail(key, f"{value!r} is out of range [{lo:g}, {hi:g}]")
        return float(value)

    def vector(self, key: str, n: int, default: Sequence[float] | None = None) -> tuple[float, ...]:
        if key not in self.table:
            if default is None:
                self.fail(key, "missing (required)")
            return tuple(float(x) for x in default)
        value = self.table[key]
        ok = isinstance(value, list) and len(value) == n
        ok = ok and all(_finite_number(x) for x in value)
        if not ok:
            self.fail(key, f"must be a list of {n} finite numbers, got {_short(value)}")
        return tuple(float(x) for x in value)

    def points(self, key: str, min_count: int) -> list[tuple[float, float]]:
        """A list of at least ``min_count`` [x, y] pairs of finite numbers (required)."""
        if key not in self.table:
            self.fail(key, "missing (required)")
        value = self.table[key]
        ok = isinstance(value, list) and len(value) >= min_count
        ok = ok and all(
            isinstance(p, list) and len(p) == 2 and all(_finite_number(x) for x in p) for p in value
        )
        if not ok:
            self.fail(
                key,
                f"must be a list of at least {min_count} [x, y] pairs of finite numbers, "
                f"got {_short(value)}",
            )
        return [(float(x), float(y)) for x, y in value]

    def pair(self, key: str, default: Sequence[float] | None = None) -> tuple[float, float]:
        """Two finite numbers, e.g. an (x, y) position in metres."""
        a, b = self.vector(key, 2, default)
        return a, b
