"""The paper's sequence table as a suite of batch jobs (``ibiscape-eval sim suite``).

The IBISCape paper's ``table:ibiscape_sequences`` lists 34 sequences: calibration runs in clear
weather (1 still IMU, 2 each of SVI, ESVI, RGB-D and the full setup; half toward the checkerboard,
half toward the AprilGrid) and SLAM runs through the town (SVI 2/2/3, ESVI, RGB-D and full 2/2/2 in
clear / moderate / dynamic weather).  :func:`suite_entries` gives one :class:`SuiteEntry` per
sequence, named like the paper's folders (``SVI_calib_1``, ``ESVI_slam_dyn_2``), and
:func:`suite_jobs` one :class:`~ibiscape_eval.batch.Job` per entry, so the suite runs locally or on
a Dask cluster like every other batch.

Scale
-----
``scale = F`` in (0, 1] shrinks every sequence for quick runs, exactly as follows:

- duration: ``max(MIN_DURATION_S[kind], F * FULL_DURATION_S[kind])``, with the full-scale
  durations 60 s (calibration drives and SLAM runs) and 604 800 s (the paper's 168 h still IMU),
  and the minima 3 s (SLAM runs), 12 s (calibration drives: the camera-IMU calibration needs a few
  shuttle legs over the bumps) and 1 800 s (still IMU: the Allan deviation needs a few hundred
  seconds of averaging time to show the bias random walk);
- image side: ``clamp(16 * round(1024 * sqrt(F) / 16), MIN_SIDE_PX[kind], 1024)`` pixels for every
  camera (square, field of view kept), so the pixel count (the rendering cost of a frame) scales
  with F; the minimum is 128 px for SLAM runs, 320 px for checkerboard calibration drives and 512
  px for AprilGrid drives (below that the board's squares or tags, 4.5-15 m away on the shuttle
  drive, are too small to detect or decode);
- calibration drives are the simulator's default shuttle drive (the board in view all the time).
- the still IMU is written as ``other_sensors/imu.npy`` (streamed, bounded memory) when it is longer
  than 2 h, as ``imu.csv`` otherwise.

``F = 1`` is the paper's table at full size (1024 px cameras, 60 s drives, 168 h of still IMU).

Re-runs
-------
Each sequence folder gets a ``suite_entry.json`` (its entry and the generator's summary) once it is
complete; a re-run skips every sequence whose folder holds the same entry, so an interrupted suite
resumes where it stopped.  ``suite.json`` (the manifest) lists every entry, its full configuration
and its status.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ibiscape_eval.core.errors import IbiscapeError

if TYPE_CHECKING:
    from ibiscape_eval.batch import Executor, Job, JobResult

    from .config import SimConfig

__all__ = [
    "FULL_DURATION_S",
    "MANIFEST",
    "MIN_DURATION_S",
    "PAPER_TABLE",
    "SuiteEntry",
    "SuiteResult",
    "generate_entry",
    "read_manifest",
    "run_suite",
    "scaled_duration_s",
    "scaled_side_px",
    "suite_entries",
    "suite_jobs",
]

#: (setup, kind, {weather: count}) rows of the paper's ``table:ibiscape_sequences``.
PAPER_TABLE: tuple[tuple[str, str, Mapping[str, int]], ...] = (
    ("imu", "calibration", {"clear": 1}),
    ("svi", "calibration", {"clear": 2}),
    ("esvi", "calibration", {"clear": 2}),
    ("rgbd", "calibration", {"clear": 2}),
    ("full", "calibration", {"clear": 2}),
    ("svi", "slam", {"clear": 2, "moderate": 2, "dynamic": 3}),
    ("esvi", "slam", {"clear": 2, "moderate": 2, "dynamic": 2}),
    ("rgbd", "slam", {"clear": 2, "moderate": 2, "dynamic": 2}),
    ("full", "slam", {"clear": 2, "moderate": 2, "dynamic": 2}),
)

#: Durations at scale 1 [s]: 60 s drives and runs, the paper's 168 h still IMU.
FULL_DURATION_S = {"calibration": 60.0, "slam": 60.0, "imu": 604_800.0}
#: Shortest durations at any scale [s].
MIN_DURATION_S = {"calibration": 12.0, "slam": 3.0, "imu": 1_800.0}
FULL_SIDE_PX = 1024
#: Smallest image side at any scale [px], by kind (AprilGrid drives: their 0.55 m tags need 512 px
#: to be decoded 3.4-11 m away).
MIN_SIDE_PX = {"calibration": 320, "calibration-aprilgrid": 512, "slam": 128}
NPY_ABOVE_S = 7_200.0
MANIFEST = "suite.json"
ENTRY_FILE = "suite_entry.json"

_LABEL = {"imu": "IMU", "svi": "SVI", "esvi": "ESVI", "rgbd": "RGBD", "full": "FULL"}
_WEATHER = {"clear": "clear", "moderate": "mod", "dynamic": "dyn"}


def _check_scale(scale: float) -> float:
    if isinstance(scale, bool) or not isinstance(scale, int | float) or not math.isfinite(scale) \
            or not 0.0 < scale <= 1.0:
        raise IbiscapeError(f"scale must be a number in (0, 1], got {scale!r} "
                            "(1 = the paper's full-size suite, 0.05 = a quick run)")
    return float(scale)


def scaled_duration_s(kind: str, scale: float) -> float:
    """Duration of a sequence of ``kind`` (``calibration``, ``slam`` or ``imu``) at ``scale``."""
    s = _check_scale(scale)
    return max(MIN_DURATION_S[kind], round(s * FULL_DURATION_S[kind], 3))


def scaled_side_px(scale: float, kind: str = "slam") -> int:
    """Image side [px] at ``scale``: ``clamp(16 round(1024 sqrt(F) / 16), MIN_SIDE_PX[kind], 1024)``."""
    s = _check_scale(scale)
    return int(min(FULL_SIDE_PX, max(MIN_SIDE_PX[kind],
                                      16 * round(FULL_SIDE_PX * math.sqrt(s) / 16))))


@dataclass(frozen=True)
class SuiteEntry:
    """One sequence of the suite: its name and the recipe of its configuration.

    Attributes
    ----------
    name : str
        ``<SETUP>_calib_<i>`` or ``<SETUP>_slam_<clear|mod|dyn>_<i>`` (``IMU_calib_1``).
    setup, kind, weather : str
        The preset (:func:`ibiscape_eval.sim.preset`).
    index : int
        1-based number within its setup, kind and weather.
    seed : int
        Seed of every random process of the sequence.
    duration_s : float
    side_px : int or None
        Image side of every camera (None: no cameras).
    target : str or None
        Calibration drives: ``checkerboard`` (odd index) or ``aprilgrid`` (even index).
    still_format : str
        Still IMU: ``csv`` or ``npy``.
    """

    name: str
    setup: str
    kind: str
    weather: str
    index: int
    seed: int
    duration_s: float
    side_px: int | None
    target: str | None
    still_format: str

    def config(self) -> SimConfig:
        """The simulator configuration of this sequence."""
        from .config import preset, with_resolution

        kw: dict[str, Any] = {"duration_s": self.duration_s, "seed": self.seed}
        if self.target is not None:
            kw["target"] = self.target
        if self.setup == "imu":
            kw["still_format"] = self.still_format
        cfg = preset(self.setup, self.kind, self.weather, **kw)
        if self.side_px is not None and cfg.cameras:
            cfg = with_resolution(cfg, self.side_px, self.side_px)
        if self.kind == "calibration" and cfg.cameras:
            # a clock offset between the cameras and the IMU, seeded, within +-20 ms, for the
            # camera-IMU calibration to recover; one for the whole rig, whose cameras are
            # synchronised with each other (the stereo calibration pairs views by their stamps)
            shift = float(np.random.default_rng([self.seed, 20]).uniform(-0.02, 0.02))
            cfg = replace(cfg, cameras=tuple(replace(c, timeshift_cam_imu_s=round(shift, 4))
                                             for c in cfg.cameras))
        return cfg

    @property
    def has_cameras(self) -> bool:
        return self.setup != "imu"

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> SuiteEntry:
        """Inverse of :meth:`to_dict` (unknown or missing keys are an error)."""
        names = {f for f in cls.__dataclass_fields__}
        if set(doc) != names:
            raise IbiscapeError(f"suite entry: expected keys {sorted(names)}, got {sorted(doc)}")
        return cls(**{k: doc[k] for k in names})

    def __repr__(self) -> str:
        return (f"SuiteEntry({self.name}: {self.setup} {self.kind} {self.weather}, "
                f"{self.duration_s:g} s, {self.side_px or '-'} px)")


def suite_entries(scale: float = 1.0, *, seed: int = 0) -> tuple[SuiteEntry, ...]:
    """The 34 sequences of the paper's table at ``scale`` (see the module docstring).

    Seeds are ``seed + position in the table`` (1..34), so every sequence differs and the same
    ``seed`` gives the same suite.
    """
    s = _check_scale(scale)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise IbiscapeError(f"seed must be a non-negative integer, got {seed!r}")
    out: list[SuiteEntry] = []
    for setup, kind, counts in PAPER_TABLE:
        for weather, n in counts.items():
            for i in range(1, n + 1):
                if setup == "imu":
                    d = scaled_duration_s("imu", s)
                    name = f"IMU_calib_{i}"
                    out.append(SuiteEntry(name, setup, kind, weather, i, seed + len(out) + 1, d,
                                          None, None, "npy" if d > NPY_ABOVE_S else "csv"))
                    continue
                d = scaled_duration_s(kind, s)
                if kind == "calibration":
                    name = f"{_LABEL[setup]}_calib_{i}"
                    target: str | None = "checkerboard" if i % 2 else "aprilgrid"
                else:
                    name = f"{_LABEL[setup]}_slam_{_WEATHER[weather]}_{i}"
                    target = None
                side_kind = f"{kind}-{target}" if target == "aprilgrid" else kind
                out.append(SuiteEntry(name, setup, kind, weather, i, seed + len(out) + 1, d,
                                      scaled_side_px(s, side_kind), target, "csv"))
    return tuple(out)


# ---------------------------------------------------------------------------------------------
# jobs


def generate_entry(entry: Mapping[str, Any], out: str, render: bool = True) -> dict[str, Any]:
    """Batch job: generate one suite sequence into ``out`` unless it already holds this entry.

    Returns ``{"name", "path", "reused", "summary"}`` (the generator's summary as a mapping).
    """
    from ibiscape_eval.batch.jobs import canonical_json
    from ibiscape_eval.io.atomic import atomic_write

    from .generator import generate

    e = SuiteEntry.from_dict(entry)
    want = {"entry": e.to_dict(), "render": bool(render)}
    marker = Path(out) / ENTRY_FILE
    try:
        have = json.loads(marker.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        have = None
    if isinstance(have, dict) and {k: have.get(k) for k in want} == json.loads(canonical_json(want)):
        return {"name": e.name, "path": str(out), "reused": True, "summary": have.get("summary")}
    cfg = e.config()
    summary = generate(cfg, out, overwrite=True, render=render and bool(cfg.cameras))
    doc = json.loads(canonical_json({**want, "summary": summary.to_dict()}))
    with atomic_write(marker) as f:
        f.write(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    return {"name": e.name, "path": str(out), "reused": False, "summary": doc["summary"]}


def suite_jobs(entries: Sequence[SuiteEntry], out_dir: str | os.PathLike[str], *,
               render: bool = True) -> list[Job]:
    """One :class:`~ibiscape_eval.batch.Job` per entry, writing ``out_dir/<name>``."""
    from ibiscape_eval.batch import Job

    root = Path(out_dir)
    return [Job(e.name, generate_entry,
                {"entry": e.to_dict(), "out": str(root / e.name), "render": bool(render)})
            for e in entries]


@dataclass(frozen=True)
class SuiteResult:
    """What :func:`run_suite` did: the manifest's rows and the batch counts."""

    path: str
    scale: float
    sequences: tuple[dict[str, Any], ...]
    summary: dict[str, int]

    @property
    def failed(self) -> tuple[dict[str, Any], ...]:
        return tuple(s for s in self.sequences if s["status"] != "ok")

    def to_dict(self) -> dict[str, Any]:
        return {"path": self.path, "scale": self.scale, "sequences": [dict(s) for s in self.sequences],
                "summary": dict(self.summary)}

    def __repr__(self) -> str:
        return (f"SuiteResult({self.path}: {len(self.sequences)} sequences at scale {self.scale:g}, "
                f"{len(self.failed)} failed)")


def _manifest_doc(entries: Sequence[SuiteEntry], scale: float, seed: int, render: bool,
                  results: Mapping[str, JobResult] | None) -> dict[str, Any]:
    rows = []
    for e in entries:
        row: dict[str, Any] = {**e.to_dict(), "config": e.config().to_dict()}
        if results is not None:
            r = results[e.name]
            row["status"] = r.status
            row["error"] = r.error
            row["reused"] = bool(r.value and r.value.get("reused"))
            row["seconds"] = r.seconds
            row["summary"] = (r.value or {}).get("summary")
        rows.append(row)
    return {
        "suite": "IBISCape paper, table:ibiscape_sequences",
        "scale": scale,
        "seed": seed,
        "render": render,
        "scaling": {
            "duration_s": "max(MIN_DURATION_S[kind], scale * FULL_DURATION_S[kind])",
            "full_duration_s": FULL_DURATION_S,
            "min_duration_s": MIN_DURATION_S,
            "side_px": "clamp(16 * round(1024 * sqrt(scale) / 16), MIN_SIDE_PX[kind], 1024)",
            "min_side_px": MIN_SIDE_PX,
        },
        "sequences": rows,
    }


def run_suite(out_dir: str | os.PathLike[str], *, scale: float = 1.0, seed: int = 0,
              render: bool = True, executor: Executor | None = None,
              progress: Callable[[int, int, int], None] | None = None,
              only: Sequence[str] | None = None) -> SuiteResult:
    """Generate the suite into ``out_dir`` (one folder per sequence) and write ``suite.json``.

    Parameters
    ----------
    out_dir : path
        Created if missing; sequences already complete (same entry) are kept.
    scale : float in (0, 1]
    seed : int
    render : bool
        Render the cameras (images, depth, segmentation, events); False: ground truth and IMU only.
    executor : Executor, optional
        Where the jobs run (default: a local process pool).
    progress : callable, optional
        ``progress(done, failed, remaining)`` after each sequence.
    only : sequence of str, optional
        Generate only these sequence names (the manifest still lists every entry).

    Returns
    -------
    SuiteResult
        A sequence that failed is recorded with its error; the others are generated.
    """
    from ibiscape_eval.batch import run_jobs
    from ibiscape_eval.batch.jobs import canonical_json
    from ibiscape_eval.io.atomic import atomic_write

    entries = suite_entries(scale, seed=seed)
    if only is not None:
        names = {e.name for e in entries}
        unknown = sorted(set(only) - names)
        if unknown:
            raise IbiscapeError(f"unknown suite sequence(s) {', '.join(unknown)}; the suite has "
                                f"{', '.join(e.name for e in entries)}")
        entries = tuple(e for e in entries if e.name in set(only))
    root = Path(out_dir)
    if root.exists() and not root.is_dir():
        raise IbiscapeError(f"{root}: exists and is not a folder; choose another --out")
    root.mkdir(parents=True, exist_ok=True)
    jobs = suite_jobs(entries, root, render=render)
    results, summary = run_jobs(jobs, executor, progress=progress)
    doc = _manifest_doc(entries, float(scale), seed, render, results)
    with atomic_write(root / MANIFEST) as f:
        f.write(json.dumps(json.loads(canonical_json(doc)), indent=1) + "\n")
    return SuiteResult(str(root), float(scale), tuple(doc["sequences"]), summary.to_dict())


def read_manifest(suite_dir: str | os.PathLike[str]) -> tuple[dict[str, Any], tuple[SuiteEntry, ...]]:
    """``suite.json`` of a generated suite: the document and its entries."""
    from ibiscape_eval.core.errors import FormatError

    path = Path(suite_dir) / MANIFEST
    if not path.is_file():
        raise IbiscapeError(f"{path}: not found; is {suite_dir} a folder written by "
                            "'ibiscape-eval sim suite'?")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        rows = doc["sequences"]
        fields = SuiteEntry.__dataclass_fields__
        entries = tuple(SuiteEntry.from_dict({k: r[k] for k in fields}) for r in rows)
    except (ValueError, KeyError, TypeError, IbiscapeError) as e:
        raise FormatError(path, f"not a suite manifest ({type(e).__name__}: {e}); generate the "
                          "suite again with 'ibiscape-eval sim suite'") from None
    return doc, entries

