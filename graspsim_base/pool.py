"""The one process pool of graspsim: run independent jobs in this process or in ``spawn``ed worker
processes, and hand back each result with the index of its job as soon as it is ready.

Every parallel command uses it (the paper's experiments, the physical grasp study, the task-cycle
bench). Workers are started with the ``spawn`` method (a ``fork``ed child of a process that has
rendered with EGL hangs) and ignore Ctrl-C, which is the parent's to handle: leaving
:func:`map_unordered` early (an error, Ctrl-C, or the caller stopping its loop) stops every worker
at once, so no job keeps running in the background.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import TypeVar

J = TypeVar("J")
R = TypeVar("R")

#: Environment for workers that should use one core each: one thread per math library
#: (OpenBLAS, OpenMP, MKL). The caller's own values win (:func:`one_thread_env`).
ONE_THREAD_ENV: dict[str, str] = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}


class WorkerLostError(RuntimeError):
    """A worker process died under a job (killed, out of memory, crashed in native code)."""

    def __init__(self, index: int, cause: BaseException) -> None:
        super().__init__(f"a worker process died while running job {index} ({cause})")
        self.index = index


def one_thread_env(extra: Mapping[str, str] | None = None) -> dict[str, str]:
    """:data:`ONE_THREAD_ENV` plus ``extra``, with the variables already set in this process
    kept as they are."""
    wanted = {**ONE_THREAD_ENV, **(extra or {})}
    return {k: os.environ.get(k, v) for k, v in wanted.items()}


@contextmanager
def environment(values: Mapping[str, str]) -> Iterator[None]:
    """Set ``values`` in ``os.environ`` inside the block (processes started in it inherit them),
    then restore what was there."""
    before = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def ignore_sigint() -> None:
    """Worker initializer: Ctrl-C goes to the parent alone, which stops the pool (a worker that
    caught it would print a traceback and leave the pool broken)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _stop(executor: ProcessPoolExecutor) -> None:
    """Drop the queued jobs and end the running ones now."""
    procs = list((getattr(executor, "_processes", None) or {}).values())
    executor.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.terminate()
    for p in procs:
        p.join(timeout=10)


def map_unordered(
    fn: Callable[[J], R],
    jobs: Sequence[J],
    workers: int,
    env: Mapping[str, str] | None = None,
) -> Iterator[tuple[int, R]]:
    """``(index, fn(jobs[index]))`` for every job, in the order they finish.

    With ``workers`` <= 1 (or a single job) the jobs run here, one after another, in their
    order. Otherwise ``min(workers, len(jobs))`` spawned processes run them; ``fn`` and the jobs
    must be picklable (a module-level function and plain data). ``env`` is set for the workers
    (e.g. :func:`one_thread_env`). A job's exception is raised here as it is; a worker that dies
    raises :class:`WorkerLostError` naming the job.
    """
    if workers <= 1 or len(jobs) <= 1:
        for k, job in enumerate(jobs):
            yield k, fn(job)
        return
    executor = ProcessPoolExecutor(
        max_workers=min(workers, len(jobs)),
        mp_context=multiprocessing.get_context("spawn"),
        initializer=ignore_sigint,
    )
    finished = False
    try:
        # the workers start with the first submissions and inherit the environment set here
        with environment(env or {}):
            pending: dict[Future[R], int] = {
                executor.submit(fn, job): k for k, job in enumerate(jobs)
            }
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                k = pending.pop(future)
                try:
                    result = future.result()
                except BrokenProcessPool as e:
                    raise WorkerLostError(k, e) from e
                yield k, result
        finished = True
    finally:
        if finished:
            executor.shutdown(wait=True)
        else:
            _stop(executor)
