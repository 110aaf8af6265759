"""Typed results of the benchmark's steps (what the jobs of :mod:`.steps` return, and the records
the benchmark keeps of every job).

A job's value travels as JSON (between processes, to and from a Dask cluster, through the content
cache); on this side it is read once into a frozen dataclass (``from_dict``), and the benchmark,
its report and the command line use the attributes, so a renamed field is an error mypy sees, not
a ``KeyError`` in a report.  ``to_dict()`` gives back the same JSON, key for key and in the same
order, so ``report.json`` is unchanged.

::

    from ibiscape_eval.benchmark.results import CameraCalibrationResult
    r = CameraCalibrationResult.from_dict(job_value)
    r.cameras[0].fx_error_px
"""

from __future__ import annotations

import dataclasses
import functools
import sys
import types
import typing
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Generic, TypeVar

from ibiscape_eval.core.errors import IbiscapeError

__all__ = [
    "STEP_VALUES",
    "BenchmarkSteps",
    "CameraCalibrationResult",
    "CameraError",
    "EvaluationScores",
    "HotPixelsResult",
    "ImuCameraError",
    "ImuCameraResult",
    "ImuNoiseResult",
    "JsonRecord",
    "NoiseRow",
    "PairError",
    "StepRecord",
    "SuiteSequence",
    "VioResult",
]

R = TypeVar("R", bound="JsonRecord")
V = TypeVar("V", bound="JsonRecord")


def _json_name(f: dataclasses.Field[Any]) -> str:
    return str(f.metadata.get("json", f.name))


def _to_json(x: Any) -> Any:
    if isinstance(x, JsonRecord):
        return x.to_dict()
    if isinstance(x, tuple | list):
        return [_to_json(v) for v in x]
    if isinstance(x, Mapping):
        return {k: _to_json(v) for k, v in x.items()}
    return x


def _from_json(tp: Any, x: Any) -> Any:
    """``x`` (JSON) as the annotated type ``tp``: records and tuples of records are rebuilt."""
    if x is None:
        return None
    args = typing.get_args(tp)
    origin = typing.get_origin(tp)
    if isinstance(tp, type) and issubclass(tp, JsonRecord):
        return tp.from_dict(x)
    if origin is tuple:
        return tuple(_from_json(args[0], v) for v in x)
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        return _from_json(inner[0], x) if len(inner) == 1 else x
    if origin is dict:
        return dict(x)
    return x


@functools.cache
def _hints(cls: Any) -> dict[str, Any]:
    return typing.get_type_hints(cls, vars(sys.modules[cls.__module__]))


class JsonRecord:
    """A frozen dataclass that is read from and written to one JSON object.

    Fields map to keys of the same name (``field(metadata={"json": "from"})`` renames one); a
    field with ``metadata={"omit_none": True}`` is left out of :meth:`to_dict` when None.  Keys
    are sorted (``sorted_keys``) as a job's value is after its trip through
    :func:`~ibiscape_eval.batch.canonical_json`, so a value reads and writes back unchanged.
    """

    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]
    sorted_keys: ClassVar[bool] = True

    def to_dict(self) -> dict[str, Any]:
        """The JSON object (keys sorted; in field order for ``sorted_keys = False``)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if v is None and f.metadata.get("omit_none"):
                continue
            out[_json_name(f)] = _to_json(v)
        return dict(sorted(out.items())) if self.sorted_keys else out

    @classmethod
    def from_dict(cls: type[R], doc: Mapping[str, Any]) -> R:
        """Read :meth:`to_dict`'s JSON object back (missing optional keys take their defaults)."""
        hints = _hints(typing.cast(Any, cls))
        fields = dataclasses.fields(cls)
        missing = [_json_name(f) for f in fields if _json_name(f) not in doc
                   and f.default is dataclasses.MISSING]
        if missing:
            raise IbiscapeError(f"{cls.__name__}: no {', '.join(missing)} in {sorted(doc)}; not "
                                "the JSON of this ibiscape-eval version's benchmark result")
        return cls(**{f.name: _from_json(hints[f.name], doc[_json_name(f)])
                      for f in fields if _json_name(f) in doc})


# --------------------------------------------------------------------------------------------
# the job values, one class per step


@dataclass(frozen=True)
class SuiteSequence(JsonRecord):
    """The suite step's value: the simulator's summary of the sequence
    (``ibiscape_eval.sim.SequenceSummary.to_dict()``), kept as the simulator wrote it."""

    summary: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return dict(self.summary)

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> SuiteSequence:
        return cls(dict(doc))


@dataclass(frozen=True)
class CameraError(JsonRecord):
    """One calibrated camera against its true intrinsics [px]."""

    camera: str
    fx_error_px: float
    fy_error_px: float
    cx_error_px: float
    cy_error_px: float
    distortion_max_error: float
    fx_px: float
    fx_truth_px: float


@dataclass(frozen=True)
class PairError(JsonRecord):
    """One neighbouring camera pair against its true relative pose."""

    from_camera: str = field(metadata={"json": "from"})
    to_camera: str = field(metadata={"json": "to"})
    baseline_error_mm: float
    baseline_truth_m: float
    rotation_error_deg: float


@dataclass(frozen=True)
class CameraCalibrationResult(JsonRecord):
    """:func:`~.steps.camera_calibration`: intrinsics and baselines against the truth."""

    sequence: str
    target: str | None
    model: str
    cameras: tuple[CameraError, ...]
    chain: tuple[PairError, ...]
    rms_px: float | None
    n_views: int | None
    reconstruction: dict[str, str]


@dataclass(frozen=True)
class ImuCameraError(JsonRecord):
    """One camera's ``T_cam_imu`` and time offset against the simulator's mounting."""

    camera: str
    rotation_error_deg: float | None
    translation_error_mm: float | None
    timeshift_error_ms: float | None
    timeshift_ms: float | None
    timeshift_truth_ms: float | None
    reprojection_rms_px: float | None


@dataclass(frozen=True)
class ImuCameraResult(JsonRecord):
    """:func:`~.steps.imu_camera_calibration`: per camera, and the solver's warnings."""

    sequence: str
    cameras: tuple[ImuCameraError, ...]
    forced: bool
    warnings: tuple[str, ...]
    method: str


@dataclass(frozen=True)
class NoiseRow(JsonRecord):
    """One Kalibr noise key: configured truth, estimate, error [%]."""

    key: str
    truth: float | None
    estimate: float | None
    error_pct: float | None


@dataclass(frozen=True)
class ImuNoiseResult(JsonRecord):
    """:func:`~.steps.imu_noise`: the Allan fit of the still IMU against its densities."""

    sequence: str
    n_samples: int
    duration_h: float
    rate_hz: float
    rows: tuple[NoiseRow, ...]


@dataclass(frozen=True)
class HotPixelsResult(JsonRecord):
    """:func:`~.steps.hot_pixels`: events removed, precision and recall against the planted
    noisy pixels (None: nothing to compare)."""

    sequence: str
    camera: str
    n_events: int
    n_hot_pixels: int
    n_noisy_pixels: int
    fraction_removed: float | None
    precision: float | None
    recall: float | None


@dataclass(frozen=True)
class VioResult(JsonRecord):
    """:func:`~.steps.vio`: the run's statistics (a subset of ``VioResult.to_dict()`` of the VIO
    pipeline) and the estimate as TUM text (None once the benchmark has written it to its runs
    folder; then left out of the JSON)."""

    sequence: str
    stats: dict[str, Any]
    n_poses: int
    estimate_tum: str | None = field(default=None, metadata={"omit_none": True})


@dataclass(frozen=True)
class EvaluationScores(JsonRecord):
    """The evaluation step's value: ATE and RPE of one VIO estimate (made in this process, its
    keys in field order)."""

    sorted_keys: ClassVar[bool] = False

    ate_rmse_m: float | None
    rpe_m: float | None
    rpe_deg: float | None
    n_matched: int | None


#: The value type of every step's records.
STEP_VALUES: dict[str, type[JsonRecord]] = {
    "suite": SuiteSequence,
    "camera_calibration": CameraCalibrationResult,
    "imu_camera": ImuCameraResult,
    "imu_noise": ImuNoiseResult,
    "hot_pixels": HotPixelsResult,
    "vio": VioResult,
    "evaluation": EvaluationScores,
}


@dataclass(frozen=True)
class StepRecord(Generic[V]):
    """One job of a step: its key, the sequence, how it went and its typed value."""

    key: str
    sequence: str
    status: str
    error: str | None
    seconds: float
    cached: bool
    value: V | None

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.key, "sequence": self.sequence, "status": self.status,
                "error": self.error, "seconds": self.seconds, "cached": self.cached,
                "value": None if self.value is None else self.value.to_dict()}

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any], value_type: type[V]) -> StepRecord[V]:
        v = doc.get("value")
        return cls(str(doc["key"]), str(doc["sequence"]), str(doc["status"]), doc.get("error"),
                   float(doc.get("seconds", 0.0)), bool(doc.get("cached", False)),
                   None if v is None else value_type.from_dict(v))


@dataclass(frozen=True)
class BenchmarkSteps:
    """Every step's job records, in the order the steps run (:data:`STEP_VALUES`)."""

    suite: tuple[StepRecord[SuiteSequence], ...] = ()
    camera_calibration: tuple[StepRecord[CameraCalibrationResult], ...] = ()
    imu_camera: tuple[StepRecord[ImuCameraResult], ...] = ()
    imu_noise: tuple[StepRecord[ImuNoiseResult], ...] = ()
    hot_pixels: tuple[StepRecord[HotPixelsResult], ...] = ()
    vio: tuple[StepRecord[VioResult], ...] = ()
    evaluation: tuple[StepRecord[EvaluationScores], ...] = ()

    def items(self) -> Iterator[tuple[str, tuple[StepRecord[Any], ...]]]:
        """``(step name, records)`` in step order."""
        for name in STEP_VALUES:
            yield name, getattr(self, name)

    def to_dict(self) -> dict[str, list[dict[str, Any]]]:
        return {name: [r.to_dict() for r in recs] for name, recs in self.items()}

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> BenchmarkSteps:
        steps: dict[str, Any] = {
            name: tuple(StepRecord.from_dict(r, STEP_VALUES[name]) for r in doc[name])
            for name in STEP_VALUES if name in doc}
        return cls(**steps)
