"""Find the runs of a results folder and their ground truth.

Layout (documented in the README, ``report`` section)::

    RUNS_DIR/
      <sequence>/
        groundtruth.<ext>          ground truth of the sequence (any format the readers know), or
                                   the IBISCape sequence DIR/<sequence>/ given by --sequences
        gnss.csv                   optional GNSS fixes (IBISCape gnss.csv) for the figures
        <algorithm>/
          run.yaml                 optional, every trial of the algorithm: ``align: sim3``
          <trial>/
            <trajectory file>      exactly one (TUM, KITTI [+ <stem>.times.txt], EuRoC, bag, ...)
            run.yaml               optional, this trial (wins over the algorithm's run.yaml)

Hidden entries (``.name``) are skipped silently; anything else that does not fit is listed in
:attr:`RunsLayout.ignored` with the reason, so the command line can say what it left out.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ibiscape_eval.core.errors import IbiscapeError, Remedy
from ibiscape_eval.io.run_meta import RUN_META_NAME, read_run_meta

__all__ = ["RunSpec", "RunsLayout", "SequenceTruth", "discover_runs", "natural_key"]

GROUNDTRUTH_STEM = "groundtruth"
GNSS_NAME = "gnss.csv"
IBISCAPE_GT = Path("vehicle_gt") / "groundtruth_sync.csv"
IBISCAPE_GNSS = Path("other_sensors") / "gnss.csv"


def natural_key(text: str) -> tuple[Any, ...]:
    """Sort key that puts ``trial_2`` before ``trial_10``."""
    return tuple(int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", text))


@dataclass(frozen=True)
class RunSpec:
    """One estimated trajectory: ``RUNS_DIR/<sequence>/<algorithm>/<trial>/<path>``.

    ``align`` is the alignment its ``run.yaml`` asks for (None: none asked), ``meta_path`` that
    file (the trial's, else the algorithm's).
    """

    sequence: str
    algorithm: str
    trial: str
    path: str
    times_path: str | None = None
    align: str | None = None
    meta_path: str | None = None

    @property
    def key(self) -> str:
        return f"{self.sequence}/{self.algorithm}/{self.trial}"


@dataclass(frozen=True)
class SequenceTruth:
    """Ground truth (and optional GNSS) of one sequence."""

    sequence: str
    groundtruth: str
    gnss: str | None = None


@dataclass(frozen=True)
class RunsLayout:
    """What :func:`discover_runs` found.

    Attributes
    ----------
    root : str
        The runs folder.
    runs : tuple of RunSpec
        Sorted by sequence, algorithm, trial (natural order).
    truths : dict
        Sequence name -> :class:`SequenceTruth`, for every sequence with runs.
    ignored : tuple of (str, str)
        Paths that do not fit the layout, with the reason.
    """

    root: str
    runs: tuple[RunSpec, ...]
    truths: dict[str, SequenceTruth] = field(default_factory=dict)
    ignored: tuple[tuple[str, str], ...] = ()

    @property
    def sequences(self) -> list[str]:
        return sorted({r.sequence for r in self.runs}, key=natural_key)

    @property
    def algorithms(self) -> list[str]:
        return sorted({r.algorithm for r in self.runs}, key=natural_key)

    def __repr__(self) -> str:
        return (f"RunsLayout({len(self.runs)} runs, {len(self.sequences)} sequences, "
                f"{len(self.algorithms)} algorithms, {len(self.ignored)} ignored)")


def _visible(p: Path) -> list[Path]:
    return sorted((c for c in p.iterdir() if not c.name.startswith(".")),
                  key=lambda c: natural_key(c.name))


def _is_bag_folder(p: Path) -> bool:
    return p.is_dir() and (p / "metadata.yaml").is_file()


def _trial_file(trial: Path, ignored: list[tuple[str, str]]) -> tuple[Path, Path | None] | None:
    """The one trajectory of a trial folder (and its KITTI times file), or None (ignored)."""
    entries = [e for e in _visible(trial) if e.name != RUN_META_NAME]
    if _is_bag_folder(trial):
        return trial, None
    times = {e for e in entries if e.is_file() and e.name.endswith(".times.txt")}
    candidates = [e for e in entries if e not in times and (e.is_file() or _is_bag_folder(e))]
    for e in entries:
        if e.is_dir() and not _is_bag_folder(e):
            ignored.append((str(e), "a folder inside a trial folder (expected one trajectory "
                                    "file per trial)"))
    if not candidates:
        ignored.append((str(trial), "trial folder without a trajectory file"))
        return None
    if len(candidates) > 1:
        names = ", ".join(c.name for c in candidates[:4])
        ignored.append((str(trial), f"trial folder with {len(candidates)} candidate trajectory "
                                    f"files ({names}); keep exactly one per trial folder"))
        return None
    est = candidates[0]
    own_times = est.with_name(f"{est.stem}.times.txt")
    for t in times:
        if t != own_times:
            ignored.append((str(t), f"times file that belongs to no trajectory (expected "
                                    f"{own_times.name})"))
    return est, (own_times if own_times in times else None)


def _truth_in_runs(seq_dir: Path) -> list[Path]:
    return [e for e in _visible(seq_dir)
            if (e.is_file() or _is_bag_folder(e))
            and (e.name == GROUNDTRUTH_STEM or e.name.split(".", 1)[0] == GROUNDTRUTH_STEM)]


def _algorithm_runs(seq: str, alg_dir: Path, ignored: list[tuple[str, str]]) -> list[RunSpec]:
    """The runs of one ``<sequence>/<algorithm>/`` folder (their alignment from ``run.yaml``)."""
    alg_meta = alg_dir / RUN_META_NAME
    alg_align = read_run_meta(alg_meta).align if alg_meta.is_file() else None
    runs: list[RunSpec] = []
    for trial_dir in _visible(alg_dir):
        if trial_dir == alg_meta:
            continue
        if not trial_dir.is_dir():
            ignored.append((str(trial_dir), "a file in an algorithm folder (expected "
                                            "<trial>/ folders holding one trajectory)"))
            continue
        found = _trial_file(trial_dir, ignored)
        if found is None:
            continue
        est, times = found
        align, meta = alg_align, (str(alg_meta) if alg_align else None)
        trial_meta = trial_dir / RUN_META_NAME
        if trial_meta.is_file() and not _is_bag_folder(trial_dir):
            own = read_run_meta(trial_meta).align
            if own is not None:
                align, meta = own, str(trial_meta)
        runs.append(RunSpec(seq, alg_dir.name, trial_dir.name, str(est),
                            None if times is None else str(times), align, meta))
    return runs


def _sequence_runs(seq_dir: Path, gts: list[Path], ignored: list[tuple[str, str]]
                   ) -> list[RunSpec]:
    """Every run of one ``<sequence>/`` folder (its ground truth and GNSS files skipped)."""
    runs: list[RunSpec] = []
    for alg_dir in _visible(seq_dir):
        if alg_dir in gts or alg_dir == seq_dir / GNSS_NAME:
            continue
        if not alg_dir.is_dir():
            ignored.append((str(alg_dir), "a file in a sequence folder that is neither "
                                          "groundtruth.<ext> nor gnss.csv"))
            continue
        runs += _algorithm_runs(seq_dir.name, alg_dir, ignored)
    return runs


def _sequence_truth(seq_dir: Path, gts: list[Path], seq_root: Path | None) -> SequenceTruth | None:
    """The ground truth of a sequence with runs: ``groundtruth.<ext>`` beside them, else the
    IBISCape sequence under ``seq_root``; None when neither exists."""
    seq, gnss = seq_dir.name, seq_dir / GNSS_NAME
    if len(gts) > 1:
        raise IbiscapeError(
            f"{seq_dir}: {len(gts)} ground-truth files ({', '.join(g.name for g in gts)}); "
            "keep exactly one groundtruth.<ext> per sequence"
        )
    seq_gt = seq_root / seq if seq_root is not None else None
    if gts:
        return SequenceTruth(seq, str(gts[0]), str(gnss) if gnss.is_file() else None)
    if seq_gt is not None and (seq_gt / IBISCAPE_GT).is_file():
        g = gnss if gnss.is_file() else seq_gt / IBISCAPE_GNSS
        return SequenceTruth(seq, str(seq_gt / IBISCAPE_GT), str(g) if g.is_file() else None)
    return None


def _check_found(root: Path, seq_root: Path | None, runs: list[RunSpec], missing: list[str],
                 ignored: list[tuple[str, str]]) -> None:
    """Refuse sequences without ground truth, and a folder without runs."""
    if missing:
        where = f"{root}/<sequence>/groundtruth.<ext>"
        if seq_root is not None:
            where += f" or {seq_root}/<sequence>/{IBISCAPE_GT.as_posix()}"
        else:
            where += " (or give {0}, a folder of IBISCape sequences)"
        raise IbiscapeError(
            f"no ground truth for sequence{'s' if len(missing) > 1 else ''} "
            f"{', '.join(missing[:10])}{' ...' if len(missing) > 10 else ''}; expected {where}",
            hint=() if seq_root is not None else (Remedy("sequences_dir"),))
    if not runs:
        detail = "; ".join(f"{p}: {why}" for p, why in ignored[:3])
        raise IbiscapeError(
            f"{root}: no runs found; expected RUNS_DIR/<sequence>/<algorithm>/<trial>/"
            f"<trajectory file>" + (f" (ignored: {detail})" if detail else "")
        )


def discover_runs(
    runs_dir: str | os.PathLike[str], *, sequences_dir: str | os.PathLike[str] | None = None
) -> RunsLayout:
    """Find every run of ``runs_dir`` and the ground truth of its sequences.

    Parameters
    ----------
    runs_dir
        ``<sequence>/<algorithm>/<trial>/<trajectory file>`` (see the module docstring).
    sequences_dir
        Folder of IBISCape-layout sequences: ``<sequence>/vehicle_gt/groundtruth_sync.csv`` (and
        ``other_sensors/gnss.csv``) are used for sequences without ``groundtruth.<ext>``.

    Returns
    -------
    RunsLayout

    Raises
    ------
    IbiscapeError
        ``runs_dir`` is not a folder, holds no run, or a sequence with runs has no ground truth
        (the message lists them and says where the ground truth is looked for).
    """
    root = Path(runs_dir)
    if not root.is_dir():
        raise IbiscapeError(f"{root}: not a folder; expected RUNS_DIR/<sequence>/<algorithm>/"
                            "<trial>/<trajectory file>")
    seq_root = None if sequences_dir is None else Path(sequences_dir)
    if seq_root is not None and not seq_root.is_dir():
        raise IbiscapeError(f"{seq_root}: {{0}} is not a folder of IBISCape sequences",
                            hint=(Remedy("sequences_dir"),))
    runs: list[RunSpec] = []
    truths: dict[str, SequenceTruth] = {}
    ignored: list[tuple[str, str]] = []
    missing: list[str] = []
    for seq_dir in _visible(root):
        if not seq_dir.is_dir():
            ignored.append((str(seq_dir), "a file directly in the runs folder (expected "
                                          "<sequence>/ folders)"))
            continue
        if (seq_dir / "report.json").is_file():
            ignored.append((str(seq_dir), "an ibiscape-eval report folder (--out), not a "
                                          "sequence"))
            continue
        gts = _truth_in_runs(seq_dir)
        seq_runs = _sequence_runs(seq_dir, gts, ignored)
        if not seq_runs:
            ignored.append((str(seq_dir), "sequence folder without any <algorithm>/<trial>/"
                                          "<trajectory> run"))
            continue
        runs.extend(seq_runs)
        truth = _sequence_truth(seq_dir, gts, seq_root)
        if truth is None:
            missing.append(seq_dir.name)
        else:
            truths[seq_dir.name] = truth
    _check_found(root, seq_root, runs, missing, ignored)
    runs.sort(key=lambda r: (natural_key(r.sequence), natural_key(r.algorithm),
                             natural_key(r.trial)))
    return RunsLayout(str(root), tuple(runs), truths, tuple(ignored))
