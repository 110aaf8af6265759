"""Moving cars and pedestrians with closed-form paths.

Each agent goes round an axis-aligned rectangle at constant speed (cars along the lanes around a
block, pedestrians along the sidewalks), so its pose at any time is exact and cheap:
``s = (phase + speed t) mod perimeter`` picks the edge and the offset along it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["AGENT_CAR", "AGENT_PEDESTRIAN", "Agents"]

FloatArray = npt.NDArray[np.float64]
AGENT_CAR = 0
AGENT_PEDESTRIAN = 1


@dataclass(frozen=True, eq=False)
class Agents:
    """Moving agents on rectangular loops.

    Attributes
    ----------
    kind_id : ndarray, shape (A,), int
        ``AGENT_CAR`` (0) or ``AGENT_PEDESTRIAN`` (1).
    size_m : ndarray, shape (A, 3)
        Bounding box length (along the heading), width, height, metres.
    loop_min_m, loop_max_m : ndarray, shape (A, 2)
        Opposite corners of each agent's rectangular loop, world x, y, metres.
    clockwise : ndarray, shape (A,), bool
        Direction round the loop (seen from above).
    speed_m_s : ndarray, shape (A,)
    phase_m : ndarray, shape (A,)
        Arc length along the loop at ``epoch_ns``.
    epoch_ns : int
        Time at which every agent is at its ``phase_m``.
    """

    kind_id: npt.NDArray[np.int64]
    size_m: FloatArray
    loop_min_m: FloatArray
    loop_max_m: FloatArray
    clockwise: npt.NDArray[np.bool_]
    speed_m_s: FloatArray
    phase_m: FloatArray
    epoch_ns: int = 1_000_000_000_000

    @classmethod
    def none(cls) -> Agents:
        """No agents."""
        z2 = np.zeros((0, 2))
        return cls(
            np.zeros(0, np.int64), np.zeros((0, 3)), z2, z2.copy(), np.zeros(0, bool),
            np.zeros(0), np.zeros(0),
        )

    def __len__(self) -> int:
        return int(self.kind_id.shape[0])

    def _corners(self) -> FloatArray:
        lo, hi = self.loop_min_m, self.loop_max_m
        ccw = np.stack(
            (lo, np.stack((hi[:, 0], lo[:, 1]), -1), hi, np.stack((lo[:, 0], hi[:, 1]), -1), lo), 1
        )
        cw = ccw[:, ::-1]
        return np.where(self.clockwise[:, None, None], cw, ccw)  # (A, 5, 2)

    def poses_at(self, stamps_ns: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Positions and headings of every agent at the given stamps.

        Parameters
        ----------
        stamps_ns : array_like, shape (N,), int64

        Returns
        -------
        pos_m : ndarray, shape (A, N, 3)
            Ground contact point (z = 0), world frame, metres.
        yaw_rad : ndarray, shape (A, N)
            Heading from world x, radians.
        """
        st = np.asarray(stamps_ns)
        if st.ndim != 1 or not np.issubdtype(st.dtype, np.integer):
            raise IbiscapeError("stamps_ns must be a 1-D integer array of nanoseconds")
        A, N = len(self), len(st)
        if A == 0:
            return np.zeros((0, N, 3)), np.zeros((0, N))
        t_s = (st.astype(np.int64) - self.epoch_ns).astype(np.float64) * 1e-9
        corners = self._corners()
        edges = np.diff(corners, axis=1)  # (A, 4, 2)
        lens = np.hypot(edges[..., 0], edges[..., 1])
        cum = np.concatenate((np.zeros((A, 1)), np.cumsum(lens, axis=1)), axis=1)  # (A, 5)
        s = np.mod(self.phase_m[:, None] + self.speed_m_s[:, None] * t_s[None, :], cum[:, 4:5])
        k = np.clip((s[:, :, None] >= cum[:, None, 1:4]).sum(-1), 0, 3)  # edge index (A, N)
        start = np.take_along_axis(corners[:, :4], k[..., None], axis=1)
        e = np.take_along_axis(edges, k[..., None], axis=1)
        el = np.take_along_axis(lens, k, axis=1)
        u = s - np.take_along_axis(cum, k, axis=1)
        xy = start + (u / el)[..., None] * e
        pos = np.concatenate((xy, np.zeros((A, N, 1))), axis=-1)
        return pos, np.arctan2(e[..., 1], e[..., 0])

    def to_dict(self) -> dict[str, int]:
        """Counts for ``sequence.yaml``."""
        return {
            "cars": int(np.sum(self.kind_id == AGENT_CAR)),
            "pedestrians": int(np.sum(self.kind_id == AGENT_PEDESTRIAN)),
        }
