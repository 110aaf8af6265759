"""Stereo-VIO baseline: ATE/RPE and speed on clear, moderate and dynamic SVI sequences, as a table
shaped like the paper's ``table:evaluation`` with its ORB-SLAM3 and BASALT figures beside ours.

    .venv/bin/python benchmarks/bench_vio.py                      # render 3 x 60 s at 512 px, run
    .venv/bin/python benchmarks/bench_vio.py --sequences A B C    # rendered folders you already have
    .venv/bin/python benchmarks/bench_vio.py --synthetic          # no images: back end only

Each estimate comes from ``ibiscape-eval vio SEQ -o est.txt --json`` in a fresh process (wall time,
peak RSS); ATE after SE(3) alignment and RPE over 1 s (mean +- std) come from the project's own
metrics.  The speed column is the speed-up over real time (sequence seconds per wall-clock second
and, in brackets, per second of the process's CPU time, which other load on this shared machine
does not inflate).  ``--speed-1024`` adds a 10 s 1024 x 1024 run for the speed factor there.

``--synthetic`` runs the same estimator on synthetic stereo measurements (landmarks around the
route, 0.5 px noise) of ``--no-render`` sequences: the back end's accuracy without a front end.

The paper's figures are for the real IBISCape SVI sequences (CARLA, 1024 px), not for ours: they
are quoted for context, not as a same-data comparison.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _runner import run

CLI = str(Path(sys.executable).with_name("ibiscape-eval"))

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


def _score(est_path: Path, seq: Path) -> dict[str, float]:
    from ibiscape_eval.io import read_trajectory
    from ibiscape_eval.metrics import ate, rpe

    est = read_trajectory(est_path, "tum")
    gt = read_trajectory(seq / "vehicle_gt" / "groundtruth_sync.csv", "ibiscape")
    a = ate(est, gt, align="se3", max_diff_s=0.02)
    r = rpe(est, gt, delta=1.0, delta_unit="seconds", max_diff_s=0.02)
    return {"ate_m": a.translation_m.rmse, "length_m": float(a.ref.path_length_m()[-1]),
            "rpe_m": r.translation_m.mean, "rpe_m_std": r.translation_m.std,
            "rpe_deg": r.rotation_deg.mean, "rpe_deg_std": r.rotation_deg.std}


def _vio(seq: Path, tmp: Path) -> dict[str, float]:
    est = tmp / f"{seq.name}_est.txt"
    r = run([CLI, "vio", str(seq), "-o", str(est), "--json"])
    if not r.ok:
        raise SystemExit(f"ibiscape-eval vio {seq} failed")
    doc = json.loads(r.stdout)
    row = _score(est, seq)
    row.update(wall_s=r.wall_s, peak_mb=r.peak_mb, speed=doc["realtime_factor"],
               cpu_speed=doc["cpu_realtime_factor"], failures=len(doc["failures"]),
               poses=doc["poses"], frames=doc["frames"])
    return row


def _synthetic(seq: Path) -> dict[str, float]:
    import numpy as np

    from ibiscape_eval.metrics import ate, rpe
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
    a = ate(tr, gt, align="se3")
    r = rpe(tr, gt, delta=1.0, delta_unit="seconds")
    dur = (gt.stamps_ns[-1] - gt.stamps_ns[0]) * 1e-9
    return {"ate_m": a.translation_m.rmse, "length_m": float(gt.path_length_m()[-1]),
            "rpe_m": r.translation_m.mean, "rpe_m_std": r.translation_m.std,
            "rpe_deg": r.rotation_deg.mean, "rpe_deg_std": r.rotation_deg.std,
            "wall_s": wall, "peak_mb": float("nan"), "speed": dur / wall, "cpu_speed": dur / cpu,
            "failures": len(est.failures), "poses": len(tr), "frames": len(obs),
            "mean_obs": float(np.mean([len(o) for o in obs]))}


def _fmt(v: float, s: float) -> str:
    return f"{v:.4f}±{s:.4f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", nargs="*", type=Path, help="rendered SVI sequence folders")
    ap.add_argument("--synthetic", action="store_true", help="synthetic measurements, no images")
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--resolution", type=int, default=512)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--speed-1024", action="store_true", help="also a 10 s run at 1024 x 1024")
    ap.add_argument("--keep", type=Path, default=None, help="keep generated sequences here")
    a = ap.parse_args()
    rows: list[tuple[str, str, dict[str, float]]] = []
    with tempfile.TemporaryDirectory(prefix="bench_vio_") as d:
        tmp = Path(d)
        root = a.keep or tmp
        if a.sequences:
            import yaml

            for seq in a.sequences:
                doc = yaml.safe_load((seq / "sequence.yaml").read_text())
                weather = (doc.get("weather") or {}).get("preset", "clear")
                rows.append((seq.name, weather, _vio(seq, tmp)))
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
                rows.append((seq.name, weather, _synthetic(seq) if a.synthetic else _vio(seq, tmp)))
        if a.speed_1024 and not a.synthetic:
            seq = root / "SVI_clear_1024"
            if not seq.exists():
                _render("clear", seq, seed=a.seed, duration_s=10.0, resolution=1024)
            rows.append((seq.name + " (speed)", "clear", _vio(seq, tmp)))
    mode = "synthetic measurements (no images)" if a.synthetic else "rendered images"
    print(f"\nibiscape-eval vio on {mode}; ATE after SE(3) alignment, RPE over 1 s (mean ± std)")
    head = (f"{'sequence':<24}{'length':>8}{'ATE [m]':>9}{'ATE %':>7}{'target':>7}  "
            f"{'RPE [m]':>15}  {'RPE [deg]':>15}{'fail':>5}  speed-up (CPU)")
    print(head)
    for name, weather, r in rows:
        pct = 100 * r["ate_m"] / max(r["length_m"], 1e-9)
        print(f"{name:<24}{r['length_m']:>7.0f}m{r['ate_m']:>9.3f}{pct:>6.2f}%"
              f"{TARGET_PCT[weather]:>6.0f}%  {_fmt(r['rpe_m'], r['rpe_m_std']):>15}  "
              f"{_fmt(r['rpe_deg'], r['rpe_deg_std']):>15}{int(r['failures']):>5}  "
              f"x{r['speed']:.2f} (x{r['cpu_speed']:.2f})")
    print("\nthe paper's table:evaluation, SVI setup (real IBISCape sequences, ~140 m; for context):")
    print(f"{'sequence':<24}{'system':<11}{'ATE [m]':>9}  {'RPE [m]':>15}  {'RPE [deg]':>15}")
    for weather, systems in PAPER.items():
        for system, seqs in systems.items():
            for i, (ate_m, rm, rs, dm, ds) in enumerate(seqs, start=1):
                print(f"{weather.capitalize() + '-' + str(i):<24}{system:<11}{ate_m:>9.4f}  "
                      f"{_fmt(rm, rs):>15}  {_fmt(dm, ds):>15}")


if __name__ == "__main__":
    main()
