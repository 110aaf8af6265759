"""ibiscape-eval: evaluate and calibrate multi-modal SLAM systems.

Notebook use (every capability of the command line is one import away)::

    from ibiscape_eval import read_trajectory, ate, rpe, drift
    est = read_trajectory("est.txt")
    gt = read_trajectory("groundtruth.csv")
    res = ate(est, gt, align="se3")
    print(res.translation_m.rmse)
    res.plot().savefig("ate.png")              # results draw themselves: .plot() -> Figure

    from ibiscape_eval import open_sequence, calibrate_cameras, calibrate_imu_camera, run_vio
    seq = open_sequence("V1_01_easy")          # IBISCape, EuRoC, TUM-VI, ROS bag, or images=[...]
    run_vio(seq).trajectory

    from ibiscape_eval import sim_preset, simulate
    simulate(sim_preset("svi", "calibration", "clear", duration_s=5, seed=1), "SVI_1_calib")

Names are imported lazily, so ``import ibiscape_eval`` stays fast and loads nothing heavy;
``dir(ibiscape_eval)`` lists the public names only.  The ``examples/`` folder has one
notebook-style script per capability.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .core.lazy import lazy_exports

__version__ = "0.1.0"

# public name -> module that defines it ("module:attribute" when it is named differently there)
_EXPORTS: dict[str, str] = {
    # types and errors
    "Trajectory": "ibiscape_eval.core.trajectory",
    "Sequence": "ibiscape_eval.core.sequence",
    "IbiscapeError": "ibiscape_eval.core.errors",
    "FormatError": "ibiscape_eval.core.errors",
    "DegenerateInputError": "ibiscape_eval.core.errors",
    "CalibrationError": "ibiscape_eval.core.errors",
    "IbiscapeWarning": "ibiscape_eval.core.errors",
    "Remedy": "ibiscape_eval.core.errors",
    # files and recordings
    "read_trajectory": "ibiscape_eval.io",
    "write_trajectory": "ibiscape_eval.io",
    "open_sequence": "ibiscape_eval.io.open_sequence",
    "read_imu": "ibiscape_eval.io.imu",
    "open_events": "ibiscape_eval.io.events",
    "read_target": "ibiscape_eval.io.kalibr",
    # trajectory metrics
    "ate": "ibiscape_eval.metrics",
    "rpe": "ibiscape_eval.metrics",
    "drift": "ibiscape_eval.metrics",
    "compare": "ibiscape_eval.metrics",
    "associate": "ibiscape_eval.metrics",
    "align": "ibiscape_eval.metrics",
    "estimate_time_offset": "ibiscape_eval.metrics",
    # IMU noise
    "allan_deviation": "ibiscape_eval.imu",
    "fit_noise_model": "ibiscape_eval.imu",
    "NoiseModel": "ibiscape_eval.imu",
    # event cameras
    "hot_pixels": "ibiscape_eval.events.pipeline",
    "detect_hot_pixels": "ibiscape_eval.events",
    "hot_pixel_mask": "ibiscape_eval.events",
    # calibration and VIO: one door for a recording, one pipeline per job
    "calibrate_cameras": "ibiscape_eval.calib.pipeline",
    "calibrate_imu_camera": "ibiscape_eval.calib.imu_camera.sequence",
    "run_vio": "ibiscape_eval.vio.pipeline",
    "VioParams": "ibiscape_eval.vio.params",
    # the synthetic generator
    "simulate": "ibiscape_eval.sim.generator:generate",
    "sim_preset": "ibiscape_eval.sim.config:preset",
    "SimConfig": "ibiscape_eval.sim.config",
    # a folder of runs: discover, evaluate, write the report
    "discover_runs": "ibiscape_eval.report.runs",
    "evaluate_runs": "ibiscape_eval.report.evaluate",
    "EvaluationOptions": "ibiscape_eval.report.evaluate",
    "write_report": "ibiscape_eval.report.batch_report",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, relative=False)


if TYPE_CHECKING:  # pragma: no cover
    from .calib.imu_camera.sequence import calibrate_imu_camera  # noqa: F401
    from .calib.pipeline import calibrate_cameras  # noqa: F401
    from .core.errors import (  # noqa: F401
        CalibrationError,
        DegenerateInputError,
        FormatError,
        IbiscapeError,
        IbiscapeWarning,
        Remedy,
    )
    from .core.sequence import Sequence  # noqa: F401
    from .core.trajectory import Trajectory  # noqa: F401
    from .events import detect_hot_pixels, hot_pixel_mask  # noqa: F401
    from .events.pipeline import hot_pixels  # noqa: F401
    from .imu import NoiseModel, allan_deviation, fit_noise_model  # noqa: F401
    from .io import read_trajectory, write_trajectory  # noqa: F401
    from .io.events import open_events  # noqa: F401
    from .io.imu import read_imu  # noqa: F401
    from .io.kalibr import read_target  # noqa: F401
    from .io.open_sequence import open_sequence  # noqa: F401
    from .metrics import (  # noqa: F401
        align,
        associate,
        ate,
        compare,
        drift,
        estimate_time_offset,
        rpe,
    )
    from .report.batch_report import write_report  # noqa: F401
    from .report.evaluate import EvaluationOptions, evaluate_runs  # noqa: F401
    from .report.runs import discover_runs  # noqa: F401
    from .sim.config import SimConfig  # noqa: F401
    from .sim.config import preset as sim_preset  # noqa: F401
    from .sim.generator import generate as simulate  # noqa: F401
    from .vio.params import VioParams  # noqa: F401
    from .vio.pipeline import run_vio  # noqa: F401
