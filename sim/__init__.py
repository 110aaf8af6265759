"""Synthetic IBISCape-layout sequences with exact ground truth (CPU only, seeded).

Notebook use::

    from ibiscape_eval.sim import preset, generate
    cfg = preset("svi", "calibration", "clear", duration_s=20, seed=1, ideal=True)
    summary = generate(cfg, "SVI_1_calib")
    print(summary.length_m, summary.roll_std_deg)

Parts: ``config`` (presets, YAML), ``rig`` (extrinsics), ``imu``/``gnss``/``weather`` (sensor
models), ``still`` (streamed still IMU), ``writer`` (layout, sequence.yaml), ``generate``
(orchestration); the world, targets, terrain and vehicle motion live in ``world``, ``targets``,
``terrain``, ``route``, ``motion``.  Names below are imported lazily.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ibiscape_eval.core.lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    "SimConfig": "config",
    "CameraSpec": "config",
    "ImuSpec": "config",
    "ImuNoise": "config",
    "GnssSpec": "config",
    "WeatherSpec": "config",
    "MotionSpec": "config",
    "SETUPS": "config",
    "KINDS": "config",
    "WEATHERS": "config",
    "SCENARIOS": "config",
    "preset": "config",
    "load_config": "config",
    "dump_config": "config",
    "generate": "generator",
    "plan": "generator",
    "sequence_name": "generator",
    "SequenceSummary": "generator",
    "ImuMeasurements": "imu",
    "ideal_imu": "imu",
    "simulate_imu": "imu",
    "simulate_gnss": "gnss",
    "simulate_weather": "weather",
    "WeatherLog": "weather",
    "still_imu_chunks": "still",
    "MotionState": "types",
    "Controls": "types",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


if TYPE_CHECKING:  # pragma: no cover
    from .config import (  # noqa: F401
        CameraSpec,
        GnssSpec,
        ImuNoise,
        ImuSpec,
        MotionSpec,
        SimConfig,
        WeatherSpec,
        dump_config,
        load_config,
        preset,
    )
    from .generator import SequenceSummary, generate, plan, sequence_name  # noqa: F401
    from .gnss import simulate_gnss  # noqa: F401
    from .imu import ImuMeasurements, ideal_imu, simulate_imu  # noqa: F401
    from .still import still_imu_chunks  # noqa: F401
    from .types import Controls, MotionState  # noqa: F401
    from .weather import WeatherLog, simulate_weather  # noqa: F401
