"""Where the bench's episodes run: in this process, in a pool of processes on this machine, or on
a Ray cluster. Each runner takes :class:`experiments.bench.jobs.Job` s and yields their
:class:`experiments.bench.jobs.JobResult` s as they finish (in any order); every runner runs the
same :func:`experiments.bench.jobs.run_job`, so a seed's episode does not depend on where it ran.

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

import os
from collections.abc import Iterable, Iterator
from typing import Any

from experiments.bench.jobs import Job, JobResult, run_job
from graspsim_base.pool import ONE_THREAD_ENV, map_unordered, one_thread_env
from graspsim_base.pool import WorkerLostError as PoolWorkerLostError

#: Environment of the workers: one thread per math library, headless rendering through EGL
#: (osmesa does not work here). The user's own values win.
WORKER_ENV = {**ONE_THREAD_ENV, "MUJOCO_GL": "egl"}
#: ``--ray`` value that starts a private Ray instance on this machine with ``--workers`` CPUs.
RAY_LOCAL = "local"


class WorkerLostError(RuntimeError):
    """A worker process died, or a Ray task failed, under an episode."""


def worker_env() -> dict[str, str]:
    """:data:`WORKER_ENV` with the variables already set in this process kept as they are."""
    return one_thread_env(WORKER_ENV)


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
    """Run the episodes in ``workers`` processes of this machine (:mod:`graspsim_base.pool`)."""

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._results: Iterator[tuple[int, JobResult]] | None = None

    def __enter__(self) -> ProcessPool:
        return self

    def __exit__(self, *exc: object) -> None:
        # an error or Ctrl-C: closing the pool's iterator stops its workers now
        results, self._results = self._results, None
        if results is not None:
            results.close()  # type: ignore[attr-defined]

    def run(self, jobs: Iterable[Job]) -> Iterator[JobResult]:
        queued = list(jobs)
        self._results = map_unordered(run_job, queued, max(self.workers, 2), worker_env())
        try:
            for _, result in self._results:
                yield result
        except PoolWorkerLostError as e:
            raise WorkerLostError(
                f"a worker process died while running seed {queued[e.index].seed} "
                f"({e.__cause__}); run again with --resume to continue"
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
            root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
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
