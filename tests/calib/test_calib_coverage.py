"""Do the camera calibration's standard deviations cover the truth as often as they say?

Seeded stereo calibrations of projected board corners (no rendering: fast) with known noise; the
error of every intrinsic, distortion and extrinsic parameter divided by its reported std, pooled
over parameters and seeds, must fall below 1 in 60-75 % (normal: 68.3 %) and below 2 in 90-98 %
(95.4 %) of the cases.  ``benchmarks/bench_coverage.py --camera`` runs the same with more seeds
and on rendered, detected boards.
"""

from __future__ import annotations

import numpy as np
from _calib_render import random_poses, sim_target, stereo_extrinsics
from _calib_scenes import CAM_RADTAN, CAM_RADTAN_R
from scipy.spatial.transform import Rotation

from ibiscape_eval.calib.calibrate import Observations, calibrate
from ibiscape_eval.calib.detect import Detection

SEEDS = range(1, 31)
T10 = stereo_extrinsics(0.2)


def _calibration(seed: int, noise_px: tuple[float, float], view_offset_px: float):
    target = sim_target("checkerboard")
    obj = target.object_points()
    cams = (CAM_RADTAN, CAM_RADTAN_R)
    rng = np.random.default_rng(seed)
    dets: list[list[Detection | None]] = [[], []]
    for T in random_poses("checkerboard", 12, rng, distance_m=(3.0, 6.0), spread=0.1):
        for n, Tn in enumerate((np.eye(4), T10)):
            cam, Tc = cams[n], Tn @ T
            uv = cam.project(obj @ Tc[:3, :3].T + Tc[:3, 3])
            inside = (np.all(np.isfinite(uv), 1) & (uv[:, 0] > 2) & (uv[:, 0] < cam.width_px - 3)
                      & (uv[:, 1] > 2) & (uv[:, 1] < cam.height_px - 3))
            if not inside.all():
                dets[n].append(None)
                continue
            uv = uv + rng.normal(0, noise_px[n], uv.shape) + rng.normal(0, view_offset_px, 2)
            dets[n].append(Detection(np.arange(len(uv), dtype=np.int64), uv, (cam.width_px, cam.height_px)))
    obs = tuple(Observations(f"cam{n}", (cams[n].width_px, cams[n].height_px), dets[n]) for n in range(2))
    return calibrate(target, obs, model="pinhole-radtan"), cams


def _z(noise_px=(0.1, 0.1), view_offset_px=0.0):
    """Normalised errors (seeds, 22): per camera fx fy cx cy d0..d3, then the chain's rotation
    vector and translation; reported std and the plain pooled ``s^2 (J^T J)^-1``."""
    after, before = [], []
    for seed in SEEDS:
        res, cams = _calibration(seed, noise_px, view_offset_px)
        e = [np.r_[np.array(c.camera.intrinsics) - t.intrinsics, np.array(c.camera.coeffs) - t.coeffs]
             for c, t in zip(res.cameras, cams, strict=True)]
        rv = (Rotation.from_matrix(res.T_cn_cnm1[0][:3, :3]).as_rotvec()
              - Rotation.from_matrix(T10[:3, :3]).as_rotvec())
        err = np.r_[np.concatenate(e), rv, res.T_cn_cnm1[0][:3, 3] - T10[:3, 3]]
        sd = np.r_[np.concatenate([np.r_[c.std["intrinsics"], c.std["distortion_coeffs"]] for c in res.cameras]),
                   np.radians(res.T_cn_cnm1_std[0]["rotation_std_deg"]), res.T_cn_cnm1_std[0]["translation_std_m"]]
        after.append(err / sd)
        before.append(err / np.asarray(res.extra["uncertainty"]["std_plain"]))
    return np.abs(np.array(after)), np.abs(np.array(before))


def _in_band(z: np.ndarray) -> bool:
    one, two = float(np.mean(z < 1)), float(np.mean(z < 2))
    return 0.60 <= one <= 0.75 and 0.90 <= two <= 0.98


def test_white_corner_noise_is_covered():
    z, _ = _z()
    assert _in_band(z), (np.mean(z < 1), np.mean(z < 2))
    assert _in_band(z[:, 16:]), "the extrinsics alone"


def test_errors_shared_by_a_view_are_covered():
    """Each view's corners share an offset as large as their own noise (blur, a pose-dependent
    detector bias): the plain white-noise std misses the extrinsics (2-sigma covers 64 %); the
    per-view (cluster-robust) covariance covers them."""
    z, z_plain = _z(view_offset_px=0.1)
    assert _in_band(z), (np.mean(z < 1), np.mean(z < 2))
    assert np.mean(z_plain[:, 16:] < 2) < 0.80  # the old std: a confident wrong number
    assert np.mean(z[:, 16:] < 2) >= 0.85


def test_a_noisier_camera_gets_its_own_noise():
    """Camera 1's corners 4x noisier than camera 0's: one pooled ``s^2`` overstates camera 0's
    std and understates camera 1's; each camera's own residual variance covers both."""
    z, z_plain = _z(noise_px=(0.05, 0.2))
    for n in range(2):
        zc = z[:, 8 * n:8 * n + 8]
        assert 0.55 <= np.mean(zc < 1) <= 0.80 and np.mean(zc < 2) >= 0.88, (n, np.mean(zc < 1), np.mean(zc < 2))
    assert np.mean(z_plain[:, 0:8] < 1) > 0.85  # camera 0: the pooled std was far too wide
    assert np.mean(z_plain[:, 8:16] < 1) < np.mean(z[:, 8:16] < 1)
