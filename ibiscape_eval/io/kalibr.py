"""Kalibr's YAML files: the target description and the camera chain (``camchain.yaml``).

- target yaml (``target_type: checkerboard | aprilgrid`` and its keys): :func:`read_target_yaml`;
- ``camchain.yaml`` (``cam0``, ``cam1``, ... each with ``camera_model``, ``intrinsics``,
  ``distortion_model``, ``distortion_coeffs``, ``resolution``, ``rostopic`` and, from ``cam1`` on,
  ``T_cn_cnm1``: the 4x4 transform from camera n-1 to camera n): :func:`read_camchain` /
  :func:`write_camchain`.

Files are parsed with ``yaml.safe_load`` only and written atomically (temp file, then rename).
This module is also where the calibration command's other outputs (JSON report, figures) are
written, so that every output goes through the project's atomic writer.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError, IbiscapeError

from .atomic import atomic_output_path, atomic_write

__all__ = [
    "CameraChain",
    "camchain_document",
    "read_camchain",
    "read_target_yaml",
    "read_yaml_mapping",
    "write_camchain",
    "write_figure",
    "write_figures",
    "write_json",
]


@dataclass(frozen=True, eq=False)
class CameraChain:
    """Cameras of a rig in chain order.

    Attributes
    ----------
    names : tuple of str
        ``cam0``, ``cam1``, ... (or the sensor names of the sequence).
    cameras : tuple of CameraModel
    T_cn_cnm1 : tuple of ndarray (4, 4)
        One per camera after the first: maps camera n-1 coordinates to camera n.
    rostopics : tuple of str
    """

    names: tuple[str, ...]
    cameras: tuple[CameraModel, ...]
    T_cn_cnm1: tuple[npt.NDArray[np.float64], ...]
    rostopics: tuple[str, ...]

    def __post_init__(self) -> None:
        n = len(self.cameras)
        if len(self.names) != n or len(self.rostopics) != n or len(self.T_cn_cnm1) != max(n - 1, 0):
            raise IbiscapeError("camera chain: names, cameras, rostopics and n-1 transforms needed")

    def T_cn_c0(self, n: int) -> npt.NDArray[np.float64]:
        """Transform from camera 0 to camera n (product of the chain)."""
        T = np.eye(4)
        for k in range(n):
            T = self.T_cn_cnm1[k] @ T
        return T

    def __repr__(self) -> str:
        return f"CameraChain({', '.join(self.names)})"


def read_yaml_mapping(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A YAML file that must hold a mapping (through :func:`ibiscape_eval.io.paths.safe_yaml`: checked
    path, UTF-8, bounded size and depth, ``yaml.safe_load``); FormatError naming the file otherwise."""
    from .paths import safe_yaml

    doc = safe_yaml(path)
    if not isinstance(doc, dict):
        raise FormatError(path, f"expected a YAML mapping, got {type(doc).__name__}")
    return doc


def read_target_yaml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a Kalibr target yaml: the mapping with ``target_type`` and its keys.

    The keys are checked by :func:`ibiscape_eval.calib.targets.target_from_kalibr`; here only that
    the file is YAML and names a ``target_type``.
    """
    doc = read_yaml_mapping(path)
    if "target_type" not in doc:
        raise FormatError(path, "lacks the key target_type (checkerboard or aprilgrid); is it a "
                          "Kalibr target yaml?")
    return doc


def _matrix(value: Any, where: str) -> npt.NDArray[np.float64]:
    try:
        T = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise IbiscapeError(f"{where}: T_cn_cnm1 must be a 4x4 list of numbers") from None
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise IbiscapeError(f"{where}: T_cn_cnm1 must be a finite 4x4 matrix, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise IbiscapeError(f"{where}: T_cn_cnm1's rotation block is not a rotation matrix")
    return T


def read_camchain(path: str | os.PathLike[str]) -> CameraChain:
    """Read a Kalibr ``camchain.yaml`` (keys ``cam0``, ``cam1``, ... in order)."""
    doc = read_yaml_mapping(path)
    keys = sorted((k for k in doc if isinstance(k, str) and k.startswith("cam") and k[3:].isdigit()),
                  key=lambda k: int(k[3:]))
    if not keys:
        raise FormatError(path, "holds no cam0, cam1, ... entries; is it a Kalibr camchain.yaml?")
    if keys != [f"cam{i}" for i in range(len(keys))]:
        raise FormatError(path, f"cameras must be numbered cam0, cam1, ... without gaps, got {keys}")
    cams, Ts, topics = [], [], []
    for i, k in enumerate(keys):
        entry = doc[k]
        if not isinstance(entry, dict):
            raise FormatError(path, f"{k}: expected a mapping of camera keys")
        try:
            cams.append(CameraModel.from_kalibr(entry))
            if i > 0:
                if "T_cn_cnm1" not in entry:
                    raise IbiscapeError("lacks the key 'T_cn_cnm1' (transform from the previous camera)")
                Ts.append(_matrix(entry["T_cn_cnm1"], k))
        except IbiscapeError as e:
            raise FormatError(path, f"{k}: {e}") from None
        topics.append(str(entry.get("rostopic", f"/{k}/image_raw")))
    return CameraChain(tuple(keys), tuple(cams), tuple(Ts), tuple(topics))


def camchain_document(chain: CameraChain) -> dict[str, Any]:
    """The ``camchain.yaml`` mapping of a chain."""
    doc: dict[str, Any] = {}
    for i, cam in enumerate(chain.cameras):
        entry = cam.to_kalibr()
        if i > 0:
            entry["T_cn_cnm1"] = [[float(v) for v in row] for row in chain.T_cn_cnm1[i - 1]]
        entry["rostopic"] = chain.rostopics[i]
        doc[f"cam{i}"] = entry
    return doc


def write_camchain(path: str | os.PathLike[str], chain: CameraChain) -> None:
    """Write a Kalibr ``camchain.yaml`` atomically (``cam0``, ``cam1``, ... in chain order)."""
    import yaml

    text = yaml.safe_dump(camchain_document(chain), sort_keys=False, default_flow_style=None)
    with atomic_write(path, "w") as f:
        f.write(text)


def _strict(o: Any) -> Any:
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, np.ndarray):
        return _strict(o.tolist())
    if isinstance(o, np.generic):
        return _strict(o.item())
    if isinstance(o, dict):
        return {str(k): _strict(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [_strict(v) for v in o]
    return o


def write_json(path: str | os.PathLike[str], doc: Any) -> None:
    """Write a strict JSON document (NaN/Infinity as null) atomically."""
    text = json.dumps(_strict(doc), indent=2, allow_nan=False)
    with atomic_write(path, "w") as f:
        f.write(text + "\n")


def write_figure(path: str | os.PathLike[str], fig: Any, *, dpi: int = 110) -> None:
    """Save a matplotlib ``Figure`` atomically (format from the suffix)."""
    with atomic_output_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=Path(path).suffix.lstrip(".") or "png")


def write_figures(folder: str | os.PathLike[str], figures: Sequence[tuple[str, Any]]) -> list[Path]:
    """Save ``(file name, Figure)`` pairs into ``folder`` (created), each atomically."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, fig in figures:
        write_figure(out / name, fig)
        paths.append(out / name)
    return paths
