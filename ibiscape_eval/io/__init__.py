"""Every on-disk format: readers return core types, writers write atomically.

Trajectories::

    from ibiscape_eval.io import read_trajectory, write_trajectory, detect_trajectory_format
    traj = read_trajectory("groundtruth.txt")            # format detected from name and content
    write_trajectory("out.csv", traj, "euroc")

Formats: TUM (``tum``), KITTI (``kitti``, optional times file), EuRoC/ASL and BASALT csv
(``euroc``), IBISCape ``groundtruth_sync.csv`` (``ibiscape``, converted from CARLA's left-handed
frame), ROS 1/2 bags (``bag``).  GNSS: :func:`read_gnss` / :func:`write_gnss`.

Nothing is imported here: each name loads its module on first use (numba, the tokenizer, and
rosbags later still).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ibiscape_eval.core.lazy import lazy_exports

# public name -> submodule (imported on first use: ``ibiscape_eval.io.kalibr`` alone must not load
# scipy through the trajectory readers)
_EXPORTS = {
    "TRAJECTORY_FORMATS": "detect",
    "detect_trajectory_format": "detect",
    "GnssFixes": "gnss",
    "read_gnss": "gnss",
    "write_gnss": "gnss",
    "IbiscapeGroundTruth": "ibiscape",
    "read_ibiscape_groundtruth": "ibiscape",
    "write_ibiscape_groundtruth": "ibiscape",
    "WRITABLE_FORMATS": "trajectory",
    "has_timestamps": "trajectory",
    "read_trajectory": "trajectory",
    "write_trajectory": "trajectory",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # pragma: no cover
    from .detect import TRAJECTORY_FORMATS, detect_trajectory_format  # noqa: F401
    from .gnss import GnssFixes, read_gnss, write_gnss  # noqa: F401
    from .ibiscape import (  # noqa: F401
        IbiscapeGroundTruth,
        read_ibiscape_groundtruth,
        write_ibiscape_groundtruth,
    )
    from .trajectory import WRITABLE_FORMATS, has_timestamps, read_trajectory, write_trajectory  # noqa: F401
