"""Typed errors of the camera-IMU calibration: the fields a caller needs, the message built from
them (a caller adds the IMU file by :meth:`ImuStreamError.at`, never by reading the message)."""

from __future__ import annotations

from os import PathLike

from ibiscape_eval.core.errors import CalibrationError

__all__ = ["ImuCoverageError", "ImuRateError", "ImuStreamError"]


class ImuStreamError(CalibrationError):
    """The IMU samples do not fit ``imu.yaml`` or the images; ``source`` is the IMU file (None
    while unknown, e.g. samples given in memory)."""

    source: str | None

    def describe(self) -> str:  # pragma: no cover - every subclass says what is wrong
        raise NotImplementedError

    def _set_message(self, source: str | PathLike[str] | None) -> None:
        self.source = None if source is None else str(source)
        text = self.describe()
        self.args = (text if self.source is None else f"{self.source}: {text}",)

    def at(self, source: str | PathLike[str]) -> ImuStreamError:
        """The same error naming the IMU file ``source``."""
        raise NotImplementedError  # pragma: no cover


class ImuRateError(ImuStreamError):
    """``imu.yaml``'s ``update_rate`` disagrees with the rate of the IMU samples."""

    def __init__(self, update_rate_hz: float, data_rate_hz: float,
                 source: str | PathLike[str] | None = None):
        super().__init__()
        self.update_rate_hz = float(update_rate_hz)
        self.data_rate_hz = float(data_rate_hz)
        self._set_message(source)

    def describe(self) -> str:
        return (f"imu.yaml says update_rate {self.update_rate_hz:g} Hz but the IMU data run at "
                f"{self.data_rate_hz:.2f} Hz; fix update_rate or give the imu.yaml of this IMU")

    def at(self, source: str | PathLike[str]) -> ImuRateError:
        return ImuRateError(self.update_rate_hz, self.data_rate_hz, source)


class ImuCoverageError(ImuStreamError):
    """The IMU stream does not cover the images of camera ``camera`` (stamps in ns)."""

    def __init__(self, camera: str, imu_ns: tuple[int, int], images_ns: tuple[int, int],
                 source: str | PathLike[str] | None = None):
        super().__init__()
        self.camera = camera
        self.imu_ns = (int(imu_ns[0]), int(imu_ns[1]))
        self.images_ns = (int(images_ns[0]), int(images_ns[1]))
        self._set_message(source)

    def describe(self) -> str:
        return (f"the IMU stream ({self.imu_ns[0]}..{self.imu_ns[1]} ns) does not cover the "
                f"images of camera {self.camera} ({self.images_ns[0]}..{self.images_ns[1]}"
                " ns); give the IMU recording of the same run")

    def at(self, source: str | PathLike[str]) -> ImuCoverageError:
        return ImuCoverageError(self.camera, self.imu_ns, self.images_ns, source)
