"""Batched SO(3) operations on unit quaternions in **x, y, z, w** order (scipy's).

Every function takes arrays of shape ``(N, 4)`` (or ``(4,)``, broadcast) and works on all rows at
once.  Rotation matrices are ``(N, 3, 3)``.  Quaternions are Hamilton quaternions: ``q1 * q2``
applies ``q2`` first, and ``R(q) v`` rotates a vector of the body frame into the world frame when
``q`` is the orientation part of ``T_world_body``.

These are thin wrappers over :class:`scipy.spatial.transform.Rotation` that keep the project's
names and array conventions (rows of ``(N, 4)`` or a single ``(4,)``); the fused numba kernels of
``metrics`` repeat the formulas where one pass over millions of poses matters.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

__all__ = [
    "angle_rad_from_quat",
    "matrix_from_quat",
    "quat_conjugate",
    "quat_from_matrix",
    "quat_from_rotvec",
    "quat_from_yaw",
    "quat_multiply",
    "quat_normalize",
    "quat_rotate",
    "quat_slerp",
    "rotvec_from_quat",
]

FloatArray = npt.NDArray[np.float64]


def _rot(quat_xyzw: npt.ArrayLike) -> tuple[Rotation, tuple[int, ...]]:
    """A scipy Rotation over all rows of ``quat_xyzw`` and its leading shape."""
    q = np.asarray(quat_xyzw, dtype=np.float64)
    return Rotation.from_quat(np.array(q.reshape(-1, 4))), q.shape[:-1]


def _broadcast_rows(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """Both arrays as writable C-contiguous rows over their broadcast leading shape (scipy's
    Cython code refuses read-only buffers, and :class:`Trajectory` arrays are read-only)."""
    lead = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
    return (np.array(np.broadcast_to(a, (*lead, a.shape[-1])).reshape(-1, a.shape[-1])),
            np.array(np.broadcast_to(b, (*lead, b.shape[-1])).reshape(-1, b.shape[-1])), lead)


def quat_normalize(quat_xyzw: npt.ArrayLike) -> FloatArray:
    """Return unit quaternions with a non-negative w (the same rotation, a canonical sign)."""
    q = np.asarray(quat_xyzw, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., 3:4] < 0.0, -q, q)


def quat_conjugate(quat_xyzw: npt.ArrayLike) -> FloatArray:
    """Inverse rotation of unit quaternions."""
    q = np.array(quat_xyzw, dtype=np.float64)
    q[..., :3] *= -1.0
    return q


def quat_multiply(q1_xyzw: npt.ArrayLike, q2_xyzw: npt.ArrayLike) -> FloatArray:
    """Hamilton product ``q1 * q2`` (rotation ``q2`` first, then ``q1``), broadcast over rows.

    (numpy, not scipy: composing 1M rotations measured 175 ms here against 1230 ms with
    ``Rotation.__mul__``, on RPE/offset/IBISCape-writer paths that see every pose.)
    """
    a = np.asarray(q1_xyzw, dtype=np.float64)
    b = np.asarray(q2_xyzw, dtype=np.float64)
    x1, y1, z1, w1 = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    x2, y2, z2, w2 = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        (
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ),
        axis=-1,
    )


def matrix_from_quat(quat_xyzw: npt.ArrayLike) -> FloatArray:
    """Rotation matrices, shape ``(N, 3, 3)``, from unit quaternions ``(N, 4)``."""
    r, lead = _rot(quat_xyzw)
    return r.as_matrix().reshape(*lead, 3, 3)


def quat_from_matrix(R: npt.ArrayLike) -> FloatArray:
    """Unit quaternions (w >= 0) from rotation matrices ``(N, 3, 3)``.

    Uses the numerically stable branch selection of Shepperd (1978): the largest of the four
    candidate diagonal combinations is used as the divisor, row by row.  (numpy, not scipy: 1M
    matrices measured 630-730 ms here against 1080-1240 ms with ``Rotation.from_matrix``; KITTI
    reading converts every pose.)
    """
    M = np.asarray(R, dtype=np.float64)
    m00, m11, m22 = M[..., 0, 0], M[..., 1, 1], M[..., 2, 2]
    trace = m00 + m11 + m22
    cand = np.stack((m00, m11, m22, trace), axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty((*M.shape[:-2], 4))
    # Branch w largest.
    s = np.sqrt(np.maximum(1.0 + trace, 0.0)) * 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        qw = np.stack(
            (
                (M[..., 2, 1] - M[..., 1, 2]) / s,
                (M[..., 0, 2] - M[..., 2, 0]) / s,
                (M[..., 1, 0] - M[..., 0, 1]) / s,
                0.25 * s,
            ),
            axis=-1,
        )
        s0 = np.sqrt(np.maximum(1.0 + m00 - m11 - m22, 0.0)) * 2.0
        qx = np.stack(
            (
                0.25 * s0,
                (M[..., 0, 1] + M[..., 1, 0]) / s0,
                (M[..., 0, 2] + M[..., 2, 0]) / s0,
                (M[..., 2, 1] - M[..., 1, 2]) / s0,
            ),
            axis=-1,
        )
        s1 = np.sqrt(np.maximum(1.0 - m00 + m11 - m22, 0.0)) * 2.0
        qy = np.stack(
            (
                (M[..., 0, 1] + M[..., 1, 0]) / s1,
                0.25 * s1,
                (M[..., 1, 2] + M[..., 2, 1]) / s1,
                (M[..., 0, 2] - M[..., 2, 0]) / s1,
            ),
            axis=-1,
        )
        s2 = np.sqrt(np.maximum(1.0 - m00 - m11 + m22, 0.0)) * 2.0
        qz = np.stack(
            (
                (M[..., 0, 2] + M[..., 2, 0]) / s2,
                (M[..., 1, 2] + M[..., 2, 1]) / s2,
                0.25 * s2,
                (M[..., 1, 0] - M[..., 0, 1]) / s2,
            ),
            axis=-1,
        )
    q = np.where(
        (k == 3)[..., None],
        qw,
        np.where((k == 0)[..., None], qx, np.where((k == 1)[..., None], qy, qz)),
    )
    return quat_normalize(q)


def quat_rotate(quat_xyzw: npt.ArrayLike, vec: npt.ArrayLike) -> FloatArray:
    """Rotate vectors ``(N, 3)`` by unit quaternions ``(N, 4)``: ``R(q) v``."""
    q, v, lead = _broadcast_rows(np.asarray(quat_xyzw, dtype=np.float64),
                                 np.asarray(vec, dtype=np.float64))
    return Rotation.from_quat(q).apply(v).reshape(*lead, 3)


def angle_rad_from_quat(quat_xyzw: npt.ArrayLike) -> FloatArray:
    """Rotation angle in [0, pi] of unit quaternions, accurate for small and large angles."""
    r, lead = _rot(quat_xyzw)
    return r.magnitude().reshape(lead)


def rotvec_from_quat(quat_xyzw: npt.ArrayLike) -> FloatArray:
    """Rotation vectors (axis * angle, rad), shape ``(N, 3)``.

    (numpy, not scipy: 1M rows measured 270 ms here against 570 ms with
    ``Rotation.as_rotvec``, on the IBISCape ground-truth writer path.)
    """
    q = quat_normalize(quat_xyzw)
    n = np.linalg.norm(q[..., :3], axis=-1)
    angle = 2.0 * np.arctan2(n, q[..., 3])
    # angle / sin(angle/2) -> 2 as n -> 0
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(n > 1e-12, angle / n, 2.0)
    return q[..., :3] * scale[..., None]


def quat_from_rotvec(rotvec: npt.ArrayLike) -> FloatArray:
    """Unit quaternions from rotation vectors (axis * angle, rad) ``(N, 3)``."""
    v = np.asarray(rotvec, dtype=np.float64)
    return Rotation.from_rotvec(np.array(v.reshape(-1, 3))).as_quat().reshape(*v.shape[:-1], 4)


def quat_from_yaw(yaw_rad: npt.ArrayLike) -> FloatArray:
    """Quaternions of rotations about +z by ``yaw_rad``."""
    y = np.asarray(yaw_rad, dtype=np.float64)
    return Rotation.from_euler("z", y.reshape(-1, 1)).as_quat().reshape(*y.shape, 4)


def quat_slerp(q0_xyzw: npt.ArrayLike, q1_xyzw: npt.ArrayLike, t: npt.ArrayLike) -> FloatArray:
    """Spherical linear interpolation, row by row, taking the shorter arc; ``t`` in [0, 1].

    (numpy, not scipy: 1M rows measured 410 ms here against 3840 ms as
    ``q0 * exp(t log(q0^-1 q1))`` with ``Rotation``; ``--interpolate`` sees every pose.)
    """
    a = np.asarray(q0_xyzw, dtype=np.float64)
    b = np.asarray(q1_xyzw, dtype=np.float64)
    tt = np.asarray(t, dtype=np.float64)[..., None]
    dot = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(dot < 0.0, -b, b)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        w0 = np.where(small, 1.0 - tt, np.sin((1.0 - tt) * theta) / sin_theta)
        w1 = np.where(small, tt, np.sin(tt * theta) / sin_theta)
    return quat_normalize(w0 * a + w1 * b)
