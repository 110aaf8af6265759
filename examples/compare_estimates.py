"""Several estimates against one reference, evo's options, and figures for a paper.

Run as a script (``.venv/bin/python examples/compare_estimates.py [OUT_DIR]``) or paste the cells
into a notebook (each result then renders as a table).  Uses the real trajectories in
``examples/data``.
"""

# %% Read the reference and two estimates of TUM RGB-D fr1/xyz.
import sys
import tempfile
from pathlib import Path

from ibiscape_eval import read_trajectory
from ibiscape_eval.metrics import ate, compare, rpe
from ibiscape_eval.report.plots import (
    compare_figure,
    metric_figure,
    save_figure,
    trajectory_errors_figure,
)

DATA = Path(__file__).resolve().parent / "data"
OUT = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="compare-"))
OUT.mkdir(parents=True, exist_ok=True)
gt = read_trajectory(DATA / "freiburg1_xyz-groundtruth.txt")
rgbd = read_trajectory(DATA / "freiburg1_xyz-rgbdslam.txt")
orb = read_trajectory(DATA / "freiburg1_xyz-ORB_kf_mono.txt")

# %% One table for both (Sim(3) for the monocular scale), one figure, saved results.
cmp = compare(gt, [rgbd, orb], labels=["rgbdslam", "ORB mono"], align="sim3")
print(cmp)                      # a few lines, not arrays
print(cmp.to_frame()[["ate_rmse_m", "rpe_rmse_m", "n_matched"]])
files = cmp.save(OUT / "results")   # compare.json + <label>.{ate,rpe}.{json,csv}
print("saved", [p.name for p in files])
# each row says how well its alignment is determined, and warns when it is not
print(cmp.to_frame()[["ate_rotation_sigma_deg", "stamps", "warnings"]])
save_figure(compare_figure(cmp, title="fr1/xyz"), OUT / "compare.png")

# %% evo's pose relations and projection: the rotation part of the error, flattened to x-y.
res = ate(rgbd, gt, pose_relation="rot-part", project_to_plane="xy")
print(res)                      # includes the 'error' statistics of the chosen relation
print(f"||R-I|| rmse {res.stats.rmse:.5f}")

# %% RPE over 10 cm of the REFERENCE path (what papers mean), not evo's default estimate path.
r_ref = rpe(rgbd, gt, delta=0.1, delta_unit="metres", pairs_from="ref")
r_est = rpe(rgbd, gt, delta=0.1, delta_unit="metres", pairs_from="est")
print(f"RPE 0.1 m: {r_ref.translation_m.rmse:.4f} m over {r_ref.n_pairs} pairs (ref path), "
      f"{r_est.translation_m.rmse:.4f} m over {r_est.n_pairs} pairs (est path)")

# %% A single publishable panel: the trajectory coloured by its error, in the x-z plane.
a = ate(rgbd, gt)
fig = trajectory_errors_figure(est_aligned=a.est_aligned, ref=a.ref, stamps_ns=a.stamps_ns,
                               errors_m=a.errors_m, errors_deg=a.errors_deg, plane="xz",
                               panels=["trajectory"], aligned=a.alignment.method)
save_figure(fig, OUT / "ate_xz.png")

# %% The whole figure of a result in one call (errors, distance, pose-index axis for synthetic
# stamps), in centimetres; the same options as the command line (evo's time window, motion
# filter).
w = ate(rgbd, gt, t_start_s=gt.stamps_ns[0] / 1e9 + 5, motion_filter=(0.02, 2.0))
save_figure(metric_figure(w, unit="cm", plane="xy", title="after 5 s, every 2 cm / 2 deg"),
            OUT / "ate_window.png")
print("figures in", OUT)
