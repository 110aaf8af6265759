"""``read_trajectory`` / ``write_trajectory``: one entry point over every trajectory format."""

from __future__ import annotations

import os

from ibiscape_eval.core.errors import IbiscapeError, Remedy
from ibiscape_eval.core.trajectory import Trajectory

from .detect import TRAJECTORY_FORMATS, detect_trajectory_format

__all__ = ["WRITABLE_FORMATS", "has_timestamps", "read_trajectory", "write_trajectory"]

WRITABLE_FORMATS: tuple[str, ...] = ("tum", "kitti", "euroc", "ibiscape")


def has_timestamps(fmt: str, times_path: str | os.PathLike[str] | None = None) -> bool:
    """Whether :func:`read_trajectory` gives real timestamps for format ``fmt`` (not ``"auto"``):
    False only for KITTI poses without a times file (stamped by index at 10 Hz)."""
    return not (fmt.lower() == "kitti" and times_path is None)


def read_trajectory(
    path: str | os.PathLike[str],
    fmt: str = "auto",
    *,
    topic: str | None = None,
    times_path: str | os.PathLike[str] | None = None,
    name: str | None = None,
) -> Trajectory:
    """Read a trajectory in any supported format.

    Parameters
    ----------
    path
        File (or ROS 2 bag folder).
    fmt
        ``"auto"`` (see :func:`detect_trajectory_format`; nothing is printed), or one of
        ``"tum"``, ``"kitti"``, ``"euroc"``, ``"ibiscape"``, ``"bag"``.
    topic
        Bag topic or ``"/tf:parent.child"`` (bags only).
    times_path
        KITTI times file (seconds, one per line).  Without it KITTI poses are stamped at 10 Hz
        by index, ``i * 100_000_000`` ns, marked ``stamps_synthetic`` (metrics then report pose
        indices, not times), and the command line pairs trajectories by index.
    name
        Label of the trajectory; the file name (bags: the topic) by default.

    Returns
    -------
    Trajectory
        Poses ``T_world_body``: int64 ns stamps, positions (N, 3) m, quaternions (N, 4) x y z w.
        IBISCape files are converted from CARLA's left-handed frame to our right-handed one.

    Raises
    ------
    FormatError
        Any malformed input; the message names the file and line.
    IbiscapeError
        Unknown ``fmt`` or options that do not apply to it.
    """
    from .paths import check_input

    fmt = fmt.lower()
    check_input(path, "any" if fmt in ("auto", "bag") else "file")
    if times_path is not None:
        check_input(times_path, what="times file")
    if fmt == "auto":
        fmt = detect_trajectory_format(path)
    if fmt not in TRAJECTORY_FORMATS:
        raise IbiscapeError(f"unknown trajectory format {fmt!r}; use one of "
                            f"{', '.join(TRAJECTORY_FORMATS)} or auto")
    if topic is not None and fmt != "bag":
        raise IbiscapeError(f"{{0}} applies to bags only, but {path} is {fmt}",
                            hint=(Remedy("topic"),))
    if times_path is not None and fmt != "kitti":
        raise IbiscapeError(f"a times file applies to KITTI poses only, but {path} is {fmt}")
    if fmt == "tum":
        from .tum import read_tum

        return read_tum(path, name=name)
    if fmt == "kitti":
        from .kitti import read_kitti

        return read_kitti(path, times_path=times_path, name=name)
    if fmt == "euroc":
        from .euroc import read_euroc

        return read_euroc(path, name=name)
    if fmt == "ibiscape":
        from .ibiscape import read_ibiscape

        return read_ibiscape(path, name=name)
    from .bag import read_bag

    return read_bag(path, topic=topic, name=name)


def write_trajectory(
    path: str | os.PathLike[str],
    traj: Trajectory,
    fmt: str = "tum",
    *,
    times_path: str | os.PathLike[str] | None = None,
) -> None:
    """Write ``traj`` atomically as ``"tum"`` (seconds), ``"kitti"`` (poses only; stamps go to
    ``times_path`` if given), ``"euroc"`` (ns) or ``"ibiscape"`` (CARLA's left-handed frame;
    velocity, acceleration and angular rate estimated by finite differences).

    Stamps are written exactly from the int64 ns; floats with 15 significant digits.
    """
    fmt = fmt.lower()
    if fmt not in WRITABLE_FORMATS:
        raise IbiscapeError(f"cannot write trajectory format {fmt!r}; use one of "
                            f"{', '.join(WRITABLE_FORMATS)}")
    if times_path is not None and fmt != "kitti":
        raise IbiscapeError("a times file applies to KITTI output only")
    if fmt == "tum":
        from .tum import write_tum

        write_tum(path, traj)
    elif fmt == "kitti":
        from .kitti import write_kitti

        write_kitti(path, traj, times_path=times_path)
    elif fmt == "euroc":
        from .euroc import write_euroc

        write_euroc(path, traj)
    else:
        from .ibiscape import write_ibiscape

        write_ibiscape(path, traj)
