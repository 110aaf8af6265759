"""``make demo``: the whole product on embedded and generated data, no downloads.

Each step runs the real command line (``ibiscape-eval ...``) exactly as a user would type it, prints
the command and its output, and writes figures and files into ``--out`` (default ``demo-output``).

Steps:
  1. trajectory metrics on the real trajectories in ``examples/data`` (TUM RGB-D fr1/xyz, EuRoC V1_02,
     an ORB-SLAM monocular run that needs Sim(3)): ATE with every alignment, RPE, KITTI-style drift,
     several estimates compared;
  2. the simulator: an SVI calibration drive toward the AprilGrid, a FULL SLAM run in dynamic weather
     and a 2-hour still IMU (ground truth only, for speed), a trajectory converted from CARLA's frame;
  3. the benchmark: six sequences of the paper's 34-sequence suite (every setup, the checkerboard
     drive, clear and dynamic weather) generated at a small scale (rendered stereo RGB,
     DVS events, depth, segmentation), camera and camera-IMU calibration against
     the true cameras, IMU noise from the Allan deviation against the configured densities, DVS hot
     pixels against the noisy pixels the weather planted, the stereo-VIO baseline on every SLAM run
     scored with ATE/RPE, one report (HTML, Markdown, JSON), contact sheets of two sequences and a
     screenshot of the report;
  4. DVS hot-pixel filtering on a 1024x1024 stream with planted hot pixels, then event frames;
  5. batch evaluation of a runs folder (real and synthetic runs, several trials, one crashed) into
     the paper's table, figures and an HTML page, screenshotted by a headless Chromium;
  6. stereo camera calibration on tilted views of a checkerboard rendered by the simulator, and of
     a stereo event camera on a short drive (frames from events, corners refined from the events);
  7. camera-IMU calibration (extrinsics and clock offsets, ``calib --imu``) on a calibration drive;
  8. a rendered SVI drive exported to EuRoC, the stereo-VIO baseline on the export, scored with ``ate``.

What it measured goes to ``--out``/numbers.json: the wall time of every step and of the whole demo,
the machine (CPUs, load), and the benchmark's accuracies against the truth (ranges over its jobs, read
from the benchmark's report.json).  The README quotes these numbers through
``benchmarks/update_readme_numbers.py --from demo-output/numbers.json``, and ``tests/test_readme.py``
fails when the README and the recorded copy (``benchmarks/measured/demo.json``) disagree.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
EXE = str(Path(sys.executable).parent / "ibiscape-eval")


def banner(text: str) -> None:
    print(f"\n{'=' * 100}\n{text}\n{'=' * 100}", flush=True)


def _relative(arg: str) -> str:
    """Paths under the working folder are shown relative to it, so commands can be copied."""
    p = Path(arg)
    if p.is_absolute() and p.is_relative_to(Path.cwd()):
        return str(p.relative_to(Path.cwd()))
    return arg


def sh(*args: str | Path) -> None:
    """Run one ibiscape-eval command, echoing it; stop the demo if it fails."""
    argv = [EXE, *map(str, args)]
    shown = [_relative(a) for a in argv[1:]]
    print(f"\n$ ibiscape-eval {shlex.join(shown)}", flush=True)
    t0 = time.perf_counter()
    proc = subprocess.run(argv, check=False)
    print(f"  [{time.perf_counter() - t0:.2f} s, exit {proc.returncode}]", flush=True)
    if proc.returncode != 0:
        raise SystemExit(f"demo step failed: {shlex.join(argv)}")


def trajectories(out: Path) -> None:
    banner("1. Trajectory metrics on real data (TUM RGB-D fr1/xyz, EuRoC V1_02, ORB-SLAM mono)")
    gt = DATA / "freiburg1_xyz-groundtruth.txt"
    sh(
        "ate",
        DATA / "freiburg1_xyz-rgbdslam.txt",
        gt,
        "--align",
        "se3",
        "--plot",
        out / "ate_fr1_rgbdslam.png",
        "--save-csv",
        out / "ate_fr1_rgbdslam.csv",
    )
    # A monocular run has an arbitrary scale: only Sim(3) alignment makes its ATE meaningful.
    sh(
        "ate",
        DATA / "freiburg1_xyz-ORB_kf_mono.txt",
        gt,
        "--align",
        "sim3",
        "--plot",
        out / "ate_fr1_orb_mono_sim3.png",
        "--save-aligned",
        out / "orb_mono_aligned.txt",
    )
    # VIO: gravity is observable, so align position + yaw only (4-DoF); estimate the time offset.
    sh(
        "ate",
        DATA / "V102.txt",
        DATA / "V102_groundtruth.csv",
        "--align",
        "yaw",
        "--estimate-offset",
        "--plot",
        out / "ate_v102_yaw.png",
    )
    sh(
        "rpe",
        DATA / "V102.txt",
        DATA / "V102_groundtruth.csv",
        "--delta",
        "1",
        "--delta-unit",
        "metres",
        "--pairs",
        "all",
        "--plot",
        out / "rpe_v102_1m.png",
    )
    sh("rpe", DATA / "freiburg1_xyz-rgbdslam.txt", gt, "--delta", "1", "--delta-unit", "seconds")
    sh(
        "drift",
        DATA / "V102.txt",
        DATA / "V102_groundtruth.csv",
        "--lengths-pct",
        "10,20,30,40,50",
        "--align",
        "yaw",
        "--plot",
        out / "drift_v102.png",
    )
    sh("ate", DATA / "V102.txt", DATA / "V102_groundtruth.csv", "--align", "sim3", "--json")
    # Several estimates at once (REF last, as in ate), evo's pose relations, single panels.
    sh("compare", DATA / "freiburg1_xyz-rgbdslam.txt", DATA / "freiburg1_xyz-ORB_kf_mono.txt", gt,
       "--labels", "rgbdslam,ORB-mono", "--align", "sim3", "--plot", out / "compare_fr1.png",
       "--save-results", out / "compare_fr1")
    sh("ate", DATA / "V102.txt", DATA / "V102_groundtruth.csv", "--pose-relation", "full",
       "--project-to-plane", "xy", "--plot", out / "ate_v102_traj_xz.png", "--plot-plane", "xz",
       "--plot-panels", "trajectory")
    sh("rpe", DATA / "V102.txt", DATA / "V102_groundtruth.csv", "--delta", "1", "--delta-unit",
       "metres", "--pairs-from", "ref", "--align", "se3")


def simulate(out: Path) -> None:
    banner("2. Synthetic sequences with exact ground truth (IBISCape layout, CPU only, seeded)")
    # A calibration run toward the AprilGrid over bubbles and waves (pitch/roll excitation), a SLAM run
    # through the town in dynamic weather, and a still IMU for the noise calibration of step 3.
    sh(
        "sim",
        "--setup",
        "svi",
        "--kind",
        "calibration",
        "--target",
        "aprilgrid",
        "--duration-s",
        "40",
        "--seed",
        "1",
        "--no-render",
        "--out",
        out / "SVI_calib",
    )
    sh(
        "sim",
        "--setup",
        "full",
        "--kind",
        "slam",
        "--weather",
        "dynamic",
        "--duration-s",
        "60",
        "--seed",
        "2",
        "--no-render",
        "--out",
        out / "FULL_dynamic",
    )
    sh("sim", "--setup", "imu", "--duration-s", "7200", "--seed", "3", "--out", out / "IMU_still")
    # The ground truth is in CARLA's left-handed frame like the real dataset; our readers convert it.
    sh(
        "convert",
        out / "FULL_dynamic" / "vehicle_gt" / "groundtruth_sync.csv",
        out / "full_gt_tum.txt",
    )


# The benchmark's scale: 144 px cameras and 3 s SLAM runs, a 12 s calibration drive at 320 px, a
# 3.4 h still IMU (see `sim suite --help`), on six of the paper's 34 sequences that exercise every
# step (every setup; clear and dynamic weather, where rain and fog plant noisy DVS pixels), so that
# the whole demo stays under 5 minutes on an idle 2-core machine.  A calibration drive costs as much
# to render as all the SLAM runs together (the AprilGrid one at 512 px 2.5 times the checkerboard at
# 320 px), so the demo keeps one; `make bench` and `ibiscape-eval benchmark DIR --scale 0.02`
# without --only run all 34 (both targets, every weather).
BENCH_SCALE = "0.02"
BENCH_ONLY = ("IMU_calib_1", "SVI_calib_1", "SVI_slam_clear_1", "ESVI_slam_dyn_1",
              "RGBD_slam_clear_1", "FULL_slam_dyn_1")


def benchmark(out: Path) -> None:
    banner(f"3. The whole paper on generated data: `benchmark` ({len(BENCH_ONLY)} of the 34 "
           "sequences, every step as batch jobs)")
    from ibiscape_eval.report.browser import check_page, find_chromium
    from ibiscape_eval.sim.render.preview import contact_sheet

    sh("sim", "suite", "--list", "--scale", BENCH_SCALE)
    bench = out / "bench"
    sh("benchmark", bench, "--scale", BENCH_SCALE, "--cache", out / ".cache",
       *(a for name in BENCH_ONLY for a in ("--only", name)))
    for name in ("SVI_calib_1", "FULL_slam_dyn_1"):
        rows = contact_sheet(bench / "suite" / name, out / f"{name}_sheet.png", n_frames=4,
                             tile_px=144)
        print(f"contact sheet {out / f'{name}_sheet.png'}: rows {', '.join(rows)}")
    page = bench / "report" / "report.html"
    if find_chromium() is not None:
        shot = out / "benchmark_screenshot.png"
        seen = check_page(page, screenshot=shot, window=(1400, 3000))
        print(f"headless Chromium: {len(seen.console)} console messages; screenshot {shot}")
    print(f"\nbenchmark report: {page}  (also {page.with_suffix('.md')}, "
          f"{page.with_suffix('.json')})")


def events(out: Path) -> None:
    banner(
        "4. DVS hot pixels (generated 1024x1024 stream with 40 planted hot pixels, IBISCape layout)"
    )
    from ibiscape_eval.events import synthetic_events
    from ibiscape_eval.io.events import write_events, write_hot_pixels

    # The IBISCape DVS resolution; a moving edge, background activity, and hot pixels firing at
    # rates that rain and fog produce in CARLA's DVS.
    s = synthetic_events(
        sensor_size=(1024, 1024),
        duration_s=2.0,
        edge_rate_hz=5_000_000,
        noise_rate_hz=1.0,
        n_hot=40,
        hot_rate_hz=3000.0,
        seed=3,
    )
    write_events(out / "davisL", s.events, fmt="ibiscape")
    write_hot_pixels(out / "planted_hot_pixels.txt", s.hot_pixels)
    print(
        f"generated {out / 'davisL'}: {len(s.events):,} events, 40 planted hot pixels "
        f"(listed in {out / 'planted_hot_pixels.txt'})"
    )
    sh(
        "hotpix",
        out / "davisL",
        "--n-sigma",
        "5",
        "--hot-out",
        out / "hot_pixels.txt",
        "--filtered-out",
        out / "davisL_filtered",
        "--plot",
        out / "hotpix.png",
    )
    found = (out / "hot_pixels.txt").read_text().split("\n")
    planted = (out / "planted_hot_pixels.txt").read_text().split("\n")
    same = sorted(filter(None, found)) == sorted(filter(None, planted))
    print(f"detected set equals the planted set: {same}")
    sh(
        "events",
        "frames",
        out / "davisL_filtered",
        "--out",
        out / "event_frames",
        "--rate-hz",
        "10",
    )


def report(out: Path) -> None:
    banner("5. Batch evaluation: sequences x algorithms x trials -> the paper's table and figures")
    from report_runs import make_runs_folder  # examples/report_runs.py

    from ibiscape_eval.report.browser import check_page, find_chromium

    # fr1/xyz and V1_02 (real data and real estimates) plus the simulated FULL_dynamic sequence of
    # step 2 (ground truth and GNSS read from its IBISCape folder with --sequences).
    runs = make_runs_folder(out / "runs", sim_sequences=out)
    args: list[str | Path] = ["report", runs, "--sequences", out, "--cache", out / ".cache"]
    sh(*args, "--out", out / "report")
    sh(*args)  # again, table on stdout: every finished run now comes from the cache
    if find_chromium() is None:
        print("chromium not found (make demo installs it): no screenshot of report.html")
        return
    shot = out / "report_screenshot.png"
    seen = check_page(out / "report" / "report.html", screenshot=shot, window=(1500, 2600))
    print(f"headless Chromium: {len(seen.console)} console messages; screenshot {shot}")


#: The stereo DVS calibration drive of step 6 [s]: its simulation (events from frames rendered at
#: a high rate) is the longest part of the step (about 105 s of CPU); 5 s give 20-24 board views
#: per camera with corners refined from the events, 4 s only 7 (the frames' corners are used).
DVS_DRIVE_S = "5"


def calib(out: Path) -> None:
    banner("6. Stereo camera calibration against known cameras (checkerboard views rendered by the simulator; "
           "a stereo DVS on a drive)")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from calibrate_cameras import render_sequence

    print("\nrendering 16 stereo views of the checkerboard (in this process) ...", flush=True)
    seq = render_sequence(out / "stereo_checkerboard", "checkerboard", n_views=16, seed=0)
    sh("calib", seq, "--yaml", out / "camchain.yaml", "--plot", out / "calib_plots")
    sh("calib", seq, "--check", out / "camchain.yaml")
    # event cameras: a short ESVI drive toward the checkerboard (stereo DVS); frames reconstructed
    # from the events find the board, its corners are then refined from the events' timestamps
    # (examples/calibrate_event_cameras.py does the same with more views and reconstructions)
    dvs = out / "ESVI_calib_dvs"
    sh("sim", "--setup", "esvi", "--kind", "calibration", "--target", "checkerboard",
       "--resolution", "320x240", "--duration-s", DVS_DRIVE_S, "--seed", "1", "--out", dvs)
    sh("calib", dvs, "--yaml", out / "camchain_dvs.yaml")


def imu_camera(out: Path) -> None:
    banner("7. Camera-IMU calibration (B-spline, time offsets) on a 20 s calibration drive over the bumps")
    sys.path.insert(0, str(HERE))
    from calibrate_imu_camera import make_sequence  # examples/calibrate_imu_camera.py

    # the shuttle drive in front of the checkerboard, clock offsets +12.3 / -17.1 ms planted, the
    # board rendered in every frame (board-only frames: the drive's full render is benchmark work)
    print("\nsimulating the 20 s drive and rendering the board in each frame (in this process) ...",
          flush=True)
    seq = make_sequence(out / "SVI_calib_imu", duration_s=20.0, size=384)
    sh("calib", seq, "--imu", seq / "imu.yaml", "--cams", seq / "camchain.yaml",
       "--yaml", out / "camchain-imucam.yaml", "--plot", out / "imucam_plots")


def vio(out: Path) -> None:
    banner("8. A rendered SVI drive exported to EuRoC; the stereo-VIO baseline on the export, scored with ATE")
    seq = out / "SVI_vio"
    sh("sim", "--setup", "svi", "--kind", "slam", "--weather", "clear", "--duration-s", "10",
       "--seed", "4", "--resolution", "192", "--out", seq, "--export", "euroc")
    sh("vio", out / "SVI_vio_euroc", "-o", out / "vio_est.txt", "--plot", out / "vio_top.png")
    sh("ate", out / "vio_est.txt", seq / "vehicle_gt" / "groundtruth_sync.csv", "--align", "yaw",
       "--plot", out / "vio_ate.png")


def _span(values: list[Any]) -> list[float] | None:
    """``[min, max]`` of the finite numbers (absolute values: errors), or None."""
    v = [abs(float(x)) for x in values if isinstance(x, int | float) and x == x]
    return [min(v), max(v)] if v else None


def benchmark_numbers(report_json: Path) -> dict[str, Any]:
    """The benchmark's measured numbers (ranges over its jobs) from its ``report.json``."""
    from ibiscape_eval.benchmark import BenchmarkResult

    res = BenchmarkResult.from_dict(json.loads(report_json.read_text(encoding="utf-8")))
    st = res.steps
    recs = dict(st.items())
    out: dict[str, Any] = {"scale": res.scale, "n_jobs": res.n_jobs, "n_failed": res.n_failed,
                           "steps": {}}
    for name, wall in res.wall_s.items():
        out["steps"][name] = {"wall_s": wall, "jobs": len(recs.get(name, ())),
                              "failed": sum(not r.ok for r in recs.get(name, ()))}
    out["total_wall_s"] = sum(res.wall_s.values())
    cams: dict[str, Any] = {}
    for cal in (r.value for r in st.camera_calibration if r.ok and r.value):
        t = cams.setdefault(str(cal.target), {"focal": [], "principal": [], "baseline": [],
                                              "rms": []})
        for c in cal.cameras:
            t["focal"] += [c.fx_error_px, c.fy_error_px]
            t["principal"] += [c.cx_error_px, c.cy_error_px]
        t["baseline"] += [p.baseline_error_mm for p in cal.chain]
        t["rms"].append(cal.rms_px)
    out["camera_calibration"] = {
        target: {"focal_error_px": _span(t["focal"]), "principal_error_px": _span(t["principal"]),
                 "baseline_error_mm": _span(t["baseline"]), "rms_px": _span(t["rms"])}
        for target, t in cams.items()}
    imucam = [c for r in st.imu_camera if r.ok and r.value for c in r.value.cameras]
    out["imu_camera"] = {
        "rotation_error_deg": _span([c.rotation_error_deg for c in imucam]),
        "translation_error_mm": _span([c.translation_error_mm for c in imucam]),
        "timeshift_error_ms": _span([c.timeshift_error_ms for c in imucam])}
    noise = [r.value for r in st.imu_noise if r.ok and r.value]
    if noise:
        out["imu_noise"] = {"duration_h": noise[0].duration_h,
                            "error_pct": {k.key: k.error_pct for k in noise[0].rows}}
    hot = [r.value for r in st.hot_pixels if r.ok and r.value]
    out["hot_pixels"] = {"removed_pct": _span([100 * (v.fraction_removed or 0.0) for v in hot]),
                         "precision": _span([v.precision for v in hot]),
                         "recall": _span([v.recall for v in hot])}
    vio = [r.value.stats for r in st.vio if r.ok and r.value]
    out["vio"] = {"frames": _span([s.get("frames") for s in vio]),
                  "frames_estimated": _span([s.get("frames_estimated") for s in vio]),
                  "failure_spans": sum(len(s.get("failures") or []) for s in vio)}
    ev = [r.value for r in st.evaluation if r.ok and r.value]
    out["evaluation"] = {"ate_m": _span([v.ate_rmse_m for v in ev]),
                         "rpe_m": _span([v.rpe_m for v in ev]),
                         "rpe_deg": _span([v.rpe_deg for v in ev])}
    return out


def _cpu_s() -> float:
    """CPU seconds of this process and its finished children (the commands, their workers)."""
    import resource

    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(
        resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def write_numbers(out: Path, steps_wall_s: dict[str, float], complete: bool,
                  load_start: float | None, cpu_s: dict[str, float] | None = None) -> Path:
    """``out/numbers.json``: what this demo run measured (see the module docstring); ``cpu_s``
    is the CPU time of each step (stable on a busy machine, where wall times are not)."""
    from ibiscape_eval.io.atomic import atomic_write

    doc: dict[str, Any] = {
        "schema": "ibiscape-eval demo numbers 1",
        "recorded_utc": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%MZ"),
        "machine": {"cpus": os.cpu_count(), "load_1min_start": load_start,
                    "load_1min_end": _load()},
        "complete": complete,
        "steps": list(steps_wall_s),
        "wall_s": dict(steps_wall_s),
        "cpu_s": dict(cpu_s or {}),
    }
    if complete:  # the whole demo's time only from a whole run
        doc["wall_s"]["total"] = sum(steps_wall_s.values())
        doc["wall_min"] = doc["wall_s"]["total"] / 60.0
    report_json = out / "bench" / "report" / "report.json"
    if "benchmark" in steps_wall_s and report_json.is_file():
        doc["benchmark"] = benchmark_numbers(report_json)
    path = out / "numbers.json"
    with atomic_write(path) as f:
        f.write(json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return path


def _load() -> float | None:
    try:
        return round(os.getloadavg()[0], 2)
    except OSError:
        return None


STEPS: list[tuple[str, Callable[[Path], None]]] = [
    ("trajectories", trajectories),
    ("sim", simulate),
    ("benchmark", benchmark),
    ("events", events),
    ("report", report),
    ("calib", calib),
    ("imu-camera", imu_camera),
    ("vio", vio),
]


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", type=Path, default=Path("demo-output"))
    ap.add_argument("--only", choices=[name for name, _ in STEPS], action="append", default=None,
                    help="run only these steps (repeatable; 'report' needs 'sim')")
    args = ap.parse_args()
    marker = args.out / ".ibiscape-demo"
    if args.out.exists() and any(args.out.iterdir()):
        if not marker.exists():
            raise SystemExit(
                f"{args.out} exists and is not a demo output folder; choose another --out"
            )
        shutil.rmtree(args.out)  # a previous demo run: start afresh
    args.out.mkdir(parents=True, exist_ok=True)
    marker.touch()
    t0 = time.perf_counter()
    load_start = _load()
    walls: dict[str, float] = {}
    cpus: dict[str, float] = {}
    for name, step in STEPS:
        if args.only is None or name in args.only:
            t_step, c_step = time.perf_counter(), _cpu_s()
            step(args.out)
            walls[name] = round(time.perf_counter() - t_step, 1)
            cpus[name] = round(_cpu_s() - c_step, 1)
    banner(f"demo finished in {time.perf_counter() - t0:.1f} s; figures and files in {args.out}/")
    numbers = write_numbers(args.out, walls, complete=args.only is None, load_start=load_start,
                            cpu_s=cpus)
    print(f"measured numbers: {numbers} (README: benchmarks/update_readme_numbers.py --from "
          f"{numbers})")
    for p in sorted(args.out.iterdir()):
        if p.is_dir():
            print(f"  {p}/  ({sum(1 for q in p.rglob('*') if q.is_file())} files)")
        else:
            print(f"  {p}  ({p.stat().st_size / 1e3:,.0f} kB)")
    page = args.out / "bench" / "report" / "report.html"
    if page.is_file():
        print(f"\nthe benchmark's report (every step of the paper on generated data): {page}")


if __name__ == "__main__":
    main()
