"""Which file column holds which IMU axis, in which unit: header names, ``--columns``, stamp units.

A header is read by name, in any order: EuRoC's ``w_RS_S_x [rad s^-1]`` / ``a_RS_S_x [m s^-2]``,
IBISCape's ``w_x``, a ``rostopic echo -p`` CSV's ``field.angular_velocity.x`` /
``field.linear_acceleration.x`` (time ``field.header.stamp``, ns), and the usual spellings
``gx, gyro_x, gyr_x, omega_x, angular_velocity_x`` / ``ax, acc_x, accel_x, linear_acceleration_x``.
A unit in brackets or parentheses (``[deg/s]``, ``(g)``) or as a suffix (``gyro_x_dps``, ``acc_x_g``)
is converted to rad/s and m/s^2 and said so in :attr:`ImuLayout.notes`.  Columns that are not
selected (a text ``frame_id``, covariances, orientation) are never parsed.

Without a header, or with names that are not all recognised, the EuRoC order
``t, w_x, w_y, w_z, a_x, a_y, a_z`` is assumed, and :func:`ibiscape_eval.io.imu.read_imu` checks by
physics that the columns read as gyro do not hold gravity.

The unit of the stamps comes from the header (``[ns]``, ``_s``, ``%time``), else from the
magnitude of epoch stamps, else from the sample interval (:func:`stamp_unit`).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.imu import AXES, ImuRecord

from .options import ACCEL_UNITS, GYRO_UNITS, STANDARD_GRAVITY_M_S2

__all__ = [
    "STAMP_UNITS",
    "ImuFileRecord",
    "ImuLayout",
    "classify_header",
    "override_units",
    "resolve_layout",
    "stamp_unit",
    "with_layout",
]

#: Nanoseconds per unit of a stamp column.
STAMP_UNITS = {"ns": 1, "us": 1_000, "ms": 1_000_000, "s": 1_000_000_000}
#: Sample rates (Hz) that the sample-interval rule accepts: a factor 1000 wide, so that exactly
#: one unit of s / ms / us / ns gives a rate inside it.
IMU_RATE_WINDOW_HZ = (4.0, 4000.0)
#: Rates outside this are refused even when a unit is stated: no IMU samples like that.
IMU_RATE_LIMITS_HZ = (0.05, 1.0e6)
#: Epoch stamps (1990 .. 2100) in seconds; in ms, us and ns scaled by 1e3, 1e6, 1e9.
_EPOCH_S = (6.3e8, 4.1e9)

_GYRO_PREFIX = ("w", "g", "gyr", "gyro", "gyroscope", "omega", "angular_velocity", "ang_vel",
                "angvel", "w_rs_s", "gyro_rate", "rot_rate", "rotation_rate")
_ACCEL_PREFIX = ("a", "acc", "accel", "accelerometer", "acceleration", "linear_acceleration",
                 "lin_acc", "linacc", "a_rs_s", "accl")
_TIME_NAMES = ("t", "time", "timestamp", "stamp", "stamps", "ts", "header_stamp", "%time",
               "time_stamp")
#: name suffixes that state a unit (``gyro_x_dps``)
_SUFFIX_UNITS = {"rad_s": "rad/s", "rads": "rad/s", "dps": "deg/s", "deg_s": "deg/s",
                 "degs": "deg/s", "m_s2": "m/s^2", "mps2": "m/s^2", "ms2": "m/s^2", "g": "g",
                 "mg": "mg", "ns": "ns", "us": "us", "ms": "ms", "s": "s", "sec": "s",
                 "nsec": "ns", "usec": "us", "msec": "ms"}
_UNIT_ALIASES = {
    "rad/s": "rad/s", "rads^-1": "rad/s", "rad*s^-1": "rad/s", "rad/sec": "rad/s",
    "rad_s": "rad/s", "deg/s": "deg/s", "degs^-1": "deg/s", "dps": "deg/s", "°/s": "deg/s",
    "deg/sec": "deg/s", "deg_s": "deg/s",
    "m/s^2": "m/s^2", "m/s2": "m/s^2", "ms^-2": "m/s^2", "m*s^-2": "m/s^2", "m/s/s": "m/s^2",
    "m_s2": "m/s^2", "g": "g", "mg": "mg",
    "ns": "ns", "nsec": "ns", "us": "us", "µs": "us", "usec": "us", "ms": "ms", "msec": "ms",
    "s": "s", "sec": "s",
}
_GYRO_SCALE = dict(GYRO_UNITS)
_ACCEL_SCALE = {**ACCEL_UNITS, "mg": STANDARD_GRAVITY_M_S2 / 1000.0}


@dataclass(frozen=True)
class ImuLayout:
    """How the columns of a table file were mapped to an IMU record.

    Attributes
    ----------
    time_column : int or None
        0-based column of the stamps (None: no stamps, the rate was given).
    time_unit : str or None
        ``"ns"``, ``"us"``, ``"ms"`` or ``"s"``.
    time_unit_from : str
        How the unit was decided: ``"header"``, ``"--columns"``, ``"epoch magnitude"``,
        ``"sample interval"`` or ``"format"``.
    axis_columns : tuple of int
        0-based columns of ``w_x w_y w_z a_x a_y a_z``.
    gyro_scale, accel_scale : float
        Factors to rad/s and m/s^2 (1 when the file is in those units).
    mapped_by : str
        ``"header names"``, ``"--columns"`` or ``"default order"``.
    names : tuple of str or None
        The header row, if any.
    notes : tuple of str
        Conversions and choices made, one sentence each (printed by the CLI).
    """

    time_column: int | None
    time_unit: str | None
    time_unit_from: str
    axis_columns: tuple[int, ...]
    gyro_scale: float = 1.0
    accel_scale: float = 1.0
    mapped_by: str = "default order"
    names: tuple[str, ...] | None = None
    notes: tuple[str, ...] = ()

    @property
    def used_columns(self) -> list[int]:
        """Every column parsed (time first)."""
        t = [] if self.time_column is None else [self.time_column]
        return t + list(self.axis_columns)

    def swapped_option(self) -> str:
        """The ``--columns`` value that reads this file with gyro and accelerometer exchanged."""
        a = self.axis_columns
        swapped = (*a[3:], *a[:3])
        width = max((*swapped, -1 if self.time_column is None else self.time_column)) + 1
        if width <= 10:  # the file's columns in order: t,ax,ay,az,gx,gy,gz
            roles = ["_"] * width
            if self.time_column is not None:
                roles[self.time_column] = "t"
            for name, c in zip(("gx", "gy", "gz", "ax", "ay", "az"), swapped, strict=True):
                roles[c] = name
            return ",".join(roles)
        parts = [] if self.time_column is None else [f"t={self.time_column}"]
        parts += [f"{name}={c}" for name, c in zip(AXES, swapped, strict=True)]
        return ",".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return {
            "time_column": self.time_column,
            "time_unit": self.time_unit,
            "time_unit_from": self.time_unit_from,
            "axis_columns": dict(zip(AXES, self.axis_columns, strict=True)),
            "gyro_scale_to_rad_s": self.gyro_scale,
            "accel_scale_to_m_s2": self.accel_scale,
            "mapped_by": self.mapped_by,
            "notes": list(self.notes),
        }


def _split_unit(name: str) -> tuple[str, str | None]:
    """``"w_RS_S_x [rad s^-1]"`` -> (``"w_rs_s_x"``, ``"rad/s"``-ish raw unit)."""
    unit = None
    m = re.search(r"[\[(]([^\])]*)[\])]", name)
    if m:
        unit = m.group(1).strip()
        name = name[: m.start()] + name[m.end():]
    n = name.strip().lstrip("#").strip().lower()
    if n.startswith("%"):
        n = "%" + re.sub(r"[^a-z0-9%]+", "_", n[1:]).strip("_")
    else:
        n = re.sub(r"[^a-z0-9]+", "_", n).strip("_")
    return n, unit


def _norm_unit(raw: str) -> str | None:
    u = raw.strip().lower().replace(" ", "")
    return _UNIT_ALIASES.get(u)


@dataclass(frozen=True)
class _Role:
    role: str  # w_x .. a_z or "t"
    unit: str | None  # normalised unit, or the raw text when unknown
    unit_known: bool


def _classify(name: str) -> _Role | None:
    base, raw_unit = _split_unit(name)
    if base.startswith("field_"):
        base = base[len("field_"):]
    unit = None
    known = True
    if raw_unit is not None and raw_unit != "":
        unit = _norm_unit(raw_unit)
        if unit is None:
            unit, known = raw_unit, False
    # time
    for tn in _TIME_NAMES:
        if base == tn:
            if base in ("%time", "header_stamp"):
                unit = unit or "ns"  # rostopic echo -p prints stamps in ns
            return _Role("t", unit, known)
        for suf, u in _SUFFIX_UNITS.items():
            if base == f"{tn}_{suf}" and u in STAMP_UNITS:
                return _Role("t", unit or u, known)
    # axes: <prefix>[_]<x|y|z>[_<unit suffix>]
    stem = base
    for suf, u in _SUFFIX_UNITS.items():
        if stem.endswith("_" + suf) and re.search(r"[xyz]_" + re.escape(suf) + "$", stem):
            stem = stem[: -len(suf) - 1]
            if unit is None:
                unit = u
            break
    m = re.fullmatch(r"(.*?)_?([xyz])", stem)
    if not m:
        return None
    prefix, axis = m.group(1), m.group(2)
    if prefix in _GYRO_PREFIX:
        return _Role(f"w_{axis}", unit, known)
    if prefix in _ACCEL_PREFIX:
        return _Role(f"a_{axis}", unit, known)
    return None


def classify_header(names: Sequence[str]) -> dict[str, tuple[int, str | None]] | None:
    """Map a header row to roles: ``{"t": (col, unit), "w_x": (col, unit), ...}``.

    Returns None unless all six axes are recognised.  Raises :class:`ValueError` naming the
    columns when two of them claim one role (the caller turns it into a :class:`FormatError`).
    """
    found: dict[str, list[tuple[int, _Role]]] = {}
    for i, n in enumerate(names):
        r = _classify(n)
        if r is not None:
            found.setdefault(r.role, []).append((i, r))
    if any(a not in found for a in AXES):
        return None
    out: dict[str, tuple[int, str | None]] = {}
    for role, hits in found.items():
        if role == "t" and len(hits) > 1:
            # rostopic: field.header.stamp (sensor time) before %time (receipt time)
            pref = [h for h in hits if _split_unit(names[h[0]])[0] in ("field_header_stamp",
                                                                       "header_stamp")]
            hits = pref or hits[:1]
        if len(hits) > 1:
            raise ValueError(f"columns {', '.join(repr(names[h[0]]) for h in hits)} all look like "
                             f"{role}")
        i, r = hits[0]
        if not r.unit_known:
            raise ValueError(f"unknown unit {r.unit!r} in column {names[i]!r}")
        out[role] = (i, r.unit)
    return out


def stamp_unit(values: np.ndarray) -> tuple[str, str]:
    """Unit of a stamp column from its values: (unit, how it was decided).

    Epoch stamps (1990..2100) are recognised by magnitude when that unit also gives a plausible
    rate; otherwise the unit is the one whose median interval gives a rate in
    :data:`IMU_RATE_WINDOW_HZ` (4 Hz .. 4 kHz: 0.25 s .. 0.25 ms).
    """
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    d = np.diff(v)
    d = d[d > 0]
    if d.size == 0:
        return "ns", "default (no interval to judge by)"
    med = float(np.median(d))
    first = float(abs(v[0]))
    lo, hi = IMU_RATE_LIMITS_HZ
    for unit, f in STAMP_UNITS.items():
        scale = f / 1e9  # seconds per unit
        if _EPOCH_S[0] <= first * scale <= _EPOCH_S[1] and lo <= 1.0 / (med * scale) <= hi:
            return unit, "epoch magnitude"
    wlo, whi = IMU_RATE_WINDOW_HZ
    for unit, f in STAMP_UNITS.items():
        rate = 1.0 / (med * f / 1e9)
        if wlo <= rate < whi:
            return unit, "sample interval"
    return "ns", "default (no unit gives a 4 Hz .. 4 kHz rate)"


def check_rate(p: Any, unit: str, med_interval: float, how: str) -> None:
    """Refuse a stated stamp unit that makes the rate impossible, naming the likely unit."""
    if not (med_interval > 0 and math.isfinite(med_interval)):
        return
    rate = 1e9 / (med_interval * STAMP_UNITS[unit])
    lo, hi = IMU_RATE_LIMITS_HZ
    if lo <= rate <= hi:
        return
    guess = next((u for u, f in STAMP_UNITS.items()
                  if IMU_RATE_WINDOW_HZ[0] <= 1e9 / (med_interval * f) < IMU_RATE_WINDOW_HZ[1]),
                 None)
    hint = f"; they look like {guess} (give --columns t_{guess}=COLUMN)" if guess else ""
    raise FormatError(p, f"stamps read as {unit} ({how}) give a sample rate of {rate:.4g} Hz, "
                      f"which no IMU has{hint}")


def _header_scales(p: Any, names: Sequence[str] | None, axis: Sequence[int],
                   notes: list[str]) -> tuple[float, float]:
    """Units the header states for the columns ``--columns`` chose (1.0 where it states none)."""
    if names is None:
        return 1.0, 1.0
    out = []
    for cols, table, what, target in ((axis[:3], _GYRO_SCALE, "gyro", "rad/s"),
                                      (axis[3:], _ACCEL_SCALE, "accelerometer", "m/s^2")):
        units: set[str] = set()
        for c in cols:
            raw = _split_unit(names[c])[1]
            u = _norm_unit(raw) if raw else None
            if u is None and raw is None:
                r = _classify(names[c])
                u = r.unit if r is not None and r.role != "t" else None
            if u is not None:
                units.add(u)
        if len(units) > 1 or (units and next(iter(units)) not in table):
            raise FormatError(p, f"the header states the {what} columns in {sorted(units)}, not "
                              f"one {what} unit; give --units")
        scale = table[units.pop()] if units else 1.0
        if scale != 1.0:
            notes.append(f"{what} columns in a unit the header states, converted to {target}")
        out.append(scale)
    return out[0], out[1]


def resolve_layout(p: Any, cols: Mapping[str, str | int], names: Sequence[str] | None,
                   n_fields: int) -> ImuLayout:
    """Columns of a table file from ``--columns`` (``cols``), else the header, else the default
    order.  The stamp unit is left None when it must be judged from the values
    (:func:`stamp_unit`)."""
    notes: list[str] = []
    names_t = tuple(names) if names is not None else None
    if cols:
        def idx(v: str | int) -> int:
            if isinstance(v, int):
                if not 0 <= v < n_fields:
                    raise FormatError(p, f"--columns index {v} is outside the file's {n_fields} "
                                      "columns (0-based)")
                return v
            if names is None:
                raise FormatError(p, f"--columns names {v!r} but the file has no header row; "
                                  "give 0-based column numbers")
            if v in names:
                return list(names).index(v)
            bare = [_split_unit(n)[0] for n in names]
            if _split_unit(v)[0] in bare and bare.count(_split_unit(v)[0]) == 1:
                return bare.index(_split_unit(v)[0])
            raise FormatError(p, f"--columns names {v!r}, which is not in the header "
                              f"({', '.join(names)})")

        t_keys = [k for k in cols if k == "t" or k.startswith("t_")]
        t_col = idx(cols[t_keys[0]]) if t_keys else None
        unit = None
        how = "--columns"
        if t_keys and t_keys[0] != "t":
            unit = t_keys[0][2:]
        elif t_keys and names is not None:
            r = _classify(names[t_col]) if t_col is not None else None
            if r is not None and r.role == "t" and r.unit in STAMP_UNITS:
                unit, how = r.unit, "header"
        axis = tuple(idx(cols[a]) for a in AXES)
        gs, as_ = _header_scales(p, names, axis, notes)
        return ImuLayout(t_col, unit, how, axis, gs, as_, mapped_by="--columns", names=names_t,
                         notes=tuple(notes))
    if names is not None:
        try:
            roles = classify_header(names)
        except ValueError as e:
            raise FormatError(p, f"ambiguous header: {e}; choose with --columns, e.g. "
                              "--columns t=0,w_x=1,w_y=2,w_z=3,a_x=4,a_y=5,a_z=6") from None
        if roles is not None:
            axis = tuple(roles[a][0] for a in AXES)
            gunits = {roles[a][1] for a in AXES[:3]} - {None} or {None}
            aunits = {roles[a][1] for a in AXES[3:]} - {None} or {None}
            if len(gunits) > 1 or len(aunits) > 1:
                raise FormatError(p, "the header gives different units to the axes of one sensor "
                                  f"({sorted(map(str, gunits | aunits))}); give --units")
            gu, au = gunits.pop(), aunits.pop()
            gs = _header_scale(p, gu, _GYRO_SCALE, "gyro", "an angular rate", "rad/s", notes)
            as_ = _header_scale(p, au, _ACCEL_SCALE, "accelerometer", "an acceleration", "m/s^2",
                                notes)
            t = roles.get("t")
            t_col = None if t is None else t[0]
            t_unit = None if t is None else t[1]
            if t_unit is not None and t_unit not in STAMP_UNITS:
                raise FormatError(p, f"the header's time unit {t_unit!r} is not one of "
                                  f"{', '.join(STAMP_UNITS)}")
            mapped = ", ".join(f"{a}={names[c]}" for a, c in zip(AXES, axis, strict=True))
            if axis != tuple(range(1, 7)) or t_col != 0:
                notes.append(f"columns by header name: {mapped}")
            return ImuLayout(t_col, t_unit, "header" if t_unit else "", axis, gs, as_,
                             "header names", names_t, tuple(notes))
        notes.append("header names not recognised as gyro/accelerometer axes; read in the "
                     "default order t, w_x, w_y, w_z, a_x, a_y, a_z (give --columns to be sure)")
    if n_fields < 7:
        raise FormatError(p, f"expected 7 columns (timestamp, w_x w_y w_z rad/s, a_x a_y a_z "
                          f"m/s^2), got {n_fields}; give --columns for another layout")
    t_unit = None
    how = ""
    if names is not None:
        r = _classify(names[0])
        if r is not None and r.role == "t" and r.unit in STAMP_UNITS:
            t_unit, how = r.unit, "header"
    return ImuLayout(0, t_unit, how, tuple(range(1, 7)), names=names_t, notes=tuple(notes))


@dataclass(frozen=True, eq=False)
class ImuFileRecord(ImuRecord):
    """An :class:`~ibiscape_eval.core.imu.ImuRecord` read from a file, with the :class:`ImuLayout`
    that says how its columns, units and stamps were read (None for formats without a choice)."""

    layout: ImuLayout | None = None
    #: Conversions and checks made while reading, one sentence each.
    notes: tuple[str, ...] = ()


def with_layout(rec: ImuRecord, layout: ImuLayout | None, notes: Sequence[str] = ()) -> ImuFileRecord:
    """``rec`` as an :class:`ImuFileRecord` carrying ``layout`` and ``notes`` (appended)."""
    base = {f.name: getattr(rec, f.name) for f in dataclasses.fields(ImuRecord)}
    old_layout = getattr(rec, "layout", None)
    old_notes = tuple(getattr(rec, "notes", ()))
    lay = layout if layout is not None else old_layout
    if layout is not None and old_layout is None:
        old_notes = (*old_notes, *layout.notes)
    return ImuFileRecord(**base, layout=lay, notes=(*old_notes, *notes))


def override_units(layout: ImuLayout, scales: tuple[float, float]) -> ImuLayout:
    """``--units`` given: its scales replace the header's (said so when they differ)."""
    notes = [n for n in layout.notes if "(header), converted" not in n]
    if (layout.gyro_scale, layout.accel_scale) not in ((1.0, 1.0), scales):
        notes.append("--units overrides the units in the header")
    return dataclasses.replace(layout, gyro_scale=scales[0], accel_scale=scales[1],
                               notes=tuple(notes))


def _header_scale(p: Any, unit: str | None, table: dict[str, float], sensor: str, kind: str,
                  si: str, notes: list[str]) -> float:
    """The factor to SI of a sensor's unit named in the header (1 when none); a conversion is
    noted, a unit of the wrong kind refused."""
    if unit is None:
        return 1.0
    if unit not in table:
        raise FormatError(p, f"the header's {sensor} unit {unit!r} is not {kind}; "
                          "give --columns and --units")
    if table[unit] != 1.0:
        notes.append(f"{sensor} in {unit} (header), converted to {si}")
    return table[unit]
