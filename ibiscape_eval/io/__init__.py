"""Every on-disk format: readers return core types, writers write atomically.

Trajectories::

    from ibiscape_eval.io import read_trajectory, write_trajectory, detect_trajectory_format
    traj = read_trajectory("groundtruth.txt")            # format detected from name and content
    write_trajectory("out.csv", traj, "euroc")

Formats: TUM (``tum``), KITTI (``kitti``, optional times file), EuRoC/ASL and BASALT csv
(``euroc``), IBISCape ``groundtruth_sync.csv`` (``ibiscape``, converted from CARLA's left-handed
frame), ROS 1/2 bags (``bag``).  GNSS: :func:`read_gnss` / :func:`write_gnss`.

Nothing heavy is imported here: numba (the tokenizer) and rosbags load on first use.
"""

from __future__ import annotations

from .detect import TRAJECTORY_FORMATS, detect_trajectory_format
from .gnss import GnssFixes, read_gnss, write_gnss
from .ibiscape import IbiscapeGroundTruth, read_ibiscape_groundtruth, write_ibiscape_groundtruth
from .trajectory import WRITABLE_FORMATS, has_timestamps, read_trajectory, write_trajectory

__all__ = [
    "TRAJECTORY_FORMATS",
    "WRITABLE_FORMATS",
    "GnssFixes",
    "IbiscapeGroundTruth",
    "detect_trajectory_format",
    "has_timestamps",
    "read_gnss",
    "read_ibiscape_groundtruth",
    "read_trajectory",
    "write_gnss",
    "write_ibiscape_groundtruth",
    "write_trajectory",
]
