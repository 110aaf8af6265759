"""Trajectory metrics from a notebook: read, evaluate, inspect, plot.

Run as a script (``.venv/bin/python examples/trajectory_metrics.py``) or paste the cells into a
notebook.  Uses the real trajectories shipped in ``examples/data``.
"""

# %% Read trajectories: the format is detected from name and content.
from pathlib import Path

from ibiscape_eval import ate, drift, read_trajectory, rpe

DATA = Path(__file__).resolve().parent / "data"
gt = read_trajectory(DATA / "V102_groundtruth.csv")  # EuRoC ASL data.csv, ns stamps
est = read_trajectory(DATA / "V102.txt")  # TUM, seconds
print(gt, est)

# %% ATE with a 4-DoF (yaw) alignment, as VIO needs, and an estimated time offset.
res = ate(est, gt, align="yaw", estimate_offset=True)
print(f"matched {res.n_matched}, dropped {res.n_dropped_est} est / {res.n_dropped_ref} ref")
print(f"time offset {res.t_offset_s * 1e3:+.2f} ms")
print(f"ATE rmse {res.translation_m.rmse:.4f} m, rotation rmse {res.rotation_deg.rmse:.3f} deg")
print(res.alignment.transform.round(4))

# %% Per-pose errors as a pandas DataFrame.
frame = res.to_frame()
print(frame.describe().T[["mean", "std", "max"]])

# %% RPE over 1 m segments (every start pose), and KITTI-style drift over 10..50 % of the length.
r = rpe(est, gt, delta=1.0, delta_unit="metres", pairs="all")
print(f"RPE 1 m: {r.translation_m.mean:.4f} ± {r.translation_m.std:.4f} m, "
      f"{r.rotation_deg.mean:.3f} ± {r.rotation_deg.std:.3f} deg over {r.n_pairs} pairs")
d = drift(est, gt, lengths_pct=(10, 20, 30, 40, 50), align="yaw")
print(d.to_frame())

# %% A monocular estimate has no metric scale: Sim(3) alignment recovers it.
mono = read_trajectory(DATA / "freiburg1_xyz-ORB_kf_mono.txt")
fr1 = read_trajectory(DATA / "freiburg1_xyz-groundtruth.txt")
m = ate(mono, fr1, align="sim3")
print(f"ORB mono: scale {m.alignment.scale:.4f}, ATE rmse {m.translation_m.rmse:.4f} m")

# %% How well is the alignment determined?  Every se3/sim3/yaw alignment carries its conditioning:
# 1-sigma of its rotation (per principal axis), translation and scale, from the point geometry
# and the residual.  A warning (also in res.warnings and the JSON) says when the rotation error
# is mostly the alignment's own, e.g. on a standing vehicle or a straight drive with se3.
c = res.alignment.conditioning
print(f"alignment rotation 1-sigma {c.rotation_sigma_total_deg:.4f} deg, residual "
      f"{c.sigma_pos_m * 1e3:.1f} mm, warnings: {list(res.warnings) or 'none'}")
import warnings

from ibiscape_eval.core import IbiscapeWarning

t0 = est.stamps_ns[0] / 1e9
with warnings.catch_warnings(record=True) as caught:  # the first second: a few cm of motion
    warnings.simplefilter("always", IbiscapeWarning)
    s = ate(est, gt, align="se3", t_end_s=t0 + 1.5)
print(f"on {s.n_matched} poses: rotation error {s.rotation_deg.rmse:.2f} deg, alignment 1-sigma "
      f"{s.alignment.conditioning.rotation_sigma_total_deg:.2f} deg; {len(s.warnings)} warning(s)")

# %% evo's pose selection and units: a time window, evenly downsampled or motion-filtered poses,
# errors in centimetres.
w = ate(est, gt, align="yaw", t_start_s=t0 + 10, t_end_s=t0 + 40, motion_filter=(0.05, 5.0))
print(f"10..40 s, a pose every 5 cm / 5 deg: {w.n_matched} matched, "
      f"ATE rmse {w.to_dict(unit='cm')['translation_cm']['rmse']:.2f} cm")

# %% Drift on a path shorter than the KITTI lengths: unreached lengths are marked, not nan.
k = drift(est, gt, align="yaw")
print(k.to_frame()[["length_m", "reached", "n_segments"]].head(3), list(k.warnings)[:1])

# %% Plots: every result draws itself on a new matplotlib Figure (no display, pyplot untouched);
# in a notebook the Figure shows itself, in a script save it.
from ibiscape_eval.io.figure import save_figure

save_figure(res.plot(), "trajectory_metrics_example.png")  # trajectory, error over time, histogram
save_figure(k.plot(), "drift_example.png")                  # drift per segment length
print("wrote trajectory_metrics_example.png, drift_example.png")
