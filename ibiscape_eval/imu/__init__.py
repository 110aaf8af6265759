"""IMU noise analysis: overlapping Allan deviation and the N / K / B noise model."""

from .allan import ONE_SIGMA_CI, AllanResult, ChunkedSamples, allan_deviation, edf_white_fm
from .fit import BIAS_INSTABILITY_FACTOR, AxisNoise, NoiseModel, fit_noise_model

__all__ = [
    "BIAS_INSTABILITY_FACTOR",
    "ONE_SIGMA_CI",
    "AllanResult",
    "AxisNoise",
    "ChunkedSamples",
    "NoiseModel",
    "allan_deviation",
    "edf_white_fm",
    "fit_noise_model",
]
