"""Camera calibration: ``ibiscape-eval calib`` against a plain OpenCV pipeline on the same views.

    .venv/bin/python benchmarks/bench_calib.py                  # 100 stereo frames, 1024x1024
    .venv/bin/python benchmarks/bench_calib.py --frames 40 --targets aprilgrid

For each target (checkerboard 7x7, AprilGrid 6x6 as the simulator prints them) a stereo pair with
the paper's cameras (1024 x 1024, f = 512 px, mild radtan distortion, 0.4 m baseline) sees the
board in ``--frames`` varied poses 4-12 m away, rendered by the simulator's renderer in its
calibration world (``ibiscape_eval.sim.calib_views``: supersampled board edges, lens blur, sensor
noise) and written as an IBISCape sequence with a ``sequence.yaml`` holding the truth.  Then, in the same run:

- ours: ``ibiscape-eval calib SEQ --json`` in a fresh process (wall time, peak RSS);
- peer: the plain OpenCV pipeline (``findChessboardCornersSB`` / ``aruco`` + ``cornerSubPix`` per
  image, one thread; ``calibrateCamera`` per camera; ``stereoCalibrate``), timed in-process.

Printed: wall time and RATIO (peer / ours, > 1 means we are faster), detection time per frame,
and the accuracy table against the truth (focal, principal point, baseline, RMS).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _runner import run

from ibiscape_eval.core.camera import CameraModel

CLI = str(Path(sys.executable).with_name("ibiscape-eval"))
CAM_L = CameraModel(1024, 1024, 512.0, 512.0, 511.5, 511.5, "radtan", (-0.05, 0.01, 0.0005, -0.0003))
CAM_R = CameraModel(1024, 1024, 512.0, 512.0, 511.5, 511.5, "radtan", (-0.04, 0.008, -0.0004, 0.0002))
BASELINE_M = 0.4


def rig() -> np.ndarray:
    """``T_cam0_cam1``: the right camera ``BASELINE_M`` to the right, turned 0.5 deg."""
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("yxz", [0.5, 0.3, -0.2], degrees=True).as_matrix()
    T[:3, 3] = [BASELINE_M, 0.01, -0.005]
    return T


def make_sequence(root: Path, kind: str, n: int, seed: int) -> np.ndarray:
    """Render the stereo views with the simulator (sim.calib_views); returns ``T_cam0_cam1``."""
    from ibiscape_eval.sim.calib_views import render_calibration_views

    T01 = rig()
    render_calibration_views(root, {"rgbL": CAM_L, "rgbR": CAM_R}, {"rgbR": T01}, target=kind,
                             n_views=n, seed=seed, distance_m=(4.0, 12.0))
    return T01


def sim_target(root: Path):
    import yaml

    from ibiscape_eval.calib import target_from_kalibr

    return target_from_kalibr(yaml.safe_load((root / "sequence.yaml").read_text())["target"])


def opencv_pipeline(root: Path, kind: str) -> tuple[float, float, dict]:
    """Plain OpenCV: detect every frame (one thread), calibrateCamera x2, stereoCalibrate."""
    import cv2

    target = sim_target(root)
    obj = target.object_points().astype(np.float32)
    files = sorted((root / "rgbL" / "frames").glob("*.png"))
    t0 = time.perf_counter()
    det_s = 0.0
    op, lp, rp = [], [], []
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = 2
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    aruco = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11),
                                    params, cv2.aruco.RefineParameters())
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)

    def detect(img: np.ndarray) -> dict[int, np.ndarray] | None:
        if kind == "checkerboard":
            ok, c = cv2.findChessboardCornersSB(img, (7, 7), flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
            return dict(enumerate(np.asarray(c).reshape(-1, 2))) if ok else None
        corners, ids, _ = aruco.detectMarkers(img)
        if ids is None:
            return None
        out = {}
        for q, i in zip(corners, ids.ravel(), strict=True):
            q = cv2.cornerSubPix(img, np.asarray(q, np.float32).reshape(-1, 1, 2), (4, 4), (-1, -1), crit)
            cids = target.tag_corner_ids([i])[0][[1, 0, 3, 2]]  # OpenCV's order on Kalibr's print
            for k in range(4):
                out[int(cids[k])] = q.reshape(-1, 2)[k]
        return out

    for f in files:
        t = time.perf_counter()
        a = detect(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE))
        b = detect(cv2.imread(str(root / "rgbR" / "frames" / f.name), cv2.IMREAD_GRAYSCALE))
        det_s += time.perf_counter() - t
        if a is None or b is None:
            continue
        common = sorted(set(a) & set(b))
        if len(common) < 8:
            continue
        op.append(obj[common])
        lp.append(np.array([a[c] for c in common], np.float32))
        rp.append(np.array([b[c] for c in common], np.float32))
    size = (1024, 1024)
    flags = cv2.CALIB_FIX_K3
    _, K1, D1, _, _ = cv2.calibrateCamera(op, lp, size, None, None, flags=flags)
    _, K2, D2, _, _ = cv2.calibrateCamera(op, rp, size, None, None, flags=flags)
    out = cv2.stereoCalibrate(op, lp, rp, K1, D1, K2, D2, size, flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS)
    rms, K1, _, K2, _, _, T = out[:7]
    wall = time.perf_counter() - t0
    return wall, det_s / (2 * len(files)), {"K": (K1, K2), "baseline_m": float(np.linalg.norm(T)),
                                             "rms_px": float(rms), "views": len(op)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--targets", nargs="+", default=["checkerboard", "aprilgrid"])
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_calib_") as d:
        for kind in a.targets:
            seq = Path(d) / kind
            t = time.perf_counter()
            T10 = make_sequence(seq, kind, a.frames, a.seed)
            print(f"[{kind}] rendered {2 * a.frames} frames in {time.perf_counter() - t:.0f} s", flush=True)
            ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            r = run([CLI, "calib", str(seq), "--json"])
            ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu_s = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
            if not r.ok:
                raise SystemExit(f"ibiscape-eval calib failed on {seq}")
            ours = json.loads(r.stdout)
            import cv2

            from ibiscape_eval.calib.detect import detect_corners

            files = sorted((seq / "rgbL" / "frames").glob("*.png"))[:10]
            t = time.perf_counter()
            for f in files:
                detect_corners(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), sim_target(seq))
            our_det = (time.perf_counter() - t) / len(files)
            c0 = time.process_time()
            cv_wall, cv_det, cv = opencv_pipeline(seq, kind)
            cv_cpu = time.process_time() - c0
            gt = ours["ground_truth"]
            cv_f = max(abs(K[i, i] - 512.0) for K in cv["K"] for i in (0, 1))
            cv_c = max(abs(K[i, 2] - 511.5) for K in cv["K"] for i in (0, 1))
            rows.append((kind, r.wall_s, r.peak_mb, our_det, cv_wall, cv_det, cpu_s, cv_cpu, gt, ours, cv,
                         cv_f, cv_c, T10))
    print()
    print(f"{'target':<13}{'ours [s]':>9}{'CPU [s]':>8}{'peak MB':>9}{'OpenCV [s]':>11}{'CPU [s]':>8}"
          f"  RATIO wall (OpenCV/ours){'det/frame ours':>16}{'OpenCV':>8}")
    for kind, w, mb, od, cw, cd, cpu, ccpu, *_ in rows:
        print(f"{kind:<13}{w:>9.1f}{cpu:>8.1f}{mb:>9.0f}{cw:>11.1f}{ccpu:>8.1f}  {cw / w:>24.2f}"
              f"{1e3 * od:>13.0f} ms{1e3 * cd:>5.0f} ms")
    print(f"load average during the run: {os.getloadavg()[0]:.1f} (2 cores)")
    print()
    print(f"{'target':<13}{'pipeline':<10}{'max |df| px':>12}{'max |dc| px':>12}{'baseline err mm':>16}"
          f"{'RMS px':>8}{'views':>7}")
    for kind, *_, gt, ours, cv, cv_f, cv_c, T10 in rows:
        true_b = float(np.linalg.norm(T10[:3, 3]))
        print(f"{kind:<13}{'ours':<10}{gt['max_focal_error_px']:>12.3f}{gt['max_principal_point_error_px']:>12.3f}"
              f"{gt['max_baseline_error_mm']:>16.2f}{ours['rms_px']:>8.3f}{ours['n_views']:>7}")
        print(f"{'':<13}{'OpenCV':<10}{cv_f:>12.3f}{cv_c:>12.3f}{1e3 * abs(cv['baseline_m'] - true_b):>16.2f}"
              f"{cv['rms_px']:>8.3f}{cv['views']:>7}")
    print("issue targets: focal < 0.3 px, principal point < 0.5 px, baseline < 1 mm, RMS < 0.1 px, "
          "100-frame 1024x1024 stereo < 60 s")


if __name__ == "__main__":
    main()
