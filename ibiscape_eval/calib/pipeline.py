"""From a sequence to a calibration: frames, preselection, parallel detection, view selection, solve.

:func:`calibrate_cameras` is the whole job on a sequence opened by
:func:`ibiscape_eval.io.open_sequence` (the ``calib`` command, the benchmark and notebooks call it):
:func:`camera_frames` turns the sequence's cameras into one :class:`CameraFrames` each (images
loaded on demand; event cameras' frames reconstructed from their windows by
:func:`ibiscape_eval.calib.events.event_set_frames`), :func:`detect_frames` finds the target in the
view table (:func:`ibiscape_eval.io.image_sets.pair_views`) and :func:`calibrate_frames` solves.
Nothing here parses a path.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import CalibrationError, IbiscapeError, Remedy
from ibiscape_eval.core.kalibr import CalibrationTarget

from .calibrate import CalibrationResult, Observations, calibrate, evaluate
from .detect import Detection, detect_corners, sharpness
from .select import preselect_frames, select_views

if TYPE_CHECKING:
    from ibiscape_eval.core.sequence import Sequence as Recording

__all__ = ["CameraCalibrationRun", "CameraFrames", "DetectionSummary", "calibrate_cameras",
           "calibrate_frames", "camera_frames", "check_frames", "detect_frames", "sequence_target"]

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


def _first_frame(row: Sequence[int | None]) -> tuple[int, int] | None:
    """The first camera of a view-table row with a frame, and that frame."""
    for k, i in enumerate(row):
        if i is not None:
            return k, i
    return None


def _detection_runs(views: Sequence[Sequence[int | None]], picked: Sequence[int],
                    n_cam: int) -> list[list[tuple[int, int, int]]]:
    """Each camera's ``(camera, index into picked, frame)`` jobs in runs of neighbouring views:
    a run is searched in order, every frame first around the board of the frame before it."""
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
    return runs


@dataclass
class _Detected:
    """Per camera: detections per picked view, frames tried and unreadable, image sizes seen."""

    dets: list[list[Detection | None]]
    tried: list[int]
    bad: list[int]
    first_bad: list[int | None]
    sizes: list[dict[tuple[int, int], int]]


def _run_detection(target: CalibrationTarget, cameras: Sequence[CameraFrames],
                   runs: list[list[tuple[int, int, int]]], n_picked: int, *, exhaustive: bool,
                   near_search: bool, workers: int,
                   progress: Callable[[int], Any] | None) -> _Detected:
    """Detect the target in every job of ``runs`` (runs in parallel threads, each in order)."""
    from ._threads import thread_map

    n_cam = len(cameras)
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
                det = detect_corners(img, target, near=prev if near_search else None,
                                     exhaustive=exhaustive,
                                     event_frame=cameras[k].reconstruction is not None,
                                     fast=cameras[k].reconstruction is None, photo=not near_search)
            prev = det
            if progress is not None:
                progress(1)
            out.append((k, vi, det, img is None))
        return out

    results = [r for rr in thread_map(one_run, runs, workers) for r in rr]
    out = _Detected([[None] * n_picked for _ in range(n_cam)], [0] * n_cam, [0] * n_cam,
                    [None] * n_cam, sizes)
    jobs = [j for r in runs for j in r]
    for (_, _, i), (k, vi, det, unreadable) in zip(jobs, results, strict=True):
        out.dets[k][vi] = det
        out.tried[k] += 1
        out.bad[k] += int(unreadable)
        if unreadable and out.first_bad[k] is None:
            out.first_bad[k] = i
    return out


def _check_camera(target: CalibrationTarget, cam: CameraFrames, k: int, det: _Detected) -> None:
    """Raise :class:`CalibrationError` when camera ``k``'s images differ in size, too many are
    unreadable, or the target was found in none of them."""
    tried, bad = det.tried[k], det.bad[k]
    if len(det.sizes[k]) > 1:
        (s1, i1), (s2, i2) = list(det.sizes[k].items())[:2]
        raise CalibrationError(
            f"{cam.name}: images of different sizes in one camera: {cam.label(i1)} is "
            f"{s1[0]}x{s1[1]}, {cam.label(i2)} is {s2[0]}x{s2[1]}; calibrate each size separately")
    if bad and tried - bad < 3:
        fb = det.first_bad[k]
        raise CalibrationError(f"{cam.name}: only {tried - bad} of {tried} images could be "
                               f"read (the first unreadable: {cam.label(fb) if fb is not None else '?'}); "
                               "at least 3 are needed")
    if any(d is not None for d in det.dets[k]):
        return
    if getattr(cam.load, "n_events_read", None) == 0:
        where = Path(cam.label(0)).parent
        raise CalibrationError(
            f"{where}: no events in any of the {getattr(cam.load, 'windows_read', 0)} event windows "
            f"read for {cam.name}; check that the recording saw the target moving or blinking")
    how = f" (frames reconstructed from events by {cam.reconstruction})" if cam.reconstruction else ""
    raise CalibrationError(
        f"{cam.name}: no target found in any of the {tried - bad} frames tried{how}; "
        f"check the target description ({target!r}) and that the board is fully visible "
        "(checkerboards) and in focus")


def detect_frames(target: CalibrationTarget, cameras: Sequence[CameraFrames],
                  views: Sequence[Sequence[int | None]], *, max_detect: int = 300,
                  workers: int | None = None, progress: Callable[[int], Any] | None = None,
                  total: Callable[[int], Any] | None = None, near_search: bool = True) -> DetectionSummary:
    """Detect the target in (a preselection of) the views, in parallel threads.

    ``near_search``: search every frame first around the board of the frame before it (frames of
    a video; False for independent photos, whose boards are anywhere: the failed search around the
    previous board cost 18 ms per 640x512 photo, 40 % of its detection).

    Raises :class:`CalibrationError` when a camera's images differ in size, when too many are
    unreadable, or when the target is found in none of a camera's frames (naming how many were
    tried).
    """
    from ibiscape_eval.core.cpus import usable_cpus

    n_cam = len(cameras)
    if n_cam == 0:
        raise IbiscapeError("no cameras given")
    if not views:
        raise CalibrationError("no frames to calibrate from")

    def sharp(v: int) -> float:
        ref = _first_frame(views[v])
        if ref is None:
            return 0.0
        img = cameras[ref[0]].load(ref[1])
        return 0.0 if img is None else sharpness(img)

    picked = preselect_frames(len(views), max_detect, sharp if len(views) > max_detect else None)
    # With many views a missed board is not searched exhaustively (8x the time): the others
    # supply the views
    runs = _detection_runs(views, picked, n_cam)
    if not near_search:  # independent photos: one job each, so that the threads share them evenly
        runs = [[job] for run in runs for job in run]
    if total is not None:
        total(sum(len(r) for r in runs))
    det = _run_detection(target, cameras, runs, len(picked), exhaustive=len(picked) < _EXHAUSTIVE_BELOW,
                         near_search=near_search, workers=max(1, workers or usable_cpus()),
                         progress=progress)
    refined: dict[str, Any] = {}
    for k, cam in enumerate(cameras):  # event cameras: corners refined from the events themselves
        refine = getattr(cam.load, "refine_detections", None)
        if refine is not None and any(d is not None for d in det.dets[k]):
            det.dets[k], refined[cam.name] = refine(target, [views[v][k] for v in picked], det.dets[k])
    for k, cam in enumerate(cameras):
        _check_camera(target, cam, k, det)
    obs = tuple(Observations(cam.name, next(iter(det.sizes[k])), det.dets[k]) for k, cam in enumerate(cameras))
    return DetectionSummary(obs, tuple(picked), tuple(det.tried), tuple(det.bad),
                            tuple(sum(d is not None for d in det.dets[k]) for k in range(n_cam)),
                            {"event_corner_refinement": refined} if refined else {})


def _partial_view_corners(summary: DetectionSummary) -> int | None:
    """The corners a view needs when event cameras' views hold only their corners refined from the
    events (:data:`~ibiscape_eval.calib.events.REFINE_MIN_CORNERS`); None: whole boards."""
    refined = summary.extra.get("event_corner_refinement") or {}
    if not any(r.get("method") == "events" for r in refined.values()):
        return None
    from .events import REFINE_MIN_CORNERS  # event cameras only

    return REFINE_MIN_CORNERS


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


# ----------------------------------------------------------------------------------- sequences
def sequence_target(seq: Recording, target: CalibrationTarget | None = None) -> CalibrationTarget:
    """``target``, else the one the sequence names (``sequence.yaml``'s ``target``).

    Raises :class:`IbiscapeError` saying to give ``--target`` when neither is there."""
    from ibiscape_eval.core.kalibr import target_from_kalibr

    if target is not None:
        return target
    if seq.target is not None:
        return target_from_kalibr(dict(seq.target), source=seq.target_source or f"{seq.path}: target")
    where = "" if seq.layout == "images" else (
        f"; {seq.path}/sequence.yaml has no 'target'" if seq.layout == "ibiscape"
        else f"; a {seq.layout} recording names none")
    raise IbiscapeError(f"no target description: give {{0}} (Kalibr's format){where}",
                        hint=(Remedy("target"),))


def camera_frames(seq: Recording, target: CalibrationTarget, *, reconstruction: str = "auto",
                  refine: bool = True, bidirectional: bool = True,
                  sensor_size: tuple[int, int] | None = None
                  ) -> tuple[list[CameraFrames], dict[str, dict[str, Any]]]:
    """One :class:`CameraFrames` per camera of ``seq`` and, per event camera, how its frames were
    reconstructed (:func:`ibiscape_eval.calib.events.event_set_frames`).

    Event cameras need their sensor size: ``sensor_size`` (an override), else the size the
    sequence states; :class:`IbiscapeError` asks for ``--sensor-size`` when neither is known.
    """
    frames: list[CameraFrames] = []
    recon: dict[str, dict[str, Any]] = {}
    for cam in seq.cameras:
        if cam.kind == "frames":
            frames.append(CameraFrames(cam.name, len(cam), cam.load, cam.label))
            continue
        from .events import event_set_frames  # event cameras only

        size = sensor_size or cam.sensor_size
        if size is None:
            raise IbiscapeError(f"{cam.root}: sensor size unknown (the recording does not state it); "
                                "pass {0}", hint=(Remedy("sensor_size"),))
        if cam.windows_ns is None:
            raise IbiscapeError(f"{cam.root}: camera {cam.name}: event windows are needed to build "
                                "frames (an IBISCape DVS folder with timestamps.csv)")
        source, recon[cam.name] = event_set_frames(
            cam.paths, cam.windows_ns, (int(size[0]), int(size[1])), target,
            reconstruction=reconstruction, refine=refine, bidirectional=bidirectional,
            camera_doc=dict(cam.entry) if cam.entry else None)
        frames.append(CameraFrames(cam.name, len(cam), source, cam.label,
                                   reconstruction=recon[cam.name]["method"]))
    return frames, recon


@dataclass(frozen=True, eq=False)
class CameraCalibrationRun:
    """What :func:`calibrate_cameras` did: the detection, the calibration (or the check of a
    given one), the reconstruction of event cameras, the comparison with a known truth.

    Attributes
    ----------
    sequence : Sequence
    target : CalibrationTarget
    detection : DetectionSummary
    reconstruction : dict
        Event camera name -> how its frames were reconstructed.
    result : CalibrationResult or None
        None when a given calibration was checked (``check``).
    truth : TruthComparison or None
        Errors against the true cameras when the sequence holds them.
    check : dict or None
        The evaluation of a given calibration (:func:`check_frames`).
    """

    sequence: Recording
    target: CalibrationTarget
    detection: DetectionSummary
    reconstruction: dict[str, dict[str, Any]]
    result: CalibrationResult | None = None
    truth: Any = None
    check: dict[str, Any] | None = None

    def rostopics(self) -> tuple[str, ...]:
        """The rostopic of every calibrated camera (the sequence's, else ``/<name>/image_raw``)."""
        assert self.result is not None
        out = []
        for c in self.result.cameras:
            topic = next((s.rostopic for s in self.sequence.cameras if s.name == c.name and s.rostopic), None)
            out.append(str(topic) if topic else f"/{c.name}/image_raw")
        return tuple(out)

    def to_dict(self) -> dict[str, Any]:
        """Strict JSON: target, detection, reconstruction, then the check or the result with
        ``ground_truth``."""
        doc: dict[str, Any] = {"target": self.target.to_kalibr(), "detection": self.detection.to_dict(),
                               "reconstruction": self.reconstruction}
        if self.check is not None:
            return {**doc, **self.check}
        assert self.result is not None
        return {**doc, **self.result.to_dict(),
                "ground_truth": None if self.truth is None else self.truth.to_dict()}

    def __repr__(self) -> str:
        what = "check" if self.check is not None else repr(self.result)
        return f"CameraCalibrationRun({self.sequence.path}: {what})"


def calibrate_cameras(seq: Recording, *, target: CalibrationTarget | None = None,
                      model: str = "pinhole-radtan", max_views: int = 60, max_frames: int = 300,
                      reconstruction: str = "auto", event_corners: str = "events",
                      sensor_size: tuple[int, int] | None = None, outlier_sigma: float = 5.0,
                      workers: int | None = None, check: Any = None,
                      progress: Callable[[int], Any] | None = None,
                      total: Callable[[int], Any] | None = None,
                      solve_progress: Callable[[str], Any] | None = None) -> CameraCalibrationRun:
    """Calibrate every camera of a sequence (mono, stereo, chains; frames and event cameras).

    Parameters
    ----------
    seq : Sequence
        From :func:`ibiscape_eval.open_sequence` (``seq.select([...])`` picks cameras).
    target : CalibrationTarget, optional
        Default: the target the sequence names (``sequence.yaml``).
    model : ``"pinhole-radtan"`` or ``"pinhole-equi"``
    max_views, max_frames : int
        Views kept for the solve; frames searched for the target.
    reconstruction : str
        Event cameras: how frames are built from the events (``auto`` tries them).
    event_corners : ``"events"`` or ``"frames"``
        Event cameras: refine corners from the events' timestamps, or keep the frames' corners.
    sensor_size : (w, h), optional
        Event cameras' sensor size, overriding what the sequence states.
    check : CameraChain, optional
        Evaluate this calibration on the detections instead of calibrating.
    progress, total : callable, optional
        Detection progress (frames done) and the number of frames to detect.
    solve_progress : callable(str), optional

    Raises
    ------
    IbiscapeError, CalibrationError
        No target, unknown sensor size of an event camera, no target found, too few views.
    """
    from ibiscape_eval.io.image_sets import pair_views

    from .report import compare_with_truth, truth_from_sequence

    tgt = sequence_target(seq, target)
    frames, recon = camera_frames(seq, tgt, reconstruction=reconstruction,
                                  refine=event_corners == "events", sensor_size=sensor_size)
    views = pair_views(seq.cameras)
    # photos (--images globs) are independent views: no search around the previous one's board
    summary = detect_frames(tgt, frames, views, max_detect=max_frames, workers=workers,
                            progress=progress, total=total, near_search=seq.layout != "images")
    if check is not None:
        doc = check_frames(tgt, summary, check.models, check.relative_transforms)
        return CameraCalibrationRun(seq, tgt, summary, recon, check=doc)
    result = calibrate_frames(tgt, summary, model=model, max_views=max_views,
                              outlier_sigma=outlier_sigma, progress=solve_progress)
    truth = compare_with_truth(result, truth_from_sequence(dict(seq.doc)))
    return CameraCalibrationRun(seq, tgt, summary, recon, result, truth)
