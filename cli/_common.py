"""What every command shares: error mapping (a library error's remedies printed as flags by
:func:`cli_flag`), warnings on stderr, JSON output, and the options several commands take
(trajectory inputs as one typed :class:`TrajectoryInputs`, alignments, event formats, sensor
sizes).  Commands import this module and the library, never each other.

No math here.  Commands parse options, call ``ibiscape_eval.io`` and one library function, print.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import re
import sys
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import click

from ibiscape_eval.core.errors import IbiscapeError, IbiscapeWarning, Remedy

F = TypeVar("F", bound=Callable[..., Any])

__all__ = [
    "ALIGNMENTS",
    "EVENT_FORMAT_CHOICES",
    "TrajectoryInputs",
    "check_tf_topic",
    "cli_flag",
    "cli_terms",
    "collect",
    "echo_json",
    "fail",
    "info",
    "parse_sensor_size",
    "read_trajectories",
    "show_doc_warnings",
    "strict_json",
    "trajectory_options",
    "user_errors",
]


def fail(message: str) -> None:
    """Print one line on stderr and exit with status 2."""
    click.echo(f"error: {' '.join(str(message).split())}", err=True)
    sys.exit(2)


def info(message: str) -> None:
    """A one-line note on stderr (format chosen, poses dropped ...), never on stdout."""
    click.echo(message, err=True)


def _show_warning(
    message: Any, category: Any, filename: Any, lineno: Any, file: Any = None, line: Any = None
) -> None:
    label = "warning" if issubclass(category, IbiscapeWarning) else category.__name__
    click.echo(f"{label}: {cli_terms(' '.join(str(message).split()))}", err=True)


def user_errors(func: F) -> F:
    """Decorate a command: map :class:`IbiscapeError` and OS errors on user files to one stderr line
    and exit status 2; show library warnings as one line each on stderr."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        old = warnings.showwarning
        warnings.showwarning = _show_warning
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("always", IbiscapeWarning)
                warnings.showwarning = _show_warning
                return func(*args, **kwargs)
        except IbiscapeError as e:
            fail(e.render(cli_flag))
        except FileNotFoundError as e:
            fail(f"{e.filename}: no such file or directory; check the path")
        except IsADirectoryError as e:
            fail(f"{e.filename}: is a directory, expected a file")
        except PermissionError as e:
            fail(f"{e.filename}: permission denied")
        except OSError as e:  # symbolic-link loops, full disks, devices ...
            from ibiscape_eval.io.paths import os_error_message

            fail(os_error_message(e))
        except MemoryError:
            fail("out of memory; process the input in smaller pieces")
        finally:
            warnings.showwarning = old

    return wrapper  # type: ignore[return-value]


def echo_json(doc: Any) -> None:
    """Write one strict JSON document on stdout (``allow_nan=False``).

    numpy scalars and arrays are converted; a non-finite number becomes ``null`` and its place is
    listed under the top-level key ``"non_finite"`` (JSON pointer -> ``"nan"``, ``"inf"`` or
    ``"-inf"``), so a reader knows why the value is missing.
    """
    text = json.dumps(strict_json(doc), indent=2, allow_nan=False)
    click.echo(text)


def strict_json(doc: Any) -> Any:
    """``doc`` as plain JSON values with every non-finite float replaced by None; the replaced
    places are listed under ``"non_finite"`` when ``doc`` is a mapping."""
    import math

    import numpy as np

    missing: dict[str, str] = {}

    def clean(o: Any, where: str) -> Any:
        if isinstance(o, np.ndarray):
            o = o.tolist()
        elif isinstance(o, np.generic):
            o = o.item()
        if isinstance(o, float):
            if math.isfinite(o):
                return o
            missing[where or "/"] = "nan" if o != o else ("inf" if o > 0 else "-inf")
            return None
        if isinstance(o, dict):
            return {str(k): clean(v, f"{where}/{k}") for k, v in o.items()}
        if isinstance(o, list | tuple):
            return [clean(v, f"{where}/{i}") for i, v in enumerate(o)]
        if o is None or isinstance(o, bool | int | str):
            return o
        raise TypeError(f"not JSON serialisable: {type(o).__name__}")

    out = clean(doc, "")
    if missing and isinstance(out, dict):
        out = {**out, "non_finite": {**out.get("non_finite", {}), **missing}}
    return out


# --------------------------------------------------------------------------- trajectory inputs
# The options ate, rpe, drift and compare share: one definition, so every command reads, pairs
# and selects poses the same way.

_LIB_TERMS = (
    (re.compile(r'align="(\w+)"'), r"--align \1"),
    (re.compile(r"lengths_pct=\[([\d.,\s]+)\]"), lambda m: "--lengths-pct " + ",".join(
        v.strip() for v in m.group(1).split(","))),
    (re.compile(r"\blengths_m\b"), "--lengths"),
    (re.compile(r"\bn_align\b"), "--n-align"),
    (re.compile(r"\bmax_diff_s\b"), "--max-diff-s"),
)


def cli_terms(message: str) -> str:
    """A library warning in command-line terms: ``align="yaw"`` -> ``--align yaw``,
    ``lengths_pct=[10, 20]`` -> ``--lengths-pct 10,20``."""
    for pattern, repl in _LIB_TERMS:
        message = pattern.sub(repl, message)
    return message


# A library option whose flag is not ``--`` + its name with dashes, and the placeholder shown when
# a remedy suggests no value.
_FLAG_NAMES = {"lengths_m": "--lengths", "apply_path": "--apply", "fmt": "--format", "imu_yaml": "--imu", "topic_id": "--topic",
               "align_by_algorithm": "--align", "sequences_dir": "--sequences"}
_METAVARS = {"sensor_size": "WxH", "random_walk_fallback": "GYRO,ACCEL", "imu_yaml": "imu.yaml",
             "calib": "camchain-imucam.yaml", "topic_id": "ID", "target": "target.yaml"}


def cli_flag(remedy: Remedy) -> str:
    """A library error's remedy as the command line's flag: ``Remedy("align", "yaw")`` ->
    ``--align yaw``, ``Remedy("force", flag=True)`` -> ``--force``."""
    flag = _FLAG_NAMES.get(remedy.option, "--" + remedy.option.replace("_", "-"))
    value = remedy.value if remedy.value is not None else _METAVARS.get(remedy.option)
    return flag if remedy.flag or value is None else f"{flag} {value}"


#: the --align choices of every trajectory command
ALIGNMENTS = ("none", "origin", "se3", "sim3", "yaw")
#: the --format choices of the event commands
EVENT_FORMAT_CHOICES = ("auto", "ibiscape", "npz", "text", "hdf5", "aedat4", "bag")


def parse_sensor_size(text: str | None) -> tuple[int, int] | None:
    """``--sensor-size "346x260"`` -> (346, 260)."""
    if text is None:
        return None
    m = re.fullmatch(r"\s*(\d+)\s*[xX,]\s*(\d+)\s*", text)
    if not m or int(m.group(1)) == 0 or int(m.group(2)) == 0:
        raise IbiscapeError(f"--sensor-size must look like WIDTHxHEIGHT (e.g. 346x260), got {text!r}")
    return int(m.group(1)), int(m.group(2))


def check_tf_topic(src: Path, topic: str) -> None:
    """A TF topic named without its frames (``--topic /tf``): one line suggesting the
    ``/tf:parent.child`` forms the bag offers, instead of a list of message types."""
    if ":" in topic or topic.rstrip("/").split("/")[-1] not in ("tf", "tf_static"):
        return
    from ibiscape_eval.io.bag import list_pose_topics

    offered = [t for t in list_pose_topics(src) if t.startswith(topic.rstrip("/") + ":")]
    if not offered:
        return
    raise IbiscapeError(
        f"{src}: {topic} is a TF topic holding several transforms; name one as "
        f"TOPIC:parent.child, e.g. --topic {offered[0]} (offered: {', '.join(offered)})")


def _options(func: Callable[..., Any], opts: list[Any]) -> Callable[..., Any]:
    for opt in reversed(opts):
        func = opt(func)
    return func


def _motion(ctx: Any, param: Any, value: Any) -> tuple[float, float] | None:
    if not value:
        return None
    d, a = value
    if d < 0 or a < 0:
        raise click.BadParameter("both thresholds must be >= 0 (metres, degrees)")
    return float(d), float(a)


def collect(cls: type[Any], name: str) -> Callable[[F], F]:
    """Decorate a command: the parameters named like the fields of the dataclass ``cls`` reach
    it as one ``cls`` object, keyword ``name`` (typed option groups instead of ``**kwargs``)."""
    names = [f.name for f in dataclasses.fields(cls)]

    def decorate(func: F) -> F:
        @functools.wraps(func)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            group = cls(**{n: kwargs.pop(n) for n in names})
            return func(*args, **kwargs, **{name: group})

        return wrapper  # type: ignore[return-value]

    return decorate


@dataclass(frozen=True)
class TrajectoryInputs:
    """The reading, association and selection options of every trajectory command
    (:func:`trajectory_options`)."""

    fmt: str
    format_est: str | None
    format_ref: str | None
    topic: str | None
    topic_est: str | None
    topic_ref: str | None
    times_est: Path | None
    times_ref: Path | None
    max_diff_s: float
    offset_s: float
    estimate_offset: bool
    interpolate: bool
    n_align: int | None
    t_start: float | None
    t_end: float | None
    downsample: int | None
    motion_filter: tuple[float, float] | None
    unit: str

    def selection(self, match: str) -> dict[str, Any]:
        """The library keyword arguments of association and selection."""
        return {
            "max_diff_s": self.max_diff_s,
            "offset_s": self.offset_s,
            "estimate_offset": self.estimate_offset,
            "interpolate": self.interpolate,
            "match": match,
            "n_align": self.n_align,
            "t_start_s": self.t_start,
            "t_end_s": self.t_end,
            "downsample": self.downsample,
            "motion_filter": self.motion_filter,
        }


def trajectory_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Reading (formats, bag topics, KITTI times), association (max difference, offset,
    interpolation), evo's pose selection (time range, downsampling, motion filter), alignment
    window and output unit: the options every trajectory metric command takes, passed to the
    command as ``inputs`` (:class:`TrajectoryInputs`)."""
    from ibiscape_eval.io.detect import TRAJECTORY_FORMATS

    formats = ("auto", *TRAJECTORY_FORMATS)
    return _options(collect(TrajectoryInputs, "inputs")(func), [
        click.option("--format", "fmt", type=click.Choice(formats), default="auto",
                     show_default=True,
                     help="Format of every file (auto detects from name and content)."),
        click.option("--format-est", type=click.Choice(formats), default=None,
                     help="Format of the estimate(s), overrides --format."),
        click.option("--format-ref", type=click.Choice(formats), default=None,
                     help="Format of REF, overrides --format."),
        click.option("--topic", default=None,
                     help="Bag topic for every file (tf: '/tf:parent.child')."),
        click.option("--topic-est", default=None, help="Bag topic of the estimate(s)."),
        click.option("--topic-ref", default=None, help="Bag topic of REF."),
        click.option("--times-est", type=click.Path(path_type=Path), default=None,
                     help="KITTI times file (s, one per line) of the estimate."),
        click.option("--times-ref", type=click.Path(path_type=Path), default=None,
                     help="KITTI times file (s, one per line) of REF."),
        click.option("--max-diff-s", type=click.FloatRange(min=0.0), default=0.01,
                     show_default=True,
                     help="Largest time difference of an associated pose pair, seconds."),
        click.option("--offset-s", type=float, default=0.0, show_default=True,
                     help="Constant time offset added to the estimate's stamps, seconds."),
        click.option("--estimate-offset", is_flag=True,
                     help="Estimate the time offset between estimate and REF and report it."),
        click.option("--interpolate", is_flag=True,
                     help="Interpolate the denser trajectory at the sparser one's stamps."),
        click.option("--n-align", type=click.IntRange(min=1), default=None,
                     help="Align on the first N matched poses only."),
        click.option("--t-start", type=float, default=None,
                     help="Use reference poses stamped at or after this time (absolute "
                     "seconds of the file, as evo's --t_start)."),
        click.option("--t-end", type=float, default=None,
                     help="Use reference poses stamped at or before this time (absolute s)."),
        click.option("--downsample", type=click.IntRange(min=1), default=None,
                     help="Evenly downsample both trajectories to at most N poses first (evo)."),
        click.option("--motion-filter", type=(float, float), default=None, callback=_motion,
                     metavar="METRES DEGREES",
                     help="Keep a pose only after moving METRES or turning DEGREES since the "
                     "last kept one (evo's --motion_filter), both trajectories."),
        click.option("--change-unit", "unit", type=click.Choice(("m", "cm", "mm")),
                     default="m", show_default=True,
                     help="Unit of translation errors in the table, JSON and CSV (evo)."),
    ])


def read_trajectories(
    ests: Sequence[Path], ref: Path, o: TrajectoryInputs
) -> tuple[list[Any], Any, str, str, list[str]]:
    """Read the estimates and the reference with the shared options: say which formats were
    detected, warn when an estimate looks like the ground truth, choose time or index pairing.

    Returns the estimates, the reference, the match mode, the reference's format and the
    warnings printed (for the JSON ``warnings`` list)."""
    from ibiscape_eval.io import detect_trajectory_format, has_timestamps, read_trajectory
    from ibiscape_eval.metrics import choose_match
    from ibiscape_eval.metrics.order import swap_warning

    from .startup import numba_startup

    if o.times_est is not None and len(ests) > 1:
        raise click.UsageError("--times-est names the times of one estimate; give the "
                               "estimates one at a time, or convert them with their times first")

    def load(path: Path, side: str) -> tuple[Any, str, bool]:
        fmt = getattr(o, f"format_{side}") or o.fmt
        if fmt == "auto":
            fmt = detect_trajectory_format(path)
            info(f"{path}: format {fmt} (detected; force another with --format-{side})")
        times = getattr(o, f"times_{side}")
        topic = getattr(o, f"topic_{side}") or o.topic
        if fmt == "bag" and topic is not None:
            check_tf_topic(path, topic)
        traj = read_trajectory(path, fmt, topic=topic,
                               times_path=None if times is None else str(times), name=path.name)
        return traj, fmt, has_timestamps(fmt, times)

    notes: list[str] = []
    with numba_startup():
        loaded = [load(p, "est") for p in ests]  # in the order given: estimates, then REF
        ref_t, ref_fmt, ref_timed = load(ref, "ref")
        est_ts, match = [], None
        for p, (t, f, timed) in zip(ests, loaded, strict=True):
            warn = swap_warning(t, ref_t, est_path=p, ref_path=ref, fmt_est=f, fmt_ref=ref_fmt)
            if warn:
                notes.append(warn)
                info(f"warning: {warn}")
            m = choose_match(timed, ref_timed)
            if match is not None and m != match:
                raise click.UsageError("mixing timed and untimed (KITTI) estimates")
            match = m
            est_ts.append(t)
    if match == "index":
        info("KITTI poses without a times file: pairing poses by index; their stamps are "
             "synthetic, so results use pose indices, not times")
    return est_ts, ref_t, match or "time", ref_fmt, notes


def show_doc_warnings(doc: dict[str, Any], extra: Sequence[str] = ()) -> dict[str, Any]:
    """``doc`` with its ``warnings`` in command-line terms and ``extra`` (the reading warnings)
    in front."""
    if "warnings" in doc or extra:
        doc["warnings"] = [*extra, *(cli_terms(w) for w in doc.get("warnings", []))]
    return doc
