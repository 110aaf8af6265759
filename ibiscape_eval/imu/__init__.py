"""IMU noise analysis: overlapping Allan deviation and the N / K / B noise model."""

from .allan import ONE_SIGMA_CI, AllanResult, ChunkedSamples, allan_deviation, edf_white_fm
from .fit import BIAS_INSTABILITY_FACTOR, AxisNoise, NoiseModel, fit_noise_model
from .gaps import MAX_MISSING_FRACTION, check_gaps

__all__ = [
    "BIAS_INSTABILITY_FACTOR",
    "MAX_MISSING_FRACTION",
    "ONE_SIGMA_CI",
    "AllanResult",
    "AxisNoise",
    "ChunkedSamples",
    "NoiseModel",
    "allan_deviation",
    "check_gaps",
    "edf_white_fm",
    "fit_noise_model",
]
