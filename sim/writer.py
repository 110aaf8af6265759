"""IBISCape sequence folder: layout, ``sequence.yaml`` document, atomic folder creation.

Layout (``../shared/FORMATS.md``)::

    <out>/                                      (e.g. SVI_1_town)
      sequence.yaml                              everything a tool may check against
      weather.csv                                weather per camera frame (for the renderer)
      other_sensors/imu.csv | imu0.csv imu1.csv imu2.csv   (one IMU: imu.csv, like the scripts;
                                                 CARLA's left-handed frame, converted by io/)
      other_sensors/gnss.csv
      vehicle_gt/groundtruth_sync.csv            CARLA's left-handed frame (converted by io/)
      vehicle_gt/Tesla_simulation.txt            t_ns, throttle, steer, brake
      <camera>/timestamps.csv, frames/<ns>.png   only once images are rendered (not in this issue)

The folder is built in a hidden temporary sibling and renamed onto ``<out>`` at the end, so a
failure or Ctrl-C never leaves a partial sequence; every file inside is written atomically too.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ibiscape_eval.core.errors import IbiscapeError

from .imu import noise_parameters
from .rig import T_body_camera, T_body_imu

if TYPE_CHECKING:
    from .config import SimConfig

__all__ = ["VEHICLE", "imu_file_names", "sequence_document"]

#: Vehicle name used in ``vehicle_gt/<Vehicle>_simulation.txt``.
VEHICLE = "Tesla"

CONVENTIONS: dict[str, Any] = {
    "world_frame": "right-handed local ENU at gnss.reference: x east, y north, z up; "
                   "gravity (0, 0, -9.81) m/s^2",
    "body_frame": "IMU0: x forward, y left, z up (right-handed)",
    "camera_frame": "OpenCV: z along the optical axis, x right, y down; pixel centres at integer "
                    "coordinates (principal point of a 1024 px image at 511.5)",
    "transforms": "T_a_b maps coordinates in frame b to frame a (4x4, rows)",
    "quaternion_order_in_memory": "x, y, z, w",
    "groundtruth_file": "vehicle_gt/groundtruth_sync.csv in CARLA's LEFT-handed frame (x forward, "
                        "y right, z up) exactly like IBISCape: p, v, a mirrored in y, quaternion "
                        "w, x, y, z of Rz(yaw) Ry(pitch) Rx(roll) with CARLA's angles, angular "
                        "rate in CARLA's frame; ibiscape_eval.io.read_ibiscape_groundtruth "
                        "converts back",
    "imu_files": "other_sensors/imu*.csv: #timestamp [ns], w_x, w_y, w_z [rad/s], a_x, a_y, a_z "
                 "[m/s^2] in CARLA's LEFT-handed sensor frame (x forward, y right, z up) exactly "
                 "like IBISCape: the mirror of each IMU's right-handed frame (imus.<name>."
                 "T_body_imu), i.e. w_x, w_z and a_y negated; a_* is the specific force "
                 "R^T (a - g); ibiscape_eval.io.read_imu converts back (format ibiscape, "
                 "auto-detected in this layout). A still IMU written as other_sensors/imu*.npy "
                 "(still_format: npy; [t_ns, w_xyz, a_xyz] float64) stays in the IMU's RIGHT-handed "
                 "frame",
    "gnss_file": "other_sensors/gnss.csv: #timestamp [ns], latitude [deg], longitude [deg], "
                 "altitude [m] (WGS84) of the antenna",
    "controls_file": "vehicle_gt/<Vehicle>_simulation.txt: t [ns], throttle [0..1], steer "
                     "[-1..1] (positive = right, like CARLA), brake [0..1]",
    "timestamps": "int64 nanoseconds",
    "units": "metres, seconds, radians unless a key says _deg",
}


def imu_file_names(cfg: SimConfig) -> dict[str, str]:
    """IMU name -> file under ``other_sensors/`` (``imu.csv`` for a single IMU, else ``<name>.csv``;
    ``.npy`` for a still IMU with ``still_format: npy``)."""
    ext = ".npy" if cfg.setup == "imu" and cfg.still_format == "npy" else ".csv"
    if len(cfg.imus) == 1:
        return {cfg.imus[0].name: "imu" + ext}
    return {s.name: s.name + ext for s in cfg.imus}


def sequence_document(cfg: SimConfig, *, world: dict[str, Any] | None, target: dict[str, Any] | None,
                      scenario: dict[str, Any], weather_averages: dict[str, float] | None,
                      files: dict[str, Any], rendered: dict[str, dict[str, Any]] | None = None
                      ) -> dict[str, Any]:
    """The ``sequence.yaml`` mapping (see the module docstring of :mod:`ibiscape_eval.io.sequence`).

    ``rendered`` maps the name of every camera whose images were written to what was written
    (folders, frame count, DVS counts); camera entries carry the TRUE camera model either way.
    """
    from ibiscape_eval import __version__

    rendered = rendered or {}
    cams = _camera_entries(cfg, rendered)
    imus = _imu_entries(cfg)
    g = cfg.gnss
    T_bg = np.eye(4)
    T_bg[:3, 3] = g.position_m
    doc: dict[str, Any] = {
        "generator": {"name": "ibiscape-eval sim", "version": __version__, "seed": cfg.seed,
                      "setup": cfg.setup, "kind": cfg.kind, "scenario": cfg.scenario,
                      "ideal": cfg.ideal, "duration_s": cfg.duration_s, "start_ns": cfg.start_ns,
                      "gt_rate_hz": cfg.gt_rate_hz, "rendered": bool(rendered)},
        "conventions": CONVENTIONS,
        "files": files,
        "cameras": cams,
        "imus": imus,
        "gnss": {"reference": {"latitude_deg": g.ref_lat_deg, "longitude_deg": g.ref_lon_deg,
                               "altitude_m": g.ref_alt_m, "datum": "WGS84",
                               "local_frame": "ENU (world x east, y north, z up)"},
                 "sigma_horizontal_m": 0.0 if cfg.ideal else g.sigma_horizontal_m,
                 "sigma_vertical_m": 0.0 if cfg.ideal else g.sigma_vertical_m,
                 "rate_hz": g.rate_hz, "T_body_gnss": T_bg},
        "weather": {"preset": cfg.weather, "file": files.get("weather"),
                    "averages": weather_averages},
        "target": target,
        "scenario": scenario,
        "world": world,
        "config": cfg.to_dict(),
    }
    return doc


def _camera_entries(cfg: SimConfig, rendered: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """``sequence.yaml`` ``cameras``: Kalibr camchain fields, the rig pose, what was rendered."""
    from .dvs import dvs_config_of
    from .render.rays import camera_model

    imu0 = next(s for s in cfg.imus if s.name == "imu0")
    T_b_imu0 = T_body_imu(imu0)
    cams: dict[str, Any] = {}
    prev: np.ndarray | None = None
    for c in cfg.cameras:
        T_bc = T_body_camera(c)
        kalibr = camera_model(c).to_kalibr()
        entry: dict[str, Any] = {
            "camera_model": "pinhole",
            "intrinsics": kalibr["intrinsics"],
            "distortion_model": kalibr["distortion_model"],
            "distortion_coeffs": kalibr["distortion_coeffs"],
            "resolution": kalibr["resolution"],
            "rostopic": f"/{c.name}/image_raw",
            "kind": c.kind,
            "rate_hz": c.rate_hz,
            "fov_deg": c.fov_deg,
            "T_body_cam": T_bc,
            "T_cam_imu": np.linalg.inv(T_bc) @ T_b_imu0,
            "timeshift_cam_imu": float(c.timeshift_cam_imu_s),
            "rendered": c.name in rendered,
        }
        if c.kind == "dvs":  # the sensor settings; a rendered camera adds its event counts
            entry["dvs"] = dvs_config_of(cfg).sensor_dict()
        entry.update(rendered.get(c.name, {}))
        if prev is not None:
            entry["T_cn_cnm1"] = np.linalg.inv(T_bc) @ prev
        prev = T_bc
        cams[c.name] = entry
    return cams


def _imu_entries(cfg: SimConfig) -> dict[str, Any]:
    """``sequence.yaml`` ``imus``: Kalibr imu fields and the simulator's noise per sample."""
    names = imu_file_names(cfg)
    imus: dict[str, Any] = {}
    for s in cfg.imus:
        p = noise_parameters(cfg.imu_noise, s.rate_hz, ideal=cfg.ideal)
        imus[s.name] = {
            "accelerometer_noise_density": p.noise_density[3],
            "accelerometer_random_walk": p.random_walk[3],
            "gyroscope_noise_density": p.noise_density[0],
            "gyroscope_random_walk": p.random_walk[0],
            "rostopic": f"/{s.name}",
            "update_rate": s.rate_hz,
            "T_body_imu": T_body_imu(s),
            "file": f"other_sensors/{names[s.name]}",
            "noise_model": "ideal" if cfg.ideal else cfg.imu_noise.model,
            "gyroscope_sigma_per_sample": p.sigma_per_sample[0],
            "accelerometer_sigma_per_sample": p.sigma_per_sample[3],
            "gyroscope_random_walk_sigma_per_step": p.walk_sigma_per_step[0],
            "accelerometer_random_walk_sigma_per_step": p.walk_sigma_per_step[3],
            "gyroscope_turn_on_bias_sigma": p.turn_on_bias_sigma[0],
            "accelerometer_turn_on_bias_sigma": p.turn_on_bias_sigma[3],
            "gyroscope_constant_bias": p.constant_bias[0],
        }
    return imus


def prepare_output(out: str | os.PathLike[str], *, overwrite: bool) -> Path:
    """Check ``out``: it must not exist, or be an empty folder, or ``overwrite`` must be set."""
    p = Path(out)
    if p.exists():
        if not p.is_dir():
            raise IbiscapeError(f"{p}: exists and is not a folder; choose another --out")
        if any(p.iterdir()) and not overwrite:
            raise IbiscapeError(f"{p}: output folder exists and is not empty; use --overwrite or "
                                "another --out")
    return p


