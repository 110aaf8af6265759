"""The :class:`Trajectory` value type: timestamped poses ``T_world_body``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .errors import IbiscapeError
from .rotations import matrix_from_quat, quat_normalize
from .time import s_from_ns
from .transforms import matrices_from_pose, pose_from_matrices

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["SYNTHETIC_PERIOD_NS", "Trajectory"]

#: Period of made-up stamps (KITTI poses without a times file): pose ``i`` is stamped ``i * 0.1 s``.
SYNTHETIC_PERIOD_NS = 100_000_000


def _frozen(a: np.ndarray, *, owned: bool = False) -> np.ndarray:
    """A read-only contiguous array; copies writeable input so the caller's array stays untouched
    (``owned``: ``a`` was made here, nobody else holds it, so no copy is needed)."""
    if owned and a.flags.c_contiguous:
        a.flags.writeable = False
    elif a.flags.writeable or not a.flags.c_contiguous:
        a = np.array(a, order="C", copy=True)
        a.flags.writeable = False
    return a


def _finite_sum(a: np.ndarray) -> bool:
    with np.errstate(over="ignore", invalid="ignore"):
        return bool(np.isfinite(a.sum()))


#: Quaternions whose norm is this close to 1 (and with w >= 0) are not normalised again.
_UNIT_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Timestamped poses ``T_world_body``; immutable (its arrays are read-only).

    Parameters
    ----------
    stamps_ns : ndarray, shape (N,), int64
        Timestamps in nanoseconds, strictly increasing.
    pos_m : ndarray, shape (N, 3), float64
        Positions of the body origin in the world frame, metres.
    quat_xyzw : ndarray, shape (N, 4), float64
        Unit quaternions x, y, z, w of the body orientation in the world frame.  They are
        renormalised; rows further than 1e-3 from unit norm are rejected.
    name : str
        A label for tables and plots (usually the file name).
    stamps_synthetic : bool
        True when the stamps were made up from the pose index (KITTI poses without a times file:
        pose ``i`` at ``i * SYNTHETIC_PERIOD_NS``); results and plots then speak of pose indices,
        never of seconds.

    Readers in :mod:`ibiscape_eval.io` validate files and report the offending line; this
    constructor checks shapes, finiteness and ordering so that every metric can rely on them.
    """

    stamps_ns: npt.NDArray[np.int64]
    pos_m: npt.NDArray[np.float64]
    quat_xyzw: npt.NDArray[np.float64]
    name: str = ""
    stamps_synthetic: bool = False

    def __post_init__(self) -> None:
        stamps = np.asarray(self.stamps_ns)
        if stamps.dtype.kind not in "iu":
            raise IbiscapeError(
                f"trajectory {self.name!r}: stamps_ns must be integer nanoseconds, got {stamps.dtype}"
            )
        stamps = stamps.astype(np.int64, copy=False)
        pos = np.asarray(self.pos_m, dtype=np.float64)
        quat = np.asarray(self.quat_xyzw, dtype=np.float64)
        n = stamps.shape[0] if stamps.ndim == 1 else -1
        if stamps.ndim != 1 or pos.shape != (n, 3) or quat.shape != (n, 4):
            raise IbiscapeError(
                f"trajectory {self.name!r}: expected stamps (N,), pos (N, 3), quat (N, 4); got "
                f"{stamps.shape}, {pos.shape}, {quat.shape}"
            )
        # A finite sum proves every value finite (one pass, no temporary); only an overflow or
        # a real NaN/inf takes the exact test.
        if not (_finite_sum(pos) or np.isfinite(pos).all()) or not (
            _finite_sum(quat) or np.isfinite(quat).all()
        ):
            bad = int(np.flatnonzero(~(np.isfinite(pos).all(1) & np.isfinite(quat).all(1)))[0])
            raise IbiscapeError(f"trajectory {self.name!r}: pose {bad} is not finite")
        if n > 1 and (stamps[1:] <= stamps[:-1]).any():
            i = int(np.flatnonzero(stamps[1:] <= stamps[:-1])[0])
            raise IbiscapeError(
                f"trajectory {self.name!r}: timestamps must increase strictly, "
                f"pose {i + 1} ({stamps[i + 1]} ns) follows {stamps[i]} ns"
            )
        # |norm - 1| computed in place (large trajectories: few full-size temporaries).
        off = np.einsum("ij,ij->i", quat, quat)
        np.sqrt(off, out=off)
        np.subtract(off, 1.0, out=off)
        np.abs(off, out=off)
        owned = False
        if n:
            if off.max() > 1e-3:
                i = int(np.flatnonzero(off > 1e-3)[0])
                norm = float(np.sqrt(np.einsum("j,j->", quat[i], quat[i])))
                raise IbiscapeError(
                    f"trajectory {self.name!r}: quaternion {i} has norm {norm:.6g}, "
                    "expected a unit quaternion"
                )
            # Already unit with w >= 0 (e.g. from a reader): kept as given, not divided again.
            if off.max() > _UNIT_TOL or quat[:, 3].min() < 0.0:
                quat = quat_normalize(quat)
                owned = True
        object.__setattr__(self, "stamps_ns", _frozen(stamps))
        object.__setattr__(self, "pos_m", _frozen(pos))
        object.__setattr__(self, "quat_xyzw", _frozen(quat, owned=owned))

    # -- construction -----------------------------------------------------------------------
    @classmethod
    def from_matrices(
        cls, stamps_ns: npt.ArrayLike, T_world_body: npt.ArrayLike, name: str = ""
    ) -> Trajectory:
        """Build from homogeneous matrices ``(N, 4, 4)``."""
        pos, quat = pose_from_matrices(T_world_body)
        return cls(np.asarray(stamps_ns, dtype=np.int64), pos, quat, name)

    def describe(self, role: str) -> str:
        """``role`` followed by the trajectory's name (its file), for messages: ``estimate 'est.txt'``."""
        return f"{role} {self.name!r}" if self.name else role

    def pose_index(self) -> npt.NDArray[np.int64]:
        """The pose index of every row: ``stamps_ns // SYNTHETIC_PERIOD_NS`` for synthetic stamps
        (the line number in the file, rows skipped by the reader included), else ``0..N-1``."""
        if self.stamps_synthetic:
            return self.stamps_ns // SYNTHETIC_PERIOD_NS
        return np.arange(len(self), dtype=np.int64)

    # -- views ------------------------------------------------------------------------------
    def __len__(self) -> int:
        return int(self.stamps_ns.shape[0])

    @property
    def stamps_s(self) -> npt.NDArray[np.float64]:
        """Timestamps in seconds (float64; for plots and text output)."""
        return s_from_ns(self.stamps_ns)

    @property
    def duration_s(self) -> float:
        """Time span from the first to the last pose, seconds."""
        return float(self.stamps_ns[-1] - self.stamps_ns[0]) / 1e9 if len(self) else 0.0

    def matrices(self) -> npt.NDArray[np.float64]:
        """Poses as homogeneous matrices ``T_world_body``, shape ``(N, 4, 4)``."""
        return matrices_from_pose(self.pos_m, self.quat_xyzw)

    def rotation_matrices(self) -> npt.NDArray[np.float64]:
        """Orientations as rotation matrices ``R_world_body``, shape ``(N, 3, 3)``."""
        return matrix_from_quat(self.quat_xyzw)

    def path_length_m(self) -> npt.NDArray[np.float64]:
        """Cumulative distance travelled along the positions, metres, shape ``(N,)``, from 0."""
        steps = np.linalg.norm(np.diff(self.pos_m, axis=0), axis=1)
        return np.concatenate(([0.0], np.cumsum(steps)))

    def take(self, index: npt.ArrayLike, name: str | None = None) -> Trajectory:
        """A new trajectory of the rows selected by an index array or boolean mask."""
        idx = np.asarray(index)
        stamps, pos, quat = (a[idx] for a in (self.stamps_ns, self.pos_m, self.quat_xyzw))
        for part in (stamps, pos, quat):  # fresh gathers: read-only, the constructor keeps them
            if isinstance(part, np.ndarray):
                part.flags.writeable = False
        return Trajectory(stamps, pos, quat, self.name if name is None else name,
                          self.stamps_synthetic)

    def with_name(self, name: str) -> Trajectory:
        """The same poses under another label."""
        return Trajectory(self.stamps_ns, self.pos_m, self.quat_xyzw, name, self.stamps_synthetic)

    def to_frame(self) -> pd.DataFrame:
        """A pandas DataFrame with columns ``stamp_ns, x_m, y_m, z_m, qx, qy, qz, qw``."""
        import pandas as pd

        return pd.DataFrame(
            {
                "stamp_ns": self.stamps_ns,
                "x_m": self.pos_m[:, 0],
                "y_m": self.pos_m[:, 1],
                "z_m": self.pos_m[:, 2],
                "qx": self.quat_xyzw[:, 0],
                "qy": self.quat_xyzw[:, 1],
                "qz": self.quat_xyzw[:, 2],
                "qw": self.quat_xyzw[:, 3],
            }
        )

    def __repr__(self) -> str:
        span = f", {self.duration_s:.3f} s" if len(self) else ""
        if self.stamps_synthetic:
            span = ", synthetic stamps"
        return f"Trajectory({self.name!r}, {len(self)} poses{span})"
