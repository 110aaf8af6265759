"""Option parsers shared by the readers and the CLI: column mappings and units."""

from __future__ import annotations

import math
from collections.abc import Mapping

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.imu import AXES

__all__ = ["ACCEL_UNITS", "GYRO_UNITS", "STANDARD_GRAVITY_M_S2", "parse_columns", "parse_units"]

STANDARD_GRAVITY_M_S2 = 9.80665
#: Known units and their scale to rad/s and m/s^2.
GYRO_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
ACCEL_UNITS = {"m/s^2": 1.0, "m/s2": 1.0, "g": STANDARD_GRAVITY_M_S2}


def parse_units(text: str | Mapping[str, str] | None) -> tuple[float, float]:
    """Scale factors (gyro -> rad/s, accel -> m/s^2) from ``"gyro=deg/s,accel=g"``.

    Known units: gyro ``rad/s``, ``deg/s``; accel ``m/s^2`` (``m/s2``), ``g`` (9.80665 m/s^2).
    """
    if text is None:
        return 1.0, 1.0
    items = dict(text) if isinstance(text, Mapping) else _pairs(text, "--units")
    gyro, accel = 1.0, 1.0
    for key, unit in items.items():
        u = unit.strip().lower().replace(" ", "")
        if key in ("gyro", "w"):
            if u not in GYRO_UNITS:
                raise IbiscapeError(f"unknown gyro unit {unit!r}; use one of {', '.join(GYRO_UNITS)}")
            gyro = GYRO_UNITS[u]
        elif key in ("accel", "a"):
            if u not in ACCEL_UNITS:
                raise IbiscapeError(f"unknown accel unit {unit!r}; use one of {', '.join(ACCEL_UNITS)}")
            accel = ACCEL_UNITS[u]
        else:
            raise IbiscapeError(f"unknown --units key {key!r}; use gyro=... and accel=...")
    return gyro, accel


_TIME_KEYS = ("t", "t_s", "t_ms", "t_us", "t_ns")
_ALIAS = {"wx": "w_x", "wy": "w_y", "wz": "w_z", "gx": "w_x", "gy": "w_y", "gz": "w_z",
          "ax": "a_x", "ay": "a_y", "az": "a_z", "time": "t", "timestamp": "t"}
_SKIP = ("_", "-", "skip", "")


def parse_columns(text: str | Mapping[str, str | int] | None) -> dict[str, str | int]:
    """Column mapping from ``"t=0,w_x=1,...,a_z=6"`` (0-based indices or header names), or the
    file's columns in order, ``"t,ax,ay,az,gx,gy,gz"`` (``_`` skips a column).

    Keys: ``t`` (unit from the header or the sample interval) or ``t_s``, ``t_ms``, ``t_us``,
    ``t_ns`` (stated unit), and the six axes ``w_x w_y w_z a_x a_y a_z`` (``wx gx ax``
    spellings are accepted).  Values: 0-based column numbers or header names.
    """
    if text is None:
        return {}
    if isinstance(text, str) and "=" not in text:
        raw: dict[str, str | int] = {}
        for i, part in enumerate(text.split(",")):
            k = part.strip().lower()
            if k in _SKIP:
                continue
            if k in raw:
                raise IbiscapeError(f"--columns names {part.strip()!r} twice")
            raw[k] = i
    else:
        raw = dict(text) if isinstance(text, Mapping) else dict(_pairs(text, "--columns"))
    out: dict[str, str | int] = {}
    for key, val in raw.items():
        k = _ALIAS.get(key.lower(), key.lower())
        if k not in (*AXES, *_TIME_KEYS):
            raise IbiscapeError(f"unknown --columns key {key!r}; use t (or t_s, t_ms, t_us, t_ns) "
                                "and w_x .. a_z (gx, ax ...)")
        if k in out:
            raise IbiscapeError(f"--columns maps {k} twice")
        v: str | int = val
        if isinstance(val, str) and val.strip().lstrip("-").isdigit():
            v = int(val)
        out[k] = v
    if sum(k in _TIME_KEYS for k in out) > 1:
        raise IbiscapeError("--columns maps the time twice; give one of t, t_s, t_ms, t_us, t_ns")
    missing = [a for a in AXES if a not in out]
    if missing:
        raise IbiscapeError(f"--columns lacks {', '.join(missing)}; map all six axes")
    return out


def _pairs(text: str, option: str) -> dict[str, str]:
    out = {}
    for part in text.split(","):
        if not part.strip():
            continue
        if "=" not in part:
            raise IbiscapeError(f"{option}: expected key=value pairs separated by commas, got {part!r}")
        k, v = part.split("=", 1)
        out[k.strip()] = v.strip()
    return out
