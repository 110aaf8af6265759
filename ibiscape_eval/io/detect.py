"""Guess a trajectory file's format from its name and its first lines.

Rules, in order:

1. a folder with ``metadata.yaml``, or a ``.bag`` / ``.db3`` / ``.mcap`` file -> ``"bag"``;
2. a ``#`` header naming a timestamp: 17 columns in the order p, v, a, q, w -> ``"ibiscape"``;
   8 or more columns with ``q_w`` in column 5 (index 4) -> ``"euroc"``; 8 columns with ``qx`` in
   column 5 -> ``"tum"``;
3. otherwise the first data row: 12 columns -> ``"kitti"``; 8 columns separated by spaces or
   tabs -> ``"tum"``.

Anything else (e.g. 8 comma-separated columns without a header, which could be TUM or EuRoC)
is ambiguous: :class:`FormatError` asks for ``--format``.
"""

from __future__ import annotations

import os
import re

from ibiscape_eval.core.errors import FormatError, Remedy

from .bag import BAG_SUFFIXES

__all__ = ["TRAJECTORY_FORMATS", "detect_trajectory_format"]

TRAJECTORY_FORMATS: tuple[str, ...] = ("tum", "kitti", "euroc", "ibiscape", "bag")

_HINT = "; give the format explicitly with {0} (one of tum, kitti, euroc, ibiscape, bag)"
_FORMAT = (Remedy("fmt"),)


def _names(header: str) -> list[str]:
    h = header.lstrip("#").strip()
    parts = h.split(",") if "," in h else h.split()
    return [re.sub(r"\s+", "", x).lower() for x in parts if x.strip()]


def _is_q(name: str, axis: str) -> bool:
    """``q_RS_w []``, ``qw``, ``q_w``, ``q_RS_w__`` ... -> True for axis ``w``."""
    base = re.sub(r"\[.*?\]", "", name).strip("_ ")
    return base.startswith("q") and (base.endswith(f"_{axis}") or base == f"q{axis}")


def detect_trajectory_format(path: str | os.PathLike[str]) -> str:
    """Return ``"tum"``, ``"kitti"``, ``"euroc"``, ``"ibiscape"`` or ``"bag"`` for ``path``.

    Does not print; the command line reports the choice.  See the module docstring for the rules.

    Raises
    ------
    FormatError
        The format is ambiguous or unknown (the message suggests ``--format``), the file is
        empty or binary.
    FileNotFoundError
        ``path`` does not exist.
    """
    from .paths import check_input

    p = check_input(path, "any")
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "bag"
        raise FormatError(p, "is a folder without metadata.yaml, not a ROS 2 bag" + _HINT,
                          hint=_FORMAT)
    if p.suffix.lower() in BAG_SUFFIXES:
        return "bag"
    with open(p, "rb") as f:
        head = f.read(65536)
    if b"\x00" in head:
        raise FormatError(p, "binary data (NUL byte); expected a text trajectory file" + _HINT,
                          hint=_FORMAT)
    if head.startswith(b"#ROSBAG"):
        return "bag"
    text = head.decode("utf-8", errors="replace")
    lines = text.splitlines()
    if len(head) == 65536 and lines:
        lines = lines[:-1]  # the last line may be cut
    header = None
    first = None
    for ln in lines:
        s = ln.strip()
        if not s:
            continue
        if s.startswith("#"):
            if header is None and "timestamp" in s.lower():
                header = s
            continue
        first = s.split("#", 1)[0].strip()
        break
    if header is not None:
        names = _names(header)
        if (len(names) == 17 and names[4].startswith("v") and names[7].startswith("a")
                and _is_q(names[10], "w") and names[14].startswith("w")):
            return "ibiscape"
        if len(names) >= 8 and _is_q(names[4], "w"):
            return "euroc"
        if len(names) == 8 and _is_q(names[4], "x") and _is_q(names[7], "w"):
            return "tum"
    if first is None:
        raise FormatError(p, "no data rows found (empty file or only comments)" + _HINT,
                          hint=_FORMAT)
    tokens = [t for t in re.split(r"[\s,]+", first) if t]
    if len(tokens) == 12:
        return "kitti"
    if len(tokens) == 8 and "," not in first:
        return "tum"
    raise FormatError(
        p, f"cannot tell the format from a first row of {len(tokens)} "
        f"{'comma-separated ' if ',' in first else ''}columns"
        + (" without a header" if header is None else "") + _HINT, hint=_FORMAT)
