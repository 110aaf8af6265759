"""Export a finished IBISCape-layout sequence for other tools.

``export_sequence(seq_dir, fmt, out)`` reads the sequence through the project's readers
(``sequence.yaml``, ground truth and IMUs converted from CARLA's left-handed frame, camera
``timestamps.csv`` and PNG frames) and writes, atomically (a staging copy renamed into place):

``euroc``
    EuRoC/ASL folder (``mav0/cam0``, ``cam1``, ``imu0`` ..., ``state_groundtruth_estimate0``,
    ``sensor.yaml`` files) for ORB-SLAM3, BASALT, VINS-Fusion and OpenVINS.  Cameras: the stereo
    RGB pair (``rgbL`` -> cam0, ``rgbR`` -> cam1), or the DVS cameras' accumulated event frames
    when the setup has no RGB camera (``cameras=`` picks others); images in 8-bit grey (BASALT reads grey only).  Body frame B =
    the vehicle body (IMU0), ``T_BS = T_body_sensor``; ground truth ``T_world_body`` with world
    velocity; the bias columns are 0 (the simulator's turn-on biases are constants the file does
    not record).
``tum-rgbd``
    TUM RGB-D folder (``rgb/``, ``depth/`` 16-bit millimetres, ``rgb.txt``, ``depth.txt``,
    ``groundtruth.txt`` = pose of the RGB camera's optical frame ``T_world_cam``,
    ``association.txt``) for ORB-SLAM3's ``rgbd_tum`` (``DepthMapFactor: 1000``).
``rosbag``
    ROS 1 bag (``rosbags``): ``/cam0/image_raw`` ... (``rgb8`` colour, ``mono8`` DVS frames) and
    ``/imu0`` ... ``sensor_msgs/Imu``, so Kalibr users can run ``kalibr_calibrate_cameras`` and
    ``kalibr_calibrate_imu_camera`` on the calibration sequences.

Bad input raises :class:`IbiscapeError` with one line naming the file and what to do: a format
the setup cannot fill (RGB-D of an SVI sequence, images of an unrendered sequence), not enough
disk space (checked before writing, and a full disk while writing leaves nothing behind).
"""

from __future__ import annotations

import errno
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import FormatError, IbiscapeError

__all__ = ["EXPORT_FORMATS", "ExportSummary", "export_sequence"]

EXPORT_FORMATS = ("euroc", "tum-rgbd", "rosbag")
Progress = Callable[[float, str], None]


@dataclass(frozen=True)
class ExportSummary:
    """What an export wrote.

    Attributes
    ----------
    fmt : str
    path : str
        The export folder (euroc, tum-rgbd) or bag file.
    cameras : dict
        Source camera -> exported name (``cam0``, ``rgb``, ``/cam0/image_raw`` ...).
    imus : dict
        Source IMU -> exported name.
    n_images : int
        Images written (all cameras; depth included).
    n_imu_samples : int
    n_groundtruth : int
    bytes_written : int
    """

    fmt: str
    path: str
    cameras: dict[str, str] = field(default_factory=dict)
    imus: dict[str, str] = field(default_factory=dict)
    n_images: int = 0
    n_imu_samples: int = 0
    n_groundtruth: int = 0
    bytes_written: int = 0

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping (strict JSON)."""
        return {"fmt": self.fmt, "path": self.path, "cameras": dict(self.cameras),
                "imus": dict(self.imus), "n_images": self.n_images,
                "n_imu_samples": self.n_imu_samples, "n_groundtruth": self.n_groundtruth,
                "bytes_written": self.bytes_written}

    def __repr__(self) -> str:
        return (f"ExportSummary({self.fmt} -> {self.path}: {self.n_images} images, "
                f"{self.n_imu_samples} IMU samples, {self.n_groundtruth} poses)")


# ---------------------------------------------------------------------------------------------
# reading the sequence


@dataclass(frozen=True)
class _Camera:
    name: str
    kind: str
    entry: dict[str, Any]
    stamps_ns: npt.NDArray[np.int64]
    paths: list[Path]


def _camera_frames(seq: Path, name: str, entry: dict[str, Any]) -> _Camera | None:
    from ibiscape_eval.io.dvs_folder import read_dvs_frame_list
    from ibiscape_eval.io.images import read_frame_timestamps

    kind = str(entry.get("kind", "rgb"))
    folder = seq / name
    if kind == "dvs":
        if not (folder / "frames" / "timestamps.csv").is_file():
            return None
        st, paths = read_dvs_frame_list(folder)
    else:
        if not (folder / "timestamps.csv").is_file():
            return None
        st, names = read_frame_timestamps(folder / "timestamps.csv")
        paths = [folder / "frames" / n for n in names]
        mm = [folder / "mm" / n for n in names]
        if kind == "depth" and mm and all(p.is_file() for p in mm):
            paths = mm  # the exact 16-bit millimetre copy beside CARLA's 8-bit log depth
    if st.size == 0:
        return None
    missing = next((p for p in paths if not p.is_file()), None)
    if missing is not None:
        raise FormatError(missing, "listed in timestamps.csv but missing; re-render the sequence")
    return _Camera(name, kind, entry, st, paths)


def _read(seq: Path) -> tuple[dict[str, Any], dict[str, _Camera]]:
    from ibiscape_eval.io.sequence import read_sequence_yaml

    yml = seq / "sequence.yaml"
    if not seq.is_dir():
        raise IbiscapeError(f"{seq}: no such sequence folder; give a folder written by "
                            "ibiscape-eval sim")
    if not yml.is_file():
        raise FormatError(yml, "not found: export needs a sequence written by ibiscape-eval sim")
    doc = read_sequence_yaml(yml)
    cams: dict[str, _Camera] = {}
    for name, entry in (doc.get("cameras") or {}).items():
        c = _camera_frames(seq, str(name), entry)
        if c is not None:
            cams[str(name)] = c
    return doc, cams


def _pick_cameras(doc: dict[str, Any], cams: dict[str, _Camera], wanted: list[str] | None,
                  fmt: str, seq: Path) -> list[_Camera]:
    setup = doc.get("generator", {}).get("setup", "?")
    if wanted:
        out = []
        for n in wanted:
            if n not in cams:
                listed = ", ".join(cams) or "none has rendered frames"
                raise IbiscapeError(f"{seq}: camera {n!r} has no rendered frames (cameras with "
                                    f"frames: {listed})")
            out.append(cams[n])
        return out
    rgb = [c for c in cams.values() if c.kind == "rgb"]
    dvs = [c for c in cams.values() if c.kind == "dvs"]
    chosen = (rgb or dvs)[:2]  # the stereo pair (the RGB-D camera of "full" is the third RGB)
    if not chosen:
        configured = ", ".join(doc.get("cameras") or {}) or "no cameras"
        raise IbiscapeError(f"{seq}: {fmt} export needs camera images, but this {setup} sequence "
                            f"has no rendered RGB or DVS frames ({configured}); generate it with "
                            "rendering, or export another sequence")
    return chosen


@dataclass(frozen=True, eq=False)
class _Imu:
    name: str
    entry: dict[str, Any]
    stamps_ns: npt.NDArray[np.int64]
    gyro_rad_s: npt.NDArray[np.float64]
    accel_m_s2: npt.NDArray[np.float64]


def _imus(seq: Path, doc: dict[str, Any]) -> list[_Imu]:
    from ibiscape_eval.io.asl import read_imu_samples

    out = []
    for name, entry in (doc.get("imus") or {}).items():
        f = seq / str(entry.get("file", ""))
        if not f.is_file():
            raise FormatError(f, f"IMU {name} listed in sequence.yaml but its file is missing")
        if f.suffix != ".csv":
            raise IbiscapeError(f"{f}: only csv IMU files can be exported (a still-IMU .npy "
                                "sequence has no camera to export anyway)")
        st, g, a = read_imu_samples(f, frame="ibiscape")
        out.append(_Imu(str(name), entry, st, g, a))
    return out


def _groundtruth(seq: Path, doc: dict[str, Any]) -> Any:
    from ibiscape_eval.io.ibiscape import read_ibiscape_groundtruth

    rel = (doc.get("files") or {}).get("groundtruth") or "vehicle_gt/groundtruth_sync.csv"
    return read_ibiscape_groundtruth(seq / rel)


# ---------------------------------------------------------------------------------------------
# disk space and errors


def _existing_parent(p: Path) -> Path:
    q = p.absolute().parent
    while not q.exists():
        q = q.parent
    return q


def _check_space(out: Path, need_bytes: int) -> None:
    free = shutil.disk_usage(_existing_parent(out)).free
    if need_bytes > free:
        raise IbiscapeError(f"{out}: not enough disk space: the export needs about "
                            f"{need_bytes / 1e6:.1f} MB and {free / 1e6:.1f} MB are free; free "
                            "some space or choose another --out")


def _disk_full(out: Path, e: OSError) -> IbiscapeError:
    return IbiscapeError(f"{out}: the disk filled up while writing the export ({e.strerror}); "
                         "nothing was written; free some space or choose another --out")


def _gray(img: np.ndarray) -> npt.NDArray[np.uint8]:
    import cv2

    a = np.asarray(img)
    if a.dtype != np.uint8:
        raise IbiscapeError(f"expected 8-bit camera images, got {a.dtype}")
    if a.ndim == 3:
        a = cv2.cvtColor(np.ascontiguousarray(a[..., :3]), cv2.COLOR_RGB2GRAY)
    return np.ascontiguousarray(a)


def _folder_bytes(p: Path) -> int:
    if p.is_file():
        return p.stat().st_size
    return sum(f.stat().st_size for f in p.rglob("*") if f.is_file())


# ---------------------------------------------------------------------------------------------
# formats


def _export_euroc(seq: Path, doc: dict[str, Any], cams: list[_Camera], tmp: Path,
                  step: Progress) -> dict[str, Any]:
    from ibiscape_eval.io.asl import (
        AslGroundTruth,
        write_asl_groundtruth,
        write_asl_image_list,
        write_asl_imu,
        write_asl_sensor_yaml,
    )
    from ibiscape_eval.io.images import read_png, write_png

    mav = tmp / "mav0"
    names: dict[str, str] = {}
    n_img = 0
    total = sum(len(c.paths) for c in cams) or 1
    for i, c in enumerate(cams):
        cam_dir = mav / f"cam{i}"
        (cam_dir / "data").mkdir(parents=True)
        for t, p in zip(c.stamps_ns, c.paths, strict=True):
            write_png(cam_dir / "data" / f"{int(t)}.png", _gray(read_png(p)))
            n_img += 1
            if n_img % 20 == 0:
                step(0.8 * n_img / total, "images")
        write_asl_image_list(cam_dir / "data.csv", c.stamps_ns)
        e = c.entry
        dist = "radial-tangential" if e.get("distortion_model", "radtan") == "radtan" else \
            str(e.get("distortion_model"))
        write_asl_sensor_yaml(cam_dir / "sensor.yaml", sensor_type="camera",
                              comment=f"ibiscape-eval sim {c.name} ({c.kind})",
                              T_BS=e["T_body_cam"], fields={
                                  "rate_hz": float(e.get("rate_hz", 20.0)),
                                  "resolution": [int(v) for v in e["resolution"]],
                                  "camera_model": str(e.get("camera_model", "pinhole")),
                                  "intrinsics": [float(v) for v in e["intrinsics"]],
                                  "distortion_model": dist,
                                  "distortion_coefficients": [
                                      float(v) for v in e.get("distortion_coeffs", [0, 0, 0, 0])]})
        names[c.name] = f"cam{i}"
    step(0.8, "imu")
    imus: dict[str, str] = {}
    n_imu = 0
    for imu in _imus(seq, doc):
        name, entry, st = imu.name, imu.entry, imu.stamps_ns
        d = mav / name
        d.mkdir(parents=True)
        write_asl_imu(d / "data.csv", st, imu.gyro_rad_s, imu.accel_m_s2)
        write_asl_sensor_yaml(d / "sensor.yaml", sensor_type="imu",
                              comment=f"ibiscape-eval sim {name}", T_BS=entry["T_body_imu"],
                              fields={"rate_hz": float(entry["update_rate"]),
                                      "gyroscope_noise_density": float(entry["gyroscope_noise_density"]),
                                      "gyroscope_random_walk": float(entry["gyroscope_random_walk"]),
                                      "accelerometer_noise_density": float(
                                          entry["accelerometer_noise_density"]),
                                      "accelerometer_random_walk": float(
                                          entry["accelerometer_random_walk"])})
        imus[name] = name
        n_imu += len(st)
    step(0.9, "ground truth")
    gt = _groundtruth(seq, doc)
    zeros = np.zeros((len(gt), 3))
    d = mav / "state_groundtruth_estimate0"
    d.mkdir(parents=True)
    write_asl_groundtruth(d / "data.csv", AslGroundTruth(gt.trajectory, gt.vel_m_s, zeros, zeros))
    write_asl_sensor_yaml(d / "sensor.yaml", sensor_type="visual-inertial",
                          comment="ground truth of the body (IMU0) in the world frame (ENU)",
                          T_BS=np.eye(4), fields={})
    return {"cameras": names, "imus": imus, "n_images": n_img, "n_imu_samples": n_imu,
            "n_groundtruth": len(gt)}


def _rgbd_pair(doc: dict[str, Any], cams: dict[str, _Camera], seq: Path) -> tuple[_Camera, _Camera]:
    rgb = [c for c in cams.values() if c.kind == "rgb"]
    depth = [c for c in cams.values() if c.kind == "depth"]
    setup = doc.get("generator", {}).get("setup", "?")
    if not depth:
        have = ", ".join(f"{n} ({c.get('kind')})" for n, c in (doc.get("cameras") or {}).items())
        raise IbiscapeError(f"{seq}: tum-rgbd export needs a rendered depth camera, but this "
                            f"{setup} sequence has {have or 'no cameras'}; export an rgbd or "
                            "full sequence, or use --export euroc")
    d = depth[0]
    mount = d.entry.get("T_body_cam")
    same = [c for c in rgb if np.allclose(np.asarray(c.entry.get("T_body_cam"), float),
                                          np.asarray(mount, float))]
    pick = same or rgb
    if not pick:
        raise IbiscapeError(f"{seq}: tum-rgbd export needs a rendered RGB camera beside the depth "
                            f"camera {d.name}")
    return pick[0], d


def _read_depth_m(path: Path) -> np.ndarray:
    from ibiscape_eval.io.images import read_depth_carla_log, read_depth_mm, read_png

    img = read_png(path)
    if img.dtype == np.uint16:
        return read_depth_mm(path)
    return read_depth_carla_log(path)


def _export_tum(seq: Path, doc: dict[str, Any], cams: dict[str, _Camera], tmp: Path,
                step: Progress) -> dict[str, Any]:
    from ibiscape_eval.core.trajectory import Trajectory
    from ibiscape_eval.io.images import read_png, write_depth_mm, write_png
    from ibiscape_eval.io.tum import write_tum
    from ibiscape_eval.io.tum_rgbd import stamp_text, write_association, write_tum_list

    rgb, depth = _rgbd_pair(doc, cams, seq)
    (tmp / "rgb").mkdir()
    (tmp / "depth").mkdir()
    rgb_files = [f"rgb/{s}.png" for s in stamp_text(rgb.stamps_ns)]
    depth_files = [f"depth/{s}.png" for s in stamp_text(depth.stamps_ns)]
    total = len(rgb_files) + len(depth_files)
    n = 0
    for p, f in zip(rgb.paths, rgb_files, strict=True):
        img = read_png(p)
        write_png(tmp / f, img if img.ndim == 3 else np.repeat(img[..., None], 3, axis=2))
        n += 1
        if n % 20 == 0:
            step(0.9 * n / total, "rgb")
    for p, f in zip(depth.paths, depth_files, strict=True):
        write_depth_mm(tmp / f, _read_depth_m(p))
        n += 1
        if n % 20 == 0:
            step(0.9 * n / total, "depth")
    write_tum_list(tmp / "rgb.txt", rgb.stamps_ns, rgb_files, what="color images")
    write_tum_list(tmp / "depth.txt", depth.stamps_ns, depth_files,
                   what="depth maps (16-bit PNG, millimetres: DepthMapFactor 1000)")
    # pairs: equal stamps (one RGB-D mount), else the nearest depth within 20 ms
    j = np.clip(np.searchsorted(depth.stamps_ns, rgb.stamps_ns), 1, max(len(depth.stamps_ns) - 1, 1))
    j0 = np.clip(j - 1, 0, len(depth.stamps_ns) - 1)
    j1 = np.clip(j, 0, len(depth.stamps_ns) - 1)
    near = np.where(np.abs(depth.stamps_ns[j0] - rgb.stamps_ns) <= np.abs(depth.stamps_ns[j1]
                                                                         - rgb.stamps_ns), j0, j1)
    ok = np.abs(depth.stamps_ns[near] - rgb.stamps_ns) <= 20_000_000
    write_association(tmp / "association.txt", rgb.stamps_ns[ok],
                      [f for f, k in zip(rgb_files, ok, strict=True) if k],
                      depth.stamps_ns[near[ok]], [depth_files[i] for i in near[ok]])
    gt = _groundtruth(seq, doc)
    T_wc = gt.trajectory.matrices() @ np.asarray(rgb.entry["T_body_cam"], dtype=np.float64)
    write_tum(tmp / "groundtruth.txt",
              Trajectory.from_matrices(gt.trajectory.stamps_ns, T_wc, "groundtruth"))
    return {"cameras": {rgb.name: "rgb", depth.name: "depth"}, "imus": {},
            "n_images": total, "n_imu_samples": 0, "n_groundtruth": len(gt)}


def _export_rosbag(seq: Path, doc: dict[str, Any], cams: list[_Camera], bag: Path,
                   step: Progress, *, overwrite: bool = False) -> dict[str, Any]:
    from ibiscape_eval.io.images import read_png
    from ibiscape_eval.io.rosbag_export import RosbagWriter

    imus = _imus(seq, doc)
    # merge every message by time: (t, source index, sample index); cameras first at equal t
    keys = []
    for ci, c in enumerate(cams):
        keys.append(np.column_stack([c.stamps_ns, np.full(len(c.paths), ci),
                                     np.arange(len(c.paths))]))
    for ii, imu in enumerate(imus):
        st = imu.stamps_ns
        keys.append(np.column_stack([st, np.full(st.size, len(cams) + ii), np.arange(st.size)]))
    allk = np.concatenate(keys) if keys else np.zeros((0, 3), np.int64)
    allk = allk[np.lexsort((allk[:, 2], allk[:, 1], allk[:, 0]))]
    n_img = n_imu = 0
    with RosbagWriter(bag, overwrite=overwrite) as w:
        for k, (t, src, i) in enumerate(allk):
            if src < len(cams):
                c = cams[src]
                img = read_png(c.paths[i])
                if img.ndim == 3:
                    img = np.ascontiguousarray(img[..., :3])
                w.add_image(f"/cam{src}/image_raw", int(t), img, frame_id=f"cam{src}")
                n_img += 1
            else:
                m = src - len(cams)
                imu = imus[m]
                w.add_imu(f"/{imu.name}", int(t), imu.gyro_rad_s[i], imu.accel_m_s2[i],
                          frame_id=imu.name)
                n_imu += 1
            if k % 200 == 0:
                step(0.95 * k / max(len(allk), 1), "bag")
    return {"cameras": {c.name: f"/cam{i}/image_raw" for i, c in enumerate(cams)},
            "imus": {imu.name: f"/{imu.name}" for imu in imus}, "n_images": n_img, "n_imu_samples": n_imu,
            "n_groundtruth": 0}


# ---------------------------------------------------------------------------------------------
# entry point


def export_sequence(seq_dir: str | os.PathLike[str], fmt: str, out: str | os.PathLike[str], *,
                    cameras: list[str] | None = None, overwrite: bool = False,
                    progress: Progress | None = None) -> ExportSummary:
    """Export the sequence ``seq_dir`` in ``fmt`` to ``out`` (see the module docstring).

    Parameters
    ----------
    seq_dir : path
        A sequence folder written by ``ibiscape-eval sim`` (``sequence.yaml`` inside).
    fmt : {"euroc", "tum-rgbd", "rosbag"}
    out : path
        Export folder (euroc, tum-rgbd) or ``.bag`` file (rosbag); it must not exist (a folder
        may be empty) unless ``overwrite``, and is replaced only once the export is complete.
    cameras : list of str, optional
        Source cameras to export, in order (euroc/rosbag; default: the first two RGB cameras, the
        stereo pair, else the DVS cameras' accumulated frames).
    progress : callable(fraction, label), optional

    Returns
    -------
    ExportSummary

    Raises
    ------
    IbiscapeError
        Unknown format, a format the setup cannot fill, output exists, not enough disk space.
    FormatError
        A sequence file is missing or malformed (naming it).
    """
    from ibiscape_eval.io.atomic import atomic_output_dir

    def step(frac: float, label: str) -> None:
        if progress is not None:
            progress(frac, label)

    if fmt not in EXPORT_FORMATS:
        raise IbiscapeError(f"unknown export format {fmt!r}; choose one of {', '.join(EXPORT_FORMATS)}")
    seq = Path(seq_dir)
    dst = Path(out)
    doc, cams = _read(seq)
    if fmt == "rosbag":
        if dst.is_dir() or (dst.exists() and not overwrite):
            raise IbiscapeError(f"{dst}: already exists; choose a new .bag file, remove it or "
                                "use --overwrite")
        chosen = _pick_cameras(doc, cams, cameras, fmt, seq)
        raw = sum(len(c.paths) * int(np.prod(c.entry["resolution"])) * (3 if c.kind == "rgb" else 1)
                  for c in chosen)
        imu_bytes = sum(_folder_bytes(seq / str(e.get("file", ""))) for e in
                        (doc.get("imus") or {}).values()) * 3
        _check_space(dst, raw + imu_bytes)
        try:
            res = _export_rosbag(seq, doc, chosen, dst, step, overwrite=overwrite)
        except OSError as e:
            if e.errno == errno.ENOSPC:
                raise _disk_full(dst, e) from None
            raise
    else:
        if dst.exists() and (not dst.is_dir() or (any(dst.iterdir()) and not overwrite)):
            raise IbiscapeError(f"{dst}: exists and is not an empty folder; choose another --out "
                                "or remove it")
        if fmt == "euroc":
            chosen = _pick_cameras(doc, cams, cameras, fmt, seq)
            need = sum(_folder_bytes(p) for c in chosen for p in c.paths)
        else:
            rgb, depth = _rgbd_pair(doc, cams, seq)
            need = sum(_folder_bytes(p) for c in (rgb, depth) for p in c.paths) * 2
        need += _folder_bytes(seq / "other_sensors") + _folder_bytes(seq / "vehicle_gt")
        _check_space(dst, need)
        try:
            with atomic_output_dir(dst, overwrite=overwrite) as tmp:
                res = (_export_euroc(seq, doc, chosen, tmp, step) if fmt == "euroc"
                       else _export_tum(seq, doc, cams, tmp, step))
        except OSError as e:
            if e.errno == errno.ENOSPC:
                raise _disk_full(dst, e) from None
            raise
    step(1.0, "done")
    return ExportSummary(fmt=fmt, path=str(dst), bytes_written=_folder_bytes(dst), **res)
