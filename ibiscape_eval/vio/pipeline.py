"""Images + IMU -> trajectory: the front end feeds the estimator frame by frame.

    from ibiscape_eval import open_sequence, run_vio
    result = run_vio(open_sequence("SVI_1_town"))
    result.trajectory, result.stats.failures, result.stats.realtime_factor
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ibiscape_eval.core.errors import DegenerateInputError
from ibiscape_eval.core.numbers import finite_or_none
from ibiscape_eval.core.sequence import Sequence
from ibiscape_eval.core.trajectory import Trajectory

from .estimator import Estimator, FailureSpan
from .inputs import StereoSequence
from .params import VioParams

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["VioResult", "VioStats", "make_frontend", "run_vio"]

#: progress(frames_done, frames_total, speed_up_over_real_time)
Progress = Callable[[int, int, float], None]


@dataclass(frozen=True)
class VioStats:
    """Run statistics (the CLI's ``--json``).

    Attributes
    ----------
    frames, keyframes, frames_estimated : int
        Stereo frames read, keyframes optimised, frames with a pose in the output.
    mean_tracked, min_tracked : float, int
        Stereo-matched features per frame.
    failures : tuple of FailureSpan
        Tracking failures (IMU only), lost spans and smoother resets with their time spans.
    init_method : str
        ``standstill`` or ``moving`` (empty when it never initialised).
    mean_ms_per_frame, max_ms_per_frame : float
        Processing time per frame (reading, front end, back end).
    realtime_factor : float
        Sequence duration / wall-clock processing time (> 1: faster than real time).
    setup : str
        ``svi``, ``esvi`` or ``rgbd``: the cameras used (:func:`ibiscape_eval.vio.inputs.resolve_setup`).
    usable_frames : int
        Frames with at least ``min_tracked`` stereo measurements (the paper's "usable frames"
        of the event reconstructions).
    cpu_realtime_factor : float
        Sequence duration / CPU time of the process (all threads): the speed on an idle machine
        with one core, unaffected by other processes.
    """

    frames: int
    keyframes: int
    frames_estimated: int
    mean_tracked: float
    min_tracked: int
    failures: tuple[FailureSpan, ...]
    init_method: str
    mean_ms_per_frame: float
    max_ms_per_frame: float
    realtime_factor: float
    cpu_realtime_factor: float = float("nan")
    resets: int = 0
    params: dict[str, Any] = field(default_factory=dict)
    #: the initialiser's first standstill test (StandstillTest.to_dict; None before one ran)
    standstill: dict[str, Any] | None = None
    setup: str = "svi"
    usable_frames: int = 0

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["failures"] = [f.to_dict() for f in self.failures]
        for k in ("mean_tracked", "mean_ms_per_frame", "max_ms_per_frame", "realtime_factor",
                  "cpu_realtime_factor"):
            d[k] = finite_or_none(d[k])
        return d


@dataclass(frozen=True, eq=False)
class VioResult:
    """The estimate (``T_world_body`` of IMU0 at every estimated frame) and the statistics."""

    trajectory: Trajectory
    stats: VioStats

    def to_dict(self) -> dict[str, Any]:
        return {"poses": len(self.trajectory), **self.stats.to_dict()}

    def plot(self, ref: Trajectory | None = None, *, title: str = "") -> Figure:
        """Top view of the estimate (the ground truth ``ref`` over its span, already in the same
        frame, if given) with the tracking failures in red; a new Figure."""
        from .plots import top_view_figure

        return top_view_figure(self.trajectory, ref, self.stats.failures, title=title)

    def __repr__(self) -> str:
        s = self.stats
        return (f"VioResult({len(self.trajectory)}/{s.frames} frames, {s.keyframes} keyframes, "
                f"{len(s.failures)} failures, x{s.realtime_factor:.2f} real time)")


def run_vio(seq: StereoSequence | Sequence, params: VioParams | None = None, *,
            max_frames: int | None = None, progress: Progress | None = None,
            calib: str | os.PathLike[str] | None = None,
            imu_yaml: str | os.PathLike[str] | None = None, setup: str = "auto",
            options: Any = None) -> VioResult:
    """Run the stereo VIO over a sequence with images.

    Parameters
    ----------
    seq : Sequence or StereoSequence
        A sequence from :func:`ibiscape_eval.open_sequence` (its inputs are taken by
        :func:`ibiscape_eval.vio.inputs.stereo_inputs`, with ``calib`` and ``imu_yaml``), or
        inputs already taken.
    params : VioParams, optional
    max_frames : int, optional
        Stop after this many frames.
    progress : callable(done, total, speed_up), optional
    calib, imu_yaml : path, optional
        Kalibr ``camchain-imucam.yaml`` / ``imu.yaml`` replacing the sequence's own (a
        :class:`Sequence` only).
    setup : {"auto", "svi", "esvi", "rgbd", "full"}
        The cameras to use (a :class:`Sequence` only): stereo RGB, stereo events (frames
        reconstructed causally, :mod:`~ibiscape_eval.vio.events_input`), RGB + depth
        (:mod:`~ibiscape_eval.vio.depth`), or the best the sequence has
        (:func:`~ibiscape_eval.vio.inputs.resolve_setup`).
    options : EsviOptions or DepthOptions, optional
        The ESVI reconstruction or the depth front end's options.

    Raises
    ------
    DegenerateInputError
        No frame could be estimated (e.g. every image without texture and no standstill start).
    FormatError
        An image that cannot be read or has another size than the calibration.
    """
    if not isinstance(seq, StereoSequence):
        from .inputs import stereo_inputs

        seq = stereo_inputs(seq, calib=calib, imu_yaml=imu_yaml, setup=setup, options=options)
    p = params or VioParams.for_setup(seq.setup)
    n = _frames_to_run(seq, p, max_frames)
    fe = make_frontend(seq, p, options)
    if seq.setup == "rgbd":  # a depth unit misread by a factor is refused before any estimate
        from .scale_check import check_depth_scale

        check_depth_scale(seq, p, options, max_frames=n)
    est = Estimator(seq.rig.rectified(), seq.imu, seq.noise, p, seq.T_body_imu)
    times = np.zeros(n)
    tracked = np.zeros(n, dtype=np.int64)
    t_start = time.perf_counter()
    cpu_start = time.process_time()
    # PNG decoding costs as much as tracking: a reader thread decodes the next frames meanwhile
    # (the PNG decoder's inflate and kernel, and OpenCV, release the GIL)
    from concurrent.futures import ThreadPoolExecutor

    def read(i: int) -> tuple[Any, Any]:
        return _read_left(seq, i)

    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vio-read")
    ahead = {i: pool.submit(read, i) for i in range(min(4, n))}
    try:
        _loop(seq, p, n, fe, est, ahead, pool, read, times, tracked, t_start, progress)
        est.finish()
    except RuntimeError as e:
        # GTSAM reports a singular system (IndeterminantLinearSystemException, "Indeterminate
        # linear system ...") and other numerical failures as RuntimeError
        raise DegenerateInputError(numerical_failure_message(seq.path, e)) from None
    finally:
        for f in ahead.values():
            f.cancel()
        pool.shutdown(wait=True)
    wall = time.perf_counter() - t_start
    cpu = time.process_time() - cpu_start
    traj = est.trajectory("vio")
    if len(traj) == 0:
        raise DegenerateInputError(
            f"{seq.path}: no frame could be estimated (tracking failed from the start: images "
            "without texture, or no standstill to initialise from); see the failure spans")
    return VioResult(traj, _stats(seq, p, est, n, len(traj), times, tracked, wall, cpu))


def _frames_to_run(seq: StereoSequence, p: VioParams, max_frames: int | None) -> int:
    """How many frames to process; refuses a recording too short to initialise."""
    if seq.n_frames == 0:
        raise DegenerateInputError(f"{seq.path}: no stereo frames to process")
    n = seq.n_frames if max_frames is None else min(max_frames, seq.n_frames)
    span_s = (int(seq.frame_stamps_ns[n - 1]) - int(seq.frame_stamps_ns[0])) * 1e-9
    if n < p.init_frames and span_s < p.still_window_s:
        # neither initialisation can start: the standstill needs still_window_s of frames, the
        # moving one init_frames frames
        raise DegenerateInputError(
            f"{seq.path}: only {n} stereo frames ({span_s:.2f} s); the VIO needs {p.init_frames} "
            f"frames (moving start) or {p.still_window_s:g} s (standstill start) to initialise: "
            "give a longer recording")
    return n


def _stats(seq: StereoSequence, p: VioParams, est: Estimator, n: int, n_poses: int,
           times: np.ndarray, tracked: np.ndarray, wall: float, cpu: float) -> VioStats:
    duration = (int(seq.frame_stamps_ns[n - 1]) - int(seq.frame_stamps_ns[0])) * 1e-9
    return VioStats(frames=n, keyframes=est.n_keyframes, frames_estimated=n_poses,
                    mean_tracked=float(tracked.mean()), min_tracked=int(tracked.min()),
                    failures=tuple(est.failures), init_method=est.init_method,
                    mean_ms_per_frame=1e3 * wall / n, max_ms_per_frame=1e3 * float(times.max()),
                    realtime_factor=duration / wall if wall > 0 else float("inf"),
                    cpu_realtime_factor=duration / cpu if cpu > 0 else float("inf"),
                    resets=est.backend.resets, params=p.to_dict(), setup=seq.setup,
                    usable_frames=int(np.count_nonzero(tracked >= p.min_tracked)),
                    standstill=None if est.standstill_test is None else est.standstill_test.to_dict())


def make_frontend(seq: StereoSequence, params: VioParams, options: Any = None) -> Any:
    """The front end of the sequence's setup: :class:`~ibiscape_eval.vio.depth.DepthFrontEnd`
    for RGB-D, :class:`~ibiscape_eval.vio.frontend.StereoFrontEnd` for stereo RGB and events."""
    if seq.setup == "rgbd":
        from .depth import DepthFrontEnd, DepthOptions

        return DepthFrontEnd(seq.rig, params, seq.depth_unit or "mm",
                             options if isinstance(options, DepthOptions) else None)
    from .frontend import StereoFrontEnd

    return StereoFrontEnd(seq.rig, params)


def numerical_failure_message(path: str, exc: BaseException) -> str:
    """One line for a numerical failure of the estimator on the sequence at ``path``."""
    first = next((ln.strip() for ln in str(exc).splitlines() if ln.strip()), type(exc).__name__)
    return (f"{path}: the VIO estimator failed numerically ({first[:100]}); check the "
            "calibration (T_cam_imu, T_body_imu, intrinsics) and the IMU noise densities "
            "(--imu imu.yaml) of this sequence")


def _loop(seq: StereoSequence, p: VioParams, n: int, fe: Any, est: Estimator, ahead: dict[int, Any],
          pool: Any, read: Callable[[int], tuple[Any, Any]], times: np.ndarray,
          tracked: np.ndarray, t_start: float, progress: Progress | None) -> None:
    w, h = seq.rig.size
    prev_t: int | None = None
    for i in range(n):
        t0 = time.perf_counter()
        t_ns = int(seq.frame_stamps_ns[i])
        left, read_right = ahead.pop(i).result()
        if i + 4 < n:
            ahead[i + 4] = pool.submit(read, i + 4)
        R = None if prev_t is None else est.gyro_rotation(prev_t, t_ns)
        label_l, label_r = seq.frame_labels(i)
        left = _sized(left, label_l, w, h)
        if fe.stereo_on_demand:
            obs = fe.track(t_ns, left, R)
            if est.needs_stereo(obs):  # the right image is read and matched for stereo frames only
                obs = fe.match(_sized(read_right(), label_r, w, h))
        else:  # RGB-D: the registered depth of every frame
            obs = fe.process(t_ns, left, _sized(read_right(), label_r, w, h), R)
        est.process(obs)
        prev_t = t_ns
        tracked[i] = len(obs)
        times[i] = time.perf_counter() - t0
        if progress is not None:
            wall = time.perf_counter() - t_start
            span = (t_ns - int(seq.frame_stamps_ns[0])) * 1e-9
            progress(i + 1, n, span / wall if wall > 0 else 0.0)


def _read_left(seq: StereoSequence, i: int) -> tuple[Any, Callable[[], Any]]:
    """The left image of pair ``i`` and a reader of the right one (decoded only for the frames
    that need stereo)."""
    if seq.frame_reader is None and seq.left_files:
        from functools import partial

        from ibiscape_eval.io.stereo import read_gray_image

        return read_gray_image(seq.left_files[i]), partial(read_gray_image, seq.right_files[i])
    pair = seq.read_pair(i)
    return pair[0], lambda: pair[1]


def _sized(img: Any, label: str, w: int, h: int) -> Any:
    from ibiscape_eval.core.errors import FormatError

    if img.shape != (h, w):
        raise FormatError(label, f"image is {img.shape[1]}x{img.shape[0]} px, the calibration "
                          f"says {w}x{h}")
    return img
