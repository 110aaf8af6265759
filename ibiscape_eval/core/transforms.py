"""Batched SE(3) / Sim(3) operations on homogeneous matrices ``(N, 4, 4)``.

``T_a_b`` maps coordinates in frame b to frame a: ``p_a = T_a_b @ p_b``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .rotations import matrix_from_quat, quat_from_matrix

__all__ = ["invert_transforms", "matrices_from_pose", "pose_from_matrices", "transform_points"]

FloatArray = npt.NDArray[np.float64]


def matrices_from_pose(pos_m: npt.ArrayLike, quat_xyzw: npt.ArrayLike) -> FloatArray:
    """Homogeneous matrices ``(N, 4, 4)`` from positions ``(N, 3)`` and quaternions ``(N, 4)``."""
    p = np.asarray(pos_m, dtype=np.float64)
    T = np.zeros((*p.shape[:-1], 4, 4))
    T[..., :3, :3] = matrix_from_quat(quat_xyzw)
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def pose_from_matrices(T: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Split ``(N, 4, 4)`` rigid transforms into positions ``(N, 3)`` and quaternions ``(N, 4)``.

    The rotation block is assumed orthonormal (re-orthonormalise KITTI-style text input first).
    """
    M = np.asarray(T, dtype=np.float64)
    return M[..., :3, 3].copy(), quat_from_matrix(M[..., :3, :3])


def invert_transforms(T: npt.ArrayLike) -> FloatArray:
    """Inverse of rigid transforms ``(N, 4, 4)`` (rotation transposed, no general matrix inverse)."""
    M = np.asarray(T, dtype=np.float64)
    R_t = np.swapaxes(M[..., :3, :3], -1, -2)
    out = np.zeros_like(M)
    out[..., :3, :3] = R_t
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", R_t, M[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def transform_points(T_a_b: npt.ArrayLike, pts_b: npt.ArrayLike) -> FloatArray:
    """Apply one ``(4, 4)`` transform (rotation block may include a scale) to points ``(N, 3)``."""
    M = np.asarray(T_a_b, dtype=np.float64)
    p = np.asarray(pts_b, dtype=np.float64)
    return p @ M[:3, :3].T + M[:3, 3]
