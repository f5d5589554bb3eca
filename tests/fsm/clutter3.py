"""``python -m fsm.run --scene clutter3`` (recorded, the shipped controller), run once per test
run for every test that reads it: the episode tests of ``test_fsm.py`` and the live stream's
comparison in ``test_live.py`` (the workers of ``pytest -n`` share it through a lock and its
folder in the test run's temporary folder)."""

from __future__ import annotations

from pathlib import Path

from fsm.run import main
from tests.session import session_lock


def shared_clutter3_run(tmp_path_factory) -> tuple[Path, int]:
    """The folder of the shared clutter3 episode (``summary.json``, ``episode.rrd``) and the
    command's exit status."""
    with session_lock(tmp_path_factory, "clutter3-run") as root:
        out, code = root / "clutter3-run", root / "clutter3-run.status"
        if not code.is_file():
            status = main(["--scene", "clutter3", "--controller", "pi", "--out", str(out)])
            partial = code.with_suffix(".partial")
            partial.write_text(str(status))
            partial.replace(code)
        return out, int(code.read_text())
