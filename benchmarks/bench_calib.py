"""Camera calibration: ``ibiscape-eval calib`` against a careful OpenCV pipeline on the SAME views,
and event-camera calibration on a hand-held DVS sequence, both against the rendered truth.

    .venv/bin/python benchmarks/bench_calib.py                      # 100 stereo frames, 1024x1024
    .venv/bin/python benchmarks/bench_calib.py --frames 40 --targets aprilgrid --models radtan
    .venv/bin/python benchmarks/bench_calib.py --frames 0 --dvs-resolution 512   # DVS part only
    .venv/bin/python benchmarks/bench_calib.py --frames 0 --dvs-resolution 0 --dvs-drive 346x260 \
        --dvs-drive-s 30                          # the simulator's ESVI calibration drive (slow)

Frame cameras.  For each target (checkerboard 7x7, AprilGrid 6x6 as the simulator prints them) and
model (radtan; equidistant rendered by a fisheye-like lens) a stereo pair with the paper's cameras
(1024 x 1024, f = 512 px, 0.4 m baseline) sees the board in ``--frames`` varied poses 4-12 m away,
rendered by the simulator (``ibiscape_eval.sim.calib_views``) with its truth in ``sequence.yaml``.

- ours: ``ibiscape-eval calib SEQ --json --model ...`` in a fresh process (wall, CPU, peak RSS);
  it reports the view rows it kept (``view_rows_used``);
- peer, on exactly those views: OpenCV's detection (``findChessboardCornersSB`` with
  ``CALIB_CB_ACCURACY`` / tag36h11 ``aruco`` + ``cornerSubPix``), a consistent checkerboard
  numbering between the cameras, ``calibrateCamera`` (``fisheye.calibrate`` for equi) per camera,
  then ``stereoCalibrate`` (``tests/calib/_opencv_peer.py``).

Printed: focal and baseline difference ours vs OpenCV in %, both RMS side by side, detection time
per frame, wall-time RATIO (OpenCV / ours), and the accuracy of both against the truth.

Event cameras (``--dvs-resolution``, 0 to skip): a stereo DVS (0.2 m baseline) waved in front of
the board (``tests/calib/_dvs_handheld.py``: smooth motion through varied key poses, the
simulator's renderer and DVS model), calibrated by ``ibiscape-eval calib`` (``--reconstruction
auto``); errors against the truth beside the paper's Kalibr + E2CALIB result (1.55 px focal,
3 mm baseline).  ``--dvs-drive WxH``: the same on the simulator's ESVI calibration drive (``ibiscape-eval
sim --setup esvi --kind calibration --target ...``, stereo DVS 0.2 m apart approaching the board
head-on; about 16 s CPU per simulated second at 346x260), with the CPU time per reconstructed frame.
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
import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests" / "calib"))

from _runner import run

from ibiscape_eval.core.camera import CameraModel

CLI = str(Path(sys.executable).with_name("ibiscape-eval"))
CAMS = {
    "radtan": (CameraModel(1024, 1024, 512.0, 512.0, 511.5, 511.5, "radtan", (-0.05, 0.01, 0.0005, -0.0003)),
               CameraModel(1024, 1024, 512.0, 512.0, 511.5, 511.5, "radtan", (-0.04, 0.008, -0.0004, 0.0002))),
    "equi": (CameraModel(1024, 1024, 512.0, 512.0, 511.5, 511.5, "equidistant", (0.03, -0.01, 0.004, -0.001)),
             CameraModel(1024, 1024, 512.0, 512.0, 511.5, 511.5, "equidistant", (0.025, -0.008, 0.003, -0.0008))),
}
BASELINE_M = 0.4
PAPER_E2CALIB = {"focal_px": 1.55, "baseline_mm": 3.0}


def rig(baseline_m: float = BASELINE_M) -> np.ndarray:
    """``T_cam0_cam1``: the right camera ``baseline_m`` to the right, turned 0.5 deg."""
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("yxz", [0.5, 0.3, -0.2], degrees=True).as_matrix()
    T[:3, 3] = [baseline_m, 0.01, -0.005]
    return T


def sim_target(root: Path):
    from ibiscape_eval.calib import target_from_kalibr

    return target_from_kalibr(yaml.safe_load((root / "sequence.yaml").read_text())["target"])


def peer_on_views(seq: Path, kind: str, views: list[int], model: str) -> dict:
    """OpenCV's detection and calibration on the frames of the given view rows."""
    import cv2
    from _opencv_peer import opencv_detect, opencv_stereo

    from ibiscape_eval.calib.calibrate import Observations

    target = sim_target(seq)
    files = sorted((seq / "rgbL" / "frames").glob("*.png"))
    t0 = time.perf_counter()
    det_s = 0.0
    dl, dr = [], []
    for v in views:
        a = cv2.imread(str(files[v]), cv2.IMREAD_GRAYSCALE)
        b = cv2.imread(str(seq / "rgbR" / "frames" / files[v].name), cv2.IMREAD_GRAYSCALE)
        t = time.perf_counter()
        dl.append(opencv_detect(a, target))
        dr.append(opencv_detect(b, target))
        det_s += time.perf_counter() - t
    obs = (Observations("rgbL", (1024, 1024), dl), Observations("rgbR", (1024, 1024), dr))
    out = opencv_stereo(target, obs, (1024, 1024), equi=model == "equi")
    out["wall_s"] = time.perf_counter() - t0
    out["det_s_per_frame"] = det_s / max(2 * len(views), 1)
    return out


def frame_rows(a: argparse.Namespace, tmp: Path) -> list[dict]:
    import cv2

    from ibiscape_eval.calib.detect import detect_corners
    from ibiscape_eval.sim.calib_views import render_calibration_views

    rows = []
    for kind in a.targets:
        for model in a.models:
            seq = tmp / f"{kind}_{model}"
            t = time.perf_counter()
            cam_l, cam_r = CAMS[model]
            T10 = rig()
            render_calibration_views(seq, {"rgbL": cam_l, "rgbR": cam_r}, {"rgbR": T10}, target=kind,
                                     n_views=a.frames, seed=a.seed, distance_m=(4.0, 12.0))
            print(f"[{kind} {model}] rendered {2 * a.frames} frames in {time.perf_counter() - t:.0f} s",
                  flush=True)
            ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            r = run([CLI, "calib", str(seq), "--json", "--model", f"pinhole-{model}"])
            ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            if not r.ok:
                raise SystemExit(f"ibiscape-eval calib failed on {seq}")
            ours = json.loads(r.stdout)
            target = sim_target(seq)
            files = sorted((seq / "rgbL" / "frames").glob("*.png"))[:10]
            imgs = [cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in files]
            t = time.perf_counter()
            for img in imgs:
                if img is not None:
                    detect_corners(img, target)
            our_det = (time.perf_counter() - t) / len(imgs)
            cv = peer_on_views(seq, kind, [int(v) for v in ours["view_rows_used"]], model)
            rows.append({"kind": kind, "model": model, "ours": ours, "wall_s": r.wall_s, "peak_mb": r.peak_mb,
                         "cpu_s": (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime),
                         "our_det_s": our_det, "cv": cv, "true_baseline_m": float(np.linalg.norm(T10[:3, 3])),
                         "truth": (cam_l, cam_r)})
    return rows


def print_frame_rows(rows: list[dict]) -> None:
    print()
    print("Same views, ours vs OpenCV (difference of ours relative to OpenCV):")
    print(f"{'target':<13}{'model':<8}{'views':>6}{'max |df| %':>11}{'|db| %':>8}{'RMS ours':>10}"
          f"{'RMS OpenCV':>11}{'det/frame ours':>16}{'OpenCV':>9}{'wall ours':>11}{'OpenCV':>8}  RATIO")
    for r in rows:
        o, cv = r["ours"], r["cv"]
        df = max(abs(c["intrinsics"][i] / cv["K"][k][i, i] - 1) for k, c in enumerate(o["cameras"]) for i in (0, 1))
        db = abs(o["chain"][0]["baseline_m"] / cv["baseline_m"] - 1)
        print(f"{r['kind']:<13}{r['model']:<8}{o['n_views']:>6}{100 * df:>11.3f}{100 * db:>8.3f}"
              f"{o['rms_px']:>10.4f}{cv['rms_px']:>11.4f}{1e3 * r['our_det_s']:>13.0f} ms"
              f"{1e3 * cv['det_s_per_frame']:>6.0f} ms{r['wall_s']:>9.1f} s{cv['wall_s']:>6.1f} s"
              f"  {cv['wall_s'] / r['wall_s']:.2f}")
    print("issue: focal within 0.5 %, baseline within 1 %, our RMS <= OpenCV's; RATIO = OpenCV wall / ours "
          "(ours includes reading, detecting all frames, view selection; OpenCV only the selected views)")
    print()
    print("Accuracy against the rendered truth:")
    print(f"{'target':<13}{'model':<8}{'pipeline':<9}{'max |df| px':>12}{'max |dc| px':>12}{'baseline err mm':>16}")
    for r in rows:
        gt = r["ours"]["ground_truth"]
        print(f"{r['kind']:<13}{r['model']:<8}{'ours':<9}{gt['max_focal_error_px']:>12.3f}"
              f"{gt['max_principal_point_error_px']:>12.3f}{gt['max_baseline_error_mm']:>16.3f}")
        cv = r["cv"]
        f = max(abs(K[i, i] - c.fx if i == 0 else K[i, i] - c.fy) for K, c in zip(cv["K"], r["truth"], strict=True)
                for i in (0, 1))
        pp = max(max(abs(K[0, 2] - c.cx), abs(K[1, 2] - c.cy)) for K, c in zip(cv["K"], r["truth"], strict=True))
        print(f"{'':<21}{'OpenCV':<9}{f:>12.3f}{pp:>12.3f}{1e3 * abs(cv['baseline_m'] - r['true_baseline_m']):>16.3f}")
    print("issue targets: focal < 0.3 px, principal point < 0.5 px, baseline < 1 mm, RMS < 0.1 px")


def dvs_rows(a: argparse.Namespace, tmp: Path) -> list[dict]:
    from _dvs_handheld import write_handheld_dvs_sequence

    res = a.dvs_resolution
    f = res / 2.0
    cams = {"davisL": CameraModel(res, res, f, f, res / 2 - 0.5, res / 2 - 0.5, "radtan",
                                  (-0.05, 0.01, 0.0005, -0.0003)),
            "davisR": CameraModel(res, res, f, f, res / 2 - 0.5, res / 2 - 0.5, "radtan",
                                  (-0.04, 0.008, -0.0004, 0.0002))}
    rows = []
    for kind in a.targets:
        seq = tmp / f"dvs_{kind}"
        t = time.perf_counter()
        write_handheld_dvs_sequence(seq, cams, {"davisR": rig(0.2)}, target=kind, n_keys=a.dvs_keys,
                                    seed=a.seed, distance_m=(2.8, 5.0))
        print(f"[dvs {kind}] simulated {a.dvs_keys - 1} s of events at {res} px in "
              f"{time.perf_counter() - t:.0f} s", flush=True)
        r = run([CLI, "calib", str(seq), "--json"])
        doc = json.loads(r.stdout) if r.ok else None
        rows.append({"kind": kind, "doc": doc, "wall_s": r.wall_s, "returncode": r.returncode})
    return rows


def drive_rows(a: argparse.Namespace, tmp: Path) -> list[dict]:
    """The simulator's ESVI calibration drive per target (or the given ``--dvs-seq`` drives),
    calibrated by the calib command with the frames' corners and with the corners refined from
    the events."""
    seqs: list[tuple[str, Path]] = []
    for given in a.dvs_seq:
        doc = yaml.safe_load((Path(given) / "sequence.yaml").read_text())
        seqs.append((str(doc["target"]["target_type"]), Path(given)))
    for kind in (a.targets if not a.dvs_seq else []):
        seq = tmp / f"esvi_{kind}"
        ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        r = run([CLI, "sim", "--setup", "esvi", "--kind", "calibration", "--target", kind, "--resolution",
                 a.dvs_drive, "--duration-s", str(a.dvs_drive_s), "--seed", str(a.seed), "--out", str(seq)])
        ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if not r.ok:
            raise SystemExit(f"ibiscape-eval sim failed for {seq}")
        print(f"[dvs drive {kind}] simulated {a.dvs_drive_s} s at {a.dvs_drive} in "
              f"{(ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime):.0f} s CPU", flush=True)
        seqs.append((kind, seq))
    rows = []
    for kind, seq in seqs:
        n_frames = sum(len((seq / c / "timestamps.csv").read_text().splitlines()) - 1
                       for c in ("davisL", "davisR") if (seq / c / "timestamps.csv").exists())
        for corners in ("frames", "events") if kind == "checkerboard" else ("frames",):
            ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            r = run([CLI, "calib", str(seq), "--json", "--event-corners", corners,
                     "--max-views", str(a.dvs_max_views)])
            ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            doc = json.loads(r.stdout) if r.ok else None
            rows.append({"kind": kind, "corners": corners, "doc": doc, "wall_s": r.wall_s,
                         "returncode": r.returncode,
                         "cpu_ms_per_frame": 1e3 * ((ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime))
                         / max(n_frames, 1)})
    return rows


def print_dvs_rows(rows: list[dict], res: int | str, what: str = "hand-held stereo DVS") -> None:
    print()
    print(f"Event cameras, {what} at {res} px (paper, Kalibr + E2CALIB: "
          f"{PAPER_E2CALIB['focal_px']} px focal, {PAPER_E2CALIB['baseline_mm']} mm baseline):")
    print(f"{'target':<13}{'reconstruction':<16}{'corners':<8}{'frames with target':>19}{'views':>6}"
          f"{'max |df| px':>12}{'max |dc| px':>12}{'baseline err mm':>16}{'RMS px':>8}{'wall s':>8}")
    for r in rows:
        d = r["doc"]
        if d is None:
            print(f"{r['kind']:<13}calib failed (exit {r['returncode']}; run it on the sequence for the message)")
            continue
        gt = d["ground_truth"]
        method = "/".join(sorted({v["method"] for v in d["reconstruction"].values()}))
        found = "/".join(str(c["target_found"]) for c in d["detection"]["cameras"])
        refined = d["detection"].get("event_corner_refinement", {})
        if refined and any(v["method"] == "events" for v in refined.values()):
            found = "/".join(str(v["views_kept"]) for v in refined.values()) + " refined"
        per = f"{r['cpu_ms_per_frame']:>8.0f} ms/frame CPU" if "cpu_ms_per_frame" in r else ""
        print(f"{r['kind']:<13}{method:<16}{r.get('corners', 'frames'):<8}{found:>19}{d['n_views']:>6}"
              f"{gt['max_focal_error_px']:>12.3f}"
              f"{gt['max_principal_point_error_px']:>12.3f}{gt['max_baseline_error_mm']:>16.3f}"
              f"{d['rms_px']:>8.3f}{r['wall_s']:>8.1f}{per}")
    print("issue targets: focal < 0.3 px, principal point < 0.5 px, baseline < 1 mm, RMS < 0.1 px")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=100, help="stereo frames per sequence (0: skip)")
    ap.add_argument("--targets", nargs="+", default=["checkerboard", "aprilgrid"])
    ap.add_argument("--models", nargs="+", default=["radtan", "equi"], choices=["radtan", "equi"])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--dvs-resolution", type=int, default=256, help="DVS sensor size (0: skip)")
    ap.add_argument("--dvs-keys", type=int, default=6, help="key poses of the hand-held DVS motion (1 s apart)")
    ap.add_argument("--dvs-drive", default="", help="WxH: also the simulator's ESVI calibration drive (slow)")
    ap.add_argument("--dvs-drive-s", type=float, default=30.0, help="duration of that drive [s]")
    ap.add_argument("--dvs-seq", nargs="*", default=[], help="calibrate these generated ESVI drives instead "
                    "of simulating one (e.g. ibiscape-eval sim --setup esvi --kind calibration ...)")
    ap.add_argument("--dvs-max-views", type=int, default=160, help="--max-views of the drive calibrations")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_calib_") as d:
        rows = frame_rows(a, Path(d)) if a.frames > 0 else []
        drows = dvs_rows(a, Path(d)) if a.dvs_resolution > 0 else []
        erows = drive_rows(a, Path(d)) if a.dvs_drive or a.dvs_seq else []
    if rows:
        print_frame_rows(rows)
    if drows:
        print_dvs_rows(drows, a.dvs_resolution)
    if erows:
        print_dvs_rows(erows, a.dvs_drive or "their", "the ESVI calibration drive")
    print(f"load average during the run: {os.getloadavg()[0]:.1f} (2 cores)")


if __name__ == "__main__":
    main()
