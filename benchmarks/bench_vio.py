"""Stereo-VIO baseline: ATE/RPE and speed on clear, moderate and dynamic SVI sequences, as a table
shaped like the paper's ``table:evaluation`` with its ORB-SLAM3 and BASALT figures beside ours.

    .venv/bin/python benchmarks/bench_vio.py                      # render 3 x 60 s at 512 px, run
    .venv/bin/python benchmarks/bench_vio.py --sequences A B C    # rendered folders you already have
    .venv/bin/python benchmarks/bench_vio.py --synthetic          # no images: back end only

Each estimate is run in this process, frame by frame like ``run_vio`` (image reading, front end,
estimator), timing each stage by the CPU time of the whole process (all threads: OpenCV's and
GTSAM's worker threads count), which other load on this shared machine inflates far less than
wall time.  Like ``run_vio``, the right image is decoded and matched only for the frames that
need stereo (keyframes, initialisation, lost spans; column ``stereo``); its decoding counts as
reading.  The runs take ``VioParams.for_setup("svi")`` (what ``run_vio`` takes for these
sequences); ``--set NAME=VALUE ...`` changes its options.  One
table per setup and weather: ATE after SE(3) alignment and RPE over 1 s (mean +- std) from the
project's own metrics, the CPU milliseconds per frame of the front end (``StereoFrontEnd``) and
of the back end (``Estimator``: keyframes, smoother), and the speed-up over real time by CPU time
(sequence seconds per CPU second of reading + front end + back end) and by wall time.  OpenCV
runs on ``--cv-threads`` threads (default 1, as ``ibiscape-eval vio`` runs it; 0: OpenCV's own
default, which costs 15-25 % more CPU time per frame at 512 px for no shorter wall time).
``--cli`` runs ``ibiscape-eval vio SEQ -o est.txt --json`` in a fresh process instead (wall time,
peak RSS, no split).  ``--speed-1024`` adds a 10 s 1024 x 1024 run for the speed factor there;
``--max-frames N`` stops each run after N frames (a quick profile).  ``--keep DIR --render-only``
renders the three sequences into DIR (and writes ``DIR/READY``) without running anything;
``bench_vio_backend.py`` times the back end alone on them.

Only the SVI setup has a baseline today (ESVI and RGB-D are issue #24's other parts).

``--synthetic`` runs the same estimator on synthetic stereo measurements (landmarks around the
route, 0.5 px noise) of ``--no-render`` sequences: the back end's accuracy without a front end.

The paper's figures are for the real IBISCape SVI sequences (CARLA, 1024 px), not for ours: they
are quoted for context, not as a same-data comparison.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _runner import run

CLI = str(Path(sys.executable).with_name("ibiscape-eval"))
#: poses (N, 4, 4) of the latest in-process run (to check that a speed change keeps the estimate)
LAST_TRAJ: Any = None

#: the paper's table:evaluation, SVI setup: (ATE m, RPE m mean, std, RPE deg mean, std)
PAPER = {
    "clear": {"ORB-SLAM3": [(3.1262, 0.1145, 0.0728, 0.2699, 0.4272),
                            (1.6666, 0.1076, 0.0577, 0.3646, 0.4795)],
              "BASALT": [(12.2769, 0.1859, 0.0234, 0.0839, 0.4300),
                         (4.0626, 0.0514, 0.0845, 0.0919, 0.2049)]},
    "moderate": {"ORB-SLAM3": [(11.5160, 0.0496, 0.0913, 0.1278, 0.3385),
                               (8.8561, 0.3207, 0.1681, 0.5831, 0.7833)],
                 "BASALT": [(70.1406, 0.1290, 0.0712, 0.1087, 0.5707),
                            (27.4657, 0.3587, 0.1527, 0.1519, 0.3228)]},
    "dynamic": {"ORB-SLAM3": [(50.7355, 0.2580, 0.1351, 1.1411, 1.0240),
                              (9.5503, 0.1188, 0.1445, 0.1338, 0.4248)],
                "BASALT": [(12.4161, 0.1853, 0.1512, 0.2324, 0.4938),
                           (41.4773, 0.2414, 0.1277, 0.0921, 0.5366)]},
}
TARGET_PCT = {"clear": 1.0, "moderate": 2.0, "dynamic": 3.0}


def _render(weather: str, out: Path, *, seed: int, duration_s: float, resolution: int) -> None:
    cmd = [CLI, "sim", "--setup", "svi", "--kind", "slam", "--weather", weather, "--seed",
           str(seed), "--duration-s", str(duration_s), "--resolution", str(resolution),
           "--out", str(out)]
    if subprocess.run(cmd, check=False, stdout=subprocess.DEVNULL).returncode != 0:
        raise SystemExit(f"rendering failed: {' '.join(cmd)} (this needs the renderer; use "
                         "--synthetic or --sequences)")


def _ate(est: Any, gt: Any, **kw: Any) -> tuple[Any, str]:
    """ATE after SE(3) alignment, or after 4-DoF (yaw) alignment on a straight path (a short
    sequence), where the roll about the path line is undetermined."""
    from ibiscape_eval.core.errors import DegenerateInputError
    from ibiscape_eval.metrics import ate

    try:
        return ate(est, gt, align="se3", **kw), "se3"
    except DegenerateInputError:
        return ate(est, gt, align="yaw", **kw), "yaw"


def _score(est_path: Path, seq: Path) -> dict[str, float]:
    from ibiscape_eval.io import read_trajectory
    from ibiscape_eval.metrics import rpe

    est = read_trajectory(est_path, "tum")
    gt = read_trajectory(seq / "vehicle_gt" / "groundtruth_sync.csv", "ibiscape")
    a, align = _ate(est, gt, max_diff_s=0.02)
    r = rpe(est, gt, delta=1.0, delta_unit="seconds", max_diff_s=0.02)
    return {"ate_m": a.translation_m.rmse, "length_m": float(a.ref.path_length_m()[-1]),
            "yaw_aligned": float(align == "yaw"), "rpe_m": r.translation_m.mean, "rpe_m_std": r.translation_m.std,
            "rpe_deg": r.rotation_deg.mean, "rpe_deg_std": r.rotation_deg.std}


def _vio(seq: Path, tmp: Path, cv_threads: int) -> dict[str, float]:
    est = tmp / f"{seq.name}_est.txt"
    r = run([CLI, "vio", str(seq), "-o", str(est), "--json", "--cv-threads", str(cv_threads)])
    if not r.ok:
        raise SystemExit(f"ibiscape-eval vio {seq} failed")
    doc = json.loads(r.stdout)
    row = _score(est, seq)
    row.update(wall_s=r.wall_s, peak_mb=r.peak_mb, speed=doc["realtime_factor"],
               cpu_speed=doc["cpu_realtime_factor"], failures=len(doc["failures"]),
               poses=doc["poses"], frames=doc["frames"])
    return row


def _inprocess(seq: Path, max_frames: int | None, params: Any = None) -> dict[str, float]:
    """The VIO loop of ``run_vio`` with each stage timed by process CPU time (all threads)."""
    from ibiscape_eval.io.stereo import read_gray_image
    from ibiscape_eval.vio import Estimator, StereoFrontEnd, VioParams, load_sequence

    s = load_sequence(seq)
    p = params or VioParams.for_setup("svi")
    n = s.n_frames if max_frames is None else min(max_frames, s.n_frames)
    fe = StereoFrontEnd(s.rig, p)
    est = Estimator(s.rig.rectified(), s.imu, s.noise, p, s.T_body_imu)
    cpu = {"read": 0.0, "front": 0.0, "back": 0.0}
    clock = time.process_time
    w0 = time.perf_counter()
    prev: int | None = None
    stereo = 0
    for i in range(n):
        t_ns = int(s.frame_stamps_ns[i])
        c0 = clock()
        left = read_gray_image(s.left_files[i])
        c1 = clock()
        R = None if prev is None else est.gyro_rotation(prev, t_ns)
        obs = fe.track(t_ns, left, R)
        if est.needs_stereo(obs):  # like run_vio: the right image only for stereo frames
            c2 = clock()
            right = read_gray_image(s.right_files[i])
            c1 += clock() - c2
            obs = fe.match(right)
            stereo += 1
        c2 = clock()
        est.process(obs)
        c3 = clock()
        prev = t_ns
        cpu["read"] += c1 - c0
        cpu["front"] += c2 - c1
        cpu["back"] += c3 - c2
    c0 = clock()
    est.finish()
    tr = est.trajectory()
    cpu["back"] += clock() - c0
    global LAST_TRAJ
    LAST_TRAJ = (tr.stamps_ns.copy(), tr.matrices())
    wall = time.perf_counter() - w0
    dur = (int(s.frame_stamps_ns[n - 1]) - int(s.frame_stamps_ns[0])) * 1e-9
    from ibiscape_eval.io import write_trajectory

    with tempfile.TemporaryDirectory(prefix="bench_vio_est_") as d:
        est_path = Path(d) / "est.txt"
        write_trajectory(est_path, tr, "tum")
        row = _score(est_path, seq)
    total = sum(cpu.values())
    import resource

    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: KiB
    row.update(wall_s=wall, peak_mb=peak_mb, speed=dur / wall, cpu_speed=dur / total,
               failures=len(est.failures), poses=len(tr), frames=n,
               read_ms=1e3 * cpu["read"] / n, front_ms=1e3 * cpu["front"] / n,
               back_ms=1e3 * cpu["back"] / n, nopng_cpu_speed=dur / (cpu["front"] + cpu["back"]),
               stereo_frames=stereo)
    return row


def _params(items: list[str]) -> Any:
    import dataclasses

    from ibiscape_eval.vio import VioParams

    types = {f.name: type(getattr(VioParams(), f.name)) for f in dataclasses.fields(VioParams)}
    kw = {}
    for item in items:
        name, _, value = item.partition("=")
        if name not in types:
            raise SystemExit(f"--set {item}: no VioParams option {name!r}")
        kw[name] = types[name](value)
    return VioParams.for_setup("svi", **kw)


def _synthetic(seq: Path) -> dict[str, float]:
    import numpy as np

    from ibiscape_eval.metrics import rpe
    from ibiscape_eval.vio import Estimator, StereoRig, VioParams, load_sequence
    from ibiscape_eval.vio.synthetic import random_landmarks, synthetic_observations

    s = load_sequence(seq, require_images=False)
    rig = StereoRig(s.rig.left.scaled(512, 512), s.rig.right.scaled(512, 512), s.rig.T_body_left,
                    s.rig.T_body_right)
    gt = s.groundtruth
    assert gt is not None
    obs = synthetic_observations(gt, rig, gt.stamps_ns[::10], random_landmarks(gt, seed=1), seed=2)
    t0, c0 = time.perf_counter(), time.process_time()
    est = Estimator(rig.rectified(), s.imu, s.noise, VioParams(), s.T_body_imu)
    for o in obs:
        est.process(o)
    est.finish()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    tr = est.trajectory()
    a, align = _ate(tr, gt)
    r = rpe(tr, gt, delta=1.0, delta_unit="seconds")
    dur = (gt.stamps_ns[-1] - gt.stamps_ns[0]) * 1e-9
    return {"ate_m": a.translation_m.rmse, "length_m": float(gt.path_length_m()[-1]),
            "yaw_aligned": float(align == "yaw"), "rpe_m": r.translation_m.mean, "rpe_m_std": r.translation_m.std,
            "rpe_deg": r.rotation_deg.mean, "rpe_deg_std": r.rotation_deg.std,
            "wall_s": wall, "peak_mb": float("nan"), "speed": dur / wall, "cpu_speed": dur / cpu,
            "failures": len(est.failures), "poses": len(tr), "frames": len(obs),
            "mean_obs": float(np.mean([len(o) for o in obs]))}


def _fmt(v: float, s: float) -> str:
    return f"{v:.4f}±{s:.4f}"


def _cpu_table(rows: list[tuple[str, str, dict[str, float]]]) -> None:
    """CPU milliseconds per frame of reading, front end and back end (in-process runs)."""
    if not any("front_ms" in r for _, _, r in rows):
        return
    print("\nSVI setup: CPU time per frame (process CPU time, all threads), speed-up by CPU time")
    print(f"{'sequence':<24}{'weather':<10}{'frames':>7}{'stereo':>7}{'read':>8}{'front':>8}"
          f"{'back':>8}{'  x real time (CPU)':>20}{'  without PNG':>14}{'  wall':>8}"
          f"{'  peak RSS':>11}")
    for name, weather, r in rows:
        if "front_ms" in r:
            print(f"{name:<24}{weather:<10}{int(r['frames']):>7}{int(r['stereo_frames']):>7}"
                  f"{r['read_ms']:>6.1f}ms{r['front_ms']:>6.1f}ms{r['back_ms']:>6.1f}ms"
                  f"{r['cpu_speed']:>19.2f}x{r['nopng_cpu_speed']:>13.2f}x{r['speed']:>7.2f}x"
                  f"{r['peak_mb']:>8.0f} MB")
    print(f"(stereo: frames whose right image was decoded and matched; peak RSS of this "
          f"process so far; load average {os.getloadavg()[0]:.1f}; OpenCV threads {_cv_threads()})")


def _cv_threads() -> int:
    import cv2

    return int(cv2.getNumThreads())


def _args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", nargs="*", type=Path, help="rendered SVI sequence folders")
    ap.add_argument("--synthetic", action="store_true", help="synthetic measurements, no images")
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--resolution", type=int, default=512)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--speed-1024", action="store_true", help="also a 10 s run at 1024 x 1024")
    ap.add_argument("--keep", type=Path, default=None, help="keep generated sequences here")
    ap.add_argument("--render-only", action="store_true",
                    help="render the sequences into --keep (and write READY there), run nothing")
    ap.add_argument("--cli", action="store_true",
                    help="run the CLI in a fresh process (wall time, peak RSS; no front/back split)")
    ap.add_argument("--max-frames", type=int, default=None, help="stop each run after N frames")
    ap.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                    help="VioParams options of the in-process runs, e.g. --set klt_levels=3")
    ap.add_argument("--cv-threads", type=int, default=1,
                    help="OpenCV threads, as `ibiscape-eval vio --cv-threads` (its default 1; 0: OpenCV's)")
    a = ap.parse_args()
    if a.cv_threads > 0 and not a.cli:  # what the CLI's run does (core.cpus.opencv_threads)
        import cv2

        cv2.setNumThreads(a.cv_threads)
    return a


def main() -> None:
    a = _args()
    if a.render_only and a.keep is None:
        raise SystemExit("--render-only needs --keep DIR")
    params = _params(a.set)

    def vio(seq: Path) -> dict[str, float]:
        return _vio(seq, tmp, a.cv_threads) if a.cli else _inprocess(seq, a.max_frames, params)

    rows: list[tuple[str, str, dict[str, float]]] = []
    with tempfile.TemporaryDirectory(prefix="bench_vio_") as d:
        tmp = Path(d)
        root = a.keep or tmp
        if a.sequences:
            import yaml

            for seq in a.sequences:
                doc = yaml.safe_load((seq / "sequence.yaml").read_text())
                weather = (doc.get("weather") or {}).get("preset", "clear")
                rows.append((seq.name, weather, vio(seq)))
        else:
            for weather in ("clear", "moderate", "dynamic"):
                seq = root / f"SVI_{weather}_{a.resolution}"
                if not seq.exists():
                    if a.synthetic:
                        cmd = [CLI, "sim", "--setup", "svi", "--kind", "slam", "--weather",
                               weather, "--seed", str(a.seed), "--duration-s",
                               str(a.duration_s), "--no-render", "--out", str(seq)]
                        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
                    else:
                        _render(weather, seq, seed=a.seed, duration_s=a.duration_s,
                                resolution=a.resolution)
                if not a.render_only:
                    rows.append((seq.name, weather, _synthetic(seq) if a.synthetic else vio(seq)))
        if a.render_only:
            (root / "READY").write_text("rendered by benchmarks/bench_vio.py --render-only\n")
            return
        if a.speed_1024 and not a.synthetic:
            seq = root / "SVI_clear_1024"
            if not seq.exists():
                _render("clear", seq, seed=a.seed, duration_s=10.0, resolution=1024)
            rows.append((seq.name + " (speed)", "clear", vio(seq)))
    mode = "synthetic measurements (no images)" if a.synthetic else "rendered images"
    print(f"\nibiscape-eval vio on {mode}; ATE after SE(3) alignment, RPE over 1 s (mean ± std)")
    head = (f"{'sequence':<24}{'length':>8}{'ATE [m]':>9}{'ATE %':>7}{'target':>7}  "
            f"{'RPE [m]':>15}  {'RPE [deg]':>15}{'fail':>5}  speed-up (CPU)")
    print(head)
    for name, weather, r in rows:
        pct = 100 * r["ate_m"] / max(r["length_m"], 1e-9)
        star = "*" if r.get("yaw_aligned") else " "
        print(f"{name:<24}{r['length_m']:>7.0f}m{r['ate_m']:>8.3f}{star}{pct:>6.2f}%"
              f"{TARGET_PCT[weather]:>6.0f}%  {_fmt(r['rpe_m'], r['rpe_m_std']):>15}  "
              f"{_fmt(r['rpe_deg'], r['rpe_deg_std']):>15}{int(r['failures']):>5}  "
              f"x{r['speed']:.2f} (x{r['cpu_speed']:.2f})")
    _cpu_table(rows)
    if any(r.get("yaw_aligned") for _, _, r in rows):
        print("* a straight path: ATE after 4-DoF (yaw) alignment, SE(3) is undetermined")
    print("\nthe paper's table:evaluation, SVI setup (real IBISCape sequences, ~140 m; for context):")
    print(f"{'sequence':<24}{'system':<11}{'ATE [m]':>9}  {'RPE [m]':>15}  {'RPE [deg]':>15}")
    for weather, systems in PAPER.items():
        for system, seqs in systems.items():
            for i, (ate_m, rm, rs, dm, ds) in enumerate(seqs, start=1):
                print(f"{weather.capitalize() + '-' + str(i):<24}{system:<11}{ate_m:>9.4f}  "
                      f"{_fmt(rm, rs):>15}  {_fmt(dm, ds):>15}")


if __name__ == "__main__":
    main()
