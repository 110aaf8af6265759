"""Event-camera tools: hot-pixel detection and removal, event frames, synthetic streams.

All functions take plain arrays (``x``, ``y`` uint16, ``t`` int64 ns, ``p`` bool) or
:class:`~ibiscape_eval.core.events.Events`; file formats live in :mod:`ibiscape_eval.io.events`.
numba is imported only when an event loop first runs.
"""

from .frames import EventFrames, accumulate_frames, time_surfaces
from .hotpix import (
    HotPixelResult,
    PixelCounter,
    count_events,
    detect_hot_pixels,
    filter_arrays,
    filter_events,
    hot_pixel_mask,
    hot_pixels_from_counts,
    rate_hot_pixels,
)
from .synthetic import SyntheticStream, synthetic_events, synthetic_windows

__all__ = [
    "EventFrames",
    "HotPixelResult",
    "PixelCounter",
    "SyntheticStream",
    "accumulate_frames",
    "count_events",
    "detect_hot_pixels",
    "filter_arrays",
    "filter_events",
    "hot_pixel_mask",
    "hot_pixels_from_counts",
    "rate_hot_pixels",
    "synthetic_events",
    "synthetic_windows",
    "time_surfaces",
]
