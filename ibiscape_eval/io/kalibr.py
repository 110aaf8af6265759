"""Kalibr's YAML files: one reader and one writer for each (the types live in
:mod:`ibiscape_eval.core.kalibr`).

- target yaml (``target_type: checkerboard | aprilgrid`` and its keys): :func:`read_target` /
  :func:`write_target` -> :class:`~ibiscape_eval.core.kalibr.CalibrationTarget`;
- ``imu.yaml`` (noise densities, random walks, ``update_rate``, ``rostopic``): :func:`read_imu_noise`
  / :func:`write_imu_noise` -> :class:`~ibiscape_eval.core.kalibr.ImuNoise`.  The reader also takes
  our ``sequence.yaml`` (its ``imus`` section), an EuRoC IMU ``sensor.yaml`` and OpenVINS'
  ``kalibr_imu_chain.yaml`` (``imu0:`` nested);
- ``camchain.yaml`` and ``camchain-imucam.yaml`` (``cam0``, ``cam1``, ... each with
  ``camera_model``, ``intrinsics``, ``distortion_model``, ``distortion_coeffs``, ``resolution``,
  ``rostopic`` and, from ``cam1`` on, ``T_cn_cnm1``; with an IMU ``T_cam_imu`` and
  ``timeshift_cam_imu``): :func:`read_camchain` / :func:`write_camchain` ->
  :class:`~ibiscape_eval.core.kalibr.CameraChain`.  OpenVINS' ``T_imu_cam`` is read as the inverse
  of ``T_cam_imu``.

Files are parsed by :func:`ibiscape_eval.io.yaml_file.read_yaml` (plain or OpenCV ``%YAML:1.0``,
safe loader, duplicate keys refused) and written atomically (temp file, then rename); a malformed
file is a :class:`FormatError` naming the file and the key.  This module is also where the
calibration command's other outputs (JSON report, figures) are written, so that every output goes
through the project's atomic writer.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import FormatError, IbiscapeError
from ibiscape_eval.core.kalibr import CalibrationTarget, CameraChain, ChainCamera, ImuNoise

from .yaml_file import read_yaml_mapping

__all__ = [
    "imu_noise_from_document",
    "read_camchain",
    "read_imu_noise",
    "read_target",
    "write_camchain",
    "write_imu_noise",
    "write_json",
    "write_target",
]


def _dump(doc: Mapping[str, Any], comments: Sequence[str] = ()) -> str:
    """YAML text: lists of scalars in flow style (``[a, b]``), everything else block style; one
    ``# comment`` line per entry of ``comments`` first."""
    import yaml

    class _Dumper(yaml.SafeDumper):
        pass

    def _list(dumper: yaml.SafeDumper, data: list[Any]) -> Any:
        flow = all(not isinstance(v, list | dict) for v in data)
        return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)

    _Dumper.add_representer(list, _list)
    head = "".join(f"# {c}\n" for c in comments)
    return head + yaml.dump(dict(doc), Dumper=_Dumper, sort_keys=False)


# ============================================================================================ target
def read_target(path: str | os.PathLike[str]) -> CalibrationTarget:
    """Read a Kalibr target yaml (``target_type`` and its keys); FormatError naming the file and
    the missing or wrong key."""
    doc = read_yaml_mapping(path, what="Kalibr target yaml")
    if "target_type" not in doc:
        raise FormatError(path, "lacks the key target_type (checkerboard or aprilgrid); is it a "
                          "Kalibr target yaml?")
    try:
        return CalibrationTarget.from_kalibr(doc, source="target")
    except IbiscapeError as e:
        raise FormatError(path, str(e).removeprefix("target: ")) from None


def write_target(path: str | os.PathLike[str], target: CalibrationTarget) -> None:
    """Write a Kalibr target yaml atomically."""
    from .atomic import atomic_write  # tempfile, shutil: only when writing

    with atomic_write(path) as fh:
        fh.write(_dump(target.to_kalibr()))


# ========================================================================================= IMU noise
def imu_noise_from_document(doc: Any, source: str | os.PathLike[str]) -> ImuNoise:
    """The IMU noise of a parsed document: Kalibr's ``imu.yaml`` keys at the top, an EuRoC
    ``sensor.yaml`` (``rate_hz``), a ``sequence.yaml`` (``imus.imu0`` or its only IMU) or a chain
    of IMUs (``imu0:``, as OpenVINS writes it)."""
    src = str(source)
    if not isinstance(doc, Mapping):
        raise FormatError(src, "expected a mapping with the Kalibr IMU keys")
    if "gyroscope_noise_density" in doc or "accelerometer_noise_density" in doc:
        return ImuNoise.from_kalibr(doc, source=src)
    group, where = doc, ""
    if isinstance(doc.get("imus"), Mapping):
        group, where = doc["imus"], "imus."
    imus = {str(k): v for k, v in group.items() if isinstance(v, Mapping)
            and (where or str(k).startswith("imu"))}
    if not imus:
        return ImuNoise.from_kalibr(doc, source=src)  # names the missing keys
    if "imu0" in imus:
        name = "imu0"
    elif len(imus) == 1:
        name = next(iter(imus))
    else:
        raise FormatError(src, f"holds the IMUs {', '.join(imus)} and none is imu0; give the "
                          "imu.yaml of the IMU to use")
    return ImuNoise.from_kalibr(imus[name], source=f"{src}: {where}{name}")


def read_imu_noise(path: str | os.PathLike[str]) -> ImuNoise:
    """Read the IMU noise of a Kalibr ``imu.yaml`` (or of the files
    :func:`imu_noise_from_document` accepts); FormatError naming the file and the key."""
    return imu_noise_from_document(read_yaml_mapping(path, what="Kalibr imu.yaml"), path)


def write_imu_noise(path: str | os.PathLike[str], noise: ImuNoise, *,
                    comments: Sequence[str] = ()) -> None:
    """Write a Kalibr ``imu.yaml`` (continuous-time densities), atomically; ``comments`` become
    ``#`` lines at the top (e.g. the per-sample sigmas)."""
    import yaml

    doc = noise.to_kalibr()
    doc.setdefault("rostopic", "/imu0")
    doc["update_rate"] = doc.pop("update_rate")  # after rostopic, as Kalibr writes it
    from .atomic import atomic_write  # tempfile, shutil: only when writing

    with atomic_write(path) as fh:
        for c in comments:
            fh.write(f"# {c}\n")
        fh.write(yaml.safe_dump(doc, sort_keys=False))


# ====================================================================================== camera chain
def _matrix(value: Any, what: str) -> npt.NDArray[np.float64]:
    """A 4x4 from a nested list, an ``!!opencv-matrix`` array or ``{rows, cols, data}``."""
    if isinstance(value, Mapping) and "data" in value:
        value = value["data"]
    try:
        T = np.array(value, dtype=np.float64).reshape(4, 4)
    except (TypeError, ValueError, OverflowError):
        raise IbiscapeError(f"{what}: must be a 4x4 matrix (16 numbers)") from None
    return T


def _chain_camera(entry: Any, key: str) -> ChainCamera:
    if not isinstance(entry, Mapping):
        raise IbiscapeError(f"{key}: expected a mapping of camera keys")
    for k in ("intrinsics", "resolution"):
        if k not in entry:
            raise IbiscapeError(f"{key}: lacks the key {k!r}")
    try:
        cam = CameraModel.from_kalibr(dict(entry))
    except IbiscapeError as e:
        raise IbiscapeError(f"{key}: {e}") from None
    except OverflowError:  # int(inf)
        raise IbiscapeError(f"{key}: intrinsics [fu, fv, pu, pv] and resolution [w, h] must be "
                            "finite numbers") from None
    T_cn = _matrix(entry["T_cn_cnm1"], f"{key}.T_cn_cnm1") if "T_cn_cnm1" in entry else None
    T_ci = _matrix(entry["T_cam_imu"], f"{key}.T_cam_imu") if "T_cam_imu" in entry else None
    if "T_imu_cam" in entry:  # OpenVINS writes the inverse
        T_ic = _matrix(entry["T_imu_cam"], f"{key}.T_imu_cam")
        from ibiscape_eval.core.kalibr import rigid_transform_problem

        problem = rigid_transform_problem(T_ic)
        if problem:
            raise IbiscapeError(f"{key}.T_imu_cam: {problem}")
        inv = np.asarray(np.linalg.inv(T_ic), dtype=np.float64)
        if T_ci is not None and not np.allclose(T_ci, inv, atol=1e-6):
            raise IbiscapeError(f"{key}: T_cam_imu and T_imu_cam are not inverses of each other; "
                                "keep one of them")
        T_ci = inv if T_ci is None else T_ci
    shift = entry.get("timeshift_cam_imu")
    if shift is not None:
        try:
            if isinstance(shift, bool):
                raise ValueError
            shift = float(shift)
        except (TypeError, ValueError, OverflowError):
            raise IbiscapeError(f"{key}.timeshift_cam_imu = {shift!r} is not a number (seconds)") from None
    topic = entry.get("rostopic")
    return ChainCamera(key, cam, T_cn, T_ci, shift, None if topic is None else str(topic))


def read_camchain(path: str | os.PathLike[str]) -> CameraChain:
    """Read a Kalibr ``camchain.yaml`` or ``camchain-imucam.yaml`` (keys ``cam0``, ``cam1``, ...
    in order); FormatError naming the file and the camera's key."""
    doc = read_yaml_mapping(path, what="Kalibr camchain")
    keys = sorted((k for k in doc if isinstance(k, str) and k.startswith("cam") and k[3:].isdigit()),
                  key=lambda k: int(k[3:]))
    if not keys:
        raise FormatError(path, "holds no cam0, cam1, ... entries; is it a Kalibr camchain.yaml?")
    if keys != [f"cam{i}" for i in range(len(keys))]:
        raise FormatError(path, f"cameras must be numbered cam0, cam1, ... without gaps, got {keys}")
    cams = []
    for k in keys:
        try:
            cams.append(_chain_camera(doc[k], k))
        except IbiscapeError as e:
            raise FormatError(path, str(e)) from None
    try:
        return CameraChain(tuple(cams))
    except IbiscapeError as e:
        raise FormatError(path, str(e)) from None


def _camchain_doc(chain: CameraChain) -> dict[str, Any]:
    def rows(T: npt.NDArray[np.float64]) -> list[list[float]]:
        return [[float(v) for v in row] for row in T]

    doc: dict[str, Any] = {}
    for i, c in enumerate(chain.cameras):
        entry = c.camera.to_kalibr()
        if c.T_cam_imu is not None:
            entry["T_cam_imu"] = rows(c.T_cam_imu)
        if c.timeshift_cam_imu_s is not None:
            entry["timeshift_cam_imu"] = float(c.timeshift_cam_imu_s)
        if i > 0 and c.T_cn_cnm1 is not None:
            entry["T_cn_cnm1"] = rows(c.T_cn_cnm1)
        entry["rostopic"] = c.rostopic if c.rostopic is not None else f"/cam{i}/image_raw"
        doc[f"cam{i}"] = entry
    return doc


def write_camchain(path: str | os.PathLike[str], chain: CameraChain, *,
                   comments: Sequence[str] = ()) -> None:
    """Write a Kalibr ``camchain.yaml`` (or ``camchain-imucam.yaml`` when the chain has
    ``T_cam_imu``) atomically: ``cam0``, ``cam1``, ... in chain order, 4x4 matrices one row per
    line, ``comments`` as ``#`` lines at the top."""
    from .atomic import atomic_write  # tempfile, shutil: only when writing

    with atomic_write(path) as fh:
        fh.write(_dump(_camchain_doc(chain), comments))


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
    from .atomic import atomic_write  # tempfile, shutil: only when writing

    with atomic_write(path, "w") as f:
        f.write(text + "\n")


