"""Executors: run a list of :class:`~ibiscape_eval.batch.jobs.Job` locally or on a Dask cluster.

- :class:`LocalExecutor`: a pool of processes on this machine (``workers=1`` runs in this process),
  nothing to start or configure.  A worker that dies (a crash in native code, out of memory)
  fails the jobs it was running; the pool is rebuilt for the rest.
- :class:`DaskExecutor`: the same jobs sent to an existing ``distributed`` scheduler at an address
  (``tcp://host:8786``).  dask is imported only here, when one is created.

Both run :func:`~ibiscape_eval.batch.jobs.run_job` on each job, so a job gives the same result
wherever it runs.  :func:`run_jobs` adds the content cache and progress reporting on top of either.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from ibiscape_eval.core.errors import IbiscapeError

from .cache import ContentCache
from .jobs import Job, JobResult, run_job

__all__ = [
    "BatchSummary",
    "DaskExecutor",
    "Executor",
    "LocalExecutor",
    "Progress",
    "make_executor",
    "run_jobs",
]


class Executor(Protocol):
    """Runs jobs and yields their results in completion order."""

    def map(self, jobs: Sequence[Job]) -> Iterator[JobResult]:  # pragma: no cover (protocol)
        ...

    def close(self) -> None:  # pragma: no cover (protocol)
        ...


def _usable_cpus() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover (not Linux)
        return os.cpu_count() or 1


class LocalExecutor:
    """A pool of ``workers`` processes on this machine (default: the usable CPUs).

    ``workers=1`` runs the jobs one after the other in this process (no start-up cost).
    """

    def __init__(self, workers: int | None = None):
        n = _usable_cpus() if workers is None else int(workers)
        if n < 1:
            raise IbiscapeError(f"workers must be at least 1, got {workers!r}")
        self.workers = n

    def __repr__(self) -> str:
        return f"LocalExecutor(workers={self.workers})"

    def map(self, jobs: Sequence[Job]) -> Iterator[JobResult]:
        if self.workers == 1 or len(jobs) <= 1:
            for job in jobs:
                yield run_job(job)
            return
        yield from self._pool_map(list(jobs))

    def _pool_map(self, jobs: list[Job]) -> Iterator[JobResult]:
        import multiprocessing
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool

        # Jobs travel in small chunks (one round trip per chunk, not per job).  When a worker
        # dies the pool breaks and every chunk it held is lost: those jobs become suspects and
        # run again one at a time in a fresh pool, so the job that crashes is found and
        # reported as failed, and no other job is lost.
        size = max(1, min(8, len(jobs) // (8 * self.workers)))
        pending = [jobs[i:i + size] for i in range(0, len(jobs), size)][::-1]  # pop() = next
        suspects: list[Job] = []
        # "spawn": workers start clean, without this process's threads, locks or open files.
        ctx = multiprocessing.get_context("spawn")
        while pending or suspects:
            pool = ProcessPoolExecutor(max_workers=min(self.workers, len(pending) or 1),
                                       mp_context=ctx)
            running: dict[Any, list[Job]] = {}
            broken = False
            try:
                while (pending or suspects or running) and not broken:
                    if suspects:  # alone in the pool: a crash now names its job
                        if not running:
                            one = [suspects.pop()]
                            running[pool.submit(run_chunk, one)] = one
                    else:
                        while pending and len(running) < 2 * self.workers:
                            chunk = pending.pop()
                            running[pool.submit(run_chunk, chunk)] = chunk
                    done, _ = wait(running, return_when=FIRST_COMPLETED)
                    for fut in done:
                        if isinstance(fut.exception(), BrokenProcessPool):
                            broken = True
                            continue
                        yield from fut.result()
                        running.pop(fut)
                for fut, chunk in running.items():  # the pool broke: its chunks are lost
                    if fut.done() and fut.exception() is None:
                        yield from fut.result()
                    elif len(running) == 1 and len(chunk) == 1:
                        yield JobResult(chunk[0].key, "failed", error=(
                            "WorkerDied: the process running this job exited abruptly "
                            "(crash in native code or out of memory)"))
                    else:
                        suspects.extend(reversed(chunk))
            finally:
                pool.shutdown(wait=True, cancel_futures=True)

    def close(self) -> None:
        pass


def run_chunk(jobs: list[Job]) -> list[JobResult]:
    """Run several jobs one after the other (each failure stays its own job's)."""
    return [run_job(job) for job in jobs]


class DaskExecutor:
    """Jobs sent to an existing Dask ``distributed`` scheduler at ``address``.

    Connecting fails fast (``timeout_s``) with :class:`IbiscapeError` naming the address.
    """

    def __init__(self, address: str, *, timeout_s: float = 5.0):
        try:
            from distributed import Client
        except ImportError:
            raise IbiscapeError(
                "--scheduler needs dask's distributed package: pip install 'dask[distributed]'"
            ) from None
        self.address = address
        try:
            self.client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as e:
            raise IbiscapeError(
                f"cannot reach the Dask scheduler at {address} within {timeout_s:g} s "
                f"({type(e).__name__}: {' '.join(str(e).split())}); check the address "
                "(tcp://host:port) and that the scheduler is running"
            ) from None

    def __repr__(self) -> str:
        return f"DaskExecutor({self.address!r})"

    def map(self, jobs: Sequence[Job]) -> Iterator[JobResult]:
        from distributed import as_completed

        # Jobs go in chunks (about 4 per worker thread, at most 25 jobs each): a task costs the
        # scheduler a few milliseconds, as much as a small job itself.
        slots = max(1, sum(self.client.nthreads().values()))
        size = max(1, min(25, len(jobs) // (4 * slots)))
        chunks = [list(jobs[i:i + size]) for i in range(0, len(jobs), size)]
        keys = [f"ibiscape-{i}-{c[0].key}" for i, c in enumerate(chunks)]
        futures = self.client.map(run_chunk, chunks, key=keys, pure=False)
        by_key = {f.key: c for f, c in zip(futures, chunks, strict=True)}
        # with_results: results travel as they finish, without one round trip per task
        done = as_completed(futures, with_results=True, raise_errors=False,
                            loop=self.client.loop)
        for fut, value in done:
            if isinstance(value, list):
                yield from value
            else:  # worker lost, killed, ... (run_job itself never raises)
                err = value[1] if isinstance(value, tuple) and len(value) > 1 else value
                for job in by_key[fut.key]:
                    yield JobResult(job.key, "failed", error=f"{type(err).__name__}: {err}")
            fut.release()

    def close(self) -> None:
        self.client.close()


def make_executor(*, scheduler: str | None = None, workers: int | None = None) -> Executor:
    """A :class:`DaskExecutor` when ``scheduler`` is given, else a :class:`LocalExecutor`."""
    if scheduler:
        return DaskExecutor(scheduler)
    return LocalExecutor(workers)


Progress = Callable[[int, int, int], None]
"""Called after every finished job with ``(done, failed, remaining)``."""


@dataclass(frozen=True)
class BatchSummary:
    """Counts of a finished batch."""

    n_jobs: int
    n_ok: int
    n_failed: int
    n_cached: int

    def to_dict(self) -> dict[str, int]:
        return {"n_jobs": self.n_jobs, "n_ok": self.n_ok, "n_failed": self.n_failed,
                "n_cached": self.n_cached}


def run_jobs(
    jobs: Sequence[Job],
    executor: Executor | None = None,
    *,
    cache: ContentCache | None = None,
    progress: Progress | None = None,
) -> tuple[dict[str, JobResult], BatchSummary]:
    """Run ``jobs`` (cached ones are skipped) and return their results by key.

    Parameters
    ----------
    jobs : sequence of Job
        Keys must be unique.
    executor : Executor, optional
        Where to run them (default: :class:`LocalExecutor` over the usable CPUs).
    cache : ContentCache, optional
        Finished results are looked up and stored here.
    progress : callable, optional
        ``progress(done, failed, remaining)`` after each job (cached ones included).

    Returns
    -------
    results : dict
        Job key -> :class:`JobResult`, in the order of ``jobs``.
    summary : BatchSummary
    """
    keys = [j.key for j in jobs]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise IbiscapeError(f"duplicate job keys: {', '.join(dup[:5])}")
    results: dict[str, JobResult] = {}
    todo: list[Job] = []
    content: dict[str, str] = {}
    n_failed = 0

    def tick() -> None:
        if progress is not None:
            progress(len(results), n_failed, len(jobs) - len(results))

    for job in jobs:
        hit = None
        if cache is not None:
            try:
                content[job.key] = cache.key(job)
            except OSError:
                content.pop(job.key, None)  # an unreadable input: the job itself will say so
            else:
                hit = cache.get(job, content[job.key])
        if hit is not None:
            results[job.key] = hit
        else:
            todo.append(job)
    tick()
    if todo:
        by_key = {j.key: j for j in todo}
        own = executor is None
        ex = LocalExecutor() if executor is None else executor
        try:
            for res in ex.map(todo):
                results[res.key] = res
                if not res.ok:
                    n_failed += 1
                elif cache is not None and res.key in content:
                    cache.put(content[res.key], by_key[res.key], res)
                tick()
        finally:
            if own:
                ex.close()
    if cache is not None:
        cache.flush()
    ordered = {k: results[k] for k in keys}
    n_cached = sum(r.cached for r in ordered.values())
    return ordered, BatchSummary(len(jobs), len(jobs) - n_failed, n_failed, n_cached)

