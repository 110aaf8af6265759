"""The job model every batch command shares (``report``, and later ``sim suite`` and ``benchmark``).

A :class:`Job` holds a module-level function (a reference, checked by mypy; it travels by its
import path ``"package.module:function"``, :attr:`Job.func_name`), the JSON parameters it is called
with, and the input files whose bytes determine its result.  Nothing else in a job is a Python
object: a job can be written to JSON, hashed for the content cache
(:mod:`ibiscape_eval.batch.cache`), run in this process, in a pool of local processes or on a Dask
cluster, and gives the same :class:`JobResult` wherever it runs.

A job function takes keyword arguments (the job's ``params``) and returns a JSON-compatible
``dict``.  An exception it raises is caught where it runs and recorded as a failed result with its
message; the other jobs carry on.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import math
import time
import traceback
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["Job", "JobFunction", "JobResult", "canonical_json", "function_name", "run_job"]

#: A job function: keyword arguments (the job's JSON parameters) in, a JSON-compatible dict out.
JobFunction = Callable[..., Mapping[str, Any]]


def _check_json(value: Any, where: str) -> None:
    """Raise ``IbiscapeError`` unless ``value`` is strict JSON (no NaN/Infinity, str keys)."""
    if isinstance(value, float) and not math.isfinite(value):
        raise IbiscapeError(f"{where}: {value} is not valid JSON (NaN/Infinity); use None")
    if isinstance(value, Mapping):
        for k, v in value.items():
            if not isinstance(k, str):
                raise IbiscapeError(f"{where}: key {k!r} is not a string")
            _check_json(v, f"{where}.{k}")
    elif isinstance(value, list | tuple):
        for i, v in enumerate(value):
            _check_json(v, f"{where}[{i}]")
    elif not (value is None or isinstance(value, str | int | float | bool)):
        raise IbiscapeError(f"{where}: {type(value).__name__} is not JSON-compatible")


def canonical_json(value: Any) -> str:
    """One text per JSON value: sorted keys, no spaces, shortest round-trip floats.

    Two equal values give the same text, so it can be hashed (the cache key) and compared (local
    versus Dask results).
    """
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)


@dataclass(frozen=True)
class Job:
    """One unit of work.

    Attributes
    ----------
    key : str
        Unique, human-readable name within a batch (``"V1/orbslam3/trial_2"``); results are
        returned under it.
    func : callable
        A module-level function (:data:`JobFunction`); it travels by its import path
        (:attr:`func_name`) and is imported where the job runs.
    params : dict
        Keyword arguments of ``func``, JSON-compatible.
    inputs : tuple of str
        Files or folders whose content decides the result (hashed for the cache key).
    """

    key: str
    func: JobFunction
    params: Mapping[str, Any] = field(default_factory=dict)
    inputs: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.key:
            raise IbiscapeError("a job needs a non-empty key")
        name = function_name(self.func)
        if resolve(name) is not self.func:
            raise IbiscapeError(f"job {self.key}: {name} is not importable by that name (a job "
                                "function must be defined at the top level of a module)")
        _check_json(dict(self.params), f"job {self.key} params")
        object.__setattr__(self, "inputs", tuple(str(p) for p in self.inputs))

    @property
    def func_name(self) -> str:
        """``"package.module:function"``, the function's import path."""
        return function_name(self.func)

    def to_dict(self) -> dict[str, Any]:
        """JSON form: ``key, func`` (the import path), ``params, inputs``."""
        return {"key": self.key, "func": self.func_name, "params": dict(self.params),
                "inputs": list(self.inputs)}

    def __repr__(self) -> str:
        return f"Job({self.key!r}, {self.func_name})"


@dataclass(frozen=True)
class JobResult:
    """What a job gave: its value, or the error that stopped it.

    Attributes
    ----------
    key : str
        The job's key.
    status : {"ok", "failed"}
        ``"failed"`` when the function raised (or its worker died).
    value : dict or None
        The function's return value, passed through JSON (so a result read from the cache, or
        computed on another machine, is equal to one computed here).
    error : str or None
        ``"ExceptionType: message"`` of a failed job.
    cached : bool
        Whether the value came from the content cache.
    seconds : float
        Wall time of the function where it ran (0 for cached results).
    """

    key: str
    status: str
    value: dict[str, Any] | None = None
    error: str | None = None
    cached: bool = False
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.key, "status": self.status, "value": self.value, "error": self.error,
                "cached": self.cached, "seconds": self.seconds}

    def __repr__(self) -> str:
        return f"JobResult({self.key!r}, {self.status}{', cached' if self.cached else ''})"


def function_name(func: JobFunction) -> str:
    """``"package.module:qualified.name"`` of a function."""
    module, name = getattr(func, "__module__", None), getattr(func, "__qualname__", None)
    if not (module and name) or "<" in name:
        raise IbiscapeError(f"{func!r} is not a module-level function; a job needs one")
    return f"{module}:{name}"


def resolve(func: str) -> Any:
    """Import ``"package.module:function"`` and return the function."""
    module, _, name = func.partition(":")
    try:
        obj: Any = importlib.import_module(module)
        for part in name.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError) as e:
        raise IbiscapeError(f"cannot import job function {func!r}: {e}") from None
    return obj


@contextlib.contextmanager
def _single_threaded_kernels() -> Iterator[None]:
    """One BLAS and one OpenCV thread while a job runs, restored afterwards.

    Results must be identical whichever executor runs a job (in this process, a pool worker, a
    Dask worker), but a multi-threaded BLAS sums in an order that depends on its thread count,
    and OpenCV's parallel corner detection differs from run to run in the last digits (measured:
    two runs of the same camera calibration differed, with one OpenCV thread they are
    identical); the parallelism of a batch comes from running jobs side by side.
    """
    from threadpoolctl import threadpool_limits

    from ibiscape_eval.core.cpus import opencv_threads

    with opencv_threads(1), threadpool_limits(limits=1, user_api="blas"):
        yield


def run_job(job: Job) -> JobResult:
    """Run one job here and now; any exception becomes a failed :class:`JobResult`.

    This is the function every executor runs (in this process, a pool worker or a Dask worker).
    """
    t0 = time.perf_counter()
    try:
        with _single_threaded_kernels():
            value = job.func(**dict(job.params))
        if not isinstance(value, Mapping):
            raise IbiscapeError(
                f"job function {job.func_name} returned {type(value).__name__}, expected a dict"
            )
        try:  # json's own checks (C speed): NaN/Infinity and non-JSON types are refused
            text = canonical_json(value)
        except (TypeError, ValueError) as e:
            raise IbiscapeError(f"job function {job.func_name} returned a value that is not strict "
                                f"JSON ({e}); return None instead of NaN") from None
        value = json.loads(text)
    except Exception as e:  # a job's failure is data, not a crash of the batch
        msg = " ".join(str(e).split()) or "".join(traceback.format_exception_only(e)).strip()
        return JobResult(job.key, "failed", error=f"{type(e).__name__}: {msg}",
                         seconds=time.perf_counter() - t0)
    return JobResult(job.key, "ok", value=value, seconds=time.perf_counter() - t0)
