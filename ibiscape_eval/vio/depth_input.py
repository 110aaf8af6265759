"""RGB-D inputs of an IBISCape sequence: the RGB camera, the depth camera registered to it, and the
virtual stereo rig the estimator sees (:mod:`ibiscape_eval.vio.depth`).

Cameras: the depth camera is the ``sequence.yaml`` camera of kind ``depth`` (folder ``depth/``);
the RGB camera is ``rgb`` when present (the RGB-D housing), else the RGB camera mounted where
the depth camera is, else the first RGB camera.  ``--calib`` (a Kalibr camchain) replaces both:
``cam0`` the RGB camera, ``cam1`` the depth camera.  Frames are the instants both cameras share.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError, FormatError, Remedy
from ibiscape_eval.core.sequence import Sequence

from .depth import DepthOptions, DepthReader, virtual_rig
from .rig import StereoRig

__all__ = ["rgbd_names", "rgbd_parts"]

FloatArray = npt.NDArray[np.float64]


def rgbd_names(where: Path, cams: dict[str, Any]) -> tuple[str, str]:
    """``(rgb, depth)`` camera names of a ``sequence.yaml`` camera mapping."""
    kind = {n: (c.get("kind", "rgb") if isinstance(c, dict) else "rgb") for n, c in cams.items()}
    depth = [n for n, k in kind.items() if k == "depth"]
    rgb = [n for n, k in kind.items() if k == "rgb"]
    if not depth or not rgb:
        raise CalibrationError(f"{where}: RGB-D needs an RGB camera and a depth camera, the "
                               f"sequence has {', '.join(f'{n} ({k})' for n, k in kind.items()) or 'none'}; "
                               "use {0} or {1}", hint=(Remedy("setup", "svi"), Remedy("setup", "esvi")))
    d = depth[0]
    if "rgb" in rgb:
        return "rgb", d
    T_d = cams[d].get("T_body_cam")
    same = [n for n in rgb if T_d is not None and np.allclose(np.asarray(cams[n].get("T_body_cam", np.eye(4))),
                                                              np.asarray(T_d))]
    return (same or rgb)[0], d


def _calibration(seq: Sequence, cams: dict[str, Any], rgb: str, depth: str, calib: Any
                 ) -> tuple[CameraModel, FloatArray, CameraModel, FloatArray]:
    from .inputs import _T, _camera  # the same checks as the stereo rig's

    if calib is not None:
        from ibiscape_eval.io.kalibr import read_camchain

        chain = read_camchain(calib)
        if len(chain) < 2 or chain.cameras[0].T_cam_imu is None:
            raise CalibrationError(f"{calib}: RGB-D needs cam0 (RGB, with T_cam_imu) and cam1 (depth)")
        c0, c1 = chain.cameras[0], chain.cameras[1]
        assert c0.T_cam_imu is not None
        if c1.T_cam_imu is None and c1.T_cn_cnm1 is None:
            raise CalibrationError(f"{calib}: cam1 (depth) lacks T_cam_imu and T_cn_cnm1")
        T0: FloatArray = np.asarray(np.linalg.inv(c0.T_cam_imu), np.float64)
        T1: FloatArray = np.asarray(np.linalg.inv(c1.T_cam_imu) if c1.T_cam_imu is not None
                                    else T0 @ np.linalg.inv(np.asarray(c1.T_cn_cnm1)), np.float64)
        return (_camera(c0.camera, Path(calib), "cam0"), T0, _camera(c1.camera, Path(calib), "cam1"), T1)
    where = seq.path / "sequence.yaml"
    return (_camera(cams[rgb], where, rgb), _T(cams[rgb], "T_body_cam", where, rgb),
            _camera(cams[depth], where, depth), _T(cams[depth], "T_body_cam", where, depth))


def rgbd_parts(seq: Sequence, cams: dict[str, Any], calib: Any, options: DepthOptions | None
               ) -> tuple[StereoRig, npt.NDArray[np.int64], Any, Any, str]:
    """Rig, frame stamps, ``reader(i)`` -> (grey RGB, depth [m]), ``labels(i)`` and the depth unit.

    Raises
    ------
    CalibrationError, FormatError
        No RGB or depth camera, no depth files, RGB and depth frames that share no instant.
    """
    from ibiscape_eval.io.images import read_frame_timestamps
    from ibiscape_eval.io.stereo import read_gray_image

    o = options if isinstance(options, DepthOptions) else DepthOptions()
    rgb, depth = rgbd_names(seq.path / "sequence.yaml", cams)
    cam_rgb, T_rgb, cam_d, T_d = _calibration(seq, cams, rgb, depth, calib)
    if rgb not in seq.camera_names:
        raise FormatError(seq.path / rgb / "timestamps.csv", "no RGB frames; render the sequence first")
    stream = seq.camera(rgb)
    folder = seq.path / str(cams[depth].get("folder", depth))
    t_d, names = read_frame_timestamps(folder / "timestamps.csv")
    sub, unit = ("mm", "mm") if (folder / "mm").is_dir() else ("frames", "carla-log")
    if o.depth_unit is not None:  # given: the 16-bit units read mm/ when there is one
        unit = o.depth_unit
        sub = "mm" if unit != "carla-log" and (folder / "mm").is_dir() else "frames"
    t_rgb = np.asarray(stream.stamps_ns, np.int64)
    common = np.intersect1d(t_rgb, t_d)
    if len(common) < 2:
        raise FormatError(folder / "timestamps.csv", f"RGB ({len(t_rgb)}) and depth ({len(t_d)}) "
                          "frames share no timestamps; the RGB-D pair must be synchronised")
    ir, idp = np.searchsorted(t_rgb, common), np.searchsorted(t_d, common)
    rgb_files = [stream.paths[i] for i in ir]
    depth_files = [folder / sub / names[i] for i in idp]
    reader = DepthReader(depth_files, unit, cam_d, T_d, cam_rgb, T_rgb)

    def read(i: int) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float32]]:
        return read_gray_image(rgb_files[i]), reader(i)

    def labels(i: int) -> tuple[str, str]:
        return str(rgb_files[i]), str(depth_files[i])

    from .inputs import _checked_rig

    rig = virtual_rig(cam_rgb, T_rgb, o.baseline_m)
    _checked_rig(seq.path / "sequence.yaml", rig.left, rig.right, rig.T_body_left, rig.T_body_right)
    return rig, np.asarray(common, np.int64), read, labels, unit
