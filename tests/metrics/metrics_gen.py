"""Generated trajectories with known answers for the metrics tests (seeded, small)."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from shared_data import TRAJECTORIES as DATA

from ibiscape_eval.core import Trajectory, ns_from_s
from ibiscape_eval.core.rotations import quat_from_rotvec, quat_multiply, quat_normalize

# Skips when ../shared/data is missing, fails under CI=true (see tests/shared_data.py).
needs_data = pytest.mark.usefixtures("shared_trajectories")


def smooth_trajectory(n: int = 300, *, rate_hz: float = 50.0, t0_s: float = 100.0,
                      seed: int = 0) -> Trajectory:
    """A wiggly 3-D trajectory that rotates about all axes (sums of sines, seeded)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    amp = rng.uniform(0.5, 2.0, (3, 3))
    freq = rng.uniform(0.05, 0.6, (3, 3))
    phase = rng.uniform(0, 2 * np.pi, (3, 3))
    pos = np.stack([(amp[k] * np.sin(2 * np.pi * freq[k] * t[:, None] + phase[k])).sum(1)
                    for k in range(3)], axis=1)
    rv = np.stack([0.4 * np.sin(2 * np.pi * freq[k, 0] * t + phase[k, 1]) for k in range(3)],
                  axis=1)
    return Trajectory(ns_from_s(t0_s + t), pos, quat_from_rotvec(rv), "smooth")


def continuous_pose(t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A closed-form motion (positions, quaternions) at arbitrary times, for resampling tests."""
    pos = np.stack([3 * np.sin(0.3 * t_s), 2 * np.cos(0.25 * t_s), 0.5 * np.sin(0.7 * t_s)], 1)
    rv = np.stack([0.3 * np.sin(1.3 * t_s), 0.2 * np.sin(0.9 * t_s + 1.0),
                   0.8 * np.sin(0.5 * t_s) + 0.4 * np.sin(2.1 * t_s)], 1)
    return pos, quat_from_rotvec(rv)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A random rotation matrix (3, 3)."""
    q = quat_normalize(rng.normal(size=4))
    from ibiscape_eval.core.rotations import matrix_from_quat

    return matrix_from_quat(q)


def transformed(traj: Trajectory, R: np.ndarray, t: np.ndarray, s: float = 1.0) -> Trajectory:
    """``p' = s R p + t``, ``q' = q_R q`` (a new trajectory)."""
    from ibiscape_eval.core.rotations import quat_from_matrix

    q = quat_multiply(quat_from_matrix(R), traj.quat_xyzw)
    return Trajectory(traj.stamps_ns, s * traj.pos_m @ R.T + t, q, traj.name)


def from_evo(t: object) -> Trajectory:
    """Convert an evo PoseTrajectory3D (float s, w x y z) to ours (int ns, x y z w)."""
    q = t.orientations_quat_wxyz  # type: ignore[attr-defined]
    return Trajectory(ns_from_s(t.timestamps), t.positions_xyz,  # type: ignore[attr-defined]
                      q[:, [1, 2, 3, 0]])


def load_evo(name: str) -> object:
    """A fresh copy of :func:`_load_evo_cached` (evo objects are mutable)."""
    import copy

    return copy.deepcopy(_load_evo_cached(name))


@functools.cache
def _load_evo_cached(name: str) -> object:
    """Read a real trajectory with evo's own readers; drop rows repeating a timestamp.

    ``V102.txt`` repeats four stamps; evo would match both copies, we keep the pairing
    one-to-one, so both sides get the same de-duplicated input.
    """
    from evo.tools import file_interface

    path = str(DATA / name)
    if name.endswith(".csv"):
        t = file_interface.read_euroc_csv_trajectory(path)
    else:
        t = file_interface.read_tum_trajectory_file(path)
    keep = np.concatenate(([True], np.diff(t.timestamps) > 0))
    t.reduce_to_ids(np.flatnonzero(keep))
    return t
