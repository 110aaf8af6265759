"""ibiscape-eval: evaluate and calibrate multi-modal SLAM systems.

Notebook use::

    from ibiscape_eval import read_trajectory, ate, rpe, drift
    est = read_trajectory("est.txt")
    gt = read_trajectory("groundtruth.csv")
    print(ate(est, gt, align="se3").translation_m.rmse)

Names are imported lazily, so ``import ibiscape_eval`` stays fast and loads nothing heavy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .core.lazy import lazy_exports

__version__ = "0.1.0"

# public name -> module that defines it
_EXPORTS: dict[str, str] = {
    "Trajectory": "ibiscape_eval.core.trajectory",
    "IbiscapeError": "ibiscape_eval.core.errors",
    "FormatError": "ibiscape_eval.core.errors",
    "DegenerateInputError": "ibiscape_eval.core.errors",
    "IbiscapeWarning": "ibiscape_eval.core.errors",
    "read_trajectory": "ibiscape_eval.io",
    "write_trajectory": "ibiscape_eval.io",
    "ate": "ibiscape_eval.metrics",
    "rpe": "ibiscape_eval.metrics",
    "drift": "ibiscape_eval.metrics",
    "associate": "ibiscape_eval.metrics",
    "align": "ibiscape_eval.metrics",
    "estimate_time_offset": "ibiscape_eval.metrics",
    "allan_deviation": "ibiscape_eval.imu",
    "fit_noise_model": "ibiscape_eval.imu",
    "detect_hot_pixels": "ibiscape_eval.events",
    "hot_pixel_mask": "ibiscape_eval.events",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, relative=False)


if TYPE_CHECKING:  # pragma: no cover
    from .core.errors import (  # noqa: F401
        DegenerateInputError,
        FormatError,
        IbiscapeError,
        IbiscapeWarning,
    )
    from .core.trajectory import Trajectory  # noqa: F401
