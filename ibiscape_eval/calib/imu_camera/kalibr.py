"""The result as Kalibr's ``camchain-imucam`` (:class:`~ibiscape_eval.core.kalibr.CameraChain`) and
the comparison with a sequence's truth."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ibiscape_eval.core.kalibr import CameraChain
from ibiscape_eval.core.so3 import log_so3

from .result import ImuCameraResult

__all__ = ["camchain_imucam", "errors_against_truth"]


def camchain_imucam(result: ImuCameraResult, *,
                    rostopics: Mapping[str, str] | None = None) -> CameraChain:
    """The result as Kalibr's camchain-imucam (write it with
    :func:`ibiscape_eval.io.kalibr.write_camchain`): per camera the intrinsics, distortion,
    ``T_cam_imu``, ``timeshift_cam_imu`` and, from the second camera on, ``T_cn_cnm1`` (camera n-1 to
    camera n), in the result's camera order; topics ``/<name>/image_raw`` unless given."""
    cams = result.cameras
    return CameraChain.from_imu_extrinsics(
        [c.name for c in cams], [c.camera for c in cams], [c.T_cam_imu for c in cams],
        [c.timeshift_cam_imu_s for c in cams],
        rostopics=[(rostopics or {}).get(c.name, f"/{c.name}/image_raw") for c in cams])


def errors_against_truth(result: ImuCameraResult, truth: Mapping[str, Mapping[str, Any]]
                         ) -> dict[str, dict[str, float]]:
    """Per camera: rotation error [deg], translation error [m] and time-offset error [s] against
    ``truth[name] = {"T_cam_imu": 4x4, "timeshift_cam_imu": s}`` (``sequence.yaml``'s cameras)."""
    out: dict[str, dict[str, float]] = {}
    for cal in result.cameras:
        t = truth.get(cal.name)
        if t is None or "T_cam_imu" not in t:
            continue
        T = np.asarray(t["T_cam_imu"], dtype=np.float64)
        rot = float(np.degrees(np.linalg.norm(log_so3(T[:3, :3].T @ cal.T_cam_imu[:3, :3]))))
        out[cal.name] = {
            "rotation_error_deg": rot,
            "translation_error_m": float(np.linalg.norm(cal.T_cam_imu[:3, 3] - T[:3, 3])),
            "timeshift_error_s": float(cal.timeshift_cam_imu_s - float(t.get("timeshift_cam_imu", 0.0))),
        }
    return out
