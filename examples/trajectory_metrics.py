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

# %% Plot (matplotlib, no display needed).
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

fig, ax = plt.subplots(figsize=(6, 5))
ax.plot(res.ref.pos_m[:, 0], res.ref.pos_m[:, 1], "k-", label="ground truth")
ax.plot(res.est_aligned.pos_m[:, 0], res.est_aligned.pos_m[:, 1], label="estimate (yaw-aligned)")
ax.set_aspect("equal")
ax.legend()
fig.savefig("trajectory_metrics_example.png", dpi=100)
print("wrote trajectory_metrics_example.png")
