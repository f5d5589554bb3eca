"""Work done once per test session and shared by the workers of ``pytest -n``."""

from __future__ import annotations

import fcntl
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def session_lock(tmp_path_factory, name: str) -> Iterator[Path]:
    """This test session's folder (the one its xdist workers share), held under the lock
    ``name`` while the block runs: the first worker in makes what is shared, the others wait
    and then find it there."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # this session's folder, shared by its xdist workers
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield root
