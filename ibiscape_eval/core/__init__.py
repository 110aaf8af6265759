"""Core value types and batched geometry: numpy/scipy only, no I/O.

The value types are exported lazily (:mod:`ibiscape_eval.core.lazy`), so importing a light core
module (``errors``, ``lazy``) does not load numpy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .errors import (
    CalibrationError,
    DegenerateInputError,
    FormatError,
    IbiscapeError,
    IbiscapeWarning,
)
from .lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "CalibrationTarget": "kalibr",
    "CameraChain": "kalibr",
    "ChainCamera": "kalibr",
    "ImuNoise": "kalibr",
    "GnssFixes": "gnss",
    "ImuRecord": "imu",
    "ImuTiming": "imu",
    "NS_PER_S": "time",
    "ns_from_s": "time",
    "s_from_ns": "time",
    "Trajectory": "trajectory",
}

__all__ = [
    "NS_PER_S",
    "CalibrationError",
    "CalibrationTarget",
    "CameraChain",
    "ChainCamera",
    "DegenerateInputError",
    "FormatError",
    "GnssFixes",
    "IbiscapeError",
    "IbiscapeWarning",
    "ImuNoise",
    "ImuRecord",
    "ImuTiming",
    "Trajectory",
    "ns_from_s",
    "s_from_ns",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # pragma: no cover
    from .gnss import GnssFixes
    from .imu import ImuRecord, ImuTiming
    from .kalibr import CalibrationTarget, CameraChain, ChainCamera, ImuNoise
    from .time import NS_PER_S, ns_from_s, s_from_ns
    from .trajectory import Trajectory
