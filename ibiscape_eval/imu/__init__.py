"""IMU noise analysis: overlapping Allan deviation and the N / K / B noise model."""

from .allan import ONE_SIGMA_CI, AllanResult, ChunkedSamples, allan_deviation, edf_white_fm
from .fit import BIAS_INSTABILITY_FACTOR, AxisNoise, NoiseModel, fit_noise_model
from .gaps import MAX_MISSING_FRACTION, check_gaps
from .still import StillnessReport, assess_stillness, check_still, forced_warning

__all__ = [
    "BIAS_INSTABILITY_FACTOR",
    "MAX_MISSING_FRACTION",
    "ONE_SIGMA_CI",
    "AllanResult",
    "AxisNoise",
    "ChunkedSamples",
    "NoiseModel",
    "StillnessReport",
    "allan_deviation",
    "assess_stillness",
    "check_gaps",
    "check_still",
    "edf_white_fm",
    "fit_noise_model",
    "forced_warning",
]
