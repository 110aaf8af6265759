"""Stereo visual-inertial odometry baseline (OpenCV front end, GTSAM fixed-lag smoother).

Notebook use::

    from ibiscape_eval.vio import load_sequence, run_vio
    seq = load_sequence("SVI_1_town")            # or an EuRoC ASL folder
    result = run_vio(seq)
    result.trajectory                             # T_world_body at every camera frame
    result.stats.failures                         # tracking failures with their time spans

Parts: ``params`` (options), ``rig`` (stereo rectification), ``inputs`` (sequence reading and
its checks), ``frontend`` (features, KLT, stereo matching), ``backend`` (GTSAM smoother),
``initialise`` (standstill / moving start), ``estimator`` (keyframes, failures, output poses),
``synthetic`` (measurements without images), ``pipeline`` (images -> trajectory).  gtsam and cv2
are imported inside the functions that use them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ibiscape_eval.core.lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "VioParams": "params",
    "StereoRig": "rig",
    "RectifiedStereo": "rig",
    "StereoSequence": "inputs",
    "load_sequence": "inputs",
    "StereoObservations": "backend",
    "Backend": "backend",
    "Estimator": "estimator",
    "FailureSpan": "estimator",
    "StereoFrontEnd": "frontend",
    "VioResult": "pipeline",
    "VioStats": "pipeline",
    "run_vio": "pipeline",
    "random_landmarks": "synthetic",
    "synthetic_observations": "synthetic",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


if TYPE_CHECKING:  # pragma: no cover
    from .backend import Backend, StereoObservations  # noqa: F401
    from .estimator import Estimator, FailureSpan  # noqa: F401
    from .frontend import StereoFrontEnd  # noqa: F401
    from .inputs import StereoSequence, load_sequence  # noqa: F401
    from .params import VioParams  # noqa: F401
    from .pipeline import VioResult, VioStats, run_vio  # noqa: F401
    from .rig import RectifiedStereo, StereoRig  # noqa: F401
    from .synthetic import random_landmarks, synthetic_observations  # noqa: F401
