"""Trajectory metrics: association, alignment, ATE, RPE and KITTI-style drift.

Every function takes :class:`~ibiscape_eval.core.Trajectory` objects and returns a frozen result
with numpy arrays, ``to_frame()`` (pandas) and ``to_dict()`` (the JSON the CLI prints)::

    from ibiscape_eval.metrics import ate, rpe
    res = ate(est, gt, align="sim3")
    res.translation_m.rmse, res.n_matched, res.n_dropped_est

Definitions follow evo (APE/RPE, Umeyama alignment) and the KITTI odometry devkit (drift).
"""

from ._common import LENGTH_UNITS
from ._stats import ErrorStats
from .alignment import (
    Alignment,
    AlignmentConditioning,
    AlignmentResult,
    align,
    conditioning_warnings,
)
from .association import Matched, associate, associate_by_index, choose_match
from .ate import AteResult, ate
from .compare import CompareResult, compare
from .drift import KITTI_LENGTHS_M, DriftResult, drift
from .gnss import gnss_in_reference_frame
from .offset import estimate_time_offset
from .relations import PLANES, POSE_RELATIONS, project_to_plane
from .rpe import PAIRS_FROM, RpeResult, rpe, select_pairs
from .select import downsample, motion_filter, time_range

__all__ = [
    "KITTI_LENGTHS_M",
    "LENGTH_UNITS",
    "PAIRS_FROM",
    "PLANES",
    "POSE_RELATIONS",
    "Alignment",
    "AlignmentConditioning",
    "AlignmentResult",
    "AteResult",
    "CompareResult",
    "DriftResult",
    "ErrorStats",
    "Matched",
    "RpeResult",
    "align",
    "associate",
    "associate_by_index",
    "ate",
    "choose_match",
    "compare",
    "conditioning_warnings",
    "downsample",
    "drift",
    "estimate_time_offset",
    "gnss_in_reference_frame",
    "motion_filter",
    "project_to_plane",
    "rpe",
    "select_pairs",
    "time_range",
]
