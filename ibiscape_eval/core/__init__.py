"""Core value types and batched geometry: numpy/scipy only, no I/O."""

from .errors import (
    CalibrationError,
    DegenerateInputError,
    FormatError,
    IbiscapeError,
    IbiscapeWarning,
)
from .gnss import GnssFixes
from .imu import ImuRecord, ImuTiming
from .time import NS_PER_S, ns_from_s, s_from_ns
from .trajectory import Trajectory

__all__ = [
    "NS_PER_S",
    "CalibrationError",
    "DegenerateInputError",
    "FormatError",
    "GnssFixes",
    "IbiscapeError",
    "IbiscapeWarning",
    "ImuRecord",
    "ImuTiming",
    "Trajectory",
    "ns_from_s",
    "s_from_ns",
]
