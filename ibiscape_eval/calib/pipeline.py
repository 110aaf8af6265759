"""From frames to a calibration: frame preselection, parallel detection, view selection, solve.

The caller (the command line) opens the image sets through :mod:`ibiscape_eval.io.image_sets` and hands
one :class:`CameraFrames` per camera (a loader per frame) plus the view table
(:func:`ibiscape_eval.io.image_sets.pair_views`); nothing here touches files.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import CalibrationError, IbiscapeError
from ibiscape_eval.core.kalibr import CalibrationTarget

from .calibrate import CalibrationResult, Observations, calibrate, evaluate
from .detect import Detection, detect_corners, sharpness
from .select import preselect_frames, select_views

__all__ = ["CameraFrames", "DetectionSummary", "calibrate_frames", "check_frames", "detect_frames"]

#: views at most this far apart in the view table are neighbours (searched around each other's board)
_NEIGHBOUR_GAP = 2
#: frames per run of neighbours (the unit of work of one detection thread)
_RUN_LEN = 40
#: checkerboards missed by the plain search are searched exhaustively when fewer views are tried
_EXHAUSTIVE_BELOW = 100


@dataclass(frozen=True, eq=False)
class CameraFrames:
    """One camera's frames, loaded on demand.

    Attributes
    ----------
    name : str
    n_frames : int
    load : callable
        ``load(i)`` -> image (H, W) or (H, W, 3), or None when unreadable (skipped).
    label : callable
        ``label(i)`` -> a file name for messages.
    reconstruction : str or None
        For event cameras: how the frames are reconstructed from events (their targets are then
        detected with ``detect_corners(..., event_frame=True)``).
    """

    name: str
    n_frames: int
    load: Callable[[int], npt.NDArray[Any] | None]
    label: Callable[[int], str]
    reconstruction: str | None = None


@dataclass(frozen=True, eq=False)
class DetectionSummary:
    """What detection saw: per camera frames tried, unreadable, with the target, image size."""

    observations: tuple[Observations, ...]
    views: tuple[int, ...]            # rows of the input view table that were detected
    frames_tried: tuple[int, ...]
    frames_unreadable: tuple[int, ...]
    frames_detected: tuple[int, ...]
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"cameras": [
            {"name": o.name, "image_size": list(o.image_size), "frames_tried": t, "unreadable": u,
             "target_found": d}
            for o, t, u, d in zip(self.observations, self.frames_tried, self.frames_unreadable,
                                  self.frames_detected, strict=True)], **self.extra}


def detect_frames(target: CalibrationTarget, cameras: Sequence[CameraFrames],
                  views: Sequence[Sequence[int | None]], *, max_detect: int = 300,
                  workers: int | None = None, progress: Callable[[int], Any] | None = None,
                  total: Callable[[int], Any] | None = None) -> DetectionSummary:
    """Detect the target in (a preselection of) the views, in parallel threads.

    Raises :class:`CalibrationError` when a camera's images differ in size, when too many are
    unreadable, or when the target is found in none of a camera's frames (naming how many were
    tried).
    """
    from concurrent.futures import ThreadPoolExecutor

    from ibiscape_eval.core.cpus import usable_cpus

    n_cam = len(cameras)
    if n_cam == 0:
        raise IbiscapeError("no cameras given")
    if not views:
        raise CalibrationError("no frames to calibrate from")

    def first_frame(row: Sequence[int | None]) -> tuple[int, int] | None:
        for k, i in enumerate(row):
            if i is not None:
                return k, i
        return None

    def sharp(v: int) -> float:
        ref = first_frame(views[v])
        if ref is None:
            return 0.0
        img = cameras[ref[0]].load(ref[1])
        return 0.0 if img is None else sharpness(img)

    picked = preselect_frames(len(views), max_detect, sharp if len(views) > max_detect else None)
    # each camera's frames in runs of neighbouring views: a run is searched in order, every frame
    # first around the board of the frame before it (detect_corners(near=...)).  With many views a
    # missed board is not searched exhaustively (8x the time): the others supply the views
    exhaustive = len(picked) < _EXHAUSTIVE_BELOW
    nw = max(1, workers or usable_cpus())
    runs: list[list[tuple[int, int, int]]] = []
    for k in range(n_cam):
        run: list[tuple[int, int, int]] = []
        for vi, v in enumerate(picked):
            i = views[v][k]
            if i is None:
                continue
            if run and (v - picked[run[-1][1]] > _NEIGHBOUR_GAP or len(run) >= _RUN_LEN):
                runs.append(run)
                run = []
            run.append((k, vi, i))
        if run:
            runs.append(run)
    jobs = [j for r in runs for j in r]
    if total is not None:
        total(len(jobs))
    sizes: list[dict[tuple[int, int], int]] = [{} for _ in range(n_cam)]

    def one_run(run: list[tuple[int, int, int]]) -> list[tuple[int, int, Detection | None, bool]]:
        out = []
        prev: Detection | None = None
        for k, vi, i in run:
            img = cameras[k].load(i)
            det = None
            if img is not None:
                size = (int(img.shape[1]), int(img.shape[0]))
                sizes[k].setdefault(size, i)
                det = detect_corners(img, target, near=prev, exhaustive=exhaustive,
                                     event_frame=cameras[k].reconstruction is not None)
            prev = det
            if progress is not None:
                progress(1)
            out.append((k, vi, det, img is None))
        return out

    if nw > 1 and len(runs) > 1:
        with ThreadPoolExecutor(max_workers=nw) as pool:
            results = [r for rr in pool.map(one_run, runs) for r in rr]
    else:
        results = [r for run in runs for r in one_run(run)]
    dets: list[list[Detection | None]] = [[None] * len(picked) for _ in range(n_cam)]
    tried = [0] * n_cam
    bad = [0] * n_cam
    first_bad: list[int | None] = [None] * n_cam
    for (_, _, i), (k, vi, det, unreadable) in zip(jobs, results, strict=True):
        dets[k][vi] = det
        tried[k] += 1
        bad[k] += int(unreadable)
        if unreadable and first_bad[k] is None:
            first_bad[k] = i
    refined: dict[str, Any] = {}
    for k, cam in enumerate(cameras):  # event cameras: corners refined from the events themselves
        refine = getattr(cam.load, "refine_detections", None)
        if refine is not None and any(d is not None for d in dets[k]):
            dets[k], refined[cam.name] = refine(target, [views[v][k] for v in picked], dets[k])
    obs = []
    for k, cam in enumerate(cameras):
        if len(sizes[k]) > 1:
            (s1, i1), (s2, i2) = list(sizes[k].items())[:2]
            raise CalibrationError(
                f"{cam.name}: images of different sizes in one camera: {cam.label(i1)} is "
                f"{s1[0]}x{s1[1]}, {cam.label(i2)} is {s2[0]}x{s2[1]}; calibrate each size separately")
        if bad[k] and tried[k] - bad[k] < 3:
            fb = first_bad[k]
            raise CalibrationError(f"{cam.name}: only {tried[k] - bad[k]} of {tried[k]} images could be "
                                   f"read (the first unreadable: {cam.label(fb) if fb is not None else '?'}); "
                                   "at least 3 are needed")
        found = sum(d is not None for d in dets[k])
        if found == 0 and getattr(cam.load, "n_events_read", None) == 0:
            where = Path(cam.label(0)).parent
            raise CalibrationError(
                f"{where}: no events in any of the {getattr(cam.load, 'windows_read', 0)} event windows "
                f"read for {cam.name}; check that the recording saw the target moving or blinking")
        if found == 0:
            how = f" (frames reconstructed from events by {cam.reconstruction})" if cam.reconstruction else ""
            raise CalibrationError(
                f"{cam.name}: no target found in any of the {tried[k] - bad[k]} frames tried{how}; "
                f"check the target description ({target!r}) and that the board is fully visible "
                "(checkerboards) and in focus")
        size = next(iter(sizes[k]))
        obs.append(Observations(cam.name, size, dets[k]))
    return DetectionSummary(tuple(obs), tuple(picked), tuple(tried), tuple(bad),
                            tuple(sum(d is not None for d in dets[k]) for k in range(n_cam)),
                            {"event_corner_refinement": refined} if refined else {})


def _partial_view_corners(summary: DetectionSummary) -> int | None:
    """The corners a view needs when event cameras' views hold only their corners refined from the
    events (:data:`~ibiscape_eval.calib.events.REFINE_MIN_CORNERS`); None: whole boards."""
    from .events import REFINE_MIN_CORNERS

    refined = summary.extra.get("event_corner_refinement") or {}
    return REFINE_MIN_CORNERS if any(r.get("method") == "events" for r in refined.values()) else None


def calibrate_frames(target: CalibrationTarget, summary: DetectionSummary, *, model: str = "pinhole-radtan",
                     max_views: int = 60, outlier_sigma: float = 5.0,
                     progress: Callable[[str], Any] | None = None) -> CalibrationResult:
    """Select informative views among the detections and calibrate the chain.

    Checkerboard views of event cameras whose corners were refined from the events keep only the
    refined corners: they count with :data:`~ibiscape_eval.calib.events.REFINE_MIN_CORNERS` corners
    or more, instead of the whole board, and ``max_views`` grows so that the views kept hold as many
    corners as ``max_views`` whole boards (on the ESVI drive at 346x260 the 60 views' focal std was
    0.39 px, all 103 refined views' 0.22 px)."""
    obs = summary.observations
    min_corners = _partial_view_corners(summary)
    if min_corners is not None:  # max_views counts whole boards: as many corners in partial views
        per_view = [len(d) for o in obs for d in o.detections if d is not None]
        if per_view:
            max_views = max(max_views, round(max_views * target.n_corners / float(np.mean(per_view))))
    chosen = select_views([list(o.detections) for o in obs], max_views)
    sub = [Observations(o.name, o.image_size, [o.detections[v] for v in chosen]) for o in obs]
    res = calibrate(target, sub, model=model, outlier_sigma=outlier_sigma, progress=progress,
                    min_corners=min_corners)
    frames = [summary.views[chosen[i]] for i in res.view_ids]
    extra = {"views_detected": len(summary.views), "views_selected": len(chosen),
             "view_rows_used": frames}
    return CalibrationResult(res.model, res.target, res.cameras, res.T_cn_cnm1, res.T_cn_cnm1_std,
                             res.baselines_m, res.baselines_std_m, res.n_views,
                             tuple(int(f) for f in frames), res.renumbered_views, res.iterations,
                             {**res.extra, **extra})


def check_frames(target: CalibrationTarget, summary: DetectionSummary, cameras: Sequence[Any],
                 T_cn_cnm1: Sequence[npt.NDArray[np.float64]], *, outlier_px: float = 1.0) -> dict[str, Any]:
    """Evaluate a given calibration on the detections (see :func:`ibiscape_eval.calib.calibrate.evaluate`)."""
    doc = evaluate(target, summary.observations, cameras, T_cn_cnm1, outlier_px=outlier_px,
                   min_corners=_partial_view_corners(summary))
    # report view rows of the input table
    for o in doc["outlier_views"]:
        o["view"] = int(summary.views[o["view"]])
    return doc
