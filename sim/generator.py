"""Orchestration: world + motion (``world.py``/``motion.py``) -> sensors -> IBISCape folder.

``generate(config, out)`` plans the world and the vehicle motion, samples the exact kinematics at
the ground-truth/IMU/GNSS/camera stamps, simulates every IMU and the GNSS receiver, evolves the
weather per camera frame and writes the sequence (``writer.py``).  The ``imu`` setup streams a
still IMU chunk by chunk (``still.py``).  Same config and seed -> byte-identical files.

Accident scenario (SVI, the paper's 6.13 s ``Accident`` sequence): a SLAM route whose time is
warped by ``tau(t)`` with ``tau' = 1 - S(u)`` (quintic smooth step ``S``, ``u`` running over the
braking interval), so the car brakes hard (mean deceleration ``motion.accident_decel_m_s2``) and
stands still for the last second, its front ``motion.accident_obstacle_gap_m`` behind an obstacle
(a stopped car recorded in ``sequence.yaml: scenario.obstacle`` for the renderer).  The warp keeps
the motion C2 and exact: ``v = v(tau) tau'``, ``a = a(tau) tau'^2 + v(tau) tau''``,
``w = w(tau) tau'``, ``dw = dw(tau) tau'^2 + w(tau) tau''``; controls switch to full brake.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.rotations import quat_rotate
from ibiscape_eval.core.trajectory import Trajectory
from ibiscape_eval.io.atomic import atomic_output_dir
from ibiscape_eval.io.gnss import write_gnss
from ibiscape_eval.io.ibiscape import IbiscapeGroundTruth, write_ibiscape_groundtruth

from .config import SimConfig, check_resources
from .gnss import simulate_gnss
from .imu import simulate_imu, sub_seed
from .rig import T_body_imu
from .still import n_samples, still_imu_chunks, uniform_stamps
from .types import Controls, MotionState
from .weather import WEATHER_COLUMNS, WeatherLog, simulate_weather
from .writer import VEHICLE, imu_file_names, prepare_output, sequence_document

__all__ = ["Motion", "SequenceSummary", "generate", "plan", "sequence_name"]

Progress = Callable[[float, str], None]


class Motion(Protocol):
    """What :func:`generate` needs from a vehicle motion (``sim.motion.VehicleMotion``)."""

    start_ns: int
    end_ns: int

    def sample(self, stamps_ns: npt.NDArray[np.int64]) -> MotionState: ...

    def controls(self, stamps_ns: npt.NDArray[np.int64]) -> Controls: ...


@dataclass(frozen=True)
class SequenceSummary:
    """One-screen description of a generated sequence (columns of the paper's
    ``table:sequences_desc`` plus excitation and weather)."""

    path: str
    name: str
    setup: str
    kind: str
    weather: str
    scenario: str
    seed: int
    duration_s: float
    length_m: float
    mean_speed_m_s: float
    frames: int
    gt_samples: int
    imu_samples: int
    gnss_fixes: int
    roll_std_deg: float
    pitch_std_deg: float
    weather_averages: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping (for ``--json``)."""
        import dataclasses

        return dataclasses.asdict(self)


def sequence_name(cfg: SimConfig, index: int = 1) -> str:
    """``<Setup>_<i>_<map>`` like the dataset's folders (map: ``calib`` ground or ``town``)."""
    where = {"calibration": "calib", "slam": "town"}[cfg.kind] if cfg.setup != "imu" else "still"
    return f"{cfg.setup_label}_{index}_{where}"


# ---------------------------------------------------------------------------------------------
# motion


class HardStopMotion:
    """A motion re-timed by ``tau(t)`` so that it brakes from ``brake_ns`` and stands still from
    ``stop_ns`` (see the module docstring); C2 and exact."""

    def __init__(self, base: Motion, brake_ns: int, stop_ns: int):
        if not base.start_ns <= brake_ns < stop_ns:
            raise IbiscapeError("accident: the braking interval does not fit in the sequence")
        self.base = base
        self.start_ns = base.start_ns
        self.end_ns = base.end_ns
        self.brake_ns = int(brake_ns)
        self.stop_ns = int(stop_ns)

    def _warp(self, stamps_ns: npt.NDArray[np.int64]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(stamps_ns, dtype=np.int64)
        T = (self.stop_ns - self.brake_ns) * 1e-9
        u = np.clip((t - self.brake_ns) * 1e-9 / T, 0.0, 1.0)
        integral_s = 2.5 * u**4 - 3.0 * u**5 + u**6  # integral of the smooth step 10u^3-15u^4+6u^5
        d1 = 1.0 - (10 * u**3 - 15 * u**4 + 6 * u**5)
        d2 = -(30 * u**2 - 60 * u**3 + 30 * u**4) / T
        tau_rel_s = np.where(t < self.brake_ns, 0.0, T * (u - integral_s))
        tau_ns = np.where(t < self.brake_ns, t, self.brake_ns + np.round(tau_rel_s * 1e9).astype(np.int64))
        return tau_ns.astype(np.int64), d1, d2

    def sample(self, stamps_ns: npt.NDArray[np.int64]) -> MotionState:
        tau, d1, d2 = self._warp(stamps_ns)
        s = self.base.sample(tau)
        a, b = d1[:, None], d2[:, None]
        return MotionState(np.asarray(stamps_ns, dtype=np.int64), s.pos_m, s.quat_xyzw, s.vel_m_s * a,
                           s.acc_m_s2 * a * a + s.vel_m_s * b, s.angvel_body_rad_s * a,
                           s.angacc_body_rad_s2 * a * a + s.angvel_body_rad_s * b)

    def controls(self, stamps_ns: npt.NDArray[np.int64]) -> Controls:
        tau, _, _ = self._warp(stamps_ns)
        c = self.base.controls(tau)
        braking = np.asarray(stamps_ns) >= self.brake_ns
        return Controls(np.asarray(stamps_ns, dtype=np.int64), np.where(braking, 0.0, c.throttle),
                        c.steer, np.where(braking, 1.0, c.brake))


def _accident(cfg: SimConfig, base: Motion) -> tuple[HardStopMotion, dict[str, Any]]:
    stop_ns = base.start_ns + round((cfg.duration_s - 1.0) * 1e9)
    if stop_ns <= base.start_ns:
        raise IbiscapeError(f"accident: duration_s {cfg.duration_s} is too short (needs > 2 s)")
    brake_s = 1.0
    for _ in range(4):  # T = v(start of braking) / deceleration, a fixed point
        t_ns = np.array([max(base.start_ns, stop_ns - int(brake_s * 1e9))], dtype=np.int64)
        v0 = float(np.linalg.norm(base.sample(t_ns).vel_m_s[0]))
        brake_s = max(0.2, v0 / cfg.motion.accident_decel_m_s2)
    brake_ns = stop_ns - round(brake_s * 1e9)
    if brake_ns <= base.start_ns:
        raise IbiscapeError(f"accident: the car cannot stop within duration_s {cfg.duration_s}; "
                            "make the sequence longer or lower motion.max_speed_m_s")
    m = HardStopMotion(base, brake_ns, stop_ns)
    end = m.sample(np.array([stop_ns], dtype=np.int64))
    fwd = quat_rotate(end.quat_xyzw, np.array([[1.0, 0.0, 0.0]]))[0]
    half_len = 2.35  # half the length of the car and of the obstacle car [m]
    centre = end.pos_m[0] + fwd * (2 * half_len + cfg.motion.accident_obstacle_gap_m)
    info = {"name": "accident", "brake_ns": brake_ns, "stop_ns": stop_ns,
            "speed_before_brake_m_s": v0,
            "obstacle": {"kind": "car", "position_m": centre.tolist(),
                         "yaw_rad": float(math.atan2(fwd[1], fwd[0])),
                         "size_m": [4.7, 1.9, 1.5]}}
    return m, info


def plan(cfg: SimConfig) -> tuple[Any, Motion, dict[str, Any]]:
    """Build the world and the vehicle motion for ``cfg`` (not for the still ``imu`` setup).

    Returns ``(world, motion, scenario_info)``.
    """
    from .motion import plan_motion
    from .world import build_world

    world = build_world(kind=cfg.kind, seed=cfg.seed, target=cfg.target, scene=cfg.weather,
                        town_blocks=cfg.motion.town_blocks, bumps=cfg.motion.bumps,
                        calibration_drive=cfg.motion.calibration_drive)
    motion: Motion = plan_motion(world, duration_s=cfg.duration_s, start_ns=cfg.start_ns,
                                 seed=cfg.seed, max_speed_m_s=cfg.motion.max_speed_m_s,
                                 target=cfg.target, start_distance_m=cfg.motion.start_distance_m,
                                 drive=cfg.motion.calibration_drive)
    info: dict[str, Any] = {"name": cfg.scenario}
    if cfg.scenario == "accident":
        motion, info = _accident(cfg, motion)
    return world, motion, info


# ---------------------------------------------------------------------------------------------
# summary helpers


def roll_pitch_rad(quat_xyzw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ZYX roll and pitch of ``q_world_body``, radians."""
    x, y, z, w = quat_xyzw.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    return roll, pitch


def _frames(cfg: SimConfig) -> tuple[npt.NDArray[np.int64], float]:
    rate = max((c.rate_hz for c in cfg.cameras), default=20.0)
    n = n_samples(cfg.duration_s, rate)
    return uniform_stamps(cfg.start_ns, rate, 0, n), rate


# ---------------------------------------------------------------------------------------------
# the generator


def generate(config: SimConfig, out: str | os.PathLike[str], *, overwrite: bool = False,
             progress: Progress | None = None, motion: Motion | None = None,
             world: Any = None, render: bool = False) -> SequenceSummary:
    """Generate one sequence into the folder ``out`` (created atomically).

    Parameters
    ----------
    config : SimConfig
        See :func:`ibiscape_eval.sim.preset` / :func:`ibiscape_eval.sim.load_config`.
    out : path
        The sequence folder; it must not exist or be empty unless ``overwrite``.
    overwrite : bool
        Replace an existing folder (only once the new one is complete).
    progress : callable(fraction, label), optional
        Called with the fraction done (0..1).
    motion, world : optional
        Use this motion (anything with ``sample``/``controls``, ``start_ns``/``end_ns``) and world
        instead of planning them (tests, custom trajectories).
    render : bool
        Also render every camera (RGB, depth, segmentation, DVS events) with
        :mod:`ibiscape_eval.sim.render`; needs the world (planned, or given with ``motion``).

    Returns
    -------
    SequenceSummary

    Raises
    ------
    IbiscapeError
        Output folder not empty, impossible route (from the planner), bad config.
    """
    def step(frac: float, label: str) -> None:
        if progress is not None:
            progress(frac, label)

    check_resources(config, out, render=render)  # before anything is written: refuse with the numbers
    out_p = prepare_output(out, overwrite=overwrite)
    with atomic_output_dir(out_p, overwrite=overwrite) as tmp:
        if config.setup == "imu":
            summary = _generate_still(config, tmp, step)
        else:
            summary = _generate_moving(config, tmp, step, motion, world, render=render)
    step(1.0, "done")
    return SequenceSummary(**{**summary.to_dict(), "path": str(out_p), "name": out_p.name})


def _summary(cfg: SimConfig, gt_pos: np.ndarray, gt_quat: np.ndarray, frames: int, n_gt: int,
             n_imu: int, n_gnss: int, weather: WeatherLog | None) -> SequenceSummary:
    length = float(np.linalg.norm(np.diff(gt_pos, axis=0), axis=1).sum()) if len(gt_pos) > 1 else 0.0
    roll, pitch = roll_pitch_rad(gt_quat)
    return SequenceSummary(
        path="", name="", setup=cfg.setup, kind=cfg.kind, weather=cfg.weather,
        scenario=cfg.scenario, seed=cfg.seed, duration_s=cfg.duration_s, length_m=length,
        mean_speed_m_s=length / cfg.duration_s, frames=frames, gt_samples=n_gt, imu_samples=n_imu,
        gnss_fixes=n_gnss, roll_std_deg=float(np.degrees(roll.std())),
        pitch_std_deg=float(np.degrees(pitch.std())),
        weather_averages={} if weather is None else
        {k: round(v, 6) for k, v in weather.averages().items()})


def _groundtruth(state: MotionState) -> IbiscapeGroundTruth:
    w_world = quat_rotate(state.quat_xyzw, state.angvel_body_rad_s)
    traj = Trajectory(state.stamps_ns, state.pos_m, state.quat_xyzw, "groundtruth")
    return IbiscapeGroundTruth(traj, state.vel_m_s, state.acc_m_s2, w_world)


def _generate_moving(cfg: SimConfig, tmp: Path, step: Callable[[float, str], None],
                     motion: Motion | None, world: Any, *, render: bool = False) -> SequenceSummary:
    from ibiscape_eval.io.sequence import write_controls, write_weather_csv

    render = render and bool(cfg.cameras)
    if render and motion is not None and world is None:
        raise IbiscapeError("rendering needs the world the motion drives through: pass world= with "
                            "motion=, or render=False")
    outer = step
    if render:  # rendering dominates: ground truth, IMU and GNSS get the first 5 % of the bar
        def step(frac: float, label: str) -> None:
            outer(0.05 * frac, label)

    scenario: dict[str, Any] = {"name": cfg.scenario}
    step(0.0, "planning")
    if motion is None:
        world, motion, scenario = plan(cfg)
    step(0.15, "sampling")
    n_gt = n_samples(cfg.duration_s, cfg.gt_rate_hz)
    t_gt = uniform_stamps(cfg.start_ns, cfg.gt_rate_hz, 0, n_gt)
    gt_state = motion.sample(t_gt)
    gt = _groundtruth(gt_state)
    (tmp / "vehicle_gt").mkdir()
    (tmp / "other_sensors").mkdir()
    write_ibiscape_groundtruth(tmp / "vehicle_gt" / "groundtruth_sync.csv", gt)
    ctrl = motion.controls(t_gt)
    write_controls(tmp / "vehicle_gt" / f"{VEHICLE}_simulation.txt", ctrl.stamps_ns,
                   np.clip(ctrl.throttle, 0, 1), np.clip(ctrl.steer, -1, 1), np.clip(ctrl.brake, 0, 1))
    step(0.35, "imu")
    names = imu_file_names(cfg)
    n_imu = 0
    from ibiscape_eval.io.imu import write_imu_csv_chunks

    for i, spec in enumerate(cfg.imus):
        if spec.rate_hz == cfg.gt_rate_hz:
            st = gt_state
        else:
            st = motion.sample(uniform_stamps(cfg.start_ns, spec.rate_hz, 0,
                                              n_samples(cfg.duration_s, spec.rate_hz)))
        m = simulate_imu(st, T_body_imu(spec), cfg.imu_noise, rate_hz=spec.rate_hz,
                         seed=sub_seed(cfg.seed, "imu", i), ideal=cfg.ideal, name=spec.name)
        write_imu_csv_chunks(tmp / "other_sensors" / names[spec.name],
                             [(m.stamps_ns, m.gyro_rad_s, m.accel_m_s2)], frame="ibiscape")
        n_imu += len(m)
        step(0.35 + 0.35 * (i + 1) / len(cfg.imus), "imu")
    n_fix = n_samples(cfg.duration_s, cfg.gnss.rate_hz)
    fixes = simulate_gnss(motion.sample(uniform_stamps(cfg.start_ns, cfg.gnss.rate_hz, 0, n_fix)),
                          cfg.gnss, seed=sub_seed(cfg.seed, "gnss"), ideal=cfg.ideal)
    write_gnss(tmp / "other_sensors" / "gnss.csv", fixes)
    step(0.8, "weather")
    frames, _ = _frames(cfg)
    weather = simulate_weather(cfg.weather_model, frames, seed=cfg.seed, start_ns=cfg.start_ns)
    write_weather_csv(tmp / "weather.csv", weather.stamps_ns, weather.values, WEATHER_COLUMNS)
    files = {"groundtruth": "vehicle_gt/groundtruth_sync.csv",
             "controls": f"vehicle_gt/{VEHICLE}_simulation.txt",
             "imus": {k: f"other_sensors/{v}" for k, v in names.items()},
             "gnss": "other_sensors/gnss.csv", "weather": "weather.csv"}
    rendered: dict[str, dict[str, Any]] | None = None
    if render:
        from .render.sequence import render_cameras

        rendered = render_cameras(cfg, tmp, world, motion, weather, scenario=scenario,
                                  progress=lambda f, label: outer(0.05 + 0.95 * f, label))
        files["cameras"] = {k: v["folder"] for k, v in rendered.items()}
        if (tmp / "association.txt").exists():
            files["association"] = "association.txt"
    target = None
    if world is not None and cfg.kind == "calibration":
        for t in getattr(world, "targets", ()):
            if t.target_type == cfg.target:
                target = t.to_dict()
    world_doc = world.to_dict() if world is not None and hasattr(world, "to_dict") else None
    summary = _summary(cfg, gt_state.pos_m, gt_state.quat_xyzw, len(frames) if cfg.cameras else 0,
                       n_gt, n_imu, len(fixes), weather)
    doc = sequence_document(cfg, world=world_doc, target=target, scenario=scenario,
                            weather_averages=summary.weather_averages, files=files,
                            rendered=rendered)
    return _write_document(tmp, doc, summary, "IBISCape-layout synthetic sequence written by ibiscape-eval sim")


def _generate_still(cfg: SimConfig, tmp: Path, step: Callable[[float, str], None]) -> SequenceSummary:
    from ibiscape_eval.io.imu import write_imu_npy
    from ibiscape_eval.io.sequence import (
        write_controls_chunks,
        write_gnss_chunks,
        write_groundtruth_chunks,
        write_imu_csv_chunks,
    )

    (tmp / "vehicle_gt").mkdir()
    (tmp / "other_sensors").mkdir()
    names = imu_file_names(cfg)
    chunk = cfg.chunk_samples
    n_imu = 0
    for i, spec in enumerate(cfg.imus):
        n_total = n_samples(cfg.duration_s, spec.rate_hz)
        done = [0]

        def counted(gen: Any, n_total: int = n_total, done: list[int] = done, i: int = i) -> Any:
            for st, g, a in gen:
                done[0] += len(st)
                step(0.8 * (i + done[0] / n_total) / len(cfg.imus), "imu")
                yield st, g, a

        chunks = counted(still_imu_chunks(spec, cfg.imu_noise, duration_s=cfg.duration_s,
                                          start_ns=cfg.start_ns, seed=sub_seed(cfg.seed, "imu", i),
                                          ideal=cfg.ideal, chunk=chunk))
        path = tmp / "other_sensors" / names[spec.name]
        if path.suffix == ".npy":
            n_imu += write_imu_npy(path, (np.column_stack((st.astype(np.float64), g, a))
                                          for st, g, a in chunks))
        else:
            n_imu += write_imu_csv_chunks(path, chunks, frame="ibiscape")  # CARLA's frame
    n_gt = n_samples(cfg.duration_s, cfg.gt_rate_hz)

    def gt_chunks() -> Any:
        for a in range(0, n_gt, chunk):
            m = min(chunk, n_gt - a)
            st = uniform_stamps(cfg.start_ns, cfg.gt_rate_hz, a, m)
            z = np.zeros((m, 3))
            q = np.zeros((m, 4))
            q[:, 3] = 1.0
            yield IbiscapeGroundTruth(Trajectory(st, z, q, "groundtruth"), z, z, z)

    step(0.8, "ground truth")
    write_groundtruth_chunks(tmp / "vehicle_gt" / "groundtruth_sync.csv", gt_chunks())

    def ctrl_chunks() -> Any:
        for a in range(0, n_gt, chunk):
            m = min(chunk, n_gt - a)
            st = uniform_stamps(cfg.start_ns, cfg.gt_rate_hz, a, m)
            yield st, np.zeros(m), np.zeros(m), np.ones(m)  # parked: full brake

    write_controls_chunks(tmp / "vehicle_gt" / f"{VEHICLE}_simulation.txt", ctrl_chunks())
    n_fix = n_samples(cfg.duration_s, cfg.gnss.rate_hz)

    def gnss_chunks() -> Any:
        for a in range(0, n_fix, chunk):
            m = min(chunk, n_fix - a)
            st = uniform_stamps(cfg.start_ns, cfg.gnss.rate_hz, a, m)
            z = np.zeros((m, 3))
            q = np.zeros((m, 4))
            q[:, 3] = 1.0
            state = MotionState(st, z, q, z, z, z, z)
            yield simulate_gnss(state, cfg.gnss, seed=sub_seed(cfg.seed, "gnss", a), ideal=cfg.ideal)

    step(0.9, "gnss")
    n_gnss = write_gnss_chunks(tmp / "other_sensors" / "gnss.csv", gnss_chunks())
    files = {"groundtruth": "vehicle_gt/groundtruth_sync.csv",
             "controls": f"vehicle_gt/{VEHICLE}_simulation.txt",
             "imus": {k: f"other_sensors/{v}" for k, v in names.items()},
             "gnss": "other_sensors/gnss.csv", "weather": None}
    summary = _summary(cfg, np.zeros((1, 3)), np.array([[0.0, 0.0, 0.0, 1.0]]), 0, n_gt, n_imu,
                       n_gnss, None)
    doc = sequence_document(cfg, world={"kind": "still", "note": "flat ground, nothing moves"},
                            target=None, scenario={"name": cfg.scenario}, weather_averages=None,
                            files=files)
    return _write_document(tmp, doc, summary, "IBISCape-layout still-IMU sequence written by ibiscape-eval sim")


def _write_document(tmp: Path, doc: dict[str, Any], summary: SequenceSummary, comment: str) -> SequenceSummary:
    """sequence.yaml: ``doc`` with the summary (without what the folder itself says)."""
    from ibiscape_eval.io.sequence import write_sequence_yaml

    doc["summary"] = {k: v for k, v in summary.to_dict().items()
                      if k not in ("path", "name", "weather_averages")}
    write_sequence_yaml(tmp / "sequence.yaml", doc, comments=[comment])
    return summary

