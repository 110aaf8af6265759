"""Simulator configuration: typed frozen dataclasses, presets mirroring the paper, YAML load/dump.

Presets mirror the IBISCape paper's ``table:ibiscape_sequences``: a *setup* (``imu`` still IMU,
``svi`` 2x RGB + IMU, ``esvi`` 2x DVS + 2x IMU (+ IMU0), ``rgbd``, ``full``), a *kind*
(``calibration`` or ``slam``), a *weather* (``clear``, ``moderate``, ``dynamic``) and a *scenario*
(``default`` or the SVI ``accident``: a short SLAM run ending in a hard stop behind an obstacle).

Mounting (paper ``table:extrinsics``)
-------------------------------------
The paper lists "X, Y, Z translation to IMU0" as ``left RGB [0, 0.2, -2.8]``, ``GPS [0.2, 0, -2.8]``
... .  Read in CARLA's frame (y right) as "IMU0 minus sensor" the GPS would sit behind the IMU,
read as "sensor minus IMU0" the left camera would be on the right and 2.8 m below the car.  The only
reading consistent with the labels (left/right), with cameras on the roof and with the GPS ahead is
a frame x forward, y LEFT, z DOWN, so we map ``(x, y, z)_paper -> (x, y, -z)`` in our body frame
(x forward, y left, z up): cameras 2.8 m above IMU0, left RGB at y = +0.2 m, GPS at x = +0.2 m.

Cameras are pinhole, 1024 x 1024, 90 deg horizontal FOV: ``f = (w / 2) / tan(fov / 2) = 512`` px
and, in OpenCV's convention where pixel centres sit at integer coordinates, the principal point
at the image centre is ``c = ((w - 1) / 2, (h - 1) / 2) = (511.5, 511.5)``.  Camera frames are
OpenCV's (z forward along body x, x right, y down); ``rpy_deg`` rotates that mount in the body.

YAML
----
The file itself is read and written by :mod:`ibiscape_eval.io.simconfig` (YAML, lines of keys);
this module turns its plain mapping into the dataclasses.  ``load_config(path)`` reads a mapping: optional ``setup``/``kind``/``weather``/``scenario`` pick
the preset, then every other key overrides it (``cameras`` and ``imus`` map a sensor name to the
fields to change; a new name adds a sensor, ``null`` removes one).  Unknown keys are errors that
name the key and the allowed ones.  ``dump_config(cfg)`` writes the full description with a comment
per key; it loads back to the same config.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field, fields, replace
from typing import TYPE_CHECKING, Any

from ibiscape_eval.core.errors import FormatError, IbiscapeError

if TYPE_CHECKING:
    from ibiscape_eval.io.simconfig import SimConfigDoc, YamlItem

__all__ = [
    "KINDS",
    "SCENARIOS",
    "SETUPS",
    "WEATHERS",
    "CameraSpec",
    "GnssSpec",
    "ImuNoise",
    "ImuSpec",
    "MotionSpec",
    "RenderSpec",
    "SimConfig",
    "WeatherSpec",
    "dump_config",
    "load_config",
    "parse_resolution",
    "preset",
    "with_resolution",
]

SETUPS = ("imu", "svi", "esvi", "rgbd", "full")
KINDS = ("calibration", "slam")
WEATHERS = ("clear", "moderate", "dynamic")
SCENARIOS = ("default", "accident")
CAMERA_KINDS = ("rgb", "depth", "semantic", "dvs")
TARGETS = ("checkerboard", "aprilgrid")
CAM_HEIGHT_M = 2.8
#: largest camera clock offset the simulator accepts [s] (Kalibr searches offsets of this order)
MAX_TIMESHIFT_S = 0.1


def _doc(text: str) -> Any:
    return {"doc": text}


@dataclass(frozen=True)
class ImuNoise:
    """IMU noise.  ``model: continuous`` uses Kalibr's continuous-time densities (white noise,
    bias random walk) plus a constant turn-on bias drawn once per axis; ``model: carla`` uses
    CARLA's per-sample sigmas (white only) and its constant gyro bias."""

    model: str = field(default="continuous", metadata=_doc("continuous | carla"))
    gyro_noise_density_rad_s_sqrt_hz: float = field(default=1.6968e-4, metadata=_doc(
        "gyro white noise density N [rad/s/sqrt(Hz)] (Kalibr gyroscope_noise_density)"))
    gyro_random_walk_rad_s2_sqrt_hz: float = field(default=1.9393e-5, metadata=_doc(
        "gyro bias random walk K [rad/s^2/sqrt(Hz)] (Kalibr gyroscope_random_walk)"))
    accel_noise_density_m_s2_sqrt_hz: float = field(default=2.0e-3, metadata=_doc(
        "accelerometer white noise density [m/s^2/sqrt(Hz)]"))
    accel_random_walk_m_s3_sqrt_hz: float = field(default=3.0e-3, metadata=_doc(
        "accelerometer bias random walk [m/s^3/sqrt(Hz)]"))
    gyro_turn_on_bias_sigma_rad_s: float = field(default=5.0e-4, metadata=_doc(
        "sigma of the constant gyro turn-on bias, drawn once per axis [rad/s]"))
    accel_turn_on_bias_sigma_m_s2: float = field(default=2.0e-2, metadata=_doc(
        "sigma of the constant accelerometer turn-on bias [m/s^2]"))
    carla_gyro_sigma_rad_s: float = field(default=0.004, metadata=_doc(
        "carla model: gyro sigma per sample [rad/s]"))
    carla_accel_sigma_m_s2: float = field(default=0.07, metadata=_doc(
        "carla model: accelerometer sigma per sample [m/s^2]"))
    carla_gyro_bias_rad_s: float = field(default=0.0, metadata=_doc(
        "carla model: constant gyro bias on every axis [rad/s]"))


@dataclass(frozen=True)
class ImuSpec:
    """One IMU: name (file ``other_sensors/<file>.csv``), mounting and rate."""

    name: str = field(default="imu0", metadata=_doc("IMU name (imu0, imu1, ...)"))
    position_m: tuple[float, float, float] = field(default=(0.0, 0.0, 0.0), metadata=_doc(
        "position in the body frame (x fwd, y left, z up) [m]"))
    rpy_deg: tuple[float, float, float] = field(default=(0.0, 0.0, 0.0), metadata=_doc(
        "roll, pitch, yaw of the IMU axes in the body frame (ZYX) [deg]"))
    rate_hz: float = field(default=200.0, metadata=_doc("sample rate [Hz]"))
    mount: str = field(default="", metadata=_doc(
        "housing name: sensors sharing a non-empty mount may coincide"))


@dataclass(frozen=True)
class CameraSpec:
    """One camera (folder name = ``name``): pinhole, OpenCV frame, forward-looking mount."""

    name: str = field(default="rgbL", metadata=_doc("folder name (rgbL, rgbR, depth, davisL ...)"))
    kind: str = field(default="rgb", metadata=_doc("rgb | depth | semantic | dvs"))
    position_m: tuple[float, float, float] = field(default=(0.0, 0.2, CAM_HEIGHT_M), metadata=_doc(
        "optical centre in the body frame (x fwd, y left, z up) [m]"))
    rpy_deg: tuple[float, float, float] = field(default=(0.0, 0.0, 0.0), metadata=_doc(
        "extra roll, pitch, yaw (ZYX, body axes) of the forward-looking mount [deg]"))
    width_px: int = field(default=1024, metadata=_doc("image width [px]"))
    height_px: int = field(default=1024, metadata=_doc("image height [px]"))
    fov_deg: float = field(default=90.0, metadata=_doc("horizontal field of view [deg]"))
    rate_hz: float = field(default=20.0, metadata=_doc("frame rate [Hz]"))
    mount: str = field(default="", metadata=_doc(
        "housing name: sensors sharing a non-empty mount may coincide (RGB-D pair)"))
    distortion_model: str = field(default="none", metadata=_doc(
        "none | radtan | equidistant (Kalibr's models; rendered images are distorted exactly)"))
    distortion_coeffs: tuple[float, float, float, float] = field(
        default=(0.0, 0.0, 0.0, 0.0), metadata=_doc(
            "radtan [k1, k2, p1, p2] or equidistant [k1, k2, k3, k4]"))
    timeshift_cam_imu_s: float = field(default=0.0, metadata=_doc(
        "camera clock offset, Kalibr's timeshift_cam_imu (t_imu = t_cam + shift): a frame "
        "stamped t_cam shows the scene at t_cam + shift [s], within +-0.1"))

    @property
    def focal_px(self) -> float:
        """``(w / 2) / tan(fov / 2)`` rounded to 1e-9 px (exactly 512 for 1024 px and 90 deg)."""
        return round((self.width_px / 2.0) / math.tan(math.radians(self.fov_deg) / 2.0), 9)

    @property
    def intrinsics(self) -> list[float]:
        """Kalibr ``[fu, fv, pu, pv]``, pixel centres at integer coordinates."""
        f = self.focal_px
        return [f, f, (self.width_px - 1) / 2.0, (self.height_px - 1) / 2.0]


@dataclass(frozen=True)
class GnssSpec:
    """GNSS receiver: antenna position, rate, noise and the WGS84 reference of the world origin.

    The world frame is the local east-north-up frame at the reference (x east, y north, z up)."""

    position_m: tuple[float, float, float] = field(default=(0.2, 0.0, CAM_HEIGHT_M), metadata=_doc(
        "antenna position in the body frame [m]"))
    rate_hz: float = field(default=1.0, metadata=_doc("fix rate [Hz] (1 slam, 10 calibration)"))
    sigma_horizontal_m: float = field(default=0.5, metadata=_doc(
        "white noise on east and north [m]"))
    sigma_vertical_m: float = field(default=1.0, metadata=_doc("white noise on up [m]"))
    ref_lat_deg: float = field(default=48.6270, metadata=_doc(
        "latitude of the world origin (near the IBISC lab, Evry, France) [deg]"))
    ref_lon_deg: float = field(default=2.4440, metadata=_doc("longitude of the world origin [deg]"))
    ref_alt_m: float = field(default=80.0, metadata=_doc("WGS84 altitude of the world origin [m]"))
    mount: str = field(default="", metadata=_doc("housing name"))


@dataclass(frozen=True)
class WeatherSpec:
    """CARLA weather evolving in time: smooth seeded processes around the preset's means (the
    process is centred over the sequence, so the means ARE the sequence averages before clipping
    to 0..100), a shared "storm" component that couples clouds, rain, wind and fog, wetness and
    puddles that lag the rain, and the sun along ``altitude = 70 sin(phase) - 20``."""

    cloudiness: tuple[float, float] = field(default=(10.0, 5.0), metadata=_doc(
        "mean, std of cloudiness [0..100]"))
    precipitation: tuple[float, float] = field(default=(0.0, 0.0), metadata=_doc(
        "mean, std of rain [0..100]"))
    wind_intensity: tuple[float, float] = field(default=(10.0, 5.0), metadata=_doc(
        "mean, std of wind [0..100]"))
    fog_density: tuple[float, float] = field(default=(0.0, 0.0), metadata=_doc(
        "mean, std of fog density [0..100]"))
    storm_coupling: float = field(default=0.7, metadata=_doc(
        "0..1 share of the common storm component in each parameter's fluctuation"))
    correlation_time_s: float = field(default=20.0, metadata=_doc(
        "time scale of the fluctuations [s]"))
    deposit_lag_s: float = field(default=30.0, metadata=_doc(
        "time constant of wetness and puddles following the rain [s]"))
    sun_phase0_rad: float = field(default=1.5708, metadata=_doc(
        "initial phase of the sun (altitude = 70 sin(phase) - 20) [rad]"))
    sun_phase_rate_rad_s: float = field(default=0.002, metadata=_doc("phase speed [rad/s]"))
    sun_azimuth0_deg: float = field(default=120.0, metadata=_doc("initial sun azimuth [deg]"))
    sun_azimuth_rate_deg_s: float = field(default=0.25, metadata=_doc("azimuth speed [deg/s]"))


@dataclass(frozen=True)
class MotionSpec:
    """What the world/motion planner gets."""

    max_speed_m_s: float = field(default=10.0, metadata=_doc("speed limit of the route [m/s]"))
    town_blocks: int = field(default=4, metadata=_doc("slam town: blocks per side"))
    bumps: bool = field(default=True, metadata=_doc("bubbles and waves on the road"))
    accident_decel_m_s2: float = field(default=6.0, metadata=_doc(
        "accident scenario: mean deceleration of the hard stop [m/s^2]"))
    accident_obstacle_gap_m: float = field(default=2.0, metadata=_doc(
        "accident scenario: gap between the stopped car's front and the obstacle [m]"))
    start_distance_m: float = field(default=0.0, metadata=_doc(
        "calibration loop: start the approach this far in front of the board, 12..90 m, for short "
        "sequences that should see it near (0 = the full 90 m approach, as in the paper)"))
    calibration_drive: str = field(default="shuttle", metadata=_doc(
        "calibration: shuttle (forward and reverse legs 4.5-15 m in front of the board, seen from "
        "-33..33 deg off its normal, in view nearly all the time) | loop (the paper's approach loop)"))


@dataclass(frozen=True)
class RenderSpec:
    """How images are rendered (``ibiscape_eval.sim.render``)."""

    shadows: bool = field(default=True, metadata=_doc("cast shadows (one extra ray per lit pixel)"))
    target_supersample: int = field(default=6, metadata=_doc(
        "s x s rays per pixel on calibration targets (antialiased corners), 1..8"))
    sensor_noise: bool = field(default=True, metadata=_doc(
        "camera noise (read + shot, more in the dark); off with ideal: true"))
    weather_optics: bool = field(default=True, metadata=_doc(
        "fog, rain streaks and the wet road"))
    psf_sigma_px: float = field(default=0.7, metadata=_doc(
        "lens blur: Gaussian point-spread function sigma [px], 0..5 (0 = none)"))


@dataclass(frozen=True)
class SimConfig:
    """Everything :func:`ibiscape_eval.sim.generate` needs (see the module docstring)."""

    setup: str = field(default="svi", metadata=_doc("imu | svi | esvi | rgbd | full"))
    kind: str = field(default="slam", metadata=_doc("calibration | slam"))
    weather: str = field(default="clear", metadata=_doc("clear | moderate | dynamic"))
    scenario: str = field(default="default", metadata=_doc("default | accident (svi slam)"))
    duration_s: float = field(default=60.0, metadata=_doc("sequence duration [s]"))
    seed: int = field(default=0, metadata=_doc("seed of every random process"))
    target: str = field(default="checkerboard", metadata=_doc(
        "calibration target driven toward: checkerboard | aprilgrid"))
    ideal: bool = field(default=False, metadata=_doc("turn every sensor noise off"))
    start_ns: int = field(default=1_000_000_000_000, metadata=_doc("first timestamp [ns]"))
    gt_rate_hz: float = field(default=200.0, metadata=_doc("ground-truth rate [Hz]"))
    housing_m: float = field(default=0.05, metadata=_doc(
        "minimum distance between sensors in different housings [m]"))
    still_format: str = field(default="csv", metadata=_doc(
        "imu setup: IMU file format csv | npy (streamed in chunks)"))
    chunk_samples: int = field(default=1 << 18, metadata=_doc(
        "imu setup: samples per streamed chunk (bounded memory)"))
    imu_noise: ImuNoise = field(default_factory=ImuNoise, metadata=_doc("IMU noise (all IMUs)"))
    imus: tuple[ImuSpec, ...] = field(default=(ImuSpec(),), metadata=_doc("IMUs by name"))
    cameras: tuple[CameraSpec, ...] = field(default=(), metadata=_doc("cameras by folder name"))
    gnss: GnssSpec = field(default_factory=GnssSpec, metadata=_doc("GNSS receiver"))
    weather_model: WeatherSpec = field(default_factory=WeatherSpec, metadata=_doc(
        "weather process (set by the weather preset)"))
    motion: MotionSpec = field(default_factory=MotionSpec, metadata=_doc("route and motion"))
    render: RenderSpec = field(default_factory=RenderSpec, metadata=_doc("image rendering"))

    def __post_init__(self) -> None:
        validate(self)

    @property
    def setup_label(self) -> str:
        """Folder prefix as the dataset names it (``SVI``, ``ESVI``, ``RGBD``, ``Full``, ``IMU``)."""
        return {"imu": "IMU", "svi": "SVI", "esvi": "ESVI", "rgbd": "RGBD", "full": "Full"}[self.setup]

    def to_dict(self) -> dict[str, Any]:
        """Plain YAML-able description (sensors as name -> fields mappings)."""
        return _to_plain(self)


# ---------------------------------------------------------------------------------------------
# validation


def _positive(value: float, key: str) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        raise IbiscapeError(f"config: {key} must be a positive number, got {value!r}")


def _nonneg(value: float, key: str) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
        raise IbiscapeError(f"config: {key} must be >= 0, got {value!r}")


def _choice(value: str, allowed: tuple[str, ...], key: str) -> None:
    if value not in allowed:
        raise IbiscapeError(f"config: unknown {key} {value!r}; use one of {', '.join(allowed)}")


def validate(cfg: SimConfig) -> None:
    """Raise :class:`IbiscapeError` naming the key for any impossible value."""
    _choice(cfg.setup, SETUPS, "setup")
    _choice(cfg.kind, KINDS, "kind")
    _choice(cfg.weather, WEATHERS, "weather")
    _choice(cfg.scenario, SCENARIOS, "scenario")
    _choice(cfg.target, TARGETS, "target")
    _choice(cfg.still_format, ("csv", "npy"), "still_format")
    _choice(cfg.imu_noise.model, ("continuous", "carla"), "imu_noise.model")
    if cfg.scenario == "accident" and cfg.kind != "slam":
        raise IbiscapeError("config: scenario accident needs kind slam")
    _positive(cfg.duration_s, "duration_s")
    _positive(cfg.gt_rate_hz, "gt_rate_hz")
    _nonneg(cfg.housing_m, "housing_m")
    if not isinstance(cfg.seed, int) or cfg.seed < 0:
        raise IbiscapeError(f"config: seed must be an integer >= 0, got {cfg.seed!r}")
    if not isinstance(cfg.start_ns, int) or cfg.start_ns < 0:
        raise IbiscapeError(f"config: start_ns must be an integer >= 0, got {cfg.start_ns!r}")
    if not isinstance(cfg.chunk_samples, int) or cfg.chunk_samples < 1:
        raise IbiscapeError(f"config: chunk_samples must be an integer >= 1, got {cfg.chunk_samples!r}")
    for f in fields(ImuNoise):
        if f.name != "model":
            _nonneg(getattr(cfg.imu_noise, f.name), f"imu_noise.{f.name}")
    if not cfg.imus:
        raise IbiscapeError("config: at least one IMU is needed (imus is empty)")
    names = [s.name for s in cfg.imus] + [c.name for c in cfg.cameras]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise IbiscapeError(f"config: sensor names must be unique, repeated: {', '.join(dup)}")
    _validate_sensors(cfg)
    g = cfg.gnss
    _positive(g.rate_hz, "gnss.rate_hz")
    _nonneg(g.sigma_horizontal_m, "gnss.sigma_horizontal_m")
    _nonneg(g.sigma_vertical_m, "gnss.sigma_vertical_m")
    _vec3(g.position_m, "gnss.position_m")
    if not -90 < g.ref_lat_deg < 90 or not -180 <= g.ref_lon_deg <= 180:
        raise IbiscapeError(f"config: gnss reference ({g.ref_lat_deg}, {g.ref_lon_deg}) is not a "
                            "valid latitude/longitude in degrees")
    w = cfg.weather_model
    for k in ("cloudiness", "precipitation", "wind_intensity", "fog_density"):
        m, s = getattr(w, k)
        if not (0 <= m <= 100 and 0 <= s <= 100):
            raise IbiscapeError(f"config: weather_model.{k} must be (mean, std) in 0..100, got {(m, s)}")
    _positive(w.correlation_time_s, "weather_model.correlation_time_s")
    _positive(w.deposit_lag_s, "weather_model.deposit_lag_s")
    if not 0 <= w.storm_coupling <= 1:
        raise IbiscapeError(f"config: weather_model.storm_coupling must be in 0..1, got {w.storm_coupling}")
    _positive(cfg.motion.max_speed_m_s, "motion.max_speed_m_s")
    _positive(cfg.motion.accident_decel_m_s2, "motion.accident_decel_m_s2")
    _nonneg(cfg.motion.accident_obstacle_gap_m, "motion.accident_obstacle_gap_m")
    _nonneg(cfg.motion.start_distance_m, "motion.start_distance_m")
    _choice(cfg.motion.calibration_drive, ("shuttle", "loop"), "motion.calibration_drive")
    if cfg.motion.start_distance_m and cfg.motion.calibration_drive != "loop" and cfg.kind == "calibration":
        raise IbiscapeError("config: motion.start_distance_m applies to the loop drive; set "
                            "motion.calibration_drive: loop or remove start_distance_m")
    if not isinstance(cfg.motion.town_blocks, int) or cfg.motion.town_blocks < 1:
        raise IbiscapeError(f"config: motion.town_blocks must be an integer >= 1, got {cfg.motion.town_blocks!r}")
    ts = cfg.render.target_supersample
    if isinstance(ts, bool) or not isinstance(ts, int) or not 1 <= ts <= 8:
        raise IbiscapeError(f"config: render.target_supersample must be an integer in 1..8, got {ts!r}")
    ps = cfg.render.psf_sigma_px
    if not (isinstance(ps, int | float) and math.isfinite(ps) and 0.0 <= ps <= 5.0):
        raise IbiscapeError(f"config: render.psf_sigma_px must be in 0..5 px, got {ps!r}")
    check_ranges(cfg)
    from .rig import check_housings

    check_housings(cfg)


#: smallest and largest image side the renderer accepts [px]
MIN_SIDE_PX, MAX_SIDE_PX = 8, 8192


def _validate_sensors(cfg: SimConfig) -> None:
    """The IMUs' and cameras' rates, poses, sizes, optics and clock offsets."""
    for s in cfg.imus:
        _positive(s.rate_hz, f"imus.{s.name}.rate_hz")
        _vec3(s.position_m, f"imus.{s.name}.position_m")
        _vec3(s.rpy_deg, f"imus.{s.name}.rpy_deg")
    for c in cfg.cameras:
        _choice(c.kind, CAMERA_KINDS, f"cameras.{c.name}.kind")
        _positive(c.rate_hz, f"cameras.{c.name}.rate_hz")
        _positive(c.width_px, f"cameras.{c.name}.width_px")
        _positive(c.height_px, f"cameras.{c.name}.height_px")
        if not 0 < c.fov_deg < 180:
            raise IbiscapeError(f"config: cameras.{c.name}.fov_deg must be in (0, 180), got {c.fov_deg!r}")
        _vec3(c.position_m, f"cameras.{c.name}.position_m")
        _vec3(c.rpy_deg, f"cameras.{c.name}.rpy_deg")
        _check_camera_optics(c)
        ts = c.timeshift_cam_imu_s
        if not (isinstance(ts, int | float) and not isinstance(ts, bool) and math.isfinite(ts)
                and abs(ts) <= MAX_TIMESHIFT_S):
            raise IbiscapeError(f"config: cameras.{c.name}.timeshift_cam_imu_s must be a number of "
                                f"seconds within +-{MAX_TIMESHIFT_S:g}, got {ts!r}")


def _check_camera_optics(c: CameraSpec) -> None:
    key = f"cameras.{c.name}"
    for side, v in (("width_px", c.width_px), ("height_px", c.height_px)):
        if isinstance(v, bool) or not isinstance(v, int) or not MIN_SIDE_PX <= v <= MAX_SIDE_PX:
            raise IbiscapeError(f"config: {key}.{side} must be an integer in {MIN_SIDE_PX}..{MAX_SIDE_PX}, "
                                f"got {v!r}")
    _choice(c.distortion_model, ("none", "radtan", "equidistant"), f"{key}.distortion_model")
    co = c.distortion_coeffs
    if not (isinstance(co, tuple) and len(co) == 4
            and all(isinstance(x, int | float) and math.isfinite(x) for x in co)):
        raise IbiscapeError(f"config: {key}.distortion_coeffs must be four finite numbers, got {co!r}")
    if c.distortion_model == "none" and any(co):
        raise IbiscapeError(f"config: {key}.distortion_coeffs {list(co)} need a distortion_model "
                            "(radtan or equidistant)")
    # vertical field of view (pinhole): a tall image may reach 180 deg even with a sane horizontal FOV
    f = c.focal_px
    vfov = 2.0 * math.degrees(math.atan(c.height_px / (2.0 * f)))
    if c.distortion_model != "equidistant" and vfov >= 179.0:
        raise IbiscapeError(f"config: {key}: {c.width_px}x{c.height_px} px at a horizontal FOV of "
                            f"{c.fov_deg} deg gives a vertical FOV of {vfov:.1f} deg; a pinhole camera "
                            "needs less than 179 deg: use a smaller FOV or a wider image")


def parse_resolution(text: str) -> tuple[int, int]:
    """``"N"`` (square) or ``"WxH"`` -> ``(width, height)`` in pixels, refusing nonsense."""
    t = str(text).strip().lower()
    parts = t.split("x")
    try:
        if len(parts) == 1:
            w = h = int(parts[0])
        elif len(parts) == 2:
            w, h = int(parts[0]), int(parts[1])
        else:
            raise ValueError
    except ValueError:
        raise IbiscapeError(f"resolution {text!r}: give N (square) or WxH in pixels, e.g. 256 or "
                            "640x480") from None
    for v in (w, h):
        if not MIN_SIDE_PX <= v <= MAX_SIDE_PX:
            raise IbiscapeError(f"resolution {text!r}: each side must be in {MIN_SIDE_PX}..{MAX_SIDE_PX} px")
    return w, h


def with_resolution(cfg: SimConfig, width_px: int, height_px: int) -> SimConfig:
    """Every camera resized to ``width_px x height_px`` keeping its horizontal field of view
    (focal length and principal point scale with the image; distortion is unchanged)."""
    cams = tuple(replace(c, width_px=int(width_px), height_px=int(height_px)) for c in cfg.cameras)
    return replace(cfg, cameras=cams)


def _vec3(v: Any, key: str) -> None:
    if not (isinstance(v, tuple) and len(v) == 3 and all(isinstance(x, int | float) and math.isfinite(x) for x in v)):
        raise IbiscapeError(f"config: {key} must be three finite numbers, got {v!r}")


# ---------------------------------------------------------------------------------------------
# presets

_WEATHER_PRESETS: dict[str, WeatherSpec] = {
    "clear": WeatherSpec(),
    "moderate": WeatherSpec(cloudiness=(50.0, 15.0), precipitation=(20.0, 10.0),
                            wind_intensity=(35.0, 12.0), fog_density=(25.0, 10.0),
                            correlation_time_s=15.0, sun_phase0_rad=0.9),
    # the paper's fig:weather: dynamic sequences average fog ~70 %, rain ~45 %, wind ~70 %
    "dynamic": WeatherSpec(cloudiness=(80.0, 12.0), precipitation=(45.0, 18.0),
                           wind_intensity=(70.0, 14.0), fog_density=(70.0, 12.0),
                           correlation_time_s=8.0, sun_phase0_rad=0.5,
                           sun_phase_rate_rad_s=0.008),
}


def _cam(name: str, kind: str, y: float, mount: str = "") -> CameraSpec:
    return CameraSpec(name=name, kind=kind, position_m=(0.0, y, CAM_HEIGHT_M), mount=mount)


def _rig(setup: str) -> tuple[tuple[ImuSpec, ...], tuple[CameraSpec, ...]]:
    imu0 = ImuSpec("imu0")
    imu1 = ImuSpec("imu1", (0.0, 0.1, CAM_HEIGHT_M), mount="davisL")
    imu2 = ImuSpec("imu2", (0.0, -0.1, CAM_HEIGHT_M), mount="davisR")
    rgb = (_cam("rgbL", "rgb", 0.2), _cam("rgbR", "rgb", -0.2))
    dvs = (_cam("davisL", "dvs", 0.1, "davisL"), _cam("davisR", "dvs", -0.1, "davisR"))
    rgbd = (_cam("rgb", "rgb", 0.0, "rgbd"), _cam("depth", "depth", 0.0, "rgbd"))
    if setup == "imu":
        return (imu0,), ()
    if setup == "svi":
        return (imu0,), rgb
    if setup == "esvi":
        return (imu0, imu1, imu2), dvs
    if setup == "rgbd":
        return (imu0,), rgbd
    return (imu0, imu1, imu2), (*rgb, *dvs, *rgbd, _cam("semantic", "semantic", 0.0, "rgbd"))


def preset(setup: str = "svi", kind: str = "slam", weather: str = "clear", *,
           scenario: str = "default", **overrides: Any) -> SimConfig:
    """The configuration of one row of the paper's sequence table.

    Parameters
    ----------
    setup : {"imu", "svi", "esvi", "rgbd", "full"}
    kind : {"calibration", "slam"}
        ``imu`` is always a still calibration.
    weather : {"clear", "moderate", "dynamic"}
    scenario : {"default", "accident"}
        ``accident``: SVI SLAM, 6.13 s (the paper's sequence) ending in a hard stop.
    **overrides
        Top-level :class:`SimConfig` fields (``duration_s``, ``seed``, ``ideal`` ...).

    Raises
    ------
    IbiscapeError
        Unknown preset name or impossible value, naming the key.
    """
    _choice(setup, SETUPS, "setup")
    _choice(kind, KINDS, "kind")
    _choice(weather, WEATHERS, "weather")
    _choice(scenario, SCENARIOS, "scenario")
    if setup == "imu":
        kind = "calibration"
    imus, cams = _rig(setup)
    base: dict[str, Any] = {
        "setup": setup, "kind": kind, "weather": weather, "scenario": scenario,
        "imus": imus, "cameras": cams,
        "gnss": GnssSpec(rate_hz=10.0 if kind == "calibration" else 1.0),
        "weather_model": _WEATHER_PRESETS[weather],
        "duration_s": {"imu": 3600.0}.get(setup, 60.0),
    }
    if scenario == "accident":
        base["duration_s"] = 6.13
        base["motion"] = MotionSpec(max_speed_m_s=8.0)
    if setup == "imu":
        base["motion"] = MotionSpec(bumps=False)
    base.update(overrides)
    try:
        return SimConfig(**base)
    except TypeError as e:
        raise IbiscapeError(f"config: {e}") from None


# ---------------------------------------------------------------------------------------------
# YAML


def _to_plain(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out: dict[str, Any] = {}
        for f in fields(obj):
            v = getattr(obj, f.name)
            if f.name in ("imus", "cameras"):
                out[f.name] = {s.name: {k: _to_plain(x) for k, x in _to_plain(s).items() if k != "name"}
                               for s in v}
            else:
                out[f.name] = _to_plain(v)
        return out
    if isinstance(obj, tuple):
        return [_to_plain(v) for v in obj]
    return obj


def _err(src: SimConfigDoc, key: str, message: str) -> FormatError:
    """A FormatError naming the file and the line of the dotted ``key``."""
    return src.error([k for k in key.split(".") if k], message)


def _coerce(value: Any, default: Any, key: str, where: SimConfigDoc) -> Any:
    """Convert a YAML scalar/list to the type of the field's current value."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise _err(where, key, f"{key} must be true or false, got {value!r}")
        return value
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise _err(where, key, f"{key} must be an integer, got {value!r}")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise _err(where, key, f"{key} must be a number, got {value!r}")
        return float(value)
    if isinstance(default, str):
        if not isinstance(value, str):
            raise _err(where, key, f"{key} must be a string, got {value!r}")
        return value
    if isinstance(default, tuple):
        if not isinstance(value, list | tuple) or len(value) != len(default):
            raise _err(where, key, f"{key} must be a list of {len(default)} numbers, got {value!r}")
        return tuple(_coerce(v, d, key, where) for v, d in zip(value, default, strict=True))
    return value


def _override(obj: Any, doc: Any, prefix: str, where: SimConfigDoc) -> Any:
    if not isinstance(doc, dict):
        raise _err(where, prefix, f"{prefix.rstrip('.') or 'the file'} must be a mapping, got {doc!r}")
    allowed = {f.name: f for f in fields(obj)}
    changes: dict[str, Any] = {}
    for key, value in doc.items():
        name = f"{prefix}{key}"
        if key not in allowed:
            raise _err(where, name, f"unknown key {name!r}; allowed: {', '.join(allowed)}")
        cur = getattr(obj, key)
        if key in ("imus", "cameras"):
            changes[key] = _override_sensors(cur, value, name, where,
                                             ImuSpec if key == "imus" else CameraSpec)
        elif dataclasses.is_dataclass(cur):
            changes[key] = _override(cur, value, name + ".", where)
        else:
            changes[key] = _coerce(value, cur, name, where)
    return replace(obj, **changes) if not isinstance(obj, SimConfig) else changes


def _override_sensors(cur: tuple[Any, ...], doc: Any, prefix: str, where: SimConfigDoc,
                      cls: type) -> tuple[Any, ...]:
    if doc is None:
        return cur
    if not isinstance(doc, dict):
        raise _err(where, prefix, f"{prefix} must map sensor names to their fields, got {doc!r}")
    out = {s.name: s for s in cur}
    for name, spec in doc.items():
        if spec is None:
            out.pop(str(name), None)
            continue
        base = out.get(str(name), cls(name=str(name)))
        if isinstance(spec, dict) and "name" in spec:
            raise _err(where, f"{prefix}.{name}", f"{prefix}.{name}: the name is the key; remove 'name'")
        out[str(name)] = _override(base, spec, f"{prefix}.{name}.", where)
    return tuple(out.values())


def load_config(path: str | os.PathLike[str], **cli_overrides: Any) -> SimConfig:
    """Read a simulator YAML file (``yaml.safe_load``) onto its preset.

    Parameters
    ----------
    path
        YAML mapping; see the module docstring.
    **cli_overrides
        Values that win over the file (``None`` values are ignored), e.g. from the command line.

    Raises
    ------
    FormatError
        Not YAML, not a mapping, unknown key (naming it and the allowed keys), wrong type.
    IbiscapeError
        Impossible values (from :func:`validate`).
    """
    from ibiscape_eval.io.simconfig import read_sim_config_yaml

    src = read_sim_config_yaml(path)
    where, doc = src.path, dict(src.data)
    picks: dict[str, Any] = {k: doc.pop(k) for k in ("setup", "kind", "weather", "scenario")
                             if k in doc}
    picks.update({k: v for k, v in cli_overrides.items()
                  if k in ("setup", "kind", "weather", "scenario") and v is not None})
    for k, v in picks.items():
        if not isinstance(v, str):
            raise src.error([k], f"{k} must be a string, got {v!r}")
    try:
        base = preset(picks.get("setup", "svi"), picks.get("kind", "slam"),
                      picks.get("weather", "clear"), scenario=picks.get("scenario", "default"))
    except IbiscapeError as e:
        raise IbiscapeError(f"{where}: {e}") from None
    changes = _override(base, doc, "", src)
    changes.update({k: v for k, v in cli_overrides.items()
                    if v is not None and k not in ("setup", "kind", "weather", "scenario")})
    try:
        return replace(base, **changes)
    except IbiscapeError as e:
        raise IbiscapeError(f"{where}: {e}") from None


def dump_config(cfg: SimConfig) -> str:
    """The full configuration as commented YAML (loads back to ``cfg`` with :func:`load_config`)."""
    from ibiscape_eval.io.simconfig import render_commented_yaml

    return render_commented_yaml(_DUMP_HEADER, _yaml_items(cfg, preset(cfg.setup, cfg.kind, cfg.weather,
                                                                       scenario=cfg.scenario)))


_DUMP_HEADER = (
    "ibiscape-eval sim configuration (every key; units in the names and comments).",
    "Frames: body x forward, y left, z up (IMU0); world = local ENU at the gnss reference.",
    "cameras/imus map a sensor name to its fields; a new name adds a sensor, null removes one.",
)


def _yaml_items(obj: Any, base: SimConfig) -> list[YamlItem]:
    """``obj``'s fields as commented YAML items (sensors removed from ``base`` written as null)."""
    from ibiscape_eval.io.simconfig import YamlItem

    items = []
    for f in fields(obj):
        v = getattr(obj, f.name)
        doc = f.metadata.get("doc", "")
        if f.name in ("imus", "cameras"):
            present = {s.name for s in v}
            children = [YamlItem(s.name, None, "removed from the preset")
                        for s in getattr(base, f.name) if s.name not in present]
            children += [YamlItem(s.name, [YamlItem(sf.name, _to_plain(getattr(s, sf.name)),
                                                    sf.metadata.get("doc", ""))
                                           for sf in fields(s) if sf.name != "name"],
                                  is_mapping=True) for s in v]
            items.append(YamlItem(f.name, children, doc, comment_above=True, is_mapping=True))
        elif dataclasses.is_dataclass(v):
            items.append(YamlItem(f.name, _yaml_items(v, base), doc, is_mapping=True))
        else:
            items.append(YamlItem(f.name, _to_plain(v), doc))
    return items


# ---------------------------------------------------------------------------------------------
# value ranges and the resources of a run (checked before anything is generated)

#: Upper bounds of config values: beyond them a value is a typo, not a sequence (rates: the
#: fastest IMUs sample at a few kHz; 16384 px is beyond any camera the paper simulates).
LIMITS: dict[str, float] = {
    "duration_s": 1.0e7,  # 116 days (the still IMU's 168 h is 6.05e5 s)
    "gt_rate_hz": 10_000.0,
    "imu_rate_hz": 10_000.0,
    "camera_rate_hz": 10_000.0,
    "gnss_rate_hz": 100.0,
    "image_px": 16_384,
    "town_blocks": 50,
    "max_speed_m_s": 100.0,
    "chunk_samples": 1 << 24,
    "housing_m": 10.0,
    "sensor_offset_m": 1_000.0,
    "imu_noise": 1.0e3,
    "weather_time_s": 1.0e7,
    "accident_decel_m_s2": 100.0,
    "accident_obstacle_gap_m": 1_000.0,
}


def _at_most(value: Any, limit: float, key: str, unit: str = "") -> None:
    if isinstance(value, int | float) and value > limit:
        raise IbiscapeError(f"config: {key} = {value!r} is beyond the supported {limit:g}{unit}; "
                            "check for a typo")


def _finite_fields(obj: Any, prefix: str) -> None:
    """Every float in the (nested) config is finite (``.inf``/``.nan`` in YAML are floats)."""
    for f in fields(obj):
        v = getattr(obj, f.name)
        key = f"{prefix}{f.name}"
        if dataclasses.is_dataclass(v):
            _finite_fields(v, key + ".")
        elif isinstance(v, tuple):
            for i, x in enumerate(v):
                if dataclasses.is_dataclass(x):
                    _finite_fields(x, f"{key}.{getattr(x, 'name', i)}.")
                elif isinstance(x, float) and not math.isfinite(x):
                    raise IbiscapeError(f"config: {key} must be finite numbers, got {v!r}")
        elif isinstance(v, float) and not math.isfinite(v):
            raise IbiscapeError(f"config: {key} must be a finite number, got {v!r}")


def check_ranges(cfg: SimConfig) -> None:
    """Raise :class:`IbiscapeError` naming the key for a value beyond :data:`LIMITS` or not finite."""
    _finite_fields(cfg, "")
    lim = LIMITS
    _at_most(cfg.duration_s, lim["duration_s"], "duration_s", " s")
    _at_most(cfg.gt_rate_hz, lim["gt_rate_hz"], "gt_rate_hz", " Hz")
    _at_most(cfg.chunk_samples, lim["chunk_samples"], "chunk_samples")
    _at_most(cfg.housing_m, lim["housing_m"], "housing_m", " m")
    end = cfg.start_ns + cfg.duration_s * 1e9
    if end >= 2.0**63:
        raise IbiscapeError(f"config: start_ns + duration_s reach {end:.4g} ns, beyond int64 "
                            "nanoseconds (year 2262)")
    for f in fields(ImuNoise):
        if f.name != "model":
            _at_most(getattr(cfg.imu_noise, f.name), lim["imu_noise"], f"imu_noise.{f.name}")
    for s in cfg.imus:
        _at_most(s.rate_hz, lim["imu_rate_hz"], f"imus.{s.name}.rate_hz", " Hz")
        _at_most(max(abs(x) for x in s.position_m), lim["sensor_offset_m"],
                 f"imus.{s.name}.position_m", " m")
    for c in cfg.cameras:
        _at_most(c.rate_hz, lim["camera_rate_hz"], f"cameras.{c.name}.rate_hz", " Hz")
        _at_most(c.width_px, lim["image_px"], f"cameras.{c.name}.width_px", " px")
        _at_most(c.height_px, lim["image_px"], f"cameras.{c.name}.height_px", " px")
        _at_most(max(abs(x) for x in c.position_m), lim["sensor_offset_m"],
                 f"cameras.{c.name}.position_m", " m")
    g = cfg.gnss
    _at_most(g.rate_hz, lim["gnss_rate_hz"], "gnss.rate_hz", " Hz")
    _at_most(max(abs(x) for x in g.position_m), lim["sensor_offset_m"], "gnss.position_m", " m")
    _at_most(max(g.sigma_horizontal_m, g.sigma_vertical_m), lim["sensor_offset_m"],
             "gnss.sigma_*_m", " m")
    if not -1000 <= g.ref_alt_m <= 1.0e5:
        raise IbiscapeError(f"config: gnss.ref_alt_m must be in -1000..100000 m, got {g.ref_alt_m!r}")
    w = cfg.weather_model
    _at_most(w.correlation_time_s, lim["weather_time_s"], "weather_model.correlation_time_s", " s")
    _at_most(w.deposit_lag_s, lim["weather_time_s"], "weather_model.deposit_lag_s", " s")
    m = cfg.motion
    _at_most(m.town_blocks, lim["town_blocks"], "motion.town_blocks")
    _at_most(m.max_speed_m_s, lim["max_speed_m_s"], "motion.max_speed_m_s", " m/s")
    _at_most(m.accident_decel_m_s2, lim["accident_decel_m_s2"], "motion.accident_decel_m_s2",
             " m/s^2")
    _at_most(m.accident_obstacle_gap_m, lim["accident_obstacle_gap_m"],
             "motion.accident_obstacle_gap_m", " m")


@dataclass(frozen=True)
class RunEstimate:
    """What a run will need: bytes written, peak memory, samples (see :func:`estimate_run`)."""

    output_bytes: int
    memory_bytes: int
    gt_samples: int
    imu_samples: int
    frames: int

    def __repr__(self) -> str:
        return (f"RunEstimate(output {self.output_bytes / 1e9:.3g} GB, memory "
                f"{self.memory_bytes / 1e9:.3g} GB, {self.gt_samples} gt, {self.imu_samples} imu, "
                f"{self.frames} frames)")


# Measured on this generator (60 s SVI, 30 s at 200/2000 Hz ground truth): ~400 B of memory and
# ~233 B of csv per ground-truth sample; the IMU csv row is ~130 B (npy 56 B); a process base of
# ~300 MB; the still IMU streams (flat ~330 MB).  Factors of 2.5 on memory keep the estimate an
# upper bound.
_BASE_MEMORY = 300_000_000
_MEM_PER_SAMPLE = 1_000
_GT_ROW_BYTES = 240
_IMU_ROW_BYTES = {"csv": 130, "npy": 56}
_FRAME_ROW_BYTES = 200  # weather.csv and controls per camera frame
#: Bytes per rendered frame and pixel by camera kind (PNG-compressed RGB, 16-bit depth, ...),
#: used when ``render`` is true.
#: rendered bytes per pixel and frame, measured on the renderer's PNGs (noisy RGB, depth as 16-bit mm
#: and CARLA log, labels raw and in the CityScapes palette, DVS windows and their frames)
RENDER_BYTES_PER_PIXEL = {"rgb": 2.6, "depth": 1.4, "semantic": 0.3, "dvs": 1.5}


def estimate_run(cfg: SimConfig, *, render: bool = False) -> RunEstimate:
    """Upper-bound estimate of the output size and the peak memory of generating ``cfg``."""
    d = float(cfg.duration_s)
    n_gt = int(d * cfg.gt_rate_hz) + 1
    n_imu = sum(int(d * s.rate_hz) + 1 for s in cfg.imus)
    n_frames = max((int(d * c.rate_hz) + 1 for c in cfg.cameras), default=int(d * 20) + 1)
    n_gnss = int(d * cfg.gnss.rate_hz) + 1
    if cfg.setup == "imu":
        still_out = n_imu * _IMU_ROW_BYTES.get(cfg.still_format, 130)
        still_mem = _BASE_MEMORY + 3 * cfg.chunk_samples * 7 * 8 * max(len(cfg.imus), 1)
        return RunEstimate(int(still_out), int(still_mem), 0, n_imu, 0)
    out = n_gt * _GT_ROW_BYTES + n_imu * _IMU_ROW_BYTES["csv"] + n_gnss * 150 + n_frames * _FRAME_ROW_BYTES
    if render:
        out += int(sum((int(d * c.rate_hz) + 1) * c.width_px * c.height_px
                       * RENDER_BYTES_PER_PIXEL.get(c.kind, 3.0) for c in cfg.cameras))
    mem = _BASE_MEMORY + _MEM_PER_SAMPLE * (n_gt + n_imu + n_gnss + n_frames)
    return RunEstimate(int(out), int(mem), n_gt, n_imu, n_frames)


def _available_memory() -> int | None:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


_HINT = "shorten duration_s or lower the rates"


def check_memory(cfg: SimConfig, out: str | os.PathLike[str], *, render: bool = False
                 ) -> RunEstimate:
    """Refuse a run whose estimated peak memory exceeds the available memory."""
    est = estimate_run(cfg, render=render)
    mem = _available_memory()
    if mem is not None and est.memory_bytes > mem:
        raise IbiscapeError(
            f"{out}: not generated: this run would need about {est.memory_bytes / 1e9:.3g} GB of memory "
            f"({est.gt_samples} ground-truth and {est.imu_samples} IMU samples) but "
            f"{mem / 1e9:.3g} GB are available; {_HINT} (the imu setup streams)")
    return est


def check_resources(cfg: SimConfig, out: str | os.PathLike[str], *, render: bool = False) -> RunEstimate:
    """Refuse a run whose estimated output does not fit on the disk of ``out`` or whose
    estimated memory exceeds the available memory, with the numbers; returns the estimate."""
    import shutil
    from pathlib import Path

    est = check_memory(cfg, out, render=render)
    parent = Path(out).absolute()
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    try:
        free = shutil.disk_usage(parent).free
    except OSError:
        return est
    if est.output_bytes > free:
        raise IbiscapeError(
            f"{out}: not generated: this run would write about {est.output_bytes / 1e9:.3g} GB but "
            f"{free / 1e9:.3g} GB are free there; {_HINT}"
            + (", use --resolution to render smaller images or --no-render" if render else "")
            + ", or write elsewhere")
    return est
