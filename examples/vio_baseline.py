"""The stereo-VIO baseline from Python: on a rendered sequence, or on synthetic measurements.

    .venv/bin/python examples/vio_baseline.py                 # synthetic measurements (no images)
    .venv/bin/python examples/vio_baseline.py SVI_1_town      # a rendered IBISCape/EuRoC folder

Notebook-style: each block can be pasted into a cell.
"""

# %% Imports
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from ibiscape_eval import DegenerateInputError
from ibiscape_eval.metrics import ate, rpe
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.vio import (
    Estimator,
    StereoRig,
    VioParams,
    load_sequence,
    random_landmarks,
    run_vio,
    synthetic_observations,
)

# %% A sequence: the one given, or a 30 s SVI drive generated without images
if len(sys.argv) > 1:
    # any recording open_sequence reads: IBISCape, EuRoC/TUM-VI (%YAML:1.0 sensor files, ground
    # truth optional), a ROS bag (give the topics: open_sequence(bag, image_topics=[...]))
    from ibiscape_eval import open_sequence
    from ibiscape_eval.vio.inputs import stereo_inputs

    opened = open_sequence(sys.argv[1])
    print(opened)
    seq = stereo_inputs(opened)
else:
    root = Path(tempfile.mkdtemp(prefix="vio_example_"))
    scale = float(os.environ.get("IBISCAPE_EXAMPLE_SCALE", "1"))  # < 1: a shorter drive (tests)
    generate(preset("svi", "slam", "clear", duration_s=max(8.0, 30 * scale), seed=1),
             root / "SVI_1_town")
    seq = load_sequence(root / "SVI_1_town", require_images=False)
print(seq, seq.rig)
gt = seq.groundtruth

# %% Run the VIO: on the images, or on synthetic stereo measurements of random landmarks
if seq.n_frames:
    result = run_vio(seq, VioParams())
    est = result.trajectory
    print(result)
    for f in result.stats.failures:
        print(f"  {f.kind}: {f.duration_s:.2f} s")
else:
    rig = StereoRig(seq.rig.left.scaled(512, 512), seq.rig.right.scaled(512, 512),
                    seq.rig.T_body_left, seq.rig.T_body_right)
    obs = synthetic_observations(gt, rig, gt.stamps_ns[::10], random_landmarks(gt, seed=1),
                                 pixel_sigma_px=0.5, seed=2)
    estimator = Estimator(rig.rectified(), seq.imu, seq.noise, VioParams(), seq.T_body_imu)
    for o in obs:  # one frame at a time, as a live system would
        estimator.process(o)
    estimator.finish()
    est = estimator.trajectory()
    print(f"{len(est)} poses, initialised from {estimator.init_method}, "
          f"{estimator.n_keyframes} keyframes, failures: {estimator.failures}")

    # %% Tracking lost and back: no vision for 4 s with a 1 s IMU-only limit. The spans tell it:
    # "tracking" (IMU only), "standstill" (a stop held by the zero-velocity update, not lost),
    # "lost" (no pose written) closed where the estimate restarts, a new segment
    t_mid = int(gt.stamps_ns[0] + 0.5 * (gt.stamps_ns[-1] - gt.stamps_ns[0]))
    dark = synthetic_observations(gt, rig, gt.stamps_ns[::10], random_landmarks(gt, seed=1),
                                  pixel_sigma_px=0.5, seed=2, blackout=(t_mid, t_mid + int(4e9)))
    restarted = Estimator(rig.rectified(), seq.imu, seq.noise, VioParams(max_imu_only_s=1.0),
                          seq.T_body_imu)
    for o in dark:
        restarted.process(o)
    restarted.finish()
    t0 = gt.stamps_ns[0]
    print(f"blackout {(t_mid - t0) * 1e-9:.1f}-{(t_mid - t0) * 1e-9 + 4:.1f} s: "
          f"{len(restarted.trajectory())} of {len(dark)} frames estimated; spans",
          [(f.kind, round(float(f.start_ns - t0) * 1e-9, 2), round(f.duration_s, 2))
           for f in restarted.failures])

# %% Score it with the project's metrics (SE(3) alignment like the paper; 4-DoF 'yaw' for VIO)
if gt is not None:
    length = gt.path_length_m()[-1]
    for align in ("se3", "yaw"):
        try:
            a = ate(est, gt, align=align, max_diff_s=0.02)
        except DegenerateInputError as e:  # a straight drive leaves se3's roll about it free
            print(f"ATE ({align}): refused: {e}; remedy {[r.keyword() for r in e.hint]}")
            continue
        print(f"ATE ({align}): {a.translation_m.rmse:.3f} m over {length:.0f} m "
              f"({100 * a.translation_m.rmse / length:.2f} %)")
    r = rpe(est, gt, delta=1.0, delta_unit="seconds", max_diff_s=0.02)
    print(f"RPE over 1 s: {r.translation_m.mean:.4f} ± {r.translation_m.std:.4f} m, "
          f"{r.rotation_deg.mean:.4f} ± {r.rotation_deg.std:.4f} deg")
    print(f"final position error: {np.linalg.norm(a.est_aligned.pos_m[-1] - a.ref.pos_m[-1]):.3f} m")

# %% Did it start from a standstill? The test on the first 0.45 s of IMU, with what it measured
from ibiscape_eval.vio.initialise import detect_standstill, standstill_at

t0 = int(seq.frame_stamps_ns[0]) if seq.n_frames else int(gt.stamps_ns[0])
still = standstill_at(*seq.imu, t0, VioParams())
print(f"standstill: {still.still} {still.reason}")
print(f"  gyro variance {still.gyro_var_rad2_s2:.2e} (limit {still.gyro_var_limit_rad2_s2:.1e}) rad^2/s^2, "
      f"accel norm std {still.accel_norm_std_m_s2:.3f}, axis std {still.accel_axis_std_m_s2:.3f} "
      f"(limit {still.accel_std_limit_m_s2}) m/s^2; gyro bias {np.round(still.mean_gyro_rad_s, 4)} rad/s")
# any window: e.g. the 2 s after the start
print(detect_standstill(*seq.imu, t0, t0 + 2_000_000_000).still)

# %% The top view: the ground truth is drawn over the estimate's span +- 1 s only
from ibiscape_eval.io.figure import save_figure
from ibiscape_eval.vio.plots import top_view_figure

if gt is not None:
    fig = top_view_figure(a.est_aligned, gt, title="VIO top view")
    save_figure(fig, Path(tempfile.mkdtemp(prefix="vio_plot_")) / "top.png")
