"""The typed, lazy sequence every command opens: cameras, IMU, target, calibration, ground truth.

:func:`ibiscape_eval.io.open_sequence` builds a :class:`Sequence` from any supported layout
(IBISCape, EuRoC/ASL, TUM-VI, ROS 1/2 bags, image globs); ``calib``, ``calib --imu``, ``vio`` and
``benchmark`` take it and never parse a path themselves.  Opening is cheap: frame lists (stamps
and file names) are read, images, event windows, IMU samples and ground truth are read on first
use (:class:`Lazy`).  No I/O happens in this module: the readers are callables handed in by
:mod:`ibiscape_eval.io`.

What a layout states is kept apart from what is unknown: ``sensor_size``, ``rate_hz``,
``camera`` (intrinsics), ``T_body_cam``, the IMU noise and ``T_body_imu`` are None when the
recording does not say them, so a consumer can ask for an option instead of guessing.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from collections.abc import Sequence as Seq
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

import numpy as np
import numpy.typing as npt

from .camera import CameraModel
from .errors import IbiscapeError
from .kalibr import ImuNoise

if TYPE_CHECKING:  # pragma: no cover
    from .trajectory import Trajectory  # scipy: loaded by whoever reads a trajectory

__all__ = ["SEQUENCE_LAYOUTS", "CameraStream", "ImuStream", "Lazy", "Sequence"]

T = TypeVar("T")

#: layouts :func:`ibiscape_eval.io.open_sequence` recognises, in the order it tries them
SEQUENCE_LAYOUTS = ("rosbag", "ibiscape", "tumvi", "euroc", "images")

FloatArray = npt.NDArray[np.float64]


class Lazy(Generic[T]):
    """A value computed on first :meth:`get` (thread-safe), then kept."""

    __slots__ = ("_done", "_fn", "_lock", "_value")

    def __init__(self, fn: Callable[[], T]):
        self._fn = fn
        self._lock = threading.Lock()
        self._value: T | None = None
        self._done = False

    @classmethod
    def of(cls, value: T) -> Lazy[T]:
        """An already known value."""
        lz: Lazy[T] = cls(lambda: value)
        lz._value, lz._done = value, True
        return lz

    @property
    def loaded(self) -> bool:
        return self._done

    def get(self) -> T:
        if not self._done:
            with self._lock:
                if not self._done:
                    self._value = self._fn()
                    self._done = True
        return self._value  # type: ignore[return-value]

    def __repr__(self) -> str:
        return f"Lazy({'loaded' if self._done else 'not read'})"


@dataclass(frozen=True, eq=False)
class CameraStream:
    """One camera of a sequence: frames (stamps + files or a loader) or events (windows).

    Attributes
    ----------
    name : str
        The layout's camera name (``rgbL``, ``cam0``, a bag topic's camera, a glob's name).
    kind : str
        ``"frames"`` or ``"events"``.
    stamps_ns : ndarray (N,) int64 or None
        Time of every frame (the END of every event window for events); None when the file names
        carry none (plain image globs).
    root : Path
        The camera's folder (or bag, or glob).
    sensor_size : (width, height) px or None
        As the layout states it (``sequence.yaml`` resolution, ``sensor.yaml``, camchain, the
        bag's image messages); None when it does not say.
    rate_hz : float or None
        Stated frame rate (None: not stated; :meth:`measured_rate_hz` gives the stamps' rate).
    camera : CameraModel or None
        Intrinsics and distortion when the layout holds a calibration.
    T_body_cam : ndarray (4, 4) or None
        Camera pose in the body frame when the layout holds one.
    rostopic : str or None
    entry : mapping
        The layout's own description of this camera (``sequence.yaml`` ``cameras.<name>``,
        EuRoC ``sensor.yaml``): truth and sensor settings for the consumers that compare.
    windows_ns : ndarray (N, 2) int64 or None
        Event windows ``[start, end)`` (events only).
    exact_stamps : bool
        Stamps are numbers from file names (pair views exactly, not within a tolerance).
    files, loader, n
        The frame files (read on first use), ``loader(i)`` -> image, the number of frames.
    events : Lazy event source or None
        Event cameras: the :class:`ibiscape_eval.io.events.EventSource`.
    calibration_source : str
        The file ``camera`` / ``T_body_cam`` / ``entry`` came from (for messages).
    """

    name: str
    kind: str
    stamps_ns: npt.NDArray[np.int64] | None
    root: Path
    sensor_size: tuple[int, int] | None = None
    rate_hz: float | None = None
    camera: CameraModel | None = None
    T_body_cam: FloatArray | None = None
    rostopic: str | None = None
    entry: Mapping[str, Any] = field(default_factory=dict)
    windows_ns: npt.NDArray[np.int64] | None = None
    exact_stamps: bool = False
    files: Lazy[tuple[Path, ...]] | None = None
    loader: Callable[[int], Any] | None = None
    n: int = 0
    events: Lazy[Any] | None = None
    calibration_source: str = ""

    def __len__(self) -> int:
        return self.n

    @property
    def paths(self) -> tuple[Path, ...]:
        """The frame files (the event files of each window for events); empty for bag frames."""
        return () if self.files is None else self.files.get()

    def label(self, i: int) -> str:
        """A name for frame ``i`` in messages (its file, or ``<bag>:<topic>#i``)."""
        if self.files is not None:
            return str(self.paths[i])
        return f"{self.root}:{self.rostopic}#{i}"

    def load(self, i: int) -> Any:
        """Frame ``i`` as an image array (None with a warning when unreadable); frames only."""
        if self.kind != "frames" or self.loader is None:
            raise IbiscapeError(f"{self.root}: camera {self.name} has no frames to load ({self.kind})")
        return self.loader(i)

    def measured_rate_hz(self) -> float | None:
        """The frame rate of the stamps (median interval), None with fewer than two."""
        if self.stamps_ns is None or self.stamps_ns.size < 2:
            return None
        dt = float(np.median(np.diff(self.stamps_ns)))
        return 1e9 / dt if dt > 0 else None

    def with_sensor_size(self, size: tuple[int, int]) -> CameraStream:
        return replace(self, sensor_size=(int(size[0]), int(size[1])))

    def __repr__(self) -> str:
        size = "size ?" if self.sensor_size is None else f"{self.sensor_size[0]}x{self.sensor_size[1]}"
        return f"CameraStream({self.name}: {len(self)} {self.kind}, {size}, from {self.root})"


@dataclass(frozen=True, eq=False)
class ImuStream:
    """The IMU of a sequence: samples read on first use, noise and rate when stated.

    Attributes
    ----------
    name : str
    source : Path
        The csv (or bag) holding the samples.
    samples : Lazy of (stamps_ns (N,) int64, gyro_rad_s (N, 3), accel_m_s2 (N, 3))
        In the IMU frame (right-handed; IBISCape's left-handed files are converted by the reader).
    noise : ImuNoise or None
        The continuous-time noise densities (Kalibr's ``imu.yaml`` convention) when the layout
        states them.
    noise_source : str
        Where the noise came from (for messages).
    noise_problem : str or None
        What is wrong with noise the layout states but that cannot be used (a missing or bad
        key); the consumers that need the noise refuse with it.
    rate_hz : float or None
        Stated sample rate.
    T_body_imu : ndarray (4, 4) or None
    rostopic : str or None
    fmt : str
        The csv flavour (``"euroc"`` or ``"ibiscape"``: CARLA's frame converted), or ``"rosbag"``.
    """

    name: str
    source: Path
    samples: Lazy[tuple[npt.NDArray[np.int64], FloatArray, FloatArray]]
    noise: ImuNoise | None = None
    noise_source: str = ""
    rate_hz: float | None = None
    T_body_imu: FloatArray | None = None
    rostopic: str | None = None
    fmt: str = "euroc"
    noise_problem: str | None = None

    def __repr__(self) -> str:
        rate = "?" if self.rate_hz is None else f"{self.rate_hz:g}"
        return (f"ImuStream({self.name}: {rate} Hz, noise {'known' if self.noise else 'unknown'}, "
                f"from {self.source})")


@dataclass(frozen=True, eq=False)
class Sequence:
    """A recording as :func:`ibiscape_eval.io.open_sequence` opened it.

    Attributes
    ----------
    path : Path
        The folder, bag or first glob.
    layout : str
        One of :data:`SEQUENCE_LAYOUTS` (``"ibiscape"``, ``"euroc"``, ``"tumvi"``, ``"rosbag"``,
        ``"images"``).
    cameras : tuple of CameraStream
    imu : ImuStream or None
    target : mapping or None
        The calibration target in Kalibr's keys (``target_type``, ...) when the layout names one,
        with ``target_source`` saying where.
    groundtruth : Lazy of Trajectory or None
        None when the layout has no ground truth (or an empty file: ``notes`` says so).
    doc : mapping
        The layout's sequence description (IBISCape ``sequence.yaml``; empty otherwise).
    notes : tuple of str
        What was found missing or empty but is optional (e.g. an empty ground-truth csv).
    """

    path: Path
    layout: str
    cameras: tuple[CameraStream, ...]
    imu: ImuStream | None = None
    target: Mapping[str, Any] | None = None
    target_source: str = ""
    groundtruth: Lazy[Trajectory | None] | None = None
    doc: Mapping[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def camera_names(self) -> list[str]:
        return [c.name for c in self.cameras]

    def camera(self, name: str) -> CameraStream:
        for c in self.cameras:
            if c.name == name:
                return c
        raise IbiscapeError(f"{self.path}: no camera {name!r}; cameras: {', '.join(self.camera_names) or 'none'}")

    def select(self, names: Seq[str] | None) -> Sequence:
        """The sequence with only ``names`` (in that order); all cameras for None/empty."""
        if not names:
            return self
        missing = [n for n in names if n not in self.camera_names]
        if missing:
            raise IbiscapeError(f"{self.path}: camera(s) {', '.join(missing)} not found; available: "
                                f"{', '.join(self.camera_names) or 'none'}")
        return replace(self, cameras=tuple(self.camera(n) for n in names))

    def with_cameras(self, cameras: Seq[CameraStream]) -> Sequence:
        return replace(self, cameras=tuple(cameras))

    def ground_truth(self) -> Trajectory | None:
        """The ground truth (read now), None when the layout has none."""
        return None if self.groundtruth is None else self.groundtruth.get()

    def to_dict(self) -> dict[str, Any]:
        """What was opened (strict JSON; no samples)."""
        return {
            "path": str(self.path), "layout": self.layout,
            "cameras": [{"name": c.name, "kind": c.kind, "frames": len(c),
                         "sensor_size": None if c.sensor_size is None else list(c.sensor_size),
                         "rate_hz": c.rate_hz, "calibrated": c.camera is not None,
                         "rostopic": c.rostopic} for c in self.cameras],
            "imu": None if self.imu is None else {
                "name": self.imu.name, "source": str(self.imu.source), "rate_hz": self.imu.rate_hz,
                "noise_known": self.imu.noise is not None, "rostopic": self.imu.rostopic},
            "target": None if self.target is None else dict(self.target),
            "groundtruth": self.groundtruth is not None,
            "notes": list(self.notes),
        }

    def __repr__(self) -> str:
        cams = ", ".join(f"{c.name} ({len(c)} {c.kind})" for c in self.cameras)
        return (f"Sequence({self.path}, {self.layout}: {cams or 'no cameras'}; "
                f"IMU {'yes' if self.imu else 'no'}; ground truth {'yes' if self.groundtruth else 'no'})")
