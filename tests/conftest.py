"""Test-wide settings: headless rendering through EGL before anything imports MuJoCo; the whole
episodes first, and ``pytest -n`` workers that take work from each other."""

import os

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Run the tests marked ``e2e`` (whole episodes and experiment runs, 5-55 s each) before the
    rest, each module's in their order, so that the short tests fill in at the end (see
    :func:`pytest_xdist_make_scheduler`)."""
    items.sort(key=lambda item: item.get_closest_marker("e2e") is None)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object | None:
    """``-n N`` (xdist's "load") hands each worker a block of consecutive tests, which puts
    every long test on one worker; work stealing instead lets a worker that runs out take the
    end of the other's queue. Other ``--dist`` modes are left to xdist."""
    if config.getoption("dist") != "load":
        return None
    from xdist.scheduler import WorkStealingScheduling

    return WorkStealingScheduling(config, log)
