"""Seeded mutators for the input mutation campaign: bytes in, bytes out (or a path substitution).

Each mutator takes the seed file's bytes and a ``numpy.random.Generator`` and returns the mutant's
bytes.  Path mutators (FIFO, symlink loop, folder) replace the input path itself.  The names are the
"classes" the campaign reports.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

Mutator = Callable[[bytes, np.random.Generator], bytes]

_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
_HUGE = [b"1e308", b"-1e308", b"1.0e+300", b"1e400", b"9" * 40, b"18446744073709551616",
         b"-9223372036854775809", b"1.0e+9", b"1.0e+12", b"100000", b"0", b"-1"]
_SPECIAL = [b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b".nan", b".inf", b"-.inf"]


def bit_flip(data: bytes, rng: np.random.Generator) -> bytes:
    if not data:
        return data
    b = bytearray(data)
    for _ in range(int(rng.integers(1, 9))):
        i = int(rng.integers(len(b)))
        b[i] ^= 1 << int(rng.integers(8))
    return bytes(b)


def header_flip(data: bytes, rng: np.random.Generator) -> bytes:
    """Bit flips in the first 256 bytes, where binary headers live."""
    if not data:
        return data
    b = bytearray(data)
    for _ in range(int(rng.integers(1, 4))):
        i = int(rng.integers(min(len(b), 256)))
        b[i] ^= 1 << int(rng.integers(8))
    return bytes(b)


def truncate(data: bytes, rng: np.random.Generator) -> bytes:
    return data[: int(rng.integers(0, max(1, len(data))))]


def insert_bytes(data: bytes, rng: np.random.Generator) -> bytes:
    i = int(rng.integers(len(data) + 1))
    junk = rng.integers(0, 256, int(rng.integers(1, 16)), dtype=np.uint8).tobytes()
    return data[:i] + junk + data[i:]


def delete_bytes(data: bytes, rng: np.random.Generator) -> bytes:
    if not data:
        return data
    i = int(rng.integers(len(data)))
    return data[:i] + data[i + int(rng.integers(1, 64)):]


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def duplicate_line(data: bytes, rng: np.random.Generator) -> bytes:
    lines = _lines(data)
    i = int(rng.integers(len(lines)))
    lines.insert(i, lines[i])
    return b"\n".join(lines)


def _replace_number(data: bytes, rng: np.random.Generator, pool: list[bytes]) -> bytes:
    spans = [m.span() for m in _NUMBER.finditer(data[:200_000])]
    if not spans:
        return data + pool[int(rng.integers(len(pool)))]
    out = data
    for _ in range(int(rng.integers(1, 3))):
        s, e = spans[int(rng.integers(len(spans)))]
        if e > len(out):
            continue
        new = pool[int(rng.integers(len(pool)))]
        out = out[:s] + new + out[e:]
        spans = [m.span() for m in _NUMBER.finditer(out[:200_000])]
    return out


def huge_number(data: bytes, rng: np.random.Generator) -> bytes:
    return _replace_number(data, rng, _HUGE)


def nan_inf(data: bytes, rng: np.random.Generator) -> bytes:
    return _replace_number(data, rng, _SPECIAL)


def non_utf8(data: bytes, rng: np.random.Generator) -> bytes:
    i = int(rng.integers(len(data) + 1))
    return data[:i] + b"\xff\xfe\xc3\x28\x80" + data[i:]


def bom(data: bytes, rng: np.random.Generator) -> bytes:
    return b"\xef\xbb\xbf" + data


def crlf(data: bytes, rng: np.random.Generator) -> bytes:
    return data.replace(b"\r\n", b"\n").replace(b"\n", b"\r\n")


def long_line(data: bytes, rng: np.random.Generator) -> bytes:
    lines = _lines(data)
    i = int(rng.integers(len(lines)))
    lines[i] = lines[i] + b"1" * (1 << 20)
    return b"\n".join(lines)


def column_change(data: bytes, rng: np.random.Generator) -> bytes:
    lines = _lines(data)
    i = int(rng.integers(len(lines)))
    sep = b"," if b"," in lines[i] else b" "
    parts = lines[i].split(sep)
    if rng.random() < 0.5 and len(parts) > 1:
        parts.pop(int(rng.integers(len(parts))))
    else:
        parts.insert(int(rng.integers(len(parts) + 1)), b"0.5")
    lines[i] = sep.join(parts)
    return b"\n".join(lines)


def nested_brackets(data: bytes, rng: np.random.Generator) -> bytes:
    return data + b"\nx: " + b"[" * 10_000 + b"\n"


def duplicate_key(data: bytes, rng: np.random.Generator) -> bytes:
    lines = [ln for ln in _lines(data) if re.match(rb"^[a-z_]+:\s*\S", ln)]
    if not lines:
        return data
    return data + b"\n" + lines[int(rng.integers(len(lines)))] + b"\n"


def empty(data: bytes, rng: np.random.Generator) -> bytes:
    return b""


BYTE_MUTATORS: dict[str, Mutator] = {
    "bit_flip": bit_flip,
    "header_flip": header_flip,
    "truncate": truncate,
    "insert_bytes": insert_bytes,
    "delete_bytes": delete_bytes,
    "duplicate_line": duplicate_line,
    "huge_number": huge_number,
    "nan_inf": nan_inf,
    "non_utf8": non_utf8,
    "bom": bom,
    "crlf": crlf,
    "long_line": long_line,
    "column_change": column_change,
    "nested_brackets": nested_brackets,
    "duplicate_key": duplicate_key,
    "empty": empty,
}

# mutators that only make sense on text inputs (on binary ones they are just another byte edit)
TEXT_ONLY = {"duplicate_line", "huge_number", "nan_inf", "bom", "crlf", "long_line",
             "column_change", "nested_brackets", "duplicate_key"}


def make_fifo(path: Path) -> None:
    os.mkfifo(path)


def make_symlink_loop(path: Path) -> None:
    other = path.with_name(path.name + ".loop")
    os.symlink(other, path)
    os.symlink(path, other)


def make_folder(path: Path) -> None:
    path.mkdir()
    (path / "inside.txt").write_text("1 2 3\n")


PATH_MUTATORS: dict[str, Callable[[Path], None]] = {
    "fifo": make_fifo,
    "symlink_loop": make_symlink_loop,
    "folder": make_folder,
}
