"""The gap policy of the Allan deviation: which timestamp gaps a record may have.

The overlapping Allan deviation assumes equally spaced samples.  A record whose gaps hide more
than ``max_missing`` of its samples, or with one interval longer than 100 median intervals, is
refused unless the caller allows gaps (then the samples are treated as equally spaced, with a
warning).
"""

from __future__ import annotations

import os
import warnings

from ibiscape_eval.core.errors import FormatError, IbiscapeWarning, Remedy
from ibiscape_eval.core.imu import ImuTiming

__all__ = ["LONGEST_GAP_INTERVALS", "MAX_MISSING_FRACTION", "check_gaps"]

#: Default largest fraction of missing samples accepted without ``allow_gaps``.
MAX_MISSING_FRACTION = 0.005
#: A single interval longer than this many median intervals is refused without ``allow_gaps``.
LONGEST_GAP_INTERVALS = 100


def check_gaps(timing: ImuTiming, path: str | os.PathLike[str], *,
               max_missing: float = MAX_MISSING_FRACTION, allow_gaps: bool = False) -> None:
    """Apply the gap policy to a record's timing.

    Raises
    ------
    FormatError
        Naming ``path`` and the line of the first gap, when the gaps are too large and
        ``allow_gaps`` is False.

    Warns
    -----
    IbiscapeWarning
        When there are gaps and ``allow_gaps`` is True.
    """
    if not timing.has_stamps:
        return
    too_big = (timing.missing_fraction > max_missing
               or timing.largest_gap_s > LONGEST_GAP_INTERVALS * timing.median_dt_s)
    if too_big and not allow_gaps:
        raise FormatError(
            path,
            f"{timing.n_gaps} gap(s) in the timestamps, {100 * timing.missing_fraction:.3g} % of "
            f"the samples missing, longest {timing.largest_gap_s:.4g} s (first gap here): the "
            "Allan deviation assumes equal spacing; cut the record or pass {0}",
            line=timing.first_gap_line, hint=(Remedy("allow_gaps", flag=True),),
        )
    if timing.n_gaps and allow_gaps:
        warnings.warn("gaps are ignored (samples treated as equally spaced)", IbiscapeWarning,
                      stacklevel=2)
