"""ibiscape-eval: evaluate and calibrate multi-modal SLAM systems.

Notebook use::

    from ibiscape_eval import read_trajectory, ate, rpe, drift
    est = read_trajectory("est.txt")
    gt = read_trajectory("groundtruth.csv")
    print(ate(est, gt, align="se3").translation_m.rmse)

    from ibiscape_eval import open_sequence, calibrate_cameras, calibrate_imu_camera, run_vio
    seq = open_sequence("V1_01_easy")          # IBISCape, EuRoC, TUM-VI, ROS bag, or images=[...]
    run_vio(seq).trajectory

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
    # one door for a recording, one pipeline per job (the CLI, the benchmark and notebooks)
    "Sequence": "ibiscape_eval.core.sequence",
    "open_sequence": "ibiscape_eval.io.open_sequence",
    "calibrate_cameras": "ibiscape_eval.calib.pipeline",
    "calibrate_imu_camera": "ibiscape_eval.calib.imu_camera.sequence",
    "run_vio": "ibiscape_eval.vio.pipeline",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, relative=False)


if TYPE_CHECKING:  # pragma: no cover
    from .calib.imu_camera.sequence import calibrate_imu_camera  # noqa: F401
    from .calib.pipeline import calibrate_cameras  # noqa: F401
    from .core.errors import (  # noqa: F401
        DegenerateInputError,
        FormatError,
        IbiscapeError,
        IbiscapeWarning,
    )
    from .core.sequence import Sequence  # noqa: F401
    from .core.trajectory import Trajectory  # noqa: F401
    from .io.open_sequence import open_sequence  # noqa: F401
    from .vio.pipeline import run_vio  # noqa: F401
