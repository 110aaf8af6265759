"""Target detection on a calibration drive: every frame searched on its own (what OpenCV's
functions do when called per image, the exhaustive fallback included) against the sequence mode of
``ibiscape_eval.calib.detect_corners`` (``near=`` the previous frame's detection,
``exhaustive=False``), on the same frames, one thread.

    .venv/bin/python benchmarks/bench_detect.py                      # renders a 12 s 512 px drive
    .venv/bin/python benchmarks/bench_detect.py --seq SVI_calib --frames 600
    .venv/bin/python benchmarks/bench_detect.py --dvs ESVI_calib_aprilgrid --frames 300

Printed per target: CPU time per frame of both, frames with the target, corners found and the
largest difference between the two modes' corners (the same sub-pixel refinement, so it should be
far below 0.01 px), and the RATIO per-image / sequence mode (higher is better for us).

``--dvs SEQ`` (an AprilGrid sequence with DVS folders, e.g. ``ibiscape-eval sim --setup esvi --kind
calibration --target aprilgrid --resolution 346x260``): on the log-intensity frames of its first
DVS camera (reconstructed once, outside the timing), ``cv2.aruco``'s own decoding (what
``detect_corners`` does on RGB frames) against ``detect_corners(..., event_frame=True)``, both in
sequence mode: frames with the target, corners, CPU per frame and with the sequence's true
cameras the corner RMS against the truth.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]


def render(target: str, out: Path, size: int, duration_s: float) -> Path:
    seq = out / f"drive_{target}_{size}"
    if not (seq / "sequence.yaml").exists():
        subprocess.run([sys.executable, "-m", "cli.main", "sim", "--setup", "svi", "--kind", "calibration",
                        "--target", target, "--resolution", str(size), "--duration-s", str(duration_s),
                        "--seed", "3", "--out", str(seq)], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return seq


def measure(seq: Path, frames: int) -> None:
    import cv2

    from ibiscape_eval.calib import detect_corners
    from ibiscape_eval.core.kalibr import target_from_kalibr

    cv2.setNumThreads(1)
    doc = yaml.safe_load((seq / "sequence.yaml").read_text())
    target = target_from_kalibr(doc["target"])
    files = sorted((seq / "rgbL" / "frames").glob("*.png"))[:frames]
    images = [cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in files]
    c0 = time.process_time()
    alone = [detect_corners(im, target) for im in images]
    t_alone = time.process_time() - c0
    c0 = time.process_time()
    tracked, prev = [], None
    for im in images:
        prev = detect_corners(im, target, near=prev, exhaustive=False)
        tracked.append(prev)
    t_tracked = time.process_time() - c0
    diff = 0.0
    for a, b in zip(alone, tracked, strict=True):
        if a is not None and b is not None:
            _, ia, ib = np.intersect1d(a.ids, b.ids, return_indices=True)
            if len(ia):
                diff = max(diff, float(np.abs(a.corners_px[ia] - b.corners_px[ib]).max()))

    def found(ds: list) -> tuple[int, int]:
        return sum(d is not None for d in ds), sum(len(d) for d in ds if d is not None)

    n = max(1, len(images))
    (fa, ca), (ft, ct) = found(alone), found(tracked)
    print(f"{seq.name} ({target.target_type}, {len(images)} frames of {images[0].shape[1]} px):")
    print(f"  per image      {1e3 * t_alone / n:7.1f} ms/frame CPU  {fa:4d} frames  {ca:6d} corners")
    print(f"  sequence mode  {1e3 * t_tracked / n:7.1f} ms/frame CPU  {ft:4d} frames  {ct:6d} corners")
    print(f"  largest corner difference {diff:.1e} px; RATIO {t_alone / max(t_tracked, 1e-9):.2f}")


def measure_dvs(seq: Path, frames: int) -> None:
    import cv2

    from ibiscape_eval.calib import detect_corners
    from ibiscape_eval.calib.events import event_set_frames
    from ibiscape_eval.core.kalibr import target_from_kalibr
    from ibiscape_eval.io.open_sequence import open_sequence

    cv2.setNumThreads(1)
    doc = yaml.safe_load((seq / "sequence.yaml").read_text())
    target = target_from_kalibr(doc["target"])
    s = next(x for x in open_sequence(seq).cameras if doc["cameras"][x.name].get("kind") == "dvs")
    cam = doc["cameras"][s.name]
    size = (int(cam["resolution"][0]), int(cam["resolution"][1]))
    src, _ = event_set_frames(s.paths, s.windows_ns, size, target, reconstruction="log-intensity", camera_doc=cam)
    idx = np.unique(np.linspace(0, len(s) - 1, min(frames, len(s))).round().astype(int))
    images = [src(int(i)) for i in idx]
    truth = _dvs_truth(seq, doc, s.name, s.windows_ns[idx, 1], target)
    print(f"{seq.name} ({target.target_type}, {len(images)} event frames of {s.name}, {size[0]}x{size[1]}):")
    for label, event in (("aruco decoding", False), ("event_frame=True", True)):
        c0 = time.process_time()
        dets, prev = [], None
        for im in images:
            prev = detect_corners(im, target, near=prev, exhaustive=False, event_frame=event)
            dets.append(prev)
        t = time.process_time() - c0
        found = [(d, uv) for d, uv in zip(dets, truth, strict=True) if d is not None]
        n_c = sum(len(d) for d, _ in found)
        rms = (f"  RMS vs truth {np.sqrt(np.mean(np.concatenate([np.sum((d.corners_px - uv[d.ids])**2, axis=1) for d, uv in found]))):.3f} px"
               if found and truth[0] is not None else "")
        print(f"  {label:<17}{1e3 * t / len(images):7.1f} ms/frame CPU  {len(found):4d} frames  {n_c:6d} corners{rms}")


def _dvs_truth(seq: Path, doc: dict, name: str, stamps_ns: np.ndarray, target: object) -> list:
    """True corner projections at the frame instants (the sequence's ground truth), or Nones."""
    from scipy.spatial.transform import Rotation, Slerp

    from ibiscape_eval.core.camera import CameraModel
    from ibiscape_eval.io.ibiscape import read_ibiscape_groundtruth

    gt = seq / "vehicle_gt" / "groundtruth_sync.csv"
    if not gt.exists() or "T_world_target" not in doc["target"]:
        return [None] * len(stamps_ns)
    tr = read_ibiscape_groundtruth(gt).trajectory
    t_gt = tr.stamps_ns.astype(np.float64)
    cam = CameraModel.from_kalibr(doc["cameras"][name])
    T_wt = np.array(doc["target"]["T_world_target"])
    X = target.object_points() @ T_wt[:3, :3].T + T_wt[:3, 3]  # type: ignore[attr-defined]
    R = Slerp(t_gt, Rotation.from_quat(tr.quat_xyzw))(stamps_ns.astype(np.float64)).as_matrix()
    p = np.stack([np.interp(stamps_ns.astype(np.float64), t_gt, tr.pos_m[:, k]) for k in range(3)], axis=1)
    T_bc = np.array(doc["cameras"][name]["T_body_cam"])
    out = []
    for Ri, pi in zip(R, p, strict=True):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Ri, pi
        T = T @ T_bc
        out.append(cam.project((X - T[:3, 3]) @ T[:3, :3]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seq", type=Path, action="append", help="rendered calibration sequence(s)")
    ap.add_argument("--frames", type=int, default=240)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--duration-s", type=float, default=12.0)
    ap.add_argument("--dvs", type=Path, action="append", help="AprilGrid sequence(s) with DVS folders")
    args = ap.parse_args()
    if args.dvs:
        for s in args.dvs:
            measure_dvs(s, args.frames)
        return
    with tempfile.TemporaryDirectory() as tmp:
        seqs = args.seq or [render(t, Path(tmp), args.size, args.duration_s) for t in ("checkerboard", "aprilgrid")]
        for s in seqs:
            measure(s, args.frames)


if __name__ == "__main__":
    main()
