"""The one YAML reader: plain YAML and OpenCV ``FileStorage`` YAML alike.

OpenCV writes (and ORB-SLAM3, VINS-Fusion, Kimera, OpenVINS and EuRoC's ``sensor.yaml`` copy) a
dialect PyYAML refuses as it comes:

- a ``%YAML:1.0`` first line (YAML wants ``%YAML 1.0``): dropped (kept as an empty line, so line
  numbers in messages stay the file's);
- ``!!opencv-matrix`` mappings ``{rows, cols, dt, data}``: returned as a ``numpy`` array of shape
  ``(rows, cols)`` and the element type ``dt`` names (``u c w s i f d`` = uint8, int8, uint16,
  int16, int32, float32, float64), as ``cv2.FileStorage(...).getNode(key).mat()`` gives;
- in files with that header only (OpenCV's own parser accepts it): ``key:value`` without a space
  after the colon;
- numbers such as ``1e-3`` (no decimal point), which YAML 1.1 reads as a string.

Every file is parsed by a ``yaml.SafeLoader`` subclass (no Python objects are ever built),
refuses duplicate keys (YAML keeps the last one silently; a calibration file with two
``T_cam_imu`` is ambiguous) and reports every failure as one :class:`FormatError` naming the file
and line.
"""

from __future__ import annotations

import os
import re
from typing import Any

import numpy as np

from ibiscape_eval.core.errors import FormatError

__all__ = ["OPENCV_DTYPES", "read_yaml", "read_yaml_mapping"]

#: OpenCV ``dt`` letters -> numpy element types
OPENCV_DTYPES = {"u": np.uint8, "c": np.int8, "w": np.uint16, "s": np.int16, "i": np.int32,
                 "f": np.float32, "d": np.float64}

_HEADER = re.compile(r"^\s*%YAML:\d+(\.\d+)?[ \t]*$")
# ``key:value`` at the start of a line (OpenCV accepts it, YAML reads one plain scalar)
_NO_SPACE_KEY = re.compile(r"^(\s*[A-Za-z_][\w.\-]*):(?=[^\s:/])", re.MULTILINE)
# a number with an exponent and no decimal point (YAML 1.1 reads ``1e-3`` as a string)
_EXP_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$")
_MAX_BYTES = 16 << 20


def _loader_class() -> type:
    import yaml

    class _Loader(yaml.SafeLoader):
        """SafeLoader + duplicate-key refusal + ``!!opencv-matrix`` + ``1e-3`` floats."""

    def _mapping(loader: Any, node: Any, deep: bool = False) -> Any:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = loader.construct_object(key_node, deep=True)
            try:
                hash(key)
            except TypeError:
                continue  # the base constructor reports unhashable keys
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r} (first on line {seen[key] + 1})",
                    key_node.start_mark)
            seen[key] = key_node.start_mark.line
        loader.flatten_mapping(node)
        return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)

    def _map_node(loader: Any, node: Any) -> Any:
        data: dict[Any, Any] = {}
        yield data
        data.update(_mapping(loader, node))

    def _opencv_matrix(loader: Any, node: Any) -> Any:
        doc = _mapping(loader, node, deep=True)
        mark = node.start_mark
        for key_node, value_node in node.value:  # point at the data (or its bad element)
            if getattr(key_node, "value", None) == "data":
                mark = value_node.start_mark
                for item in getattr(value_node, "value", None) or []:
                    if isinstance(getattr(item, "value", None), str) and len(item.value.split()) > 1:
                        mark = item.start_mark
                        break
        return _matrix_of(doc, mark)

    _Loader.add_constructor("tag:yaml.org,2002:map", _map_node)
    _Loader.add_constructor("tag:yaml.org,2002:opencv-matrix", _opencv_matrix)
    _Loader.add_implicit_resolver(
        "tag:yaml.org,2002:float", _EXP_FLOAT, list("-+0123456789"))
    return _Loader


def _matrix_of(doc: Any, mark: Any) -> np.ndarray:
    import yaml

    def bad(what: str) -> yaml.constructor.ConstructorError:
        return yaml.constructor.ConstructorError(None, None, f"!!opencv-matrix: {what}", mark)

    if not isinstance(doc, dict) or not {"rows", "cols", "data"} <= set(doc):
        raise bad("needs the keys rows, cols, dt and data")
    rows, cols, dt = doc["rows"], doc["cols"], str(doc.get("dt", "d"))
    if (isinstance(rows, bool) or isinstance(cols, bool) or not isinstance(rows, int)
            or not isinstance(cols, int) or rows < 0 or cols < 0):
        raise bad(f"rows and cols must be counts, got {rows!r}, {cols!r}")
    if dt not in OPENCV_DTYPES:
        raise bad(f"dt {dt!r} is not one of {', '.join(OPENCV_DTYPES)} (multi-channel "
                  "matrices are not read)")
    data = doc["data"]
    if not isinstance(data, list):
        data = [data]
    if any(isinstance(v, str) and len(v.split()) > 1 for v in data):
        # "0.0\n 0.0" is one YAML scalar; OpenCV refuses it too ("Missing , between the elements")
        raise bad("data lacks a comma between two numbers (at a line break?); add it")
    try:
        if any(isinstance(v, bool | str) for v in data):
            raise ValueError
        arr = np.array([float(v) for v in data], dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise bad("data must be numbers") from None
    if arr.size != rows * cols:
        raise bad(f"rows x cols = {rows} x {cols} but data holds {arr.size} numbers")
    return arr.reshape(rows, cols).astype(OPENCV_DTYPES[dt])


def _opencv_text(text: str) -> str:
    """Blank the ``%YAML:1.0`` line; in such files accept ``key:value`` (OpenCV does)."""
    first, sep, rest = text.partition("\n")
    if not _HEADER.match(first):
        return text
    return sep + _NO_SPACE_KEY.sub(r"\1: ", rest)


def read_yaml(path: str | os.PathLike[str], *, what: str = "") -> Any:
    """Parse a YAML file (plain or OpenCV ``%YAML:1.0``) into Python values.

    Parameters
    ----------
    path : path
    what : str
        What the file should be (for the not-found message), e.g. ``"Kalibr imu.yaml"``.

    Returns
    -------
    The document: mappings, lists, scalars; ``!!opencv-matrix`` nodes as ndarrays.

    Raises
    ------
    FormatError
        Not UTF-8, larger than 16 MiB, not valid YAML, nested too deeply, a duplicate key or a
        malformed ``!!opencv-matrix`` (naming the file and line).
    """
    import yaml

    from .paths import read_text

    text = read_text(path, what=what, max_bytes=_MAX_BYTES)
    try:
        return yaml.load(_opencv_text(text), Loader=_LOADER())
    except RecursionError:
        raise FormatError(path, "YAML nested too deeply") from None
    except ValueError as e:  # e.g. an integer of more than 4300 digits
        raise FormatError(path, f"not valid YAML ({' '.join(str(e).split())[:200]})") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        problem = getattr(e, "problem", None)
        text = problem if isinstance(e, yaml.constructor.ConstructorError) and problem else str(e)
        msg = f"not valid YAML ({' '.join(str(text).split())[:200]})"
        raise FormatError(path, msg, line=None if mark is None else mark.line + 1) from None


def read_yaml_mapping(path: str | os.PathLike[str], *, what: str = "") -> dict[str, Any]:
    """:func:`read_yaml` of a file that must hold a mapping at the top level."""
    doc = read_yaml(path, what=what)
    if not isinstance(doc, dict):
        raise FormatError(path, f"expected a YAML mapping{f' ({what})' if what else ''}, got "
                          f"{type(doc).__name__}")
    return doc


_CACHE: list[type] = []


def _LOADER() -> type:
    if not _CACHE:
        _CACHE.append(_loader_class())
    return _CACHE[0]
