"""graspsim_base.pool: the same results in this process and in spawned workers, a job's error
raised as it is, a worker that dies named by its job, and workers stopped when the caller leaves
early."""

from __future__ import annotations

import multiprocessing
import os
import time
from contextlib import closing

import pytest

from graspsim_base.pool import WorkerLostError, map_unordered, one_thread_env


def square_and_pid(x: int) -> tuple[int, int]:
    return x * x, os.getpid()


def fails_on_three(x: int) -> int:
    if x == 3:
        raise ValueError(f"job {x} failed")
    return x


def dies_on_two(x: int) -> int:
    if x == 2:
        os._exit(7)  # a crash in native code looks like this to the pool
    time.sleep(0.2)
    return x


def sleeps(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def reads_env(name: str) -> str | None:
    return os.environ.get(name)


def test_workers_give_the_results_of_this_process_for_every_job() -> None:
    jobs = list(range(7))
    here = dict(map_unordered(square_and_pid, jobs, workers=1))
    there = dict(map_unordered(square_and_pid, jobs, workers=2))
    assert {k: v[0] for k, v in here.items()} == {k: v[0] for k, v in there.items()}
    assert {k: v[0] for k, v in here.items()} == {k: k * k for k in jobs}
    assert {pid for _, pid in here.values()} == {os.getpid()}
    assert os.getpid() not in {pid for _, pid in there.values()}


def test_in_this_process_the_jobs_run_in_their_order() -> None:
    assert [k for k, _ in map_unordered(square_and_pid, [5, 1, 4], workers=1)] == [0, 1, 2]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_jobs_error_is_raised_as_it_is(workers: int) -> None:
    with pytest.raises(ValueError, match="job 3 failed"):
        list(map_unordered(fails_on_three, [1, 2, 3, 4], workers=workers))


def test_a_worker_that_dies_is_named_by_its_job() -> None:
    with pytest.raises(WorkerLostError) as e:
        list(map_unordered(dies_on_two, [0, 1, 2, 3], workers=2))
    assert "died" in str(e.value)


def test_leaving_early_stops_every_worker() -> None:
    before = set(multiprocessing.active_children())
    results = map_unordered(sleeps, [0.05, 30.0, 30.0, 30.0], workers=2)
    with closing(results):
        k, value = next(results)
        assert (k, value) == (0, 0.05)
        assert len(set(multiprocessing.active_children()) - before) == 2
    start = time.monotonic()
    while set(multiprocessing.active_children()) - before and time.monotonic() - start < 10:
        time.sleep(0.05)
    assert not set(multiprocessing.active_children()) - before
    assert time.monotonic() - start < 10  # stopped, not waited for (the jobs take 30 s)


def test_workers_get_the_environment_asked_for_and_it_is_restored_here(monkeypatch) -> None:
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    env = one_thread_env({"GRASPSIM_POOL_TEST": "yes"})
    got = dict(map_unordered(reads_env, ["OMP_NUM_THREADS", "GRASPSIM_POOL_TEST"], 2, env))
    assert got == {0: "1", 1: "yes"}
    assert "OMP_NUM_THREADS" not in os.environ and "GRASPSIM_POOL_TEST" not in os.environ


def test_the_callers_own_thread_setting_wins(monkeypatch) -> None:
    monkeypatch.setenv("OMP_NUM_THREADS", "3")
    assert one_thread_env()["OMP_NUM_THREADS"] == "3"
