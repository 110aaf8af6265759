"""Batch execution: one job model, run locally (a process pool) or on a Dask cluster, cached by
content.

::

    from ibiscape_eval.batch import Job, ContentCache, LocalExecutor, DaskExecutor, run_jobs
    from mypkg.evaluate import one_run
    jobs = [Job(f"run{i}", one_run, {"path": p}, inputs=(p,)) for i, p in enumerate(paths)]
    results, summary = run_jobs(jobs, LocalExecutor(), cache=ContentCache(".cache"))
    results, summary = run_jobs(jobs, DaskExecutor("tcp://10.0.0.5:8786"))   # same results

A job holds a module-level function (sent to a worker by its import path) and JSON parameters, so
it is hashed for the cache, sent to a cluster and recorded as JSON without pickling any user data.  A job that raises is
recorded as failed with its message; the other jobs carry on.
"""

from __future__ import annotations

from .cache import ContentCache, code_version, default_cache_dir
from .executors import (
    BatchSummary,
    DaskExecutor,
    Executor,
    LocalExecutor,
    Progress,
    make_executor,
    run_jobs,
)
from .jobs import Job, JobFunction, JobResult, canonical_json, run_job

__all__ = [
    "BatchSummary",
    "ContentCache",
    "DaskExecutor",
    "Executor",
    "Job",
    "JobFunction",
    "JobResult",
    "LocalExecutor",
    "Progress",
    "canonical_json",
    "code_version",
    "default_cache_dir",
    "make_executor",
    "run_job",
    "run_jobs",
]
