"""A tiny runs folder whose table values are computable by hand (alignment "none").

seq1 (ground truth ``runs/seq1/groundtruth.txt``): 11 poses, 1 s apart, x = i m, identity attitude.
  alpha/t1   z offset 0.1 m           ATE 0.1;            RPE 0 ± 0 m, 0 ± 0 deg
  beta/t1..3 x scaled by 1.1/1.2/1.3  ATE (s-1) sqrt(35); RPE (s-1) ± 0 m  -> median s = 1.2
  beta/t4    not a trajectory (the failed trial: 3/4 succeed)
  gamma/t1   yaw 5 deg, true positions ATE 0 m (5 deg);   RPE 2 sin(2.5 deg) ± 0 m, 0 ± 0 deg
seq2 (IBISCape sequence ``seqs/seq2`` with GNSS): 21 poses on a 10 m radius arc.
  alpha/t1   z offset 0.2 m           ATE 0.2
  beta/t1    exact                    ATE 0
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ibiscape_eval.core import Trajectory
from ibiscape_eval.io import GnssFixes, IbiscapeGroundTruth, write_gnss, write_trajectory
from ibiscape_eval.io.ibiscape import write_ibiscape_groundtruth

SQRT35 = math.sqrt(35.0)
GAMMA_RPE_M = 2.0 * math.sin(math.radians(2.5))


def _traj(t_s: np.ndarray, pos: np.ndarray, yaw_rad: np.ndarray | float = 0.0) -> Trajectory:
    yaw = np.broadcast_to(np.asarray(yaw_rad, dtype=float), t_s.shape)
    q = Rotation.from_euler("z", yaw[:, None]).as_quat()
    return Trajectory((t_s * 1e9).round().astype(np.int64), pos.astype(float), q, "t")


def seq1_truth() -> Trajectory:
    t = np.arange(11.0)
    return _traj(t, np.c_[t, np.zeros(11), np.zeros(11)])


def seq2_truth() -> Trajectory:
    t = np.arange(21.0)
    th = 0.1 * t
    return _traj(t, np.c_[10 * np.sin(th), 10 * (1 - np.cos(th)), np.zeros(21)], th)


def _shift(tr: Trajectory, d: np.ndarray) -> Trajectory:
    return Trajectory(tr.stamps_ns, tr.pos_m + d, tr.quat_xyzw, tr.name)


def _write(path: Path, tr: Trajectory) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_trajectory(path, tr, "tum")


def build_runs(root: Path, *, with_failure: bool = True) -> tuple[Path, Path]:
    """Write ``root/runs`` and ``root/seqs``; return both."""
    runs, seqs = root / "runs", root / "seqs"
    gt1 = seq1_truth()
    _write(runs / "seq1" / "groundtruth.txt", gt1)
    _write(runs / "seq1" / "alpha" / "t1" / "est.txt", _shift(gt1, np.array([0.0, 0.0, 0.1])))
    for k, s in enumerate((1.1, 1.2, 1.3), start=1):
        pos = gt1.pos_m * np.array([s, 1.0, 1.0])
        _write(runs / "seq1" / "beta" / f"t{k}" / "est.txt",
               Trajectory(gt1.stamps_ns, pos, gt1.quat_xyzw, "b"))
    if with_failure:
        bad = runs / "seq1" / "beta" / "t4" / "est.txt"
        bad.parent.mkdir(parents=True)
        bad.write_text("0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\nthis line is not a pose\n")
    _write(runs / "seq1" / "gamma" / "t1" / "est.txt",
           _traj(np.arange(11.0), gt1.pos_m, math.radians(5.0)))

    gt2 = seq2_truth()
    n = len(gt2)
    gt_dir = seqs / "seq2" / "vehicle_gt"
    gt_dir.mkdir(parents=True)
    z = np.zeros((n, 3))
    write_ibiscape_groundtruth(gt_dir / "groundtruth_sync.csv", IbiscapeGroundTruth(gt2, z, z, z))
    lat0, lon0, r = 48.0, 2.0, 6378137.0
    p = gt2.pos_m
    lat = lat0 + np.degrees(p[:, 1] / r)
    lon = lon0 + np.degrees(p[:, 0] / (r * math.cos(math.radians(lat0))))
    (seqs / "seq2" / "other_sensors").mkdir(parents=True)
    write_gnss(seqs / "seq2" / "other_sensors" / "gnss.csv",
               GnssFixes(gt2.stamps_ns, lat, lon, np.full(n, 100.0)))
    _write(runs / "seq2" / "alpha" / "t1" / "est.txt", _shift(gt2, np.array([0.0, 0.0, 0.2])))
    _write(runs / "seq2" / "beta" / "t1" / "est.txt", gt2)
    return runs, seqs
