"""Camera calibration on REAL stereo checkerboard images: ``ibiscape-eval calib`` against a plain
OpenCV script, each in a fresh process, in the same run.

    .venv/bin/python benchmarks/bench_calib_real.py                  # the 13-pair fixture
    .venv/bin/python benchmarks/bench_calib_real.py --images-dir DIR --repeat 3   # any such folder

Images: ``DIR/left*.jpg`` and ``DIR/right*.jpg`` (paired by the number in their names) and
``DIR/target.yaml`` (Kalibr's checkerboard description); by default
``tests/data/real/opencv_stereo_checkerboard_640x480`` (OpenCV's 13 real 640x480 stereo sample
pairs, Apache-2.0, see its PROVENANCE.md).

- ours: ``ibiscape-eval calib --target DIR/target.yaml --images cam0=... --images cam1=... --json``;
- peer: what most users would write (:data:`PEER`): ``imread`` (grey), ``findChessboardCorners`` +
  ``cornerSubPix`` per image, ``calibrateCamera`` per camera, ``stereoCalibrate`` with the
  intrinsics fixed; one process, no threads of its own.

Both run as installed (bytecode caches written by one untimed run first, whatever
``PYTHONDONTWRITEBYTECODE`` says), taking turns run by run so that both see the same load.
Printed per tool: wall, CPU (user + system) and peak RSS (GNU time), the median of ``--repeat``
runs, the wall and CPU RATIO ours / OpenCV, the load average, and the results side by side (fx, fy
per camera, baseline, RMS; ours with its standard deviations).  ``--json PATH`` writes them.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: both tools run as installed: with their bytecode caches (a shell with PYTHONDONTWRITEBYTECODE
#: would recompile every module of the package, 0.1-0.2 s, at every run)
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
DEFAULT_DIR = HERE.parent / "tests" / "data" / "real" / "opencv_stereo_checkerboard_640x480"

PEER = r'''
import glob, json, os, sys
import cv2
import numpy as np
import yaml

d = sys.argv[1]
t = yaml.safe_load(open(os.path.join(d, "target.yaml")))
cols, rows = int(t["targetCols"]), int(t["targetRows"])
obj = np.zeros((rows * cols, 3), np.float32)
obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2)
obj[:, 0] *= float(t["colSpacingMeters"])
obj[:, 1] *= float(t["rowSpacingMeters"])
crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3)
pts = {"left": [], "right": []}
size = None
for fl, fr in zip(sorted(glob.glob(os.path.join(d, "left*.jpg"))),
                  sorted(glob.glob(os.path.join(d, "right*.jpg")))):
    found = []
    for f in (fl, fr):
        g = cv2.imread(f, cv2.IMREAD_GRAYSCALE)
        size = g.shape[::-1]
        ok, c = cv2.findChessboardCorners(g, (cols, rows))
        if ok:
            c = cv2.cornerSubPix(g, c, (11, 11), (-1, -1), crit)
        found.append(c if ok else None)
    if found[0] is not None and found[1] is not None:
        pts["left"].append(found[0])
        pts["right"].append(found[1])
objs = [obj] * len(pts["left"])
out = {"views": len(objs)}
Ks, Ds = [], []
for side in ("left", "right"):
    rms, K, D, _, _ = cv2.calibrateCamera(objs, pts[side], size, None, None)
    Ks.append(K)
    Ds.append(D)
    out[side] = {"fx": K[0, 0], "fy": K[1, 1], "cx": K[0, 2], "cy": K[1, 2], "rms_px": rms}
rms, *_, R, T, E, F = cv2.stereoCalibrate(objs, pts["left"], pts["right"], Ks[0], Ds[0], Ks[1],
                                          Ds[1], size, flags=cv2.CALIB_FIX_INTRINSIC)
out["baseline"] = float(np.linalg.norm(T))
out["rms_px"] = rms
print(json.dumps(out, default=float))
'''


def timed(cmd: list[str]) -> tuple[dict[str, float], str]:
    """Run ``cmd`` in a fresh process under GNU time: wall, user + system CPU [s], peak RSS [MB]."""
    with tempfile.NamedTemporaryFile(prefix="time_", suffix=".txt") as f:
        proc = subprocess.run(["/usr/bin/time", "-q", "-f", "%e %U %S %M", "-o", f.name, *cmd],
                              capture_output=True, text=True, check=False, env=ENV)
        if proc.returncode != 0:
            sys.exit(f"{' '.join(cmd[:3])} ... failed:\n{proc.stderr[-2000:]}")
        wall, user, sys_s, rss = Path(f.name).read_text().split()[-4:]
    return {"wall_s": float(wall), "cpu_s": float(user) + float(sys_s), "peak_mb": int(rss) / 1024}, proc.stdout


def interleaved_runs(cmds: dict[str, list[str]], repeat: int) -> dict[str, tuple[dict[str, float], str]]:
    """Per command, the median of ``repeat`` runs and the last run's output, the commands taking
    turns (so that both see the same load), after one untimed run each (which writes the
    bytecode caches)."""
    for cmd in cmds.values():
        timed(cmd)
    runs: dict[str, list[tuple[dict[str, float], str]]] = {name: [] for name in cmds}
    for _ in range(repeat):
        for name, cmd in cmds.items():
            runs[name].append(timed(cmd))
    out = {}
    for name, rr in runs.items():
        keys = rr[0][0]
        out[name] = ({k: statistics.median(r[0][k] for r in rr) for k in keys}, rr[-1][1])
    return out


def ours_cmd(d: Path) -> list[str]:
    exe = Path(sys.executable).parent / "ibiscape-eval"
    head = [str(exe)] if exe.exists() else [sys.executable, "-m", "ibiscape_eval.cli.main"]
    return [*head, "calib", "--target", str(d / "target.yaml"), "--images", f"cam0={d}/left*.jpg",
            "--images", f"cam1={d}/right*.jpg", "--json"]


def ours_numbers(doc: dict) -> dict:
    cams = doc["cameras"]
    return {"views": doc["n_views"],
            **{side: {"fx": c["intrinsics"][0], "fy": c["intrinsics"][1],
                      "fx_std": c["intrinsics_std"][0], "fy_std": c["intrinsics_std"][1],
                      "rms_px": c["reprojection_error"]["rms_px"]}
               for side, c in zip(("left", "right"), cams, strict=True)},
            "baseline": doc["chain"][0]["baseline_m"], "baseline_std": doc["chain"][0]["baseline_std_m"],
            "rms_px": doc["rms_px"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images-dir", type=Path, default=DEFAULT_DIR)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    d = a.images_dir.resolve()
    n_pairs = len(list(d.glob("left*.jpg")))
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        peer_py = Path(tmp) / "opencv_stereo.py"
        peer_py.write_text(PEER)
        res = interleaved_runs({"opencv": [sys.executable, str(peer_py), str(d)], "ours": ours_cmd(d)},
                               a.repeat)
    (peer_t, peer_out), (ours_t, ours_out) = res["opencv"], res["ours"]
    peer, ours = json.loads(peer_out), ours_numbers(json.loads(ours_out))
    load = os.getloadavg()
    print(f"{n_pairs} real stereo pairs in {d}; median of {a.repeat} runs each, taking turns; load "
          f"average {load0[0]:.1f} at the start, {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} at the "
          f"end ({os.cpu_count()} cores)")
    print(f"{'':22s}{'wall s':>9s}{'CPU s':>9s}{'peak MB':>9s}")
    for name, t in (("ibiscape-eval calib", ours_t), ("plain OpenCV script", peer_t)):
        print(f"{name:22s}{t['wall_s']:9.2f}{t['cpu_s']:9.2f}{t['peak_mb']:9.0f}")
    ratio = {k: ours_t[k] / peer_t[k] for k in ("wall_s", "cpu_s", "peak_mb")}
    print(f"{'RATIO ours / OpenCV':22s}{ratio['wall_s']:9.2f}{ratio['cpu_s']:9.2f}{ratio['peak_mb']:9.2f}")
    print(f"\n{'':22s}{'ours':>22s}{'OpenCV':>12s}")
    for side in ("left", "right"):
        for k in ("fx", "fy"):
            o = ours[side]
            print(f"{side + ' ' + k:22s}{o[k]:12.3f} +- {o[k + '_std']:5.3f}{peer[side][k]:12.3f}")
    print(f"{'baseline [squares]':22s}{ours['baseline']:12.4f} +- {ours['baseline_std']:5.4f}"
          f"{peer['baseline']:12.4f}")
    print(f"{'RMS px':22s}{ours['rms_px']:12.4f}{'':9s}{peer['rms_px']:12.4f}")
    print(f"{'views':22s}{ours['views']:12d}{'':9s}{peer['views']:12d}")
    if a.json:
        a.json.write_text(json.dumps({"pairs": n_pairs, "load_avg_start": load0, "load_avg": load,
                                      "ours": ours_t,
                                      "opencv": peer_t, "ratio": ratio, "results_ours": ours,
                                      "results_opencv": peer}, indent=1, default=float))


if __name__ == "__main__":
    main()
