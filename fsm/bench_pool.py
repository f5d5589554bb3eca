"""Where the bench's episodes run: in this process, in a pool of processes on this machine, or on
a Ray cluster. Each runner takes :class:`fsm.bench_jobs.Job` s and yields their
:class:`fsm.bench_jobs.JobResult` s as they finish (in any order); every runner runs the same
:func:`fsm.bench_jobs.run_job`, so a seed's episode does not depend on where it ran.

- :class:`InProcess`: one episode after another, here (``--workers 1``).
- :class:`ProcessPool`: ``--workers N`` processes started with the ``spawn`` method (a ``fork``ed
  child of a process that has rendered with EGL hangs); each builds its own worlds.
- :class:`RayCluster`: ``--ray ADDRESS``; Ray is imported only here (the optional extra
  ``graspsim[ray]``).

Workers run with one math-library thread each (one episode per core). Leaving a runner's
``with`` block (normally, on an error or on Ctrl-C) stops its workers; episodes still running are
lost and are run again by ``--resume``.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from typing import Any

from fsm.bench_jobs import Job, JobResult, run_job

#: Environment of the workers: one thread per math library (OpenBLAS, OpenMP, MKL), headless
#: rendering through EGL (STACK: osmesa does not work here). The user's own values win.
WORKER_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "MUJOCO_GL": "egl",
}
#: ``--ray`` value that starts a private Ray instance on this machine with ``--workers`` CPUs.
RAY_LOCAL = "local"


class WorkerLostError(RuntimeError):
    """A worker process died (killed, out of memory, crashed in native code)."""


def worker_env() -> dict[str, str]:
    """:data:`WORKER_ENV` with the variables already set in this process kept as they are."""
    return {k: os.environ.get(k, v) for k, v in WORKER_ENV.items()}


@contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """Set ``values`` in ``os.environ`` inside the block (children started in it inherit them),
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


def _ignore_sigint() -> None:
    """Pool worker initializer: Ctrl-C is the bench's to handle (it stops the workers); a worker
    that caught it would print a traceback and leave the pool broken."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class InProcess:
    """Run the episodes one after another in this process."""

    workers = 1

    def __enter__(self) -> InProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def run(self, jobs: Iterable[Job]) -> Iterator[JobResult]:
        for job in jobs:
            yield run_job(job)


class ProcessPool:
    """Run the episodes in ``workers`` processes of this machine (``spawn`` start method)."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._executor: ProcessPoolExecutor | None = None

    def __enter__(self) -> ProcessPool:
        self._executor = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_ignore_sigint,
        )
        return self

    def __exit__(self, *exc: object) -> None:
        executor, self._executor = self._executor, None
        if executor is None:
            return
        if exc[0] is None:
            executor.shutdown(wait=True)
            return
        # an error or Ctrl-C: drop the queued episodes and stop the running ones now
        processes = list(getattr(executor, "_processes", {}).values())
        executor.shutdown(wait=False, cancel_futures=True)
        for p in processes:
            if p.is_alive():
                p.terminate()
        for p in processes:
            p.join(timeout=10)

    def run(self, jobs: Iterable[Job]) -> Iterator[JobResult]:
        if self._executor is None:
            raise RuntimeError("use the pool inside its with block")
        # every job is queued at once; the workers are started by the first submissions, with
        # their environment
        with _environment(worker_env()):
            pending: dict[Future[JobResult], Job] = {
                self._executor.submit(run_job, job): job for job in jobs
            }
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                job = pending.pop(future)
                try:
                    yield future.result()
                except Exception as e:  # BrokenProcessPool: a worker died under this job
                    raise WorkerLostError(
                        f"a worker process died while running seed {job.seed} ({e}); "
                        "run again with --resume to continue"
                    ) from e


class RayCluster:
    """Run the episodes as Ray tasks of one CPU each: on a private local instance with
    ``workers`` CPUs (``address`` :data:`RAY_LOCAL`) or on the cluster at ``address`` (``auto``:
    the one this machine belongs to), where at most ``workers`` episodes run at once (None: as
    many as the cluster has CPUs for)."""

    def __init__(self, address: str, workers: int | None) -> None:
        self.address = address
        self.workers = workers
        self._ray: Any = None
        self._started = False

    def __enter__(self) -> RayCluster:
        import logging

        import ray  # the optional extra: only --ray needs it

        env = worker_env()
        if self.address == RAY_LOCAL:
            # the local workers import this checkout's code, as this process does
            root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
            path = os.environ.get("PYTHONPATH")
            env["PYTHONPATH"] = root if not path else os.pathsep.join([root, path])
        kwargs: dict[str, Any] = {
            "include_dashboard": False,
            "log_to_driver": False,
            "logging_level": logging.WARNING,
            "runtime_env": {"env_vars": env},
        }
        if self.address == RAY_LOCAL:
            kwargs["num_cpus"] = self.workers
        else:
            kwargs["address"] = self.address
        if not ray.is_initialized():
            ray.init(**kwargs)
            self._started = True
        self._ray = ray
        return self

    def __exit__(self, *exc: object) -> None:
        if self._started:
            self._ray.shutdown()
        self._started = False

    def run(self, jobs: Iterable[Job]) -> Iterator[JobResult]:
        ray = self._ray
        remote = ray.remote(num_cpus=1)(run_job)
        queue = list(jobs)
        queue.reverse()
        limit = self.workers or len(queue)
        pending: dict[Any, Job] = {}
        try:
            while queue or pending:
                while queue and len(pending) < limit:
                    job = queue.pop()
                    pending[remote.remote(job)] = job
                (ref,), _ = ray.wait(list(pending), num_returns=1)
                job = pending.pop(ref)
                try:
                    yield ray.get(ref)
                except ray.exceptions.RayError as e:
                    raise WorkerLostError(
                        f"the Ray task of seed {job.seed} failed ({type(e).__name__}); "
                        "run again with --resume to continue"
                    ) from e
        finally:
            for ref in pending:
                ray.cancel(ref, force=True)


def open_runner(
    workers: int | None, ray_address: str | None
) -> InProcess | ProcessPool | RayCluster:
    """The runner the command line asks for (not yet entered); ``workers`` None only with a Ray
    cluster."""
    if ray_address is not None:
        return RayCluster(ray_address, workers)
    if workers is None or workers == 1:
        return InProcess()
    return ProcessPool(workers)
