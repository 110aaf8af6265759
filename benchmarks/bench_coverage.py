"""Do the reported standard deviations cover the truth?  Coverage of the 1-sigma and 2-sigma
intervals over seeds, for the camera calibration (``calib``) and the camera-IMU calibration
(``calib --imu``), before (the plain ``s^2 (J^T J)^-1``) and after (what is reported now).

    .venv/bin/python benchmarks/bench_coverage.py --camera --seeds 40            # projected corners
    .venv/bin/python benchmarks/bench_coverage.py --camera --view-offset --seeds 40
    .venv/bin/python benchmarks/bench_coverage.py --camera --rendered --seeds 16 # rendered + detected
    .venv/bin/python benchmarks/bench_coverage.py --imu --seeds 16 --duration-s 12 --size 384
    .venv/bin/python benchmarks/bench_coverage.py --imu --seeds 8 --misweighted
    .venv/bin/python benchmarks/bench_coverage.py --seq DRIVE [--cams DRIVE/camchain.yaml]
    .venv/bin/python benchmarks/bench_coverage.py --make-drive /tmp/cov/SVI_calib_imu --duration-s 24

Every estimate's error is divided by its reported std (``z``); the pooled ``|z|`` over
parameters and seeds should fall below 1 in 68.3 % and below 2 in 95.4 % of the cases (the
normal fractions; the target band is 60-75 % and 90-98 %).  ``factor`` is the inflation that
would bring the 1-sigma coverage to 68.3 % (median ``|z|`` / 0.6745); a factor below 1 means the
std is conservative.  Camera calibration: stereo pair, 480x360 radtan cameras
(``tests/calib/_calib_scenes.py``), 12 views at 3-6 m, corners projected with 0.1 px white noise
(``--view-offset``: plus an offset per view and camera of the same size, a detector error shared
by a view's corners; ``--rendered``: the board rendered and detected).  Camera-IMU: the
simulator's svi calibration drive (bumps), corners projected with 0.2 px noise, the default IMU
noise; ``--intrinsics-error``: each camera's intrinsics off by a draw from ``INTR_COV``, focal
lengths and principal point refined, the covariance given; ``--misweighted``: ``imu.yaml`` densities 4x the truth and ``sigma_px`` 2x the corner noise
(Kalibr advises inflating the densities of real IMUs).  ``--seq``: ``calibrate_sequence`` on a
rendered drive (``--make-drive`` writes one like ``examples/calibrate_imu_camera.py``'s: board
frames at 10 Hz, 384 px), every parameter's error beside the std before and after.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHIFTS = {"rgbL": 0.0123, "rgbR": -0.0171}
#: --intrinsics-error: the intrinsics' covariance (fx, fy, cx, cy [px], k1, k2, p1, p2)
_SD = np.array([0.5, 0.5, 0.5, 0.5, 1e-2, 1e-2, 1e-3, 1e-3])
INTR_COV = np.diag(_SD**2)
INTR_COV[4, 5] = INTR_COV[5, 4] = -0.5 * _SD[4] * _SD[5]


def coverage_table(rows: dict[str, dict[str, list[np.ndarray]]]) -> None:
    """rows[label][quantity] = list of z arrays."""
    print(f"{'std':<8} {'quantity':<12} {'n':>5} {'1-sigma':>8} {'2-sigma':>8} {'rms z':>6} {'factor':>7}")
    for label, qs in rows.items():
        allz = []
        for q, zs in qs.items():
            a = np.abs(np.concatenate(zs))
            allz.append(a)
            _line(label, q, a)
        _line(label, "pooled", np.concatenate(allz))


def _line(label: str, q: str, a: np.ndarray) -> None:
    print(f"{label:<8} {q:<12} {a.size:5d} {np.mean(a < 1):8.2f} {np.mean(a < 2):8.2f} "
          f"{np.sqrt(np.mean(a**2)):6.2f} {np.median(a) / 0.6745:7.2f}")


# ------------------------------------------------------------------------------ camera calibration
def camera(a: argparse.Namespace) -> None:
    sys.path.insert(0, str(ROOT / "tests" / "calib"))
    from _calib_render import random_poses, render, sim_target, stereo_extrinsics
    from _calib_scenes import CAM_RADTAN, CAM_RADTAN_R
    from scipy.spatial.transform import Rotation

    from ibiscape_eval.calib.calibrate import Observations, calibrate
    from ibiscape_eval.calib.detect import Detection, detect_corners

    target = sim_target("checkerboard")
    obj = target.object_points()
    cams = (CAM_RADTAN, CAM_RADTAN_R)
    T10 = stereo_extrinsics(0.2)
    rows: dict[str, dict[str, list[np.ndarray]]] = {"before": {}, "after": {}}
    t0 = time.process_time()
    for seed in range(1, a.seeds + 1):
        rng = np.random.default_rng(seed)
        poses = random_poses("checkerboard", 12, rng, distance_m=(3.0, 6.0), spread=0.1)
        dets: list[list[Any]] = [[], []]
        for T in poses:
            for n, Tn in enumerate((np.eye(4), T10)):
                cam, Tc = cams[n], Tn @ T
                if a.rendered:
                    dets[n].append(detect_corners(render(cam, Tc, "checkerboard", rng=rng), target))
                    continue
                uv = cam.project(obj @ Tc[:3, :3].T + Tc[:3, 3])
                ok = (np.all(np.isfinite(uv), 1) & (uv[:, 0] > 2) & (uv[:, 0] < cam.width_px - 3)
                      & (uv[:, 1] > 2) & (uv[:, 1] < cam.height_px - 3))
                if not ok.all():
                    dets[n].append(None)
                    continue
                uv = uv + rng.normal(0, a.noise_px, uv.shape)
                if a.view_offset:
                    uv = uv + rng.normal(0, a.noise_px, 2)
                dets[n].append(Detection(np.arange(len(uv), dtype=np.int64), uv, (cam.width_px, cam.height_px)))
        obs = tuple(Observations(f"cam{n}", (cams[n].width_px, cams[n].height_px), dets[n]) for n in range(2))
        res = calibrate(target, obs, model="pinhole-radtan")
        err = []
        for c, truth in zip(res.cameras, cams, strict=True):
            err.append(np.r_[np.array(c.camera.intrinsics) - truth.intrinsics, np.array(c.camera.coeffs) - truth.coeffs])
        rv = (Rotation.from_matrix(res.T_cn_cnm1[0][:3, :3]).as_rotvec()
              - Rotation.from_matrix(T10[:3, :3]).as_rotvec())
        e = np.r_[np.concatenate(err), rv, res.T_cn_cnm1[0][:3, 3] - T10[:3, 3]]
        u = res.extra["uncertainty"]
        after = np.r_[np.concatenate([np.r_[c.std["intrinsics"], c.std["distortion_coeffs"]] for c in res.cameras]),
                      np.radians(res.T_cn_cnm1_std[0]["rotation_std_deg"]), res.T_cn_cnm1_std[0]["translation_std_m"]]
        for label, sd in (("before", np.asarray(u["std_plain"])), ("after", after)):
            z = e / sd
            for q, idx in (("intrinsics", np.r_[0:4, 8:12]), ("distortion", np.r_[4:8, 12:16]),
                           ("extrinsics", np.r_[16:22])):
                rows[label].setdefault(q, []).append(z[idx])
    kind = "rendered" if a.rendered else ("white + per-view offset" if a.view_offset else "white")
    print(f"camera calibration, {a.seeds} seeds, stereo 480x360, 12 views, {kind} corner noise "
          f"{a.noise_px} px; CPU {time.process_time() - t0:.0f} s")
    coverage_table(rows)


# -------------------------------------------------------------------------------------- camera-IMU
def imu_errors(res: Any, T_truth: dict[str, np.ndarray], shift_truth: dict[str, float]
               ) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per camera: error (rotation rad about IMU axes, translation m, offset s) and the std
    after and before (``uncertainty['std_plain']``), in the same units."""
    from ibiscape_eval.core.so3 import log_so3

    out = {}
    for cal in res.cameras:
        T = np.asarray(T_truth[cal.name], dtype=float)
        e = np.r_[log_so3(T[:3, :3].T @ cal.T_cam_imu[:3, :3]), cal.T_cam_imu[:3, 3] - T[:3, 3],
                  cal.timeshift_cam_imu_s - shift_truth[cal.name]]
        after = np.r_[np.radians(cal.rotation_std_deg), cal.translation_std_m, cal.timeshift_std_s]
        out[cal.name] = (e, after, np.asarray(res.uncertainty["std_plain"][cal.name]))
    return out


def _imu_rows(rows: dict[str, dict[str, list[np.ndarray]]], errs: dict[str, Any]) -> None:
    for e, after, before in errs.values():
        for label, sd in (("before", before), ("after", after)):
            z = e / sd
            for q, idx in (("rotation", slice(0, 3)), ("translation", slice(3, 6)), ("time offset", slice(6, 7))):
                rows[label].setdefault(q, []).append(z[idx])


def imu(a: argparse.Namespace) -> None:
    from ibiscape_eval.calib.imu_camera import ImuCameraOptions, calibrate_imu_camera
    from ibiscape_eval.calib.imu_camera.synthetic import calibration_scene
    from ibiscape_eval.sim import preset
    from ibiscape_eval.sim.calib_scene import simulate_calibration
    from ibiscape_eval.sim.config import MotionSpec

    rows: dict[str, dict[str, list[np.ndarray]]] = {"before": {}, "after": {}}
    t0 = time.process_time()
    for seed in range(1, a.seeds + 1):
        cfg = preset("svi", "calibration", "clear", duration_s=a.duration_s, seed=seed,
                     motion=MotionSpec(bumps=True))
        cfg = replace(cfg, cameras=tuple(replace(c, width_px=a.size, height_px=a.size, rate_hz=a.rate_hz)
                                         for c in cfg.cameras))
        sc = calibration_scene(simulate_calibration(cfg, timeshifts_s=SHIFTS), noise_px=0.2,
                               min_spacing_px=4.0)
        noise, sigma_px = sc.noise, 0.2
        obs: Any = sc.observations
        icov, refine = None, False
        if a.intrinsics_error:  # intrinsics drawn from INTR_COV, focal/principal point refined
            rng = np.random.default_rng(100 + seed)
            L = np.linalg.cholesky(INTR_COV)
            obs = []
            for o in sc.observations:
                d = L @ rng.normal(size=8)
                obs.append(replace(o, camera=replace(
                    o.camera, fx=o.camera.fx + d[0], fy=o.camera.fy + d[1], cx=o.camera.cx + d[2],
                    cy=o.camera.cy + d[3], coeffs=tuple(float(v) for v in d[4:]))))
            icov, refine = {o.name: INTR_COV for o in obs}, True
        if a.misweighted:
            noise = replace(noise, gyro_noise_density_rad_s_sqrt_hz=4 * noise.gyro_noise_density_rad_s_sqrt_hz,
                            accel_noise_density_m_s2_sqrt_hz=4 * noise.accel_noise_density_m_s2_sqrt_hz)
            sigma_px = 0.4
        res = calibrate_imu_camera(obs, sc.imu, noise, sc.corners_target_m,
                                   ImuCameraOptions(sigma_px=sigma_px, refine_intrinsics=refine),
                                   intrinsics_covariance=icov)
        errs = imu_errors(res, sc.T_cam_imu, sc.timeshift_cam_imu_s)
        _imu_rows(rows, errs)
        if a.verbose:
            for name, (e, after, before) in errs.items():
                print(f"seed {seed} {name}: z after {np.round(e / after, 2)}, before {np.round(e / before, 2)}")
    print(f"camera-IMU calibration, {a.seeds} seeds, svi drive {a.duration_s:g} s with bumps, stereo "
          f"{a.size} px at {a.rate_hz:g} Hz, 0.2 px corners"
          + (", imu.yaml densities 4x and sigma_px 2x the truth" if a.misweighted else "")
          + (", intrinsics drawn from INTR_COV (distortion held)" if a.intrinsics_error else "")
          + f"; CPU {time.process_time() - t0:.0f} s")
    coverage_table(rows)


def on_sequence(a: argparse.Namespace) -> None:
    from ibiscape_eval.calib.imu_camera import SequenceOptions, calibrate_sequence

    rows: dict[str, dict[str, list[np.ndarray]]] = {"before": {}, "after": {}}
    for seq in a.seq:
        t0 = time.perf_counter()
        res = calibrate_sequence(seq, Path(seq) / "imu.yaml", SequenceOptions(camchain=a.cams))
        T_truth = {k: v["T_cam_imu"] for k, v in res.truth.items()}
        shift_truth = {k: v["timeshift_cam_imu"] for k, v in res.truth.items()}
        errs = imu_errors(res.result, T_truth, shift_truth)
        _imu_rows(rows, errs)
        print(f"\n{seq} ({'--cams ' + a.cams if a.cams else 'own intrinsics'}), wall "
              f"{time.perf_counter() - t0:.0f} s; uncertainty: "
              f"{ {k: v for k, v in res.result.uncertainty.items() if k != 'std_plain'} }")
        print(f"{'camera':<6} {'parameter':<14} {'error':>9} {'std now':>9} {'std before':>10} {'z now':>6} {'z before':>8}")
        for name, (e, after, before) in errs.items():
            labels = ["rot x [deg]", "rot y [deg]", "rot z [deg]", "t x [mm]", "t y [mm]", "t z [mm]", "shift [ms]"]
            scale = np.r_[[np.degrees(1.0)] * 3, [1e3] * 3, 1e3]
            for i, lab in enumerate(labels):
                print(f"{name:<6} {lab:<14} {e[i] * scale[i]:9.4f} {after[i] * scale[i]:9.4f} "
                      f"{before[i] * scale[i]:10.4f} {e[i] / after[i]:6.2f} {e[i] / before[i]:8.2f}")
            print(f"{name:<6} |t| error {np.linalg.norm(e[3:6]) * 1e3:.2f} mm, |std| now "
                  f"{np.linalg.norm(after[3:6]) * 1e3:.2f} mm, before {np.linalg.norm(before[3:6]) * 1e3:.2f} mm; "
                  f"rotation error {np.degrees(np.linalg.norm(e[:3])):.4f} deg, |std| now "
                  f"{np.degrees(np.linalg.norm(after[:3])):.4f}, before {np.degrees(np.linalg.norm(before[:3])):.4f}")
    coverage_table(rows)


def make_drive(out: str, duration_s: float, seed: int) -> None:
    sys.path.insert(0, str(ROOT / "examples"))
    from calibrate_imu_camera import make_sequence

    t0 = time.perf_counter()
    make_sequence(out, duration_s=duration_s, seed=seed)
    print(f"wrote {out} in {time.perf_counter() - t0:.0f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--camera", action="store_true")
    ap.add_argument("--rendered", action="store_true", help="--camera: render and detect the board")
    ap.add_argument("--view-offset", action="store_true", help="--camera: add a per-view corner offset")
    ap.add_argument("--noise-px", type=float, default=0.1)
    ap.add_argument("--imu", action="store_true")
    ap.add_argument("--misweighted", action="store_true")
    ap.add_argument("--intrinsics-error", action="store_true", help="--imu: intrinsics off by a "
                    "draw from INTR_COV, given as intrinsics_covariance")
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--duration-s", type=float, default=12.0)
    ap.add_argument("--size", type=int, default=384)
    ap.add_argument("--rate-hz", type=float, default=20.0)
    ap.add_argument("--seq", action="append")
    ap.add_argument("--cams", default=None)
    ap.add_argument("--make-drive", default=None)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--verbose", action="store_true")
    a = ap.parse_args()
    if a.make_drive:
        make_drive(a.make_drive, a.duration_s, a.seed)
    if a.camera:
        camera(a)
    if a.imu:
        imu(a)
    if a.seq:
        on_sequence(a)


if __name__ == "__main__":
    warnings.simplefilter("ignore")
    main()
