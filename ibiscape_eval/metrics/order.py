"""Was the ground truth given as the estimate?  Signs that two trajectories are swapped."""

from __future__ import annotations

import os
import re
from pathlib import PurePath

import numpy as np

from ibiscape_eval.core import Trajectory

__all__ = ["looks_like_ground_truth", "swap_warning"]

#: ``groundtruth``, ``ground_truth``, ``gt`` as a word, EuRoC's ``state_groundtruth_estimate0``.
_GT_WORDS = re.compile(r"ground[_\- ]?truth|(?:^|[^a-z0-9])gt(?:[^a-z]|$)|vicon|mocap|leica")
#: Denser by this factor (poses per second) counts as a sign.
DENSER = 2.0
#: Smoother by this factor (jitter, see :func:`_jitter_m`) counts as a sign.
SMOOTHER = 4.0


def looks_like_ground_truth(path: str | os.PathLike[str] | None) -> bool:
    """Whether a file name (or its folder) says ground truth: ``groundtruth.txt``,
    ``gt_poses.txt``, ``V102_groundtruth.csv``, EuRoC's ``state_groundtruth_estimate0/data.csv``
    or a bare ``data.csv`` (how EuRoC names its ground truth file)."""
    if path is None:
        return False
    p = PurePath(os.fspath(path))
    parts = [x.lower() for x in (p.parent.name, p.name)]
    return p.name.lower() == "data.csv" or any(_GT_WORDS.search(x) for x in parts)


def _rate_hz(t: Trajectory) -> float:
    return (len(t) - 1) / t.duration_s if len(t) > 1 and t.duration_s > 0 else 0.0


def _jitter_m(t: Trajectory) -> float:
    """Median distance of a position from the midpoint of its two neighbours: sensor noise for
    an estimate, nearly zero for a smooth, densely sampled ground truth."""
    p = t.pos_m
    if len(p) < 3:
        return float("nan")
    d = p[1:-1] - 0.5 * (p[:-2] + p[2:])
    return float(np.median(np.sqrt(np.einsum("ij,ij->i", d, d))))


def swap_warning(
    est: Trajectory,
    ref: Trajectory,
    *,
    est_path: str | os.PathLike[str] | None = None,
    ref_path: str | os.PathLike[str] | None = None,
    fmt_est: str | None = None,
    fmt_ref: str | None = None,
) -> str | None:
    """A sentence when ``est`` looks like the reference, else None.

    Signs, any of which suffices:

    - ``est`` has at least 4 times as many poses as ``ref`` and is in EuRoC's ground-truth
      format or in ``ref``'s own format;
    - the estimate's file name says ground truth (:func:`looks_like_ground_truth`) and the
      reference's does not;
    - ``est`` is sampled at least ``DENSER`` times as densely (poses per second) and is at least
      ``SMOOTHER`` times smoother (:func:`_jitter_m`) than ``ref``, whatever the counts.
    """
    if len(ref) == 0 or len(est) == 0:
        return None
    reasons = []
    if len(est) >= 4 * len(ref) and (fmt_est == "euroc" or (fmt_est and fmt_est == fmt_ref)):
        reasons.append(f"it has {len(est)} poses, {len(est) / len(ref):.0f}x as many as the "
                       f"reference ({len(ref)}), in format {fmt_est}")
    if looks_like_ground_truth(est_path) and not looks_like_ground_truth(ref_path):
        reasons.append(f"its file name {PurePath(os.fspath(est_path or '')).name!r} says ground "
                       "truth")
    if not (est.stamps_synthetic or ref.stamps_synthetic):
        r_est, r_ref = _rate_hz(est), _rate_hz(ref)
        j_est, j_ref = _jitter_m(est), _jitter_m(ref)
        if (r_ref > 0 and r_est >= DENSER * r_ref and np.isfinite(j_est) and np.isfinite(j_ref)
                and j_est * SMOOTHER <= j_ref):
            reasons.append(f"it is denser ({r_est:.3g} against {r_ref:.3g} poses/s) and smoother "
                           f"(jitter {j_est * 1000:.3g} against {j_ref * 1000:.3g} mm)")
    if not reasons:
        return None
    return (f"the {est.describe('estimate')} looks like the ground truth: "
            f"{'; '.join(reasons)}. The order is the estimate first, then the reference: swap "
            "them if so")
