"""Batch evaluation from a notebook: a runs folder -> the IBISCape paper's table, figures, HTML.

Run as a script (``.venv/bin/python examples/report_runs.py [OUT]``) or paste the cells into a
notebook.  It builds a small runs folder from the real trajectories in ``examples/data`` (TUM RGB-D
fr1/xyz, EuRoC V1_02 and their real estimates) plus synthetic "algorithms" (a drifting visual
odometry and a noisy VIO, 3 seeded trials each, and one trial that crashed half-way through writing
its file), evaluates every run as a batch job and writes the report.  ``make demo`` runs the same
on a simulated IBISCape sequence with GNSS (``ibiscape-eval report``).

Layout of a runs folder::

    runs/<sequence>/groundtruth.<ext>
    runs/<sequence>/<algorithm>/<trial>/<one trajectory file>
    runs/<sequence>/<algorithm>/[<trial>/]run.yaml     optional: "align: sim3" (monocular runs)
"""

# %% Helpers that write a runs folder (also used by examples/demo.py).
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ibiscape_eval import Trajectory, read_trajectory, write_trajectory

DATA = Path(__file__).resolve().parent / "data"


def perturbed(gt: Trajectory, seed: int, *, yaw_walk_deg_sqrt_s: float, noise_m: float,
              every: int = 1) -> Trajectory:
    """A synthetic estimate: the ground truth rotated about z by a yaw random walk around its
    start (drift) plus white position noise, keeping every ``every``-th pose."""
    rng = np.random.default_rng(seed)
    t_s = (gt.stamps_ns - gt.stamps_ns[0]) / 1e9
    dt = np.diff(t_s, prepend=t_s[0])
    yaw = np.cumsum(rng.normal(0.0, np.radians(yaw_walk_deg_sqrt_s) * np.sqrt(dt)))
    R = Rotation.from_euler("z", yaw[:, None])
    p0 = gt.pos_m[0]
    pos = R.apply(gt.pos_m - p0) + p0 + rng.normal(0.0, noise_m, gt.pos_m.shape)
    quat = (R * Rotation.from_quat(gt.quat_xyzw)).as_quat()
    k = slice(None, None, every)
    return Trajectory(gt.stamps_ns[k], pos[k], quat[k], f"seed{seed}")


def add_runs(runs: Path, sequence: str, gt: Trajectory, *, every: int = 1) -> None:
    """Two synthetic algorithms with 3 trials each on one sequence."""
    for alg, walk, noise in (("vo_drift", 2.0, 0.01), ("vio_noise", 0.2, 0.05)):
        for trial in range(1, 4):
            est = perturbed(gt, 1000 * trial + len(sequence), yaw_walk_deg_sqrt_s=walk,
                            noise_m=noise, every=every)
            path = runs / sequence / alg / f"trial_{trial}" / "stamped_traj_estimate.txt"
            path.parent.mkdir(parents=True, exist_ok=True)
            write_trajectory(path, est, "tum")


def make_runs_folder(runs: Path, *, sim_sequences: Path | None = None) -> Path:
    """Write the example runs folder (replacing an earlier one) and return it.

    ``sim_sequences``: a folder of IBISCape-layout sequences (e.g. ``make demo``'s output); its
    ``FULL_dynamic`` sequence, if present, gets runs too, and its ground truth and GNSS are read
    from there with ``--sequences``.
    """
    if runs.exists():
        shutil.rmtree(runs)
    for seq, gt_name, real in (
        ("fr1_xyz", "freiburg1_xyz-groundtruth.txt", ("rgbdslam", "freiburg1_xyz-rgbdslam.txt")),
        ("V1_02", "V102_groundtruth.csv", ("vio", "V102.txt")),
    ):
        gt_src = DATA / gt_name
        (runs / seq).mkdir(parents=True)
        shutil.copyfile(gt_src, runs / seq / f"groundtruth{gt_src.suffix}")
        est_dir = runs / seq / real[0] / "trial_1"
        est_dir.mkdir(parents=True)
        shutil.copyfile(DATA / real[1], est_dir / real[1])
        add_runs(runs, seq, read_trajectory(gt_src), every=2)
    # A monocular run: its map has an arbitrary scale, so only a Sim(3) alignment makes its ATE
    # meaningful.  Its run.yaml says so; `report` reads it (the command line's
    # `--align ORB_mono=sim3` would do the same).  It has no run on V1_02: that cell is "--".
    mono = runs / "fr1_xyz" / "ORB_mono" / "trial_1"
    mono.mkdir(parents=True)
    shutil.copyfile(DATA / "freiburg1_xyz-ORB_kf_mono.txt", mono / "freiburg1_xyz-ORB_kf_mono.txt")
    (mono / "run.yaml").write_text("align: sim3  # monocular: the scale is not observable\n")
    # A run that crashed while writing: its last line is cut short.  It is reported as failed
    # with the file and line, and the other runs are unaffected.
    crashed = runs / "V1_02" / "vio_noise" / "trial_4" / "stamped_traj_estimate.txt"
    crashed.parent.mkdir(parents=True)
    lines = (runs / "V1_02" / "vio_noise" / "trial_1" / crashed.name).read_text().splitlines()
    crashed.write_text("\n".join(lines[: len(lines) // 2]) + "\n" + lines[len(lines) // 2][:25])
    if sim_sequences is not None:
        gt_path = sim_sequences / "FULL_dynamic" / "vehicle_gt" / "groundtruth_sync.csv"
        if gt_path.is_file():
            add_runs(runs, "FULL_dynamic", read_trajectory(gt_path), every=10)  # 200 -> 20 Hz
    return runs


# %% Build the folder, discover its runs, evaluate them as batch jobs (local process pool).
if __name__ == "__main__":
    from ibiscape_eval.batch import ContentCache, LocalExecutor
    from ibiscape_eval.report.batch_report import write_report
    from ibiscape_eval.report.evaluate import EvaluationOptions, evaluate_runs
    from ibiscape_eval.report.paper_table import PaperTable
    from ibiscape_eval.report.runs import discover_runs

    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("report-example")
    runs = make_runs_folder(out / "runs")
    layout = discover_runs(runs)
    print(layout)
    evaluation = evaluate_runs(
        layout,
        EvaluationOptions(align="se3"),
        executor=LocalExecutor(),  # or DaskExecutor("tcp://scheduler:8786"): same results
        cache=ContentCache(out / "cache"),  # a second run skips every finished run
        progress=lambda done, failed, left: print(f"\r{done} done, {failed} failed, {left} left",
                                                  end="", flush=True),
    )
    print()
    print(evaluation)
    for r in evaluation.runs:
        if r["status"] != "ok":
            print(f"failed: {r['sequence']}/{r['algorithm']}/{r['trial']}: {r['error']}")

    # %% The alignment of each algorithm and where it came from (run.yaml, --align, default).
    for alg, (align, source) in evaluation.alignments.items():
        print(f"{alg}: {align} ({source})")

    # %% The paper-style table: medians over trials, success rate, best per row in bold (where
    # two or more algorithms compare), its caption stating alignment and RPE distance.
    table = PaperTable.from_runs(evaluation.runs)
    print(table.to_markdown())
    print(table.to_latex_tables())  # table:ate and table:rpe

    # %% Everything at once: Markdown, LaTeX, CSV, HTML with the figures embedded.
    files = write_report(out / "report", evaluation)
    print("\n".join(sorted(files.values())))
