"""Camera-IMU calibration on simulated 60 s calibration drives: accuracy against the exact truth
and run time.

    .venv/bin/python benchmarks/bench_imu_camera.py                 # 1024 px and 512 px, bumps
    .venv/bin/python benchmarks/bench_imu_camera.py --size 512 --flat --four
    ibiscape-eval sim --config calib60.yaml --resolution 512 --out SVI_calib   # rendered drive
    .venv/bin/python benchmarks/bench_imu_camera.py --size 0 --seq SVI_calib [--cams camchain.yaml]

    .venv/bin/python benchmarks/bench_imu_camera.py --rendered --offsets-ms -20,-9.7,0,4.3,20 \
        --targets checkerboard,aprilgrid --size 512 --duration 60 --cache /tmp/imu_renders \
        --json-dir /work/measure/imu4 [--flat]

    .venv/bin/python benchmarks/bench_imu_camera.py --esvi 24,512,346 --cache /tmp/imu_renders \
        --json-dir /work/measure/imu4

``--esvi SECONDS,RGB_PX,DVS_PX`` calibrates the esvi rig's stereo RGB (10 Hz board frames) and
stereo DVS (the simulator's DVS model on the exact board images; frames reconstructed from the
events as in the camera calibration) in one problem, with their own intrinsics
(``tests/calib/test_imu_camera_dvs.py``'s drive, at a bigger size).
The std are the reported ones (how they are made and how often they cover the truth:
``benchmarks/bench_coverage.py``); ``err/std`` is each error in units of its std (rotation rows: truth and estimate as rotation
vectors, the error about the IMU axes, which the std refers to).
``--rendered`` renders the 60 s svi calibration drive with bumps once per (target, offset), one
clock offset for the synchronised stereo pair (a cached render is reused), and runs the whole
``calib SEQ --imu`` on it with the drive's own intrinsics; ``--flat`` also the flat-road drive at
the first offset.  ``--seq`` runs the whole ``calib SEQ --imu`` (corner detection on the rendered frames, intrinsics
from the drive's own camera calibration or ``--cams``, the solve) and prints the same table.

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
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.calib.imu_camera import (
    ImuCameraOptions,
    SequenceOptions,
    calibrate_imu_camera,
    errors_against_truth,
)
from ibiscape_eval.calib.imu_camera.synthetic import calibration_scene
from ibiscape_eval.core.so3 import log_so3
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
    res = calibrate_imu_camera(sc.observations, sc.imu, sc.noise, sc.corners_target_m,
                               ImuCameraOptions(sigma_px=0.2, force=not bumps))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    truth = {k: {"T_cam_imu": sc.T_cam_imu[k], "timeshift_cam_imu": sc.timeshift_cam_imu_s[k]}
             for k in sc.T_cam_imu}
    err = errors_against_truth(res, truth)
    print(f"\n{len(sc.observations)} cameras, {size}x{size} px, "
          f"{'bumps' if bumps else 'FLAT road (forced)'}, {duration_s:.0f} s, "
          f"seed {seed}: target frames {frames}, {res.excitation.duration_s:.1f} s of spline, "
          f"{res.iterations} iterations, wall {wall:.1f} s, cpu {cpu:.1f} s, "
          f"RATIO {120.0 / wall:.2f} (2 min budget / wall), CPU RATIO {120.0 / cpu:.2f}, "
          f"peak RSS {_peak_rss_mb():.0f} MB (the process so far)")
    table(res, sc.T_cam_imu, sc.timeshift_cam_imu_s, err)


def _peak_rss_mb() -> float:
    """The process's peak resident memory [MB] (Linux reports kB)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def table(res, T_truth, shift_truth, err) -> None:  # type: ignore[no-untyped-def]
    """Truth, estimate, error, std and error / std per parameter and camera."""
    print(f"{'camera':<6} {'parameter':<16} {'truth':>12} {'estimate':>12} {'error':>10} {'std':>9} {'err/std':>8}")
    for cal in res.cameras:
        if cal.name not in T_truth:
            continue
        T = np.asarray(T_truth[cal.name], dtype=float)
        rv_true = log_so3(T[:3, :3])
        rv_est = log_so3(cal.T_cam_imu[:3, :3])
        # the error about the IMU axes (R_est = R_true Exp(e)), the axes the std refers to
        e_rot = np.degrees(log_so3(T[:3, :3].T @ cal.T_cam_imu[:3, :3]))
        for k, ax in enumerate("xyz"):
            print(f"{cal.name:<6} {'rotvec ' + ax + ' [deg]':<16} {np.degrees(rv_true[k]):12.4f} "
                  f"{np.degrees(rv_est[k]):12.4f} {e_rot[k]:10.4f} "
                  f"{cal.rotation_std_deg[k]:9.4f} {e_rot[k] / cal.rotation_std_deg[k]:8.2f}")
        for k, ax in enumerate("xyz"):
            print(f"{cal.name:<6} {'t ' + ax + ' [mm]':<16} {T[k, 3] * 1e3:12.2f} "
                  f"{cal.T_cam_imu[k, 3] * 1e3:12.2f} {(cal.T_cam_imu[k, 3] - T[k, 3]) * 1e3:10.2f} "
                  f"{cal.translation_std_m[k] * 1e3:9.2f} "
                  f"{(cal.T_cam_imu[k, 3] - T[k, 3]) / cal.translation_std_m[k]:8.2f}")
        ts = shift_truth[cal.name]
        print(f"{cal.name:<6} {'shift [ms]':<16} {ts * 1e3:12.4f} {cal.timeshift_cam_imu_s * 1e3:12.4f} "
              f"{(cal.timeshift_cam_imu_s - ts) * 1e3:10.4f} {cal.timeshift_std_s * 1e3:9.4f} "
              f"{(cal.timeshift_cam_imu_s - ts) / cal.timeshift_std_s:8.2f}")
        e = err[cal.name]
        print(f"{cal.name:<6} TOTAL rotation {e['rotation_error_deg']:.4f} deg (goal 0.05), translation "
              f"{e['translation_error_m'] * 1e3:.2f} mm (goal 5), time {abs(e['timeshift_error_s']) * 1e3:.4f}"
              f" ms (goal 0.1); position std along IMU x y z "
              f"{' '.join(f'{v * 1e3:.1f}' for v in cal.position_std_imu_m)} mm")
    for w in res.warnings:
        print("  warning:", w)


def on_sequence(seq: str, cams: str | None, frame_step: int) -> None:
    """``calib SEQ --imu`` end to end on a generated (rendered) sequence: detection, intrinsics
    (the drive's own camera calibration, or ``cams``), the solve; truth from sequence.yaml."""
    import yaml

    from ibiscape_eval.calib.imu_camera import calibrate_sequence

    doc = yaml.safe_load((Path(seq) / "sequence.yaml").read_text())
    imu = doc["imus"]["imu0"]
    noise = Path(seq).parent / "bench_imu.yaml"
    noise.write_text(yaml.safe_dump({k: imu[k] for k in (
        "accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
        "gyroscope_random_walk", "update_rate", "rostopic")}))
    res = calibrate_sequence(seq, noise, SequenceOptions(camchain=cams, frame_step=frame_step))
    t = res.timing_s
    det = {d["name"]: f"{d['frames_with_target']}/{d['frames']}" for d in res.detection["cameras"]}
    print(f"\n{seq}: end to end (intrinsics from {', '.join(sorted(set(res.intrinsics_source.values())))}), "
          f"frames with the target {det}; wall: detection {t['detection']:.1f} s, intrinsics "
          f"{t['intrinsics']:.1f} s, camera-IMU {t['imu_camera']:.1f} s, total {t['total']:.1f} s; "
          f"CPU {t['cpu']:.1f} s; RATIO {120.0 / t['total']:.2f} (2 min budget / wall), "
          f"{120.0 / t['cpu']:.2f} (2 min / CPU)")
    if res.camera_calibration and res.camera_calibration.get("ground_truth"):
        for c in res.camera_calibration["ground_truth"]["cameras"]:
            print(f"{c['name']:<6} intrinsics error (drive's own camera calibration): "
                  + ", ".join(f"{k} {c['error'][k]:+.2f} px" for k in ("fx", "fy", "cx", "cy")))
    T_truth = {k: v["T_cam_imu"] for k, v in res.truth.items()}
    shift_truth = {k: v["timeshift_cam_imu"] for k, v in res.truth.items()}
    table(res.result, T_truth, shift_truth, res.errors_vs_truth)


def render_drive(cache: Path, target: str, offset_ms: float, size: int, duration_s: float,
                 seed: int, bumps: bool = True, setup: str = "svi") -> Path:
    """The rendered calibration drive of one (target, offset) point, from ``cache`` when present."""
    from ibiscape_eval.sim.config import with_resolution
    from ibiscape_eval.sim.generator import generate

    name = (f"{setup}_{target}_{offset_ms:+.1f}ms_{size}px_{duration_s:g}s_seed{seed}"
            + ("" if bumps else "_flat"))
    out = cache / name
    if (out / "sequence.yaml").is_file():
        return out
    cfg = preset(setup, "calibration", "clear", duration_s=duration_s, seed=seed, target=target,
                 motion=MotionSpec(bumps=bumps))
    cfg = with_resolution(cfg, size, size)
    cfg = replace(cfg, cameras=tuple(replace(c, timeshift_cam_imu_s=offset_ms * 1e-3)
                                     for c in cfg.cameras))
    t0, c0 = time.perf_counter(), time.process_time()
    generate(cfg, out, render=True, overwrite=True)
    print(f"rendered {out}: wall {time.perf_counter() - t0:.0f} s, CPU {time.process_time() - c0:.0f} s",
          flush=True)
    return out


def _noise_yaml(seq: Path) -> Path:
    import yaml

    doc = yaml.safe_load((seq / "sequence.yaml").read_text())
    imu = doc["imus"]["imu0"]
    noise = seq.parent / f"{seq.name}_imu.yaml"
    noise.write_text(yaml.safe_dump({k: imu[k] for k in (
        "accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
        "gyroscope_random_walk", "update_rate", "rostopic")}))
    return noise


def rendered_point(seq: Path, label: dict[str, Any], force: bool, json_dir: Path | None,
                   frame_step: int = 1) -> dict[str, Any]:
    """``calib SEQ --imu`` with the drive's own intrinsics on one rendered drive: the accuracy
    table printed, the raw result (plus the label and CPU times) returned and kept as JSON."""
    import json

    from ibiscape_eval.calib.imu_camera import calibrate_sequence

    c0 = time.process_time()
    res = calibrate_sequence(seq, _noise_yaml(seq), SequenceOptions(force=force, frame_step=frame_step))
    cpu = time.process_time() - c0
    d = res.to_dict()
    d["label"] = label
    d["cpu_s"] = cpu
    t = res.timing_s
    print(f"\n== {label}: {seq.name}")
    det = {c["name"]: f"{c['frames_with_target']}/{c['frames']}" for c in res.detection["cameras"]}
    print(f"frames with the target {det}; wall: detection {t['detection']:.1f} s, intrinsics "
          f"{t['intrinsics']:.1f} s, camera-IMU {t['imu_camera']:.1f} s, total {t['total']:.1f} s; "
          f"CPU {cpu:.1f} s; RATIO {120.0 / t['total']:.2f} (2 min budget / wall)")
    gt = (res.camera_calibration or {}).get("ground_truth")
    if gt:
        print(f"drive's camera calibration: focal {gt['max_focal_error_px']:.3f} px, principal point "
              f"{gt['max_principal_point_error_px']:.3f} px, baseline "
              + ", ".join(f"{c['from']}->{c['to']} {c['baseline_error_mm']:.2f} mm (vector "
                          f"{np.linalg.norm(c['translation_error_mm']):.2f} mm)" for c in gt["chain"]))
    T_truth = {k: v["T_cam_imu"] for k, v in res.truth.items()}
    shift_truth = {k: v["timeshift_cam_imu"] for k, v in res.truth.items()}
    table(res.result, T_truth, shift_truth, res.errors_vs_truth)
    if json_dir is not None:
        json_dir.mkdir(parents=True, exist_ok=True)
        (json_dir / f"{seq.name}.json").write_text(json.dumps(d, indent=1, allow_nan=False))
    return d


def summary(points: list[dict[str, Any]]) -> None:
    """One line per point: the worst camera's errors against the issue's goals."""
    print(f"\n{'target':<12} {'road':<5} {'offset ms':>9} {'rot deg':>8} {'trans mm':>8} {'dt ms':>7} "
          f"{'focal px':>8} {'pp px':>6} {'base mm':>7} {'wall s':>7} {'CPU s':>6}  goals")
    for d in points:
        e = d["errors_vs_truth"]
        rot = max(v["rotation_error_deg"] for v in e.values())
        tr = max(v["translation_error_m"] for v in e.values()) * 1e3
        dt = max(abs(v["timeshift_error_s"]) for v in e.values()) * 1e3
        gt = (d.get("camera_calibration") or {}).get("ground_truth") or {}
        ok = rot <= 0.05 and tr <= 5.0 and dt <= 0.1
        lab = d["label"]
        print(f"{lab['target']:<12} {lab['road']:<5} {lab['offset_ms']:9.1f} {rot:8.4f} {tr:8.2f} {dt:7.4f} "
              f"{gt.get('max_focal_error_px', float('nan')):8.3f} "
              f"{gt.get('max_principal_point_error_px', float('nan')):6.3f} "
              f"{gt.get('max_baseline_error_mm', float('nan')):7.3f} {d['timing_s']['total']:7.1f} "
              f"{d['cpu_s']:6.1f}  {'met' if ok else 'MISSED'}"
              + (f"; {len(d['warnings'])} warning(s)" if d["warnings"] else ""))


def rendered(a: argparse.Namespace) -> None:
    cache = Path(a.cache)
    json_dir = Path(a.json_dir) if a.json_dir else None
    offsets = [float(v) for v in a.offsets_ms.split(",") if v.strip()]
    other = [float(v) for v in a.other_offsets_ms.split(",") if v.strip()]
    targets = [t.strip() for t in a.targets.split(",") if t.strip()]
    plan: list[tuple[str, float, bool]] = []
    for target in targets:
        offs = offsets if target == targets[0] else other
        plan += [(target, o, True) for o in offs]
    if a.flat_only:
        plan = []
    if a.flat or a.flat_only:
        plan.append((targets[0], offsets[0], False))
    points = []
    for target, off, bumps in plan:
        seq = render_drive(cache, target, off, a.size[0] if a.size else 512, a.duration_s, a.seed, bumps)
        if a.render_only:
            continue
        label = {"target": target, "offset_ms": off, "road": "bumps" if bumps else "flat",
                 "size_px": a.size[0] if a.size else 512, "duration_s": a.duration_s, "seed": a.seed}
        points.append(rendered_point(seq, label, force=not bumps, json_dir=json_dir,
                                     frame_step=a.frame_step))
    if points:
        summary(points)


def esvi(a: argparse.Namespace) -> None:
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "calib"))
    from _esvi_scene import SHIFT_S, write_esvi_calibration

    dur, rgb_px, dvs_px = (float(v) for v in a.esvi.split(","))
    out = Path(a.cache) / f"esvi_board_{dur:g}s_rgb{rgb_px:g}_dvs{dvs_px:g}_seed2"
    if not (out / "sequence.yaml").is_file():
        t0, c0 = time.perf_counter(), time.process_time()
        write_esvi_calibration(out, duration_s=dur, rgb_px=int(rgb_px), dvs_px=int(dvs_px))
        print(f"generated {out}: wall {time.perf_counter() - t0:.0f} s, CPU {time.process_time() - c0:.0f} s",
              flush=True)
    label = {"target": "checkerboard", "offset_ms": SHIFT_S * 1e3, "road": "bumps", "size_px": rgb_px,
             "dvs_px": dvs_px, "duration_s": dur, "rig": "esvi: stereo RGB + stereo DVS"}
    summary([rendered_point(out, label, force=False, json_dir=Path(a.json_dir) if a.json_dir else None)])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seq", action="append", help="also (or only, with --size 0) calibrate this "
                    "generated sequence end to end (ibiscape-eval sim --kind calibration ...)")
    ap.add_argument("--cams", default=None, help="with --seq: Kalibr camchain.yaml of the intrinsics")
    ap.add_argument("--frame-step", type=int, default=1)
    ap.add_argument("--size", type=int, action="append", help="image size (default 1024 and 512)")
    ap.add_argument("--duration-s", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--flat", action="store_true", help="also the same drive without bumps")
    ap.add_argument("--four", action="store_true", help="also RGB + DVS stereo pairs in one problem")
    ap.add_argument("--rendered", action="store_true", help="render the calibration drives (cached) "
                    "and calibrate them end to end with their own intrinsics")
    ap.add_argument("--offsets-ms", default="-20,-9.7,0,4.3,20", help="--rendered: planted offsets")
    ap.add_argument("--targets", default="checkerboard,aprilgrid", help="--rendered: targets; the "
                    "first at every offset, the others at the first --other-offsets")
    ap.add_argument("--other-offsets-ms", default="-20,4.3", help="--rendered: offsets of the "
                    "other targets")
    ap.add_argument("--cache", default="/tmp/imu_camera_renders", help="--rendered: render cache")
    ap.add_argument("--json-dir", default=None, help="--rendered: keep one JSON result per point here")
    ap.add_argument("--render-only", action="store_true")
    ap.add_argument("--flat-only", action="store_true", help="--rendered: only the flat-road drive")
    ap.add_argument("--esvi", default=None, metavar="SECONDS,RGB_PX,DVS_PX",
                    help="stereo RGB + stereo DVS in one problem (board frames and DVS events)")
    a = ap.parse_args()
    if a.esvi:
        esvi(a)
        return
    if a.rendered:
        rendered(a)
        return
    for seq in a.seq or []:
        on_sequence(seq, a.cams, a.frame_step)
    for size in [s for s in (a.size or [1024, 512]) if s > 0]:
        one(size, True, a.duration_s, a.seed)
        if a.flat:
            one(size, False, a.duration_s, a.seed)
        if a.four:
            one(size, True, a.duration_s, a.seed, four=True)


if __name__ == "__main__":
    import warnings

    warnings.simplefilter("ignore")
    main()
