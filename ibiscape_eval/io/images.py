"""Camera images of the IBISCape layout: RGB frames, depth, segmentation and ``timestamps.csv``.

Encodings (``../shared/FORMATS.md``)
------------------------------------
- RGB: 8-bit PNG (arrays in memory are RGB; OpenCV's BGR order stays inside this module).
- Depth, as the real dataset saves it: CARLA's logarithmic 8-bit encoding
  ``g = clamp(1 + ln(d / 1000 m) / 5.70378, 0, 1)``, stored as ``round(255 g)`` in three equal
  channels (CARLA's ``LogarithmicDepth`` converter).  Depth below ``1000 exp(-5.70378) = 3.34 m``
  saturates to 0 and the sky (no hit) to 255, exactly like the dataset.
- Depth for RGB-D users: 16-bit PNG in millimetres (``DepthMapFactor: 1000`` in ORB-SLAM3's
  settings; 0 = no measurement, also beyond 65.535 m).  The TUM RGB-D recordings use the same
  layout with a factor of 5000.
- Segmentation: the raw CARLA tag per pixel (8-bit single channel PNG) and CityScapes colours
  (8-bit RGB PNG) like IBISCape's ``semantic/frames``.
- ``timestamps.csv``: ``#timestamp [ns], filename`` then ``<ns>, <ns>.png `` rows (comma
  separated, trailing space like the acquisition scripts).

Every writer goes through the atomic staging of :mod:`ibiscape_eval.io`; readers raise
:class:`~ibiscape_eval.core.errors.FormatError` naming the file.
"""

from __future__ import annotations

import mmap
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError

from .atomic import atomic_output_path, atomic_write
from .framelists import ns_number, read_stamped_rows, write_stamped_list
from .paths import check_input

__all__ = [
    "CARLA_LOG_DEPTH_SCALE",
    "CARLA_TAGS",
    "CITYSCAPES_PALETTE",
    "decode_depth_carla_log",
    "decode_png_grey",
    "encode_depth_carla_log",
    "imread_checked",
    "read_association",
    "read_depth_carla_log",
    "read_depth_mm",
    "read_frame_timestamps",
    "read_grey",
    "read_labels",
    "read_labels_cityscapes",
    "read_png",
    "write_association",
    "write_depth_carla_log",
    "write_depth_mm",
    "write_frame_timestamps",
    "write_labels",
    "write_labels_cityscapes",
    "write_png",
]

#: CARLA's ``LogarithmicDepth``: ``g = 1 + ln(d / far) / 5.70378`` with ``far = 1000 m``
CARLA_LOG_DEPTH_SCALE = 5.70378
_CARLA_FAR_M = 1000.0

#: CARLA's semantic tags (0.9.10 .. 0.9.13, the versions IBISCape was recorded with): id -> name
CARLA_TAGS: dict[int, str] = {
    0: "Unlabeled", 1: "Building", 2: "Fence", 3: "Other", 4: "Pedestrian", 5: "Pole",
    6: "RoadLine", 7: "Road", 8: "SideWalk", 9: "Vegetation", 10: "Vehicles", 11: "Wall",
    12: "TrafficSign", 13: "Sky", 14: "Ground", 15: "Bridge", 16: "RailTrack", 17: "GuardRail",
    18: "TrafficLight", 19: "Static", 20: "Dynamic", 21: "Water", 22: "Terrain",
}

#: (23, 3) uint8 RGB colour of every tag (CARLA's ``CityScapesPalette`` converter)
CITYSCAPES_PALETTE: npt.NDArray[np.uint8] = np.array([
    (0, 0, 0), (70, 70, 70), (100, 40, 40), (55, 90, 80), (220, 20, 60), (153, 153, 153),
    (157, 234, 50), (128, 64, 128), (244, 35, 232), (107, 142, 35), (0, 0, 142), (102, 102, 156),
    (220, 220, 0), (70, 130, 180), (81, 0, 81), (150, 100, 100), (230, 150, 140), (180, 165, 180),
    (250, 170, 30), (110, 190, 160), (170, 120, 50), (45, 60, 150), (145, 170, 100),
], dtype=np.uint8)
CITYSCAPES_PALETTE.setflags(write=False)


def write_png(path: str | os.PathLike[str], image: npt.ArrayLike, *, compression: int = 1,
              photo: bool = False) -> None:
    """Write an 8- or 16-bit image ``(H, W)`` or RGB ``(H, W, 3)`` as PNG, atomically.

    Parameters
    ----------
    compression : int
        zlib level 0..9 (1: fast, about 10 % larger than 9).
    photo : bool
        A noisy camera image: zlib's Huffman-only strategy after PNG's 'average' filter, about
        half the encoding time of the default at level 1 and 7 % smaller files (rendered RGB
        frames; flat depth or label images compress worse that way).  The filtered noise has
        hardly any repeats: the run-length strategy gave the same size (+0.01 %) 14 % slower
        (384 px calibration drive: 4.34 -> 3.74 ms per frame).
    """
    import cv2

    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16) or not (
            img.ndim == 2 or (img.ndim == 3 and img.shape[2] in (3, 4))) or img.size == 0:
        raise IbiscapeError(f"{path}: a PNG image must be uint8/uint16 (H, W) or (H, W, 3|4), "
                            f"got {img.dtype} {img.shape}")
    if img.ndim == 3:  # OpenCV writes BGR(A); one cvtColor pass (a fancy-index copy took 20x longer)
        img = cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2BGR if img.shape[2] == 3 else cv2.COLOR_RGBA2BGRA)
    with atomic_output_path(path) as tmp:
        try:
            params = [cv2.IMWRITE_PNG_COMPRESSION, int(compression)]
            if photo:
                params += [cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY,
                           cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_AVG]
            ok = cv2.imwrite(str(tmp), np.ascontiguousarray(img), params)
        except cv2.error as e:
            raise IbiscapeError(f"{path}: could not write the PNG image ({e})") from None
        if not ok:
            raise IbiscapeError(f"{path}: could not write the PNG image (disk full or no permission?)")


def imread_checked(path: str | os.PathLike[str], flags: int, *, missing: str,
                   unreadable: str) -> npt.NDArray[Any]:
    """``cv2.imread(path, flags)`` after :func:`~ibiscape_eval.io.paths.check_input`: a missing
    file or one OpenCV cannot decode is a :class:`FormatError` with the given message."""
    import cv2

    p = _image_input(path, missing)
    img = cv2.imread(str(p), flags)
    if img is None:
        raise FormatError(p, unreadable)
    return np.asarray(img)


def _image_input(path: str | os.PathLike[str], missing: str) -> Path:
    """``path`` after :func:`~ibiscape_eval.io.paths.check_input`; a missing file is a
    :class:`FormatError` with the message ``missing``."""
    p = Path(path)
    try:
        check_input(p, what="image")
    except FileNotFoundError:
        raise FormatError(p, missing) from None
    return p


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: chunks that change nothing in the grey image OpenCV decodes; any other (gAMA, sRGB, iCCP,
#: PLTE, tRNS, eXIf orientation, ...) sends the file to OpenCV
_PNG_INERT_CHUNKS = frozenset({b"IDAT", b"IEND", b"tEXt", b"zTXt", b"iTXt", b"tIME", b"pHYs"})


def _libdeflate() -> Any:
    """The ``deflate`` module (libdeflate), or None: zlib then inflates, slower."""
    try:
        import deflate
    except ImportError:  # pragma: no cover - deflate is a dependency
        return None
    return deflate


def _png_idat(data: bytes | memoryview | mmap.mmap) -> tuple[int, int, bool, bytes] | None:
    """Width, height, RGB?, the zlib stream of an 8-bit grey or RGB non-interlaced PNG with only
    inert chunks and correct CRCs, else None.  ``data`` may be a memoryview (of a mapped file):
    the chunks are checked in place and only the IDAT bodies are copied, once."""
    import struct
    import zlib

    lib = _libdeflate()
    crc32 = zlib.crc32 if lib is None else lib.crc32
    mv = memoryview(data)
    if len(mv) < 33 or mv[:8] != _PNG_SIGNATURE or mv[12:16] != b"IHDR":
        return None
    w, h, depth, colour, comp, filt, interlace = struct.unpack_from(">IIBBBBB", mv, 16)
    if (depth != 8 or colour not in (0, 2) or comp or filt or interlace
            or not 0 < w <= 65535 or not 0 < h <= 65535):
        return None
    parts: list[memoryview] = []
    pos, end = 8, len(mv)
    while pos + 12 <= end:
        n, kind = struct.unpack_from(">I4s", mv, pos)
        if pos + 12 + n > end or (crc32(mv[pos + 4:pos + 8 + n])
                                  != struct.unpack_from(">I", mv, pos + 8 + n)[0]):
            return None
        if kind == b"IDAT":
            parts.append(mv[pos + 8:pos + 8 + n])
        elif kind == b"IEND":
            return (w, h, colour == 2, b"".join(parts)) if parts else None
        elif (kind != b"IHDR" or pos != 8) and kind not in _PNG_INERT_CHUNKS:
            return None
        pos += 12 + n
    return None


def decode_png_grey(data: bytes | memoryview | mmap.mmap) -> npt.NDArray[np.uint8] | None:
    """8-bit grey image of the PNG bytes ``data``, bit-identical to ``cv2.imdecode(data,
    cv2.IMREAD_GRAYSCALE)`` (libpng's grey weights, see :mod:`._png_kernels`), or None for a PNG
    variant not handled here (palette, 16 bit, alpha, interlaced, colour-managed, corrupt), which
    the caller gives to OpenCV.

    Twice as fast as OpenCV's libpng for the RGB frames the generator writes
    (``benchmarks/bench_png.py`` on rendered SVI frames: 512 px 6.4 -> 3.0 ms, 1024 px
    23.1 -> 11.0 ms of CPU per image, at a load average of 24): libdeflate inflates about 3x faster than the zlib 1.2.11 OpenCV's wheel links,
    and the unfiltering runs in numba with the grey conversion fused into it.
    """
    import zlib

    head = _png_idat(data)
    if head is None:
        return None
    w, h, rgb, z = head
    size = h * (1 + w * (3 if rgb else 1))
    lib = _libdeflate()
    try:
        raw = zlib.decompress(z) if lib is None else lib.zlib_decompress(z, size)
    except Exception:  # deflate.DeflateError, zlib.error: OpenCV decides
        return None
    if len(raw) != size:
        return None
    from ._png_kernels import unfilter_to_grey

    out = np.empty((h, w), dtype=np.uint8)
    if unfilter_to_grey(np.frombuffer(raw, dtype=np.uint8), h, w, rgb, out) >= 0:
        return None
    return out


def read_grey(path: str | os.PathLike[str], *, missing: str, unreadable: str) -> npt.NDArray[Any]:
    """``imread_checked(path, cv2.IMREAD_GRAYSCALE, ...)``, with the PNGs
    :func:`decode_png_grey` handles decoded there (bit-identical, twice as fast)."""
    import cv2

    p = _image_input(path, missing)
    img: npt.NDArray[Any] | None = None
    try:
        # mapped, not read: no fresh 0.5 MB buffer per frame (its page faults cost as much CPU
        # as the copy in the VIO loop); the PNG chunks are checked in place
        with open(p, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as m:
            if m[:8] == _PNG_SIGNATURE:
                img = decode_png_grey(m)
    except (OSError, ValueError):  # no permission, empty file...: OpenCV's read below decides
        img = None
    if img is None:
        img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise FormatError(p, unreadable)
    return np.asarray(img)


def read_png(path: str | os.PathLike[str]) -> npt.NDArray[Any]:
    """Read a PNG unchanged: ``(H, W)`` or RGB ``(H, W, 3)`` (RGBA ``(H, W, 4)``), uint8 or uint16."""
    import cv2

    img = imread_checked(path, cv2.IMREAD_UNCHANGED, missing="image file not found",
                         unreadable="not a readable image (expected a PNG)")
    if img.ndim == 3:  # OpenCV reads BGR(A)
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB if img.shape[2] == 3 else cv2.COLOR_BGRA2RGBA)
    return np.ascontiguousarray(img)


# ----------------------------------------------------------------------------------------- depth
def _depth_array(depth_m: npt.ArrayLike, path: str | os.PathLike[str]) -> npt.NDArray[np.float64]:
    d = np.asarray(depth_m, dtype=np.float64)
    if d.ndim != 2 or d.size == 0:
        raise IbiscapeError(f"{path}: depth must be a (H, W) array in metres, got shape {d.shape}")
    return d


def encode_depth_carla_log(depth_m: npt.ArrayLike) -> npt.NDArray[np.uint8]:
    """CARLA's 8-bit logarithmic depth of z-depths ``(H, W)`` [m]; inf/NaN (sky) -> 255."""
    d = np.asarray(depth_m, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = 1.0 + np.log(d / _CARLA_FAR_M) / CARLA_LOG_DEPTH_SCALE
    g = np.where(np.isnan(g), 1.0, g)
    return np.round(255.0 * np.clip(g, 0.0, 1.0)).astype(np.uint8)


def decode_depth_carla_log(code: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Depth [m] ``(H, W)`` float32 of CARLA log codes (0 -> 3.34 m or nearer, 255 -> 1000 m or sky)."""
    g = np.asarray(code, dtype=np.float64) / 255.0
    return (_CARLA_FAR_M * np.exp((g - 1.0) * CARLA_LOG_DEPTH_SCALE)).astype(np.float32)


def write_depth_carla_log(path: str | os.PathLike[str], depth_m: npt.ArrayLike) -> None:
    """Depth ``(H, W)`` [m] as the dataset stores it: CARLA log encoding in three equal channels."""
    code = encode_depth_carla_log(_depth_array(depth_m, path))
    write_png(path, np.repeat(code[..., None], 3, axis=2))


def read_depth_carla_log(path: str | os.PathLike[str]) -> npt.NDArray[np.float32]:
    """Depth [m] ``(H, W)`` float32 of a CARLA log-depth PNG (grey, RGB or RGBA)."""
    img = read_png(path)
    if img.dtype != np.uint8:
        raise FormatError(path, f"CARLA log depth is 8-bit, got {img.dtype} (a 16-bit mm depth "
                          "PNG? use read_depth_mm)")
    if img.ndim == 3:
        if not (np.array_equal(img[..., 0], img[..., 1]) and np.array_equal(img[..., 0], img[..., 2])):
            raise FormatError(path, "CARLA log depth has three equal channels; this image is in "
                              "colour (raw CARLA depth? decode R + 256 G + 65536 B)")
        img = img[..., 0]
    return decode_depth_carla_log(img)


def write_depth_mm(path: str | os.PathLike[str], depth_m: npt.ArrayLike) -> None:
    """Depth ``(H, W)`` [m] as a 16-bit PNG in millimetres; 0 where there is no depth (sky, NaN,
    <= 0) or it exceeds 65.535 m."""
    d = _depth_array(depth_m, path)
    with np.errstate(invalid="ignore"):
        mm = np.round(d * 1000.0)
        ok = np.isfinite(mm) & (mm > 0) & (mm <= 65535)
    write_png(path, np.where(ok, mm, 0).astype(np.uint16))


def read_depth_mm(path: str | os.PathLike[str]) -> npt.NDArray[np.float32]:
    """Depth [m] ``(H, W)`` float32 of a 16-bit millimetre PNG; NaN where the file holds 0."""
    img = read_png(path)
    if img.dtype != np.uint16 or img.ndim != 2:
        raise FormatError(path, f"expected a single-channel 16-bit depth PNG, got {img.dtype} "
                          f"{img.shape}")
    d = img.astype(np.float32) / np.float32(1000.0)
    d[img == 0] = np.nan
    return d


# ---------------------------------------------------------------------------------- segmentation
def _label_array(labels: npt.ArrayLike, path: str | os.PathLike[str]) -> npt.NDArray[np.uint8]:
    lab = np.asarray(labels)
    if lab.ndim != 2 or lab.size == 0 or not np.issubdtype(lab.dtype, np.integer):
        raise IbiscapeError(f"{path}: labels must be an integer (H, W) array, got {lab.dtype} {lab.shape}")
    if lab.min() < 0 or lab.max() > 255:
        raise IbiscapeError(f"{path}: labels must be in 0..255, got {lab.min()}..{lab.max()}")
    return lab.astype(np.uint8)


def write_labels(path: str | os.PathLike[str], labels: npt.ArrayLike) -> None:
    """Semantic tags ``(H, W)`` as a raw 8-bit single-channel PNG."""
    write_png(path, _label_array(labels, path))


def read_labels(path: str | os.PathLike[str]) -> npt.NDArray[np.uint8]:
    """Semantic tags ``(H, W)`` uint8 of a raw label PNG."""
    img = read_png(path)
    if img.dtype != np.uint8 or img.ndim != 2:
        raise FormatError(path, f"expected a single-channel 8-bit label PNG, got {img.dtype} "
                          f"{img.shape} (a CityScapes colour PNG? use read_labels_cityscapes)")
    return img


def write_labels_cityscapes(path: str | os.PathLike[str], labels: npt.ArrayLike) -> None:
    """Semantic tags ``(H, W)`` in CARLA's CityScapes colours (RGB PNG), like IBISCape."""
    lab = _label_array(labels, path)
    if lab.max() >= len(CITYSCAPES_PALETTE):
        raise IbiscapeError(f"{path}: tag {int(lab.max())} has no CityScapes colour "
                            f"(tags 0..{len(CITYSCAPES_PALETTE) - 1})")
    write_png(path, CITYSCAPES_PALETTE[lab])


def read_labels_cityscapes(path: str | os.PathLike[str]) -> npt.NDArray[np.uint8]:
    """Semantic tags ``(H, W)`` uint8 of a CityScapes colour PNG; a colour outside the palette is
    an error naming the first such pixel."""
    img = read_png(path)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] < 3:
        raise FormatError(path, f"expected an 8-bit RGB CityScapes PNG, got {img.dtype} {img.shape}")
    key = (img[..., 0].astype(np.int32) << 16) | (img[..., 1].astype(np.int32) << 8) | img[..., 2]
    pal = CITYSCAPES_PALETTE.astype(np.int32)
    pkey = (pal[:, 0] << 16) | (pal[:, 1] << 8) | pal[:, 2]
    order = np.argsort(pkey)
    pos = np.clip(np.searchsorted(pkey[order], key), 0, len(pkey) - 1)
    found = pkey[order][pos] == key
    if not found.all():
        r, c = np.argwhere(~found)[0]
        raise FormatError(path, f"pixel (x={c}, y={r}) has the colour {tuple(int(v) for v in img[r, c, :3])}, "
                          "which is not in CARLA's CityScapes palette")
    return order[pos].astype(np.uint8)


# ------------------------------------------------------------------------------- timestamps.csv
def write_frame_timestamps(path: str | os.PathLike[str], stamps_ns: npt.ArrayLike,
                           filenames: Sequence[str] | None = None) -> None:
    """``timestamps.csv`` of a camera folder: ``#timestamp [ns], filename`` (default ``<ns>.png``)."""
    st = [int(t) for t in np.asarray(stamps_ns, dtype=np.int64).reshape(-1)]
    names = [f"{t}.png" for t in st] if filenames is None else list(filenames)
    if len(names) != len(st):
        raise IbiscapeError(f"{path}: {len(st)} stamps but {len(names)} file names")
    write_stamped_list(path, "#timestamp [ns], filename\n", st, names, sep=", ", end=" \n")


def read_frame_timestamps(path: str | os.PathLike[str]) -> tuple[npt.NDArray[np.int64], list[str]]:
    """Stamps [ns] and file names of a camera ``timestamps.csv`` (``#timestamp [ns], filename``)."""
    stamps, rows = read_stamped_rows(
        path, expected="'timestamp [ns], filename'", parse=ns_number, required=(1,),
        bad_stamp="is not a finite number", increasing=True, missing="timestamps.csv not found")
    return stamps, [r[1] for r in rows]


def _seconds(ns: int) -> str:
    return f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}"


def write_association(path: str | os.PathLike[str], rgb_stamps_ns: npt.ArrayLike, rgb_files: Sequence[str],
                      depth_stamps_ns: npt.ArrayLike, depth_files: Sequence[str]) -> None:
    """TUM RGB-D ``association.txt`` (``t_rgb rgb_file t_depth depth_file``, times in seconds with
    nine decimals, so the nanoseconds survive), the file ORB-SLAM3's RGB-D examples read."""
    a = np.asarray(rgb_stamps_ns, dtype=np.int64).reshape(-1)
    b = np.asarray(depth_stamps_ns, dtype=np.int64).reshape(-1)
    if not (a.size == b.size == len(rgb_files) == len(depth_files)):
        raise IbiscapeError(f"{path}: association needs as many rgb and depth stamps and files, got "
                            f"{a.size}, {b.size}, {len(rgb_files)}, {len(depth_files)}")
    with atomic_write(path) as f:
        f.writelines(f"{_seconds(int(ta))} {fa} {_seconds(int(tb))} {fb}\n"
                     for ta, fa, tb, fb in zip(a, rgb_files, b, depth_files, strict=True))


def read_association(path: str | os.PathLike[str]) -> tuple[npt.NDArray[np.int64], list[str],
                                                             npt.NDArray[np.int64], list[str]]:
    """Read an ``association.txt``: rgb stamps [ns], rgb files, depth stamps [ns], depth files."""
    p = Path(path)
    try:
        check_input(p)
    except FileNotFoundError:
        raise FormatError(p, "association file not found") from None
    ta: list[int] = []
    tb: list[int] = []
    fa: list[str] = []
    fb: list[str] = []
    with open(p, encoding="utf-8") as fh:
        for n, line in enumerate(fh, start=1):
            s = line.split()
            if not s or s[0].startswith("#"):
                continue
            if len(s) != 4:
                raise FormatError(p, "expected 't_rgb rgb_file t_depth depth_file'", line=n)
            try:
                ta.append(_ns(s[0]))
                tb.append(_ns(s[2]))
            except ValueError:
                raise FormatError(p, f"times {s[0]!r}, {s[2]!r} are not seconds", line=n) from None
            fa.append(s[1])
            fb.append(s[3])
    return np.asarray(ta, np.int64), fa, np.asarray(tb, np.int64), fb


def _ns(text: str) -> int:
    """Decimal seconds -> integer nanoseconds without going through a float."""
    whole, _, frac = text.partition(".")
    if not whole.lstrip("-").isdigit() or (frac and not frac.isdigit()):
        raise ValueError(text)
    sign = -1 if whole.startswith("-") else 1
    return sign * (abs(int(whole)) * 1_000_000_000 + int((frac + "000000000")[:9] or 0))
