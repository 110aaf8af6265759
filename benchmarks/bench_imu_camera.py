"""Camera-IMU calibration on simulated 60 s calibration drives: accuracy against the exact truth
and run time.

    .venv/bin/python benchmarks/bench_imu_camera.py                 # 1024 px and 512 px, bumps
    .venv/bin/python benchmarks/bench_imu_camera.py --size 512 --flat --four

The simulator plans the calibration world and drive (bubbles and waves on the road), simulates
IMU0 (200 Hz, the default continuous-time noise) and projects the checkerboard's corners into the
stereo RGB pair (20 Hz) with 0.2 px noise, each camera's clock shifted by a planted offset; a board
is "detected" when its corner spacing in the image is at least 4 px.  The peer, Kalibr's
``kalibr_calibrate_imu_camera``, needs ROS and cannot run here; the issue's budget is 2 minutes for
this input on 2 cores, so the RATIO column is 120 s / our wall time (higher is better).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from ibiscape_eval.calib.imu_camera import calibrate_imu_camera, errors_against_truth
from ibiscape_eval.calib.imu_camera.spline import log_so3
from ibiscape_eval.calib.imu_camera.synthetic import calibration_scene
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import simulate_calibration
from ibiscape_eval.sim.config import MotionSpec

SHIFTS = {"rgbL": 0.0123, "rgbR": -0.0171}


def one(size: int, bumps: bool, duration_s: float, seed: int, four: bool = False) -> None:
    cfg = preset("svi", "calibration", "clear", duration_s=duration_s, seed=seed,
                 motion=MotionSpec(bumps=bumps))
    cams = cfg.cameras
    shifts = dict(SHIFTS)
    if four:  # the stereo RGB pair and the stereo DVS pair of the paper's rig, one problem
        dvs = preset("esvi", "calibration").cameras
        cams = (*cams, *dvs)
        shifts.update({"davisL": 0.0071, "davisR": -0.0034})
    cfg = replace(cfg, cameras=tuple(replace(c, width_px=size, height_px=size) for c in cams))
    sc = calibration_scene(simulate_calibration(cfg, timeshifts_s=shifts), noise_px=0.2,
                           min_spacing_px=4.0)
    frames = {o.name: o.n_frames_with_target for o in sc.observations}
    t0, c0 = time.perf_counter(), time.process_time()
    res = calibrate_imu_camera(sc.observations, sc.imu, sc.noise, sc.corners_target_m, sigma_px=0.2,
                               force=not bumps)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    truth = {k: {"T_cam_imu": sc.T_cam_imu[k], "timeshift_cam_imu": sc.timeshift_cam_imu_s[k]}
             for k in sc.T_cam_imu}
    err = errors_against_truth(res, truth)
    print(f"\n{len(sc.observations)} cameras, {size}x{size} px, "
          f"{'bumps' if bumps else 'FLAT road (forced)'}, {duration_s:.0f} s, "
          f"seed {seed}: target frames {frames}, {res.excitation.duration_s:.1f} s of spline, "
          f"{res.iterations} iterations, wall {wall:.1f} s, cpu {cpu:.1f} s, "
          f"RATIO {120.0 / wall:.2f} (2 min budget / wall)")
    print(f"{'camera':<6} {'parameter':<16} {'truth':>12} {'estimate':>12} {'error':>10} {'std':>9}")
    for cal in res.cameras:
        T = sc.T_cam_imu[cal.name]
        rv_true = log_so3(T[:3, :3])
        rv_est = log_so3(cal.T_cam_imu[:3, :3])
        for k, ax in enumerate("xyz"):
            print(f"{cal.name:<6} {'rotvec ' + ax + ' [deg]':<16} {np.degrees(rv_true[k]):12.4f} "
                  f"{np.degrees(rv_est[k]):12.4f} {np.degrees(rv_est[k] - rv_true[k]):10.4f} "
                  f"{cal.rotation_std_deg[k]:9.4f}")
        for k, ax in enumerate("xyz"):
            print(f"{cal.name:<6} {'t ' + ax + ' [mm]':<16} {T[k, 3] * 1e3:12.2f} "
                  f"{cal.T_cam_imu[k, 3] * 1e3:12.2f} {(cal.T_cam_imu[k, 3] - T[k, 3]) * 1e3:10.2f} "
                  f"{cal.translation_std_m[k] * 1e3:9.2f}")
        ts = sc.timeshift_cam_imu_s[cal.name]
        print(f"{cal.name:<6} {'shift [ms]':<16} {ts * 1e3:12.4f} {cal.timeshift_cam_imu_s * 1e3:12.4f} "
              f"{(cal.timeshift_cam_imu_s - ts) * 1e3:10.4f} {cal.timeshift_std_s * 1e3:9.4f}")
        e = err[cal.name]
        print(f"{cal.name:<6} TOTAL rotation {e['rotation_error_deg']:.4f} deg (goal 0.05), translation "
              f"{e['translation_error_m'] * 1e3:.2f} mm (goal 5), time {abs(e['timeshift_error_s']) * 1e3:.4f}"
              f" ms (goal 0.1); position std along IMU x y z "
              f"{' '.join(f'{v * 1e3:.1f}' for v in cal.position_std_imu_m)} mm")
    for w in res.warnings:
        print("  warning:", w)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, action="append", help="image size (default 1024 and 512)")
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--flat", action="store_true", help="also the same drive without bumps")
    ap.add_argument("--four", action="store_true", help="also RGB + DVS stereo pairs in one problem")
    a = ap.parse_args()
    for size in a.size or [1024, 512]:
        one(size, True, a.duration_s, a.seed)
        if a.flat:
            one(size, False, a.duration_s, a.seed)
        if a.four:
            one(size, True, a.duration_s, a.seed, four=True)


if __name__ == "__main__":
    import warnings

    warnings.simplefilter("ignore")
    main()
