""".npy and .npz IMU files: bounded-memory reading and streaming writing.

A large ``.npy`` is never loaded whole: :class:`NpyRows` reads it block by block with
``readinto`` into one reused buffer.  Memory-mapping it instead (``np.load(mmap_mode="r")``) makes
every page read count toward the process' resident memory until the kernel reclaims it, so the
peak RSS grows with the file: ``benchmarks/bench_imu_npy_memory.py`` measured 170 MB with
``readinto`` against 1065 MB with a memory map on a 1.06 GB file (the 168-hour, 200 Hz record of
``bench_allan.py`` is ~5.8 GB).  Headers are read and written with numpy's own
``np.lib.format`` functions (which leave room for the row count to grow in place).
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import weakref
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.imu import CHUNK_ROWS, ImuRecord

from ..atomic import atomic_output_path
from .columns import STAMP_UNITS, stamp_unit, with_layout
from .timing import (
    TimingAccumulator,
    check_samples,
    check_stamp_dtype,
    finish_record,
    no_stamp_timing,
    record_from_array,
    record_from_parts,
)

__all__ = [
    "NpyRows",
    "NpyStreamWriter",
    "iter_npy_blocks",
    "read_imu_npy",
    "read_imu_npz",
    "read_npy_header",
    "write_imu_npy",
]


def read_npy_header(path: str | os.PathLike[str]) -> tuple[int, np.dtype[Any], tuple[int, ...], bool]:
    """``(data offset, dtype, shape, fortran_order)`` of a ``.npy`` file (no pickles)."""
    from ..npfiles import DAMAGE_ERRORS, check_magic

    check_magic(path, ".npy")
    with open(path, "rb") as fh:
        try:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
            else:
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        except DAMAGE_ERRORS as e:
            msg = " ".join(str(e).split())[:120] or type(e).__name__
            raise FormatError(path, f"damaged .npy header ({msg}); export the file again") from None
        if (not isinstance(shape, tuple) or any(not isinstance(d, int) or d < 0 for d in shape)
                or not isinstance(dtype, np.dtype)):
            raise FormatError(path, "damaged .npy header (bad shape); export the file again")
        return fh.tell(), dtype, shape, fortran


def iter_npy_blocks(fname: str, offset: int, dtype: np.dtype[Any], width: int, n_rows: int,
                    chunk_rows: int) -> Iterator[np.ndarray]:
    """Blocks of a C-order (n_rows, width) array stored at ``offset``, in one reused buffer."""
    with open(fname, "rb") as fh:
        fh.seek(offset)
        buf = np.empty((min(chunk_rows, max(n_rows, 1)), width), dtype=dtype)
        done = 0
        while done < n_rows:
            rows = min(chunk_rows, n_rows - done)
            view = buf[:rows]
            got = fh.readinto(view.data.cast("B"))
            if got != view.nbytes:
                raise FormatError(fname, f"file ends after {done + (got or 0) // (width * dtype.itemsize)} "
                                  f"of {n_rows} rows; it is truncated")
            yield view
            done += rows


class NpyRows:
    """A :class:`ibiscape_eval.core.imu.RowSource` over columns ``first .. first + 5`` of a
    ``.npy`` file; ``keep`` (a temporary folder holding the file) is removed with this object."""

    def __init__(self, path: str, *, first: int = 0,
                 keep: tempfile.TemporaryDirectory[str] | None = None):
        self.path = path
        self.offset, self.dtype, shape, _ = read_npy_header(path)
        self.n_rows, self.width = int(shape[0]), int(shape[1])
        self.first = first
        self._keep = keep
        if keep is not None:
            weakref.finalize(self, keep.cleanup)

    def iter_rows(self, chunk_rows: int) -> Iterator[np.ndarray]:
        for block in iter_npy_blocks(self.path, self.offset, self.dtype, self.width, self.n_rows,
                                     chunk_rows):
            yield block[:, self.first : self.first + 6]


class NpyStreamWriter:
    """Write an (N, width) float64 .npy row block by row block; the header (numpy's own, which
    reserves room for the row count to grow) is rewritten in place at close."""

    def __init__(self, path: str, width: int):
        self.path = path
        self.width = width
        self.rows = 0
        self.fh = open(path, "wb")  # noqa: SIM115 - closed in close()
        self._header()
        self.data_offset = self.fh.tell()

    def _header(self) -> None:
        self.fh.seek(0)
        np.lib.format.write_array_header_1_0(
            self.fh, {"descr": "<f8", "fortran_order": False, "shape": (self.rows, self.width)})

    def write(self, block: np.ndarray) -> None:
        b = np.ascontiguousarray(block, dtype="<f8")
        if b.ndim != 2 or b.shape[1] != self.width:
            raise ValueError(f"expected blocks of width {self.width}, got {b.shape}")
        self.fh.write(b.data.cast("B"))
        self.rows += b.shape[0]

    def close(self) -> None:
        if self.fh.closed:
            return
        end = self.fh.tell()
        self._header()
        if self.fh.tell() != self.data_offset:  # cannot happen with numpy's padded header
            raise RuntimeError(f"{self.path}: .npy header grew while writing")
        self.fh.seek(end)
        self.fh.close()


def write_imu_npy(path: str | os.PathLike[str], blocks: Iterable[np.ndarray], *, width: int = 7) -> int:
    """Write row blocks (each (rows, width), e.g. ``[t_ns, w_xyz, a_xyz]``) to one float64 ``.npy``,
    atomically and in bounded memory.  Returns the number of rows written."""
    with contextlib.ExitStack() as stack:
        tmp = stack.enter_context(atomic_output_path(path))
        w = NpyStreamWriter(str(tmp), width)
        try:
            for b in blocks:
                w.write(b)
        finally:
            w.close()
        return w.rows


def read_imu_npy(p: Path, rate_hz: float | None) -> ImuRecord:
    offset, dtype, shape, fortran = read_npy_header(p)
    if dtype.hasobject or dtype.kind not in "fiu":
        raise FormatError(p, f"expected a numeric array, got dtype {dtype}")
    if len(shape) != 2 or shape[1] not in (6, 7):
        raise FormatError(p, f"expected shape (N, 7) [t_ns, w_xyz, a_xyz] or (N, 6), got {shape}")
    n, width = int(shape[0]), int(shape[1])
    if fortran:
        arr = np.load(p, allow_pickle=False)
        arr = np.ascontiguousarray(arr)
        return record_from_array(p, arr, rate_hz)
    first = width - 6
    unit = "ns"
    notes: tuple[str, ...] = ()
    if first:
        acc = TimingAccumulator(str(p), first_line=1)
        factor = 1
        for i, block in enumerate(iter_npy_blocks(str(p), offset, dtype, width, n, CHUNK_ROWS)):
            if i == 0:
                unit, how = stamp_unit(block[:4000, 0])
                factor = STAMP_UNITS[unit]
                if unit != "ns":
                    notes = (f"timestamps read as {unit} ({how})",)
            if i == 0 or (dtype.kind == "f" and not np.isfinite(block[:, 0]).all()):
                check_stamp_dtype(p, block[:, 0])
            t = block[:, 0]
            acc.add(t.astype(np.int64) if factor == 1
                    else np.round(t.astype(np.float64) * factor).astype(np.int64))
        timing = acc.result()
    else:
        timing = no_stamp_timing(str(p), rate_hz, "an (N, 6) .npy")
    for block in iter_npy_blocks(str(p), offset, dtype, width, min(n, CHUNK_ROWS), CHUNK_ROWS):
        check_samples(p, block[:, first:].astype(np.float64))
    rec = finish_record(str(p), None, n, timing, rate_hz, _source=NpyRows(str(p), first=first))
    return with_layout(rec, None, notes) if notes else rec



def read_imu_npz(p: Path, rate_hz: float | None) -> ImuRecord:
    from ..npfiles import load_npz_arrays

    z = load_npz_arrays(p, ("stamps_ns", "gyro_rad_s", "accel_m_s2", "data"))
    keys = set(z)
    if {"gyro_rad_s", "accel_m_s2"} <= keys:
        g, a = z["gyro_rad_s"], z["accel_m_s2"]
        if g.shape != a.shape or g.ndim != 2 or g.shape[1] != 3:
            raise FormatError(p, f"gyro_rad_s {g.shape} and accel_m_s2 {a.shape} must both "
                              "be (N, 3)")
        for k, arr in (("gyro_rad_s", g), ("accel_m_s2", a)):
            if arr.dtype.kind not in "fiu":
                raise FormatError(p, f"{k} must be numeric, got dtype {arr.dtype}")
        stamps = z.get("stamps_ns")
        if stamps is not None and stamps.shape != (g.shape[0],):
            raise FormatError(p, f"stamps_ns has shape {stamps.shape}, expected ({g.shape[0]},)")
        if stamps is not None and stamps.dtype.kind not in "iuf":
            raise FormatError(p, f"stamps_ns must be numeric (int64 ns), got dtype {stamps.dtype}")
        return record_from_parts(p, stamps, np.concatenate([g, a], axis=1).astype(np.float64),
                                 rate_hz)
    if "data" in keys:
        if z["data"].dtype.kind not in "fiu":
            raise FormatError(p, f"data must be numeric, got dtype {z['data'].dtype}")
        return record_from_array(p, z["data"], rate_hz)
    with np.load(p, allow_pickle=False) as f:
        found = sorted(f.files)
    raise FormatError(p, f"expected keys stamps_ns, gyro_rad_s, accel_m_s2 (or data), found "
                      f"{', '.join(found) or 'none'}")
