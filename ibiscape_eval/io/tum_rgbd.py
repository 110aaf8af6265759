"""TUM RGB-D dataset folders (Sturm et al., "A benchmark for the evaluation of RGB-D SLAM
systems", IROS 2012), the layout ORB-SLAM3's ``rgbd_tum`` and the TUM tools read::

    <root>/rgb/<t>.png          colour images (8-bit, 3 channels)
    <root>/depth/<t>.png        16-bit depth; here in millimetres (DepthMapFactor 1000; the TUM
                                recordings use 5000)
    <root>/rgb.txt, depth.txt   "# ..." header lines, then "timestamp filename" (seconds)
    <root>/groundtruth.txt      TUM trajectory "t tx ty tz qx qy qz qw" (seconds)
    <root>/association.txt      "t_rgb rgb/<t>.png t_depth depth/<t>.png" per RGB-D pair

Timestamps are written exactly from int64 nanoseconds: ``%d.%06d`` when every stamp is a whole
microsecond (as the TUM files), else ``%d.%09d``; the file names use the same text.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import numpy.typing as npt

from .atomic import atomic_write
from .framelists import read_stamped_rows, seconds_exact, write_stamped_list

__all__ = ["read_tum_list", "stamp_text", "write_association", "write_tum_list"]


def stamp_text(stamps_ns: npt.ArrayLike) -> list[str]:
    """Seconds as exact decimal text (6 decimals when all stamps are whole microseconds)."""
    st = np.asarray(stamps_ns, dtype=np.int64).reshape(-1)
    if np.all(st % 1000 == 0):
        return [f"{int(t) // 1_000_000_000}.{(int(t) % 1_000_000_000) // 1000:06d}" for t in st]
    return [f"{int(t) // 1_000_000_000}.{int(t) % 1_000_000_000:09d}" for t in st]


def write_tum_list(path: str | os.PathLike[str], stamps_ns: npt.ArrayLike, files: list[str], *,
                   what: str) -> None:
    """Write ``rgb.txt`` / ``depth.txt``: three ``#`` lines, then ``timestamp filename``."""
    write_stamped_list(path, f"# {what}\n# file: '{Path(path).parent.name}' written by ibiscape-eval\n"
                       "# timestamp filename\n", stamp_text(stamps_ns), files, sep=" ")


def read_tum_list(path: str | os.PathLike[str]) -> tuple[npt.NDArray[np.int64], list[str]]:
    """Stamps [ns] (parsed exactly from the decimal text) and file names of ``rgb.txt`` /
    ``depth.txt``."""
    stamps, rows = read_stamped_rows(
        path, expected="'timestamp filename' with the time in seconds", sep=None,
        parse=seconds_exact)
    return stamps, [r[1] for r in rows]


def write_association(path: str | os.PathLike[str], rgb_ns: npt.ArrayLike, rgb_files: list[str],
                      depth_ns: npt.ArrayLike, depth_files: list[str]) -> None:
    """Write ``association.txt``: ``t_rgb rgb_file t_depth depth_file`` per pair."""
    a = stamp_text(rgb_ns)
    b = stamp_text(depth_ns)
    with atomic_write(path) as f:
        f.writelines(f"{ta} {fa} {tb} {fb}\n"
                     for ta, fa, tb, fb in zip(a, rgb_files, b, depth_files, strict=True))
