r"""Files of a (synthetic) IBISCape sequence besides ground truth and GNSS.

- ``sequence.yaml``: everything a tool may check against (cameras, IMUs, target, GNSS reference,
  weather, seed, generator version, conventions); :func:`write_sequence_yaml` /
  :func:`read_sequence_yaml` (:func:`~ibiscape_eval.io.yaml_file.read_yaml`).
- ``vehicle_gt/<Vehicle>_simulation.txt``: no header, ``t_ns, throttle, steer, brake`` per row
  (comma separated, rows ending in a space like the scripts); :func:`write_controls` /
  :func:`read_controls`.
- ``weather.csv``: ``#timestamp [ns],cloudiness,...`` per camera frame; :func:`write_weather_csv` /
  :func:`read_weather_csv`.
- Streaming writers (bounded memory, atomic): :func:`write_groundtruth_chunks` (``groundtruth_sync.csv`` in CARLA's frame,
  same conversion as :func:`ibiscape_eval.io.write_ibiscape_groundtruth`) and
  :func:`write_gnss_chunks`; the IMU csv's is :func:`ibiscape_eval.io.imu.write_imu_csv_chunks`
  (re-exported here).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError

from ._poses import check_rows
from ._text import decimal_to_ns, parse_table, read_bytes, write_table
from .atomic import atomic_write
from .gnss import GNSS_HEADER, GnssFixes
from .ibiscape import _S, IBISCAPE_HEADER, IbiscapeGroundTruth, _quat_file_from_ours

# The IMU csv writer lives in io.imu (one writer, one header); re-exported for callers of this module.
from .imu import IMU_CSV_HEADER, write_imu_csv_chunks

__all__ = [
    "IMU_CSV_HEADER",
    "Controls",
    "read_controls",
    "read_sequence_yaml",
    "read_weather_csv",
    "write_controls",
    "write_controls_chunks",
    "write_gnss_chunks",
    "write_groundtruth_chunks",
    "write_imu_csv_chunks",
    "write_sequence_yaml",
    "write_weather_csv",
]

SEQUENCE_KEYS = ("cameras", "imus", "gnss", "conventions", "generator")


@dataclass(frozen=True, eq=False)
class Controls:
    """Vehicle controls: ``throttle``, ``brake`` in [0, 1], ``steer`` in [-1, 1], per stamp."""

    stamps_ns: npt.NDArray[np.int64]
    throttle: npt.NDArray[np.float64]
    steer: npt.NDArray[np.float64]
    brake: npt.NDArray[np.float64]


def write_controls(path: str | os.PathLike[str], stamps_ns: npt.ArrayLike, throttle: npt.ArrayLike,
                   steer: npt.ArrayLike, brake: npt.ArrayLike) -> None:
    """Write ``<Vehicle>_simulation.txt``: no header, ``t_ns,throttle,steer,brake `` rows. Atomic."""
    st = np.asarray(stamps_ns, dtype=np.int64)
    vals = np.stack([np.asarray(v, dtype=np.float64) for v in (throttle, steer, brake)], axis=1)
    if vals.shape != (st.size, 3):
        raise IbiscapeError(f"controls: expected (N,) arrays, got {vals.shape} for {st.size} stamps")
    with atomic_write(path, "wb") as f:
        write_table(f, st, vals, stamp="ns", sep=",", row_end=" \n")


def write_controls_chunks(path: str | os.PathLike[str],
                          chunks: Iterable[tuple[npt.ArrayLike, ...]]) -> int:
    """Stream ``(stamps_ns, throttle, steer, brake)`` chunks into one controls file. Atomic."""
    rows = 0
    with atomic_write(path, "wb") as f:
        for st, *v in chunks:
            vals = np.stack([np.asarray(x, dtype=np.float64) for x in v], axis=1)
            write_table(f, np.asarray(st, dtype=np.int64), vals, stamp="ns", sep=",", row_end=" \n")
            rows += vals.shape[0]
    return rows


def read_controls(path: str | os.PathLike[str]) -> Controls:
    """Read ``<Vehicle>_simulation.txt`` (4 columns, stamps in ns).

    Raises
    ------
    FormatError
        Wrong column count, non-numeric field, decreasing stamps, values out of range (naming the
        file and line).
    """
    data = read_bytes(path)
    tb = parse_table(path, data, nkeep=4, ncols_min=4, ncols_max=4,
                     expected="4 columns (t [ns], throttle, steer, brake)")
    stamps = decimal_to_ns(path, tb, unit_exp=0)
    keep = check_rows(path, stamps, tb.finite, tb.lines, stacklevel=3)
    v = tb.values[keep]
    lo = np.array([0.0, -1.0, 0.0])
    bad = np.flatnonzero(((v[:, 1:] < lo) | (v[:, 1:] > 1.0)).any(axis=1))
    if bad.size:
        raise FormatError(path, "throttle and brake must be in [0, 1] and steer in [-1, 1]",
                          line=int(tb.lines[keep][bad[0]]))
    return Controls(stamps[keep], v[:, 1].copy(), v[:, 2].copy(), v[:, 3].copy())


def write_weather_csv(path: str | os.PathLike[str], stamps_ns: npt.ArrayLike,
                      values: npt.ArrayLike, columns: Sequence[str]) -> None:
    """Write ``#timestamp [ns],<columns...>`` rows (comma separated, trailing space). Atomic."""
    st = np.asarray(stamps_ns, dtype=np.int64)
    v = np.asarray(values, dtype=np.float64)
    if v.shape != (st.size, len(columns)):
        raise IbiscapeError(f"weather: expected values of shape ({st.size}, {len(columns)}), got {v.shape}")
    with atomic_write(path, "wb") as f:
        f.write(("#timestamp [ns]," + ",".join(columns) + "\n").encode())
        write_table(f, st, v, stamp="ns", sep=",", row_end=" \n")


def read_weather_csv(path: str | os.PathLike[str]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64], list[str]]:
    """Read a ``weather.csv``: ``(stamps_ns, values (N, k), column names)``."""
    from .paths import read_text

    header = read_text(path, what="weather.csv").split("\n", 1)[0].strip()
    if not header.startswith("#timestamp"):
        raise FormatError(path, "expected a '#timestamp [ns],...' header", line=1)
    names = [h.strip() for h in header.split(",")[1:]]
    k = len(names) + 1
    tb = parse_table(path, read_bytes(path), nkeep=k, ncols_min=k, ncols_max=k,
                     expected=f"{k} columns ({header})")
    stamps = decimal_to_ns(path, tb, unit_exp=0)
    keep = check_rows(path, stamps, tb.finite, tb.lines, stacklevel=3)
    return stamps[keep], tb.values[keep][:, 1:].copy(), names


def write_groundtruth_chunks(path: str | os.PathLike[str], chunks: Iterable[IbiscapeGroundTruth]) -> int:
    """Stream ground-truth chunks (OUR frame) into one ``groundtruth_sync.csv`` (CARLA's frame),
    byte-identical to :func:`ibiscape_eval.io.write_ibiscape_groundtruth` of the concatenation."""
    rows = 0
    with atomic_write(path, "wb") as f:
        f.write((IBISCAPE_HEADER + "\r\n").encode())
        for gt in chunks:
            tr = gt.trajectory
            values = np.concatenate(
                (tr.pos_m * _S, gt.vel_m_s * _S, gt.acc_m_s2 * _S, _quat_file_from_ours(tr.quat_xyzw),
                 -_S * gt.angvel_rad_s), axis=1)
            write_table(f, tr.stamps_ns, values, stamp="ns_f", sep=",", row_end=" \n")
            rows += len(tr)
    return rows


def write_gnss_chunks(path: str | os.PathLike[str], chunks: Iterable[GnssFixes]) -> int:
    """Stream GNSS chunks into one ``gnss.csv`` (same bytes as :func:`ibiscape_eval.io.write_gnss`)."""
    rows = 0
    with atomic_write(path, "wb") as f:
        f.write((GNSS_HEADER + "\r\n").encode())
        for fx in chunks:
            values = np.stack((fx.lat_deg, fx.lon_deg, fx.alt_m), axis=1)
            write_table(f, fx.stamps_ns, values, stamp="ns_f", sep=",", row_end=" \n")
            rows += len(fx)
    return rows


def _plain(o: Any) -> Any:
    if isinstance(o, dict):
        return {str(k): _plain(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [_plain(v) for v in o]
    if isinstance(o, np.ndarray):
        return _plain(o.tolist())
    if isinstance(o, np.generic):
        return o.item()
    return o


def write_sequence_yaml(path: str | os.PathLike[str], doc: dict[str, Any],
                        comments: Sequence[str] = ()) -> None:
    """Write ``sequence.yaml`` (numpy values converted, 4x4 matrices as lists of rows). Atomic."""
    import yaml

    text = yaml.safe_dump(_plain(doc), sort_keys=False, default_flow_style=None, width=120)
    with atomic_write(path) as fh:
        for c in comments:
            fh.write(f"# {c}\n")
        fh.write(text)


def read_sequence_yaml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read ``sequence.yaml`` (:func:`~ibiscape_eval.io.yaml_file.read_yaml`) and check the
    top-level keys and the 4x4 ``T_body_cam`` / ``T_body_imu`` matrices.

    Raises
    ------
    FormatError
        Not YAML, missing keys (naming them), malformed transforms.
    """
    from .yaml_file import read_yaml

    doc = read_yaml(path, what="sequence.yaml")
    if not isinstance(doc, dict):
        raise FormatError(path, "expected a mapping at the top level")
    missing = [k for k in SEQUENCE_KEYS if k not in doc]
    if missing:
        raise FormatError(path, f"missing keys: {', '.join(missing)}")
    for group, key in (("cameras", "T_body_cam"), ("imus", "T_body_imu")):
        for name, entry in (doc.get(group) or {}).items():
            T = np.asarray(entry.get(key) if isinstance(entry, dict) else None, dtype=object)
            if T.shape != (4, 4):
                raise FormatError(path, f"{group}.{name}.{key} must be a 4x4 matrix")
    return doc
