"""DVS event files: read as one time-ordered stream, in chunks, and write back in the same format.

Formats
-------
``ibiscape``
    A DVS folder of the IBISCape layout: ``timestamps.csv``
    (``#timestamp_start [ns], timestamp_end [ns], filename``) listing ``events/<ns>.npz`` windows
    with keys ``t`` (int64 ns), ``x``, ``y`` (uint16), ``p`` (bool).  Read window by window, so
    folders larger than memory stream in bounded memory.
``npz``
    One ``.npz`` file with the same four keys.
``text``
    rpg / ESIM text (``.txt``): ``t x y p`` per line, ``t`` in decimal seconds (parsed exactly to
    the nanosecond), ``p`` 0/1 (or -1/1); ``#`` comments; an optional first line ``width height``
    (E2VID's convention) gives the sensor size.
``hdf5``
    ``.h5``, ``.hdf5``, read dataset slice by dataset slice (never whole), in one of the layouts:

    - E2CALIB / DSEC: ``events/x``, ``events/y`` (uint16), ``events/t`` (integer microseconds;
      DSEC: uint32 relative to the scalar dataset ``t_offset``, also in microseconds),
      ``events/p`` (0/1); DSEC adds ``ms_to_idx`` (index of the first event at or after each
      millisecond, relative to ``t_offset``), which is recomputed when writing;
    - the same four datasets ``x, y, t, p`` at the file's root (integer microseconds);
    - event_utils (``events/xs, ys, ts, ps``; ``ts`` in float seconds, rounded to the
      microsecond, or integer microseconds);
    - MVSEC (``davis/left/events``, ``davis/right/events``: float64 rows ``x, y, t [s], p``
      with p = -1/1; ``topic`` chooses ``left`` or ``right`` when both are present).

    The sensor size comes from the attributes ``width``/``height``, ``sensor_width``/
    ``sensor_height`` or ``sensor_resolution`` (height, width; event_utils), on the file or
    on the ``events`` group.  Any other layout is refused, naming the datasets the file has.
``aedat4``
    iniVation DV's AEDAT4 (``.aedat4``; :mod:`ibiscape_eval.io.event_aedat4`): the polarity
    event stream, its sensor size from the stream table.
``bag``
    ``dvs_msgs/EventArray`` messages in a ROS 1 ``.bag`` or a ROS 2 bag folder (``.db3`` /
    ``.mcap``; :mod:`ibiscape_eval.io.event_bag`); sensor size from the messages' width/height.

A sequence folder (with ``sequence.yaml``) may be given instead of its DVS camera folder when it
has one DVS camera (``topic`` names the camera otherwise); a camera folder inside a sequence takes
its sensor size from ``sequence.yaml`` (``cameras.<name>.resolution``).

npz files are always opened with ``allow_pickle=False``: object arrays are refused, never unpickled.
Writers go through a temporary file (or folder) renamed on success.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.core.events import EventChunk, Events

from .atomic import atomic_output_path, atomic_write, discard, publish, staging_path

__all__ = [
    "EventSource",
    "detect_event_format",
    "iter_event_chunks",
    "open_events",
    "read_events",
    "read_hot_pixels",
    "write_events",
    "write_filtered_events",
    "write_frames_png",
    "write_hot_pixels",
]

FORMATS = ("ibiscape", "npz", "text", "hdf5", "aedat4", "bag")
NPZ_KEYS = ("t", "x", "y", "p")
DEFAULT_CHUNK_EVENTS = 1 << 20  # fits the caches: 1.8x faster than 1 << 24 (HDF5 read + count)
_TEXT_BLOCK_BYTES = 1 << 25


@dataclass(frozen=True)
class EventSource:
    """An opened (and checked) event recording; iterate it with :func:`iter_event_chunks`.

    Attributes
    ----------
    path : Path
        What the user gave (folder or file).
    fmt : str
        One of :data:`FORMATS`.
    windows : list of (int, int, Path)
        IBISCape: ``(t_start_ns, t_end_ns, npz path)`` per ``timestamps.csv`` row.
    sensor_size : (int, int) or None
        Width, height when the file states it (text header, HDF5 attributes, AEDAT4 stream
        table, EventArray width/height, the sequence's ``sequence.yaml``).
    size_from : str
        Where ``sensor_size`` was read (``""`` when it was not).
    n_events : int or None
        Number of events when known without reading them (HDF5).
    meta : dict
        Format details needed to write the same layout back (HDF5 dtypes, ``t_offset``...).
    """

    path: Path
    fmt: str
    windows: list[tuple[int, int, Path]] = field(default_factory=list)
    sensor_size: tuple[int, int] | None = None
    n_events: int | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    size_from: str = ""


# ------------------------------------------------------------------------------------------
# format detection and opening
# ------------------------------------------------------------------------------------------


def detect_event_format(path: str | os.PathLike[str]) -> str:
    """The format of an event recording from its path (see the module docstring)."""
    p = Path(path)
    if p.is_dir():
        return "bag" if (p / "metadata.yaml").is_file() else "ibiscape"
    suffix = p.suffix.lower()
    if suffix == ".npz":
        return "npz"
    if suffix in (".h5", ".hdf5"):
        return "hdf5"
    if suffix == ".aedat4":
        return "aedat4"
    if suffix in (".bag", ".db3", ".mcap"):
        return "bag"
    if suffix in (".txt", ".dat", ".csv", ""):
        return "text"
    raise FormatError(
        p, f"unknown event file type {suffix!r}; expected a DVS folder with timestamps.csv, "
        ".npz, .txt (t x y p), .h5 (DSEC/E2CALIB/event_utils), .aedat4 (DV) or a ROS bag "
        "(.bag, .db3, .mcap) with dvs_msgs/EventArray"
    )


def _ibiscape_root(p: Path) -> Path:
    if (p / "timestamps.csv").is_file():
        return p
    if p.name == "events" and (p.parent / "timestamps.csv").is_file():
        return p.parent
    raise FormatError(
        p, "not an IBISCape DVS folder: timestamps.csv is missing; give the davisL/davisR folder "
        "that holds timestamps.csv and events/"
    )


def _read_windows(root: Path) -> list[tuple[int, int, Path]]:
    csv = root / "timestamps.csv"
    rows: list[tuple[int, int, Path]] = []
    with open(csv, encoding="utf-8") as f:
        for n, raw in enumerate(f, start=1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            cols = [c.strip() for c in line.split(",")]
            if len(cols) != 3:
                raise FormatError(
                    csv, f"expected 3 columns (timestamp_start [ns], timestamp_end [ns], filename), "
                    f"got {len(cols)}", line=n,
                )
            try:
                a, b = (int(float(c)) if "." in c or "e" in c.lower() else int(c) for c in cols[:2])
            except ValueError:
                raise FormatError(csv, f"timestamps must be integers in ns, got {cols[:2]}", line=n) from None
            name = cols[2]
            cand = [root / "events" / name, root / name]
            hit = next((c for c in cand if c.is_file()), None)
            if hit is None:
                raise FormatError(
                    csv, f"lists {name} but {cand[0]} does not exist; restore the file or remove "
                    "its row from timestamps.csv", line=n,
                )
            rows.append((a, b, hit))
    if not rows:
        raise FormatError(csv, "lists no event windows: the recording is empty")
    return rows


def _text_header(path: Path) -> tuple[tuple[int, int] | None, bytes]:
    """An E2VID-style ``width height`` first line, if present."""
    with open(path, "rb") as f:
        first = f.readline(4096)
    if first.startswith(_BOM):
        first = first[len(_BOM):]
    cols = first.replace(b",", b" ").split()
    if len(cols) == 2 and all(c.isdigit() for c in cols):
        w, h = int(cols[0]), int(cols[1])
        if not (0 < w <= 65536 and 0 < h <= 65536):
            raise FormatError(path, f"header gives a {w}x{h} sensor; width and height must be "
                              "in 1..65536 (or remove the header line)", line=1)
        return (w, h), first
    return None, b""


_BOM = b"\xef\xbb\xbf"  # UTF-8 byte-order mark (Notepad, Excel): skipped


def _h5py() -> Any:
    import h5py

    with contextlib.suppress(ImportError):  # registers the Blosc filter DSEC files need
        import hdf5plugin  # noqa: F401
    return h5py


# HDF5 layouts: name -> dataset paths of t, x, y, p and the unit of t
H5_LAYOUTS: dict[str, tuple[tuple[str, str, str, str], str]] = {
    "dsec": (("events/t", "events/x", "events/y", "events/p"), "us"),
    "flat": (("t", "x", "y", "p"), "us"),
    "event_utils": (("events/ts", "events/xs", "events/ys", "events/ps"), "s"),
}


def _h5_datasets(f: Any, limit: int = 12) -> str:
    """``name shape dtype`` of the first datasets of an open HDF5 file, for error messages."""
    h5py = _h5py()
    found: list[str] = []

    def visit(name: str, obj: Any) -> Any:
        if isinstance(obj, h5py.Dataset):
            found.append(f"{name} {tuple(obj.shape)} {obj.dtype}")
        return True if len(found) > limit else None

    f.visititems(visit)
    if not found:
        return "no datasets"
    more = ", ..." if len(found) > limit else ""
    return ", ".join(found[:limit]) + more


def _h5_size(f: Any) -> tuple[int, int] | None:
    for node in (f, f["events"] if "events" in f and hasattr(f["events"], "attrs") else None):
        if node is None:
            continue
        at = node.attrs
        for wk, hk in (("width", "height"), ("sensor_width", "sensor_height")):
            if wk in at and hk in at:
                return int(at[wk]), int(at[hk])
        if "sensor_resolution" in at:  # event_utils: (height, width)
            r = np.asarray(at["sensor_resolution"]).reshape(-1)
            if r.size == 2 and r.min() > 0:
                return int(r[1]), int(r[0])
    return None


def _open_mvsec(p: Path, f: Any, topic: str | None) -> EventSource:
    sides = [s for s in ("left", "right") if f"davis/{s}/events" in f]
    if topic is not None and topic not in sides:
        raise FormatError(p, f"no davis/{topic}/events; the file has "
                          + ", ".join(f"davis/{s}/events" for s in sides))
    if topic is None and len(sides) > 1:
        raise FormatError(p, "two event cameras (davis/left, davis/right); choose one with "
                          "--topic left|right")
    key = f"davis/{topic or sides[0]}/events"
    d = f[key]
    if d.ndim != 2 or d.shape[1] != 4 or d.dtype.kind != "f":
        raise FormatError(p, f"{key} must be float rows x, y, t [s], p; got {d.shape} {d.dtype}")
    meta = {"layout": "mvsec", "keys": (key,), "t_unit": "s", "t_offset_us": 0,
            "attrs": {k: f.attrs[k] for k in f.attrs}}
    return EventSource(p, "hdf5", n_events=int(d.shape[0]), meta=meta)


def _open_hdf5(p: Path, topic: str | None = None) -> EventSource:
    h5py = _h5py()
    try:
        with h5py.File(p, "r") as f:
            layout = next((name for name, (keys, _) in H5_LAYOUTS.items()
                           if all(k in f for k in keys)), None)
            if layout is None and ("davis/left/events" in f or "davis/right/events" in f):
                return _open_mvsec(p, f, topic)
            if layout is None:
                part = next(([k for k in keys if k not in f] for keys, _ in H5_LAYOUTS.values()
                             if any(k in f for k in keys)), None)
                if part:
                    raise FormatError(p, f"missing datasets {', '.join(part)}; found "
                                      f"{_h5_datasets(f)}")
                raise FormatError(
                    p, f"unknown HDF5 event layout; found {_h5_datasets(f)}; expected events/x, "
                    "events/y, events/t, events/p (DSEC/E2CALIB), x, y, t, p, events/xs, ys, "
                    "ts, ps (event_utils) or davis/left/events (MVSEC)"
                )
            keys, unit = H5_LAYOUTS[layout]
            if layout == "event_utils" and f[keys[0]].dtype.kind in "iu":
                unit = "us"  # some writers store integer microseconds under events/ts
            ds = {k: f[path] for k, path in zip(NPZ_KEYS, keys, strict=True)}
            lens = {k: d.shape[0] if d.ndim == 1 else -1 for k, d in ds.items()}
            if len(set(lens.values())) != 1 or -1 in lens.values():
                raise FormatError(
                    p, f"{', '.join(keys)} must be 1-D and of one length, got "
                    + ", ".join(f"{path}={ds[k].shape}" for k, path in zip(NPZ_KEYS, keys, strict=True))
                )
            if ds["x"].dtype.kind not in "iu" or ds["y"].dtype.kind not in "iu":
                raise FormatError(p, f"{keys[1]}, {keys[2]} must be integer datasets")
            tkind = ds["t"].dtype.kind
            if (unit == "us" and tkind not in "iu") or (unit == "s" and tkind != "f"):
                raise FormatError(p, f"{keys[0]} must be integer microseconds, got {ds['t'].dtype}"
                                  if unit == "us" else f"{keys[0]} must be float seconds")
            t_offset = 0
            if "t_offset" in f:
                t_offset = int(np.asarray(f["t_offset"][()]).reshape(-1)[0])
            size = _h5_size(f)
            meta = {
                "layout": layout,
                "keys": keys,
                "t_unit": unit,
                "dtypes": {k: ds[k].dtype.str for k in NPZ_KEYS},
                "t_offset_us": t_offset,
                "has_t_offset": "t_offset" in f,
                "has_ms_to_idx": "ms_to_idx" in f,
                "attrs": {k: f.attrs[k] for k in f.attrs},
            }
            return EventSource(p, "hdf5", sensor_size=size, n_events=lens["t"], meta=meta,
                               size_from="HDF5 attributes" if size else "")
    except OSError as e:
        raise FormatError(p, f"cannot read as HDF5 ({e}); is it an .h5 file?") from None
    except (RuntimeError, KeyError, ValueError, TypeError) as e:  # h5py on damaged metadata
        raise FormatError(p, f"damaged HDF5 file ({' '.join(str(e).split())[:120]})") from None


def _sequence_size(root: Path) -> tuple[int, int] | None:
    """``cameras.<root name>.resolution`` of the ``sequence.yaml`` next to a camera folder."""
    yml = root.parent / "sequence.yaml"
    if not yml.is_file():
        return None
    from .sequence import read_sequence_yaml

    entry = (read_sequence_yaml(yml).get("cameras") or {}).get(root.name)
    res = entry.get("resolution") if isinstance(entry, dict) else None
    if not (isinstance(res, list | tuple) and len(res) == 2):
        return None
    try:
        w, h = int(res[0]), int(res[1])
    except (TypeError, ValueError):
        raise FormatError(yml, f"cameras.{root.name}.resolution must be [width, height], got "
                          f"{res!r}") from None
    if not (0 < w <= 65536 and 0 < h <= 65536):
        raise FormatError(yml, f"cameras.{root.name}.resolution {w}x{h} is not a sensor size")
    return w, h


def _sequence_camera(p: Path, camera: str | None) -> Path:
    """The DVS camera folder of a sequence folder (``sequence.yaml``, no ``timestamps.csv``)."""
    from .sequence import read_sequence_yaml

    cams = read_sequence_yaml(p / "sequence.yaml").get("cameras") or {}
    dvs = [str(n) for n, c in cams.items()
           if isinstance(c, dict) and c.get("kind") == "dvs" and (p / str(n) / "timestamps.csv").is_file()]
    if camera is not None:
        if camera not in dvs:
            raise FormatError(p / "sequence.yaml", f"no DVS camera {camera!r} with events; DVS "
                              f"cameras with events: {', '.join(dvs) or 'none'}")
        return p / camera
    if len(dvs) != 1:
        raise FormatError(p / "sequence.yaml", "the sequence has "
                          + (f"several DVS cameras ({', '.join(dvs)}); give one, e.g. "
                             f"{p / dvs[0]}" if dvs else "no DVS camera with events"))
    return p / dvs[0]


def open_events(path: str | os.PathLike[str], *, fmt: str | None = None,
                topic: str | None = None) -> EventSource:
    """Open and check an event recording without reading its events.

    Checks the folder listing (every file in ``timestamps.csv`` exists), the HDF5 layout and
    dataset lengths, the AEDAT4 stream table, the bag's topics.  Raises :class:`FormatError`
    naming the file (and line) otherwise.

    Parameters
    ----------
    path
        Event file, DVS camera folder, sequence folder or ROS bag (file or ROS 2 folder).
    fmt
        One of :data:`FORMATS`; by default from the path.
    topic
        Bag: the ``dvs_msgs/EventArray`` topic (required when the bag has several); AEDAT4: the
        event stream id; sequence folder: the DVS camera name.
    """
    from .paths import check_input

    p = check_input(path, "any")
    if (fmt in (None, "ibiscape") and p.is_dir() and (p / "sequence.yaml").is_file()
            and not (p / "timestamps.csv").is_file()):
        p = _sequence_camera(p, topic)
    fmt = fmt or detect_event_format(p)
    if fmt not in FORMATS:
        raise IbiscapeError(f"unknown event format {fmt!r}; choose one of {', '.join(FORMATS)}")
    if fmt not in ("ibiscape", "bag"):
        check_input(p, "file")
    if fmt == "ibiscape":
        root = _ibiscape_root(p)
        size = _sequence_size(root)
        return EventSource(root, fmt, windows=_read_windows(root), sensor_size=size,
                           size_from="sequence.yaml" if size else "")
    if fmt == "text":
        size, header = _text_header(p)
        return EventSource(p, fmt, sensor_size=size, meta={"header": header},
                           size_from="the header line" if size else "")
    if fmt == "hdf5":
        return _open_hdf5(p, topic)
    if fmt == "aedat4":
        from .event_aedat4 import open_aedat4

        got = open_aedat4(p, topic)
        return EventSource(p, fmt, sensor_size=got["sensor_size"], meta=got["meta"],
                           size_from="the AEDAT4 stream table" if got["sensor_size"] else "")
    if fmt == "bag":
        from .bag import _bag_path
        from .event_bag import open_bag_events

        bp = _bag_path(p)
        got = open_bag_events(bp, topic)
        return EventSource(bp, fmt, sensor_size=got["sensor_size"], meta=got["meta"],
                           size_from="EventArray width/height" if got["sensor_size"] else "")
    return EventSource(p, fmt)


# ------------------------------------------------------------------------------------------
# reading
# ------------------------------------------------------------------------------------------


def _load_npz(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    from .npfiles import load_npz_arrays

    got = load_npz_arrays(path, NPZ_KEYS)
    missing = [k for k in NPZ_KEYS if k not in got]
    if missing:
        with np.load(path, allow_pickle=False) as npz:
            found = list(npz.files)
        raise FormatError(
            path, f"missing key(s) {', '.join(missing)}; found {', '.join(found) or 'none'}; "
            "expected t (int64 ns), x, y (uint16), p (bool)"
        )
    arrays = [got[k] for k in NPZ_KEYS]
    t, x, y, p = arrays
    if any(a.ndim != 1 for a in arrays) or len({a.shape[0] for a in arrays}) != 1:
        raise FormatError(
            path, "arrays t, x, y, p must be 1-D and of one length, got "
            + ", ".join(f"{k}={a.shape}" for k, a in zip(NPZ_KEYS, arrays, strict=True))
        )
    if t.dtype.kind not in "iu":
        raise FormatError(path, f"t must be integer nanoseconds, got dtype {t.dtype}")
    t = _stamps_int64(path, t)
    for k, a in (("x", x), ("y", y)):
        if a.dtype.kind not in "iu":
            raise FormatError(path, f"{k} must be integer pixel coordinates, got dtype {a.dtype}")
        if a.dtype != np.uint16 and a.size and (int(a.min()) < 0 or int(a.max()) > 65535):
            raise FormatError(path, f"{k} must lie in 0..65535, found {int(a.min())}..{int(a.max())}")
    if p.dtype != np.bool_:
        if p.dtype.kind not in "iub" or (p.size and not np.isin(p, (-1, 0, 1)).all()):
            raise FormatError(path, f"p must be bool (or 0/1), got dtype {p.dtype}")
        p = p > 0
    return t, x, y, p


def _stamps_int64(path: Path, t: np.ndarray) -> np.ndarray:
    """Integer stamps as int64 ns; unsigned stamps beyond int64 are refused, never wrapped."""
    if t.dtype.kind == "u" and t.dtype.itemsize >= 8 and t.size and int(t.max()) > np.iinfo(np.int64).max:
        raise FormatError(path, f"t holds {int(t.max())} ns, beyond int64 nanoseconds (year 2262); "
                          "store t as int64 ns")
    return t.astype(np.int64, copy=False)


def _chunks_npz_files(files: list[Path]) -> Iterator[EventChunk]:
    for f in files:
        t, x, y, p = _load_npz(f)
        yield EventChunk(Events(t, x, y, p), str(f), 0)


def _chunks_text(src: EventSource, chunk_events: int) -> Iterator[EventChunk]:
    from . import _event_text_kernels as _kernels

    path = src.path
    line = 1
    offset = 0
    header = src.meta.get("header", b"")
    size = src.sensor_size
    with open(path, "rb") as f:
        if f.read(len(_BOM)) != _BOM:
            f.seek(0)
        if header:
            f.readline()
            line = 2
        rest = b""
        while True:
            block = f.read(_TEXT_BLOCK_BYTES)
            data = rest + block
            if not block:
                cut = len(data)
            else:
                cut = data.rfind(b"\n") + 1
                if cut == 0:
                    rest = data
                    continue
            buf = np.frombuffer(data[:cut], np.uint8)
            rest = data[cut:]
            nmax = int(np.count_nonzero(buf == 10)) + 1
            t = np.empty(nmax, np.int64)
            x = np.empty(nmax, np.uint16)
            y = np.empty(nmax, np.uint16)
            p = np.empty(nmax, np.bool_)
            ln = np.empty(nmax, np.int64)
            n, nlines, err, err_line = _kernels.parse_text(buf, line, t, x, y, p, ln)
            if err:
                raise FormatError(path, _kernels.TEXT_ERRORS[int(err)], line=int(err_line))
            if size is not None and n:
                out = (x[:n] >= size[0]) | (y[:n] >= size[1])
                if out.any():
                    i = int(np.flatnonzero(out)[0])
                    raise FormatError(path, f"event at pixel ({int(x[i])}, {int(y[i])}) lies "
                                      f"outside the {size[0]}x{size[1]} sensor of the header "
                                      "(line 1); fix the header or the event", line=int(ln[i]))
            line += int(nlines)
            for s in range(0, int(n), chunk_events):
                e = min(int(n), s + chunk_events)
                yield EventChunk(Events(t[s:e], x[s:e], y[s:e], p[s:e]), str(path), offset + s, ln[s:e])
            offset += int(n)
            if not block:
                break


def _chunks_hdf5(src: EventSource, chunk_events: int,
                 reuse: bool = False) -> Iterator[EventChunk | tuple[EventChunk, bool]]:
    """HDF5 slices of ``chunk_events``; integer-microsecond layouts go through one numba pass
    (stamps to ns with the range check); with ``reuse`` the arrays of one chunk are overwritten
    by the next (no allocation, no page faults: for consumers that keep nothing)."""
    h5py = _h5py()
    off_ns = int(src.meta["t_offset_us"]) * 1000
    keys = src.meta.get("keys", H5_LAYOUTS["dsec"][0])
    seconds = src.meta.get("t_unit") == "s"
    lim_us = (np.iinfo(np.int64).max - abs(off_ns)) // 1000
    try:
        with h5py.File(src.path, "r") as f:
            ds = [f[k] for k in keys]
            n = ds[0].shape[0]
            fast = len(ds) == 4 and not seconds and all(
                d.dtype.kind in "iu" and d.dtype.itemsize <= 8 for d in ds) and \
                ds[0].dtype != np.uint64 and ds[1].dtype == ds[2].dtype == np.uint16
            if fast:
                yield from _chunks_hdf5_fast(src, ds, n, chunk_events, off_ns, lim_us, reuse)
                return
            for s in range(0, n, chunk_events):
                e = min(n, s + chunk_events)
                if len(ds) == 1:  # MVSEC rows x, y, t, p
                    rows = ds[0][s:e]
                    x, y, t, p = (rows[:, k] for k in range(4))
                    if x.size and (not np.isfinite(rows).all() or min(x.min(), y.min()) < 0
                                   or max(x.max(), y.max()) > 65535
                                   or (x != np.floor(x)).any() or (y != np.floor(y)).any()):
                        raise FormatError(src.path, f"{keys[0]} rows {s}..{e}: x, y must be "
                                          "integers in 0..65535 and every value finite")
                    x, y = x.astype(np.int64), y.astype(np.int64)
                else:
                    t, x, y, p = (d[s:e] for d in ds)
                    for k, a in ((keys[1], x), (keys[2], y)):
                        if a.dtype != np.uint16 and a.size and (int(a.min()) < 0 or int(a.max()) > 65535):
                            raise FormatError(src.path, f"{k} holds {int(a.min())}..{int(a.max())}; "
                                              "pixel coordinates must lie in 0..65535")
                if seconds:
                    t = np.rint(np.asarray(t, np.float64) * 1e6)
                    if t.size and not np.isfinite(t).all():
                        raise FormatError(src.path, f"{keys[0]} holds NaN or infinite stamps")
                if t.size and (int(t.max()) > lim_us or int(t.min()) < -lim_us):
                    raise FormatError(src.path, f"{keys[0]} holds {int(t.max())} us, beyond int64 "
                                      "nanoseconds (year 2262); the file is damaged")
                t_ns = t.astype(np.int64)
                t_ns *= 1000
                if off_ns:
                    t_ns += off_ns
                yield EventChunk(Events(t_ns, x, y, p > 0), str(src.path), s)
    except OSError as e:
        raise FormatError(
            src.path, f"cannot read the event datasets ({e}); DSEC files are Blosc-compressed: "
            "install hdf5plugin and retry"
        ) from None
    except (RuntimeError, KeyError, ValueError, TypeError) as e:  # h5py on damaged data
        raise FormatError(src.path, f"damaged HDF5 file ({' '.join(str(e).split())[:120]})") from None


def _chunks_hdf5_fast(src: EventSource, ds: list[Any], n: int, chunk_events: int, off_ns: int,
                      lim_us: int, reuse: bool) -> Iterator[tuple[EventChunk, bool]]:
    from . import _event_text_kernels as _kernels

    size = min(chunk_events, max(n, 1))
    bufs: list[np.ndarray] = []
    prev = np.iinfo(np.int64).min
    for s in range(0, n, chunk_events):
        e = min(n, s + chunk_events)
        k = e - s
        if not bufs or not reuse:
            bufs = [np.empty(size if reuse else k, d.dtype) for d in ds]
            bufs += [np.empty(size if reuse else k, np.int64), np.empty(size if reuse else k, np.bool_)]
        raw = [b[:k] for b in bufs[:4]]
        for d, b in zip(ds, raw, strict=True):
            d.read_direct(b, np.s_[s:e], np.s_[0:k])
        t_ns, p = bufs[4][:k], bufs[5][:k]
        code, bad = (int(v) for v in _kernels.us_to_ns(raw[0], off_ns, lim_us, prev, t_ns))
        if code == 1:
            raise FormatError(src.path, f"{src.meta.get('keys', ('t',))[0]}[{s + bad}] = {int(raw[0][bad])} us lies "
                              "beyond int64 nanoseconds (year 2262); the file is damaged")
        np.greater(raw[3], 0, out=p)
        if k:
            prev = int(t_ns[-1])
        # (chunk, in order): the order was checked here, iter_event_chunks need not repeat it
        yield EventChunk(Events(t_ns, raw[1], raw[2], p), str(src.path), s), code == 0


def _chunks_stream(src: EventSource, it: Iterator[tuple[Events, int, bool]]
                   ) -> Iterator[tuple[EventChunk, bool]]:
    for ev, offset, in_order in it:
        yield EventChunk(ev, str(src.path), offset), in_order


def iter_event_chunks(
    source: EventSource | str | os.PathLike[str],
    *,
    chunk_events: int = DEFAULT_CHUNK_EVENTS,
    check_sorted: bool = True,
    allow_empty: bool = False,
    reuse_buffers: bool = False,
) -> Iterator[EventChunk]:
    """Read a recording as one stream, piece by piece (bounded memory).

    With ``reuse_buffers`` a reader may overwrite a chunk's arrays with the next chunk (HDF5
    does): for consumers that keep nothing of a chunk (counting), it saves the allocation.

    Every chunk is checked: equal lengths, integer types, and (``check_sorted``) timestamps that
    never decrease, within and across files; the first violation raises :class:`FormatError`
    naming the file and the event index (text: the line).  A recording without any event raises
    too (after its empty chunks were yielded), unless ``allow_empty``: one window of a still camera
    (an IBISCape ``events/<ns>.npz``) is a valid empty stream.

    Yields
    ------
    EventChunk
        Events with the file they come from and their position in it.
    """
    from . import _event_text_kernels as _kernels

    src = source if isinstance(source, EventSource) else open_events(source)
    it: Iterator[Any]
    if src.fmt == "ibiscape":
        it = _chunks_npz_files([w[2] for w in src.windows])
    elif src.fmt == "npz":
        it = _chunks_npz_files([src.path])
    elif src.fmt == "text":
        it = _chunks_text(src, chunk_events)
    elif src.fmt == "aedat4":
        from .event_aedat4 import iter_aedat4_events

        it = _chunks_stream(src, iter_aedat4_events(src.path, int(src.meta["stream_id"]), chunk_events))
    elif src.fmt == "bag":
        from .event_bag import iter_bag_event_arrays

        it = _chunks_stream(src, iter_bag_event_arrays(src.path, str(src.meta["topic"]), chunk_events))
    else:
        it = _chunks_hdf5(src, chunk_events, reuse_buffers)
    prev = np.iinfo(np.int64).min
    prev_where = ""
    total = 0
    size = src.sensor_size
    for item in it:
        chunk, in_order = item if isinstance(item, tuple) else (item, False)
        t = chunk.events.t_ns
        if size is not None and t.size and (int(chunk.events.x.max()) >= size[0]
                                            or int(chunk.events.y.max()) >= size[1]):
            ev = chunk.events
            i = int(np.flatnonzero((ev.x >= size[0]) | (ev.y >= size[1]))[0])
            path, line, what = chunk.where(i)
            raise FormatError(path, f"{what} at pixel ({int(ev.x[i])}, {int(ev.y[i])}) lies outside "
                              f"the {size[0]}x{size[1]} sensor {src.size_from or 'the file states'}"
                              " gives; the file is damaged, or the size is wrong", line=line)
        if in_order and t.size:
            prev = int(t[-1])
            prev_where = chunk.source
        elif check_sorted and t.size:
            bad = int(_kernels.first_decrease(t, prev))
            if bad >= 0:
                path, line, what = chunk.where(bad)
                before = f"event {chunk.offset + bad - 1}" if bad > 0 else f"the last event of {prev_where}"
                raise FormatError(
                    path, f"timestamps go backwards at {what}: {int(t[bad])} ns after {before} at "
                    f"{int(prev if bad == 0 else t[bad - 1])} ns; events must be sorted by time",
                    line=line,
                )
            prev = int(t[-1])
            prev_where = chunk.source
        total += t.size
        yield chunk
    if total == 0 and not allow_empty:
        raise FormatError(src.path, "the recording holds no events; nothing to process")


def read_events(path: str | os.PathLike[str], *, fmt: str | None = None, allow_empty: bool = False,
                topic: str | None = None) -> Events:
    """Read a whole recording into memory as one :class:`Events` stream (see
    :func:`iter_event_chunks` for the checks).  A recording without events raises
    :class:`FormatError` unless ``allow_empty`` (then it is an empty stream), e.g. for one window
    ``events/<ns>.npz`` of an IBISCape folder, which a still camera leaves empty."""
    return Events.concatenate([c.events for c in iter_event_chunks(open_events(path, fmt=fmt, topic=topic),
                                                                   allow_empty=allow_empty)])


# ------------------------------------------------------------------------------------------
# writing
# ------------------------------------------------------------------------------------------


def _text_bytes(ev: Events) -> bytes:
    from . import _event_text_kernels as _kernels

    if len(ev) and int(ev.t_ns[0]) < 0:
        raise IbiscapeError("the text format cannot hold negative timestamps")
    buf = np.empty(41 * len(ev) + 1, np.uint8)
    k = int(_kernels.format_text(ev.t_ns, ev.x, ev.y, ev.p, buf))
    return buf[:k].tobytes()


class _Writer:
    """Streaming writer of one recording in a given format, into a temporary path that
    :meth:`commit` renames onto the target (folders included)."""

    def __init__(self, dst: Path, fmt: str, like: EventSource | None,
                 sensor_size: tuple[int, int] | None = None) -> None:
        self.dst, self.fmt, self.like = dst, fmt, like
        self.size = sensor_size or (like.sensor_size if like is not None else None)
        dst.parent.mkdir(parents=True, exist_ok=True)
        self._stream: Any = None
        if fmt == "ibiscape":
            if dst.exists() and (not dst.is_dir() or any(dst.iterdir())):
                raise IbiscapeError(f"{dst}: already exists; choose a new output folder or remove it")
            self.tmp = staging_path(dst, folder=True)
            (self.tmp / "events").mkdir()
            self.rows: list[str] = []
        elif fmt == "bag" and dst.suffix.lower() != ".bag":
            self.tmp = staging_path(dst, folder=True)  # a ROS 2 bag is a folder
        else:
            self.tmp = staging_path(dst)
        self.parts: list[Events] = []
        self.n = 0
        self._fh: Any = None
        self._h5: Any = None
        self._ms: np.ndarray = np.zeros(0, np.int64)

    def add(self, ev: Events, window: tuple[int, int, Path] | None = None) -> None:
        self.n += len(ev)
        if self.fmt == "ibiscape":
            a, b, src = window if window is not None else (
                int(ev.t_ns[0]) if len(ev) else 0, int(ev.t_ns[-1]) if len(ev) else 0,
                Path(f"{int(ev.t_ns[0]) if len(ev) else len(self.rows)}.npz"))
            np.savez(self.tmp / "events" / src.name, t=np.asarray(ev.t_ns, np.int64),
                     x=np.asarray(ev.x, np.uint16), y=np.asarray(ev.y, np.uint16),
                     p=np.asarray(ev.p, np.bool_))
            self.rows.append(f"{a}, {b}, {src.name} \n")
        elif self.fmt == "npz":
            self.parts.append(ev)
        elif self.fmt == "text":
            if self._fh is None:
                self._fh = open(self.tmp, "wb")  # noqa: SIM115 (closed in commit/abort)
                if self.like is not None and self.like.meta.get("header"):
                    self._fh.write(self.like.meta["header"])
            self._fh.write(_text_bytes(ev))
        elif self.fmt in ("aedat4", "bag"):
            self._add_stream(ev)
        else:
            self._add_h5(ev)

    def _add_stream(self, ev: Events) -> None:
        if self._stream is None:
            if self.fmt == "aedat4":
                from .event_aedat4 import Aedat4Writer

                size = self.size or ((int(ev.x.max()) + 1, int(ev.y.max()) + 1) if len(ev) else (1, 1))
                self._stream = Aedat4Writer(self.tmp, size)
            else:
                from .event_bag import BagEventWriter

                ros2 = self.tmp.is_dir()
                # rosbags refuses an existing path, and names a ROS 2 bag's storage file after
                # its folder: write <staging folder>/<target name> and move that in commit
                target = self.tmp / self.dst.name if ros2 else self.tmp
                if not ros2:
                    self.tmp.unlink()
                topic = (self.like.meta.get("topic") if self.like is not None and self.like.fmt == "bag"
                         else None) or "/dvs/events"
                self._stream = BagEventWriter(target, topic=topic, sensor_size=self.size or (0, 0),
                                              ros2=ros2)
        self._stream.add(ev)

    def _add_h5(self, ev: Events) -> None:
        meta = self.like.meta if self.like is not None and self.like.fmt == "hdf5" else {}
        if meta.get("layout", "dsec") != "dsec":  # other layouts are written as DSEC/E2CALIB
            meta = {"attrs": meta.get("attrs", {})}
        dtypes = meta.get("dtypes", {"t": "<i8", "x": "<u2", "y": "<u2", "p": "|u1"})
        off = int(meta.get("t_offset_us", 0))
        if self._h5 is None:
            h5py = _h5py()
            self._h5 = h5py.File(self.tmp, "w")
            for k in NPZ_KEYS:
                self._h5.create_dataset(f"events/{k}", shape=(0,), maxshape=(None,),
                                        dtype=np.dtype(dtypes[k]), chunks=(1 << 16,))
            for k, v in meta.get("attrs", {}).items():
                self._h5.attrs[k] = v
            if meta.get("has_t_offset"):
                self._h5.create_dataset("t_offset", data=np.int64(off))
            if self.size is not None and _h5_size(self._h5) is None:
                self._h5.attrs["width"], self._h5.attrs["height"] = (int(v) for v in self.size)
        if len(ev) == 0:
            return
        t_us = ev.t_ns // 1000 - off
        if (ev.t_ns % 1000).any():
            raise IbiscapeError("HDF5 (E2CALIB/DSEC) stores microseconds; these events have ns digits")
        tdt = np.dtype(dtypes["t"])
        if tdt.kind in "iu" and (int(t_us[0]) < np.iinfo(tdt).min or int(t_us[-1]) > np.iinfo(tdt).max):
            raise IbiscapeError(f"timestamps do not fit the file's {tdt} microsecond field")
        cols = {"t": t_us, "x": ev.x, "y": ev.y, "p": ev.p}
        n0 = self._h5["events/t"].shape[0]
        for k in NPZ_KEYS:
            d = self._h5[f"events/{k}"]
            d.resize((n0 + len(ev),))
            d[n0:] = np.asarray(cols[k]).astype(np.dtype(dtypes[k]), copy=False)
        if meta.get("has_ms_to_idx"):
            ms = np.bincount(t_us // 1000)
            if ms.size > self._ms.size:
                ms[: self._ms.size] += self._ms
                self._ms = ms
            else:
                self._ms[: ms.size] += ms

    def commit(self) -> None:
        if self.fmt == "ibiscape":
            with open(self.tmp / "timestamps.csv", "w", encoding="utf-8", newline="\n") as f:
                f.write("#timestamp_start [ns], timestamp_end [ns], filename\n")
                f.writelines(self.rows)
            publish(self.tmp, self.dst)
            return
        if self.fmt == "npz":
            ev = Events.concatenate(self.parts)
            with open(self.tmp, "wb") as f:
                np.savez(f, t=np.asarray(ev.t_ns, np.int64), x=np.asarray(ev.x, np.uint16),
                         y=np.asarray(ev.y, np.uint16), p=np.asarray(ev.p, np.bool_))
        elif self.fmt == "text":
            if self._fh is None:
                self._fh = open(self.tmp, "wb")  # noqa: SIM115
            self._fh.close()
        elif self.fmt in ("aedat4", "bag"):
            if self._stream is None:
                self._add_stream(Events.empty())
            self._stream.close()
            if self.tmp.is_dir():  # a ROS 2 bag folder inside the staging folder
                publish(self.tmp / self.dst.name, self.dst)
                discard(self.tmp)
                return
        else:
            if self._h5 is None:
                self._add_h5(Events.empty())
            if self.like is not None and self.like.meta.get("has_ms_to_idx"):
                # ms_to_idx[k] = number of events before millisecond k (DSEC's definition)
                idx = np.concatenate([[0], np.cumsum(self._ms)]).astype(np.uint64)
                self._h5.create_dataset("ms_to_idx", data=idx)
            self._h5.close()
        publish(self.tmp, self.dst)

    def abort(self) -> None:
        with contextlib.suppress(Exception):
            if self._fh is not None:
                self._fh.close()
            if self._h5 is not None:
                self._h5.close()
            if self._stream is not None:
                self._stream.close()
        discard(self.tmp)


def _out_format(dst: Path, like: EventSource | None, fmt: str | None) -> str:
    if fmt is not None:
        return fmt
    if like is not None:
        return like.fmt
    if dst.suffix == "" and not dst.is_file():
        return "ibiscape"
    return detect_event_format(dst)


def write_events(
    path: str | os.PathLike[str],
    events: Events,
    *,
    fmt: str | None = None,
    like: EventSource | None = None,
    window_ns: int | None = None,
    sensor_size: tuple[int, int] | None = None,
) -> None:
    """Write a stream atomically in ``fmt`` (default: the format of ``like``, else from the
    path's suffix; a path without suffix is an IBISCape DVS folder).

    Parameters
    ----------
    path
        Target file or folder (a folder must not exist or be empty).
    events
        The events.
    fmt : {"ibiscape", "npz", "text", "hdf5", "aedat4", "bag"}, optional
        ``bag``: a ``.bag`` path is a ROS 1 bag, any other a ROS 2 bag folder.
    like : EventSource, optional
        Copy layout details (text header, HDF5 dtypes, ``t_offset``, attributes, bag topic) from
        this source.
    window_ns : int, optional
        IBISCape folders: length of the ``events/<ns>.npz`` windows (default 50 ms).
    sensor_size : (int, int), optional
        Stated in the file where the format can (HDF5 ``width``/``height`` attributes, AEDAT4
        stream table, EventArray width/height); default ``like``'s.  AEDAT4 needs one: the
        largest coordinates + 1 when neither is given.
    """
    dst = Path(path)
    fmt = _out_format(dst, like, fmt)
    if fmt == "text" and sensor_size is not None and (like is None or not like.meta.get("header")):
        like = EventSource(dst, "text", meta={"header": f"{sensor_size[0]} {sensor_size[1]}\n".encode()})
    w = _Writer(dst, fmt, like, sensor_size)
    try:
        if fmt == "ibiscape":
            win = int(window_ns or 50_000_000)
            t = events.t_ns
            if len(events):
                t0 = int(t[0])
                edges = t0 + win * np.arange(0, (int(t[-1]) - t0) // win + 2, dtype=np.int64)
                cuts = np.searchsorted(t, edges)
                for k in range(len(edges) - 1):
                    a, b = int(cuts[k]), int(cuts[k + 1])
                    part = Events(t[a:b], events.x[a:b], events.y[a:b], events.p[a:b])
                    w.add(part, (int(edges[k]), int(edges[k + 1]), Path(f"{int(edges[k])}.npz")))
        else:
            w.add(events)
        w.commit()
    except BaseException:
        w.abort()
        raise


def write_filtered_events(
    source: EventSource,
    dst: str | os.PathLike[str],
    keep: Callable[[Events], Events],
    *,
    chunk_events: int = DEFAULT_CHUNK_EVENTS,
    progress: Callable[[int], None] | None = None,
) -> tuple[int, int]:
    """Stream ``source`` through ``keep`` (e.g. a hot-pixel filter) into ``dst`` in the source's
    own format, window by window / chunk by chunk; atomic (nothing is left at ``dst`` on failure).

    Returns
    -------
    (n_in, n_out) : events read and written.
    """
    out = Path(dst)
    if out.resolve() == source.path.resolve():
        raise IbiscapeError(f"{out}: the output would overwrite the input; choose another path")
    w = _Writer(out, source.fmt, source)
    n_in = 0
    try:
        windows = iter(source.windows)
        for chunk in iter_event_chunks(source, chunk_events=chunk_events):
            kept = keep(chunk.events)
            w.add(kept, next(windows) if source.fmt == "ibiscape" else None)
            n_in += len(chunk.events)
            if progress is not None:
                progress(len(chunk.events))
        w.commit()
    except BaseException:
        w.abort()
        raise
    return n_in, w.n


# ------------------------------------------------------------------------------------------
# hot_pixels.txt (dvs_tools / E2CALIB): one "x, y" per line
# ------------------------------------------------------------------------------------------


def read_hot_pixels(path: str | os.PathLike[str]) -> npt.NDArray[np.int64]:
    """Read a ``hot_pixels.txt`` (one ``x, y`` per line; blank lines and ``#`` comments ignored).

    Returns
    -------
    ndarray, shape (K, 2), int64
        Pixels as x, y.
    """
    from .paths import read_text

    p = Path(path)
    rows: list[tuple[int, int]] = []
    for n, raw in enumerate(read_text(p, what="hot-pixel list").splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        cols = line.replace(",", " ").split()
        if len(cols) != 2:
            raise FormatError(p, f"expected 'x, y' (two integers), got {line!r}", line=n)
        try:
            xv, yv = int(cols[0]), int(cols[1])
        except ValueError:
            raise FormatError(p, f"expected integer pixel coordinates 'x, y', got {line!r}", line=n) from None
        if not (0 <= xv <= 65535 and 0 <= yv <= 65535):
            raise FormatError(p, f"pixel coordinates must be in 0..65535, got {line!r}", line=n)
        rows.append((xv, yv))
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


def write_hot_pixels(path: str | os.PathLike[str], pixels: npt.ArrayLike) -> None:
    """Write pixels (K, 2) as ``x, y`` lines (dvs_tools' format), atomically."""
    px = np.asarray(pixels, dtype=np.int64).reshape(-1, 2)
    with atomic_write(path) as f:
        f.writelines(f"{int(a)}, {int(b)}\n" for a, b in px)


# ------------------------------------------------------------------------------------------
# event frames as PNG images
# ------------------------------------------------------------------------------------------


def write_frames_png(
    out_dir: str | os.PathLike[str],
    frames: Iterator[tuple[int, int, np.ndarray]],
    *,
    to_uint8: Callable[[np.ndarray], np.ndarray],
    progress: Callable[[int], None] | None = None,
) -> int:
    """Write frames as ``<out_dir>/<t_end_ns>.png`` (20 digits, zero-padded) plus ``timestamps.csv``
    (``#timestamp_start [ns], timestamp_end [ns], filename``); each file atomically.

    Returns the number of frames written.
    """
    import cv2

    out = Path(out_dir)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    try:
        for a, b, frame in frames:
            name = f"{b:020d}.png"  # zero-padded: glob order is time order
            with atomic_output_path(out / name) as tmp:
                if not cv2.imwrite(str(tmp), to_uint8(frame)):
                    raise IbiscapeError(f"{out / name}: could not write the PNG image")
            rows.append(f"{a}, {b}, {name} \n")
            if progress is not None:
                progress(1)
    except BaseException:
        if created and not any(out.iterdir()):
            out.rmdir()  # a failure before the first frame leaves nothing behind
        raise
    with atomic_write(out / "timestamps.csv") as f:
        f.write("#timestamp_start [ns], timestamp_end [ns], filename\n")
        f.writelines(rows)
    return len(rows)
