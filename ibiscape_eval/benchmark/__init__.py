"""The whole IBISCape paper on generated data in one call (``ibiscape-eval benchmark``).

::

    from ibiscape_eval.benchmark import run_benchmark
    from ibiscape_eval.report.benchmark_report import write_benchmark_report
    res = run_benchmark("bench/", scale=0.05)          # suite, calibrations, IMU noise, hot pixels, VIO
    write_benchmark_report("bench/report", res)         # report.html, report.md, report.json

Every step runs as :mod:`ibiscape_eval.batch` jobs (local pool or Dask cluster); see
:mod:`ibiscape_eval.benchmark.run` for the steps and :mod:`ibiscape_eval.benchmark.steps` for the
job functions; their typed results are in :mod:`ibiscape_eval.benchmark.results`.
"""

from __future__ import annotations

from .results import BenchmarkSteps, StepRecord
from .run import STEPS, BenchmarkResult, benchmark_jobs, run_benchmark

__all__ = ["STEPS", "BenchmarkResult", "BenchmarkSteps", "StepRecord", "benchmark_jobs",
           "run_benchmark"]
