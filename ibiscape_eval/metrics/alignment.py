"""Aligning an estimate to a reference: Umeyama SE(3)/Sim(3), 4-DoF yaw, origin, none."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from enum import Enum

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, IbiscapeWarning, Trajectory
from ibiscape_eval.core.rotations import quat_from_matrix
from ibiscape_eval.core.transforms import invert_transforms

from ._fast import trusted

__all__ = ["Alignment", "AlignmentResult", "align", "parse_alignment"]

FloatArray = npt.NDArray[np.float64]

_DEGENERATE_HINT = "use --align yaw or --align origin"


class Alignment(str, Enum):
    """How the estimate is brought into the reference frame before errors are computed."""

    NONE = "none"
    ORIGIN = "origin"
    SE3 = "se3"
    SIM3 = "sim3"
    YAW = "yaw"


def parse_alignment(method: str | Alignment) -> Alignment:
    """The :class:`Alignment` named by ``method``; an :class:`IbiscapeError` lists the choices."""
    try:
        return Alignment(method)
    except ValueError:
        choices = ", ".join(a.value for a in Alignment)
        raise IbiscapeError(f"unknown alignment {method!r}; choose one of {choices}") from None


@dataclass(frozen=True)
class AlignmentResult:
    """A similarity transform ``T_ref_est`` with scale: ``p_ref = scale * R @ p_est + t``.

    Attributes
    ----------
    method : str
        The :class:`Alignment` value used (``"none"``, ``"origin"``, ``"se3"``, ``"sim3"``,
        ``"yaw"``).
    transform : ndarray, shape (4, 4)
        ``T_ref_est``; its rotation block is a pure rotation (the scale is kept apart).
    scale : float
        Scale applied to the estimate's positions (1 unless ``sim3``).
    n_used : int
        Number of pose pairs the alignment was computed from.
    """

    method: str
    transform: FloatArray
    scale: float
    n_used: int

    def __post_init__(self) -> None:
        T = np.array(self.transform, dtype=np.float64)
        T.flags.writeable = False
        object.__setattr__(self, "transform", T)

    @property
    def rotation(self) -> FloatArray:
        """Rotation block ``R_ref_est``, shape ``(3, 3)``."""
        return self.transform[:3, :3]

    @property
    def translation_m(self) -> FloatArray:
        """Translation ``t``, metres, shape ``(3,)``."""
        return self.transform[:3, 3]

    def apply(self, traj: Trajectory) -> Trajectory:
        """A new trajectory with ``p' = s R p + t`` and ``q' = q_R * q`` (stamps unchanged)."""
        R = self.transform[:3, :3]
        # einsum rather than a BLAS product: faster for (N, 3) x (3, 3), no thread start-up.
        pos = np.einsum("ij,nj->ni", self.scale * R, traj.pos_m) + self.transform[:3, 3]
        # q_R * q is linear in q: one (N, 4) @ (4, 4) product instead of a batched Hamilton
        # product; the sign is then made canonical (w >= 0) as the constructor does.
        x, y, z, w = quat_from_matrix(R)
        left = np.array([[w, -z, y, x], [z, w, -x, y], [-y, x, w, z], [-x, -y, -z, w]])
        quat = np.einsum("ij,nj->ni", left, traj.quat_xyzw)
        quat *= np.where(quat[:, 3:4] < 0.0, -1.0, 1.0)
        return trusted(traj.stamps_ns, pos, quat, traj.name)

    def inverse(self) -> AlignmentResult:
        """The transform taking the reference to the estimate (``p_est = R^T (p_ref - t) / s``)."""
        T_inv = invert_transforms(self.transform)
        T_inv[:3, 3] /= self.scale
        return AlignmentResult(self.method, T_inv, 1.0 / self.scale, self.n_used)


def _se3(R: FloatArray, t: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def _check_spread(pts: FloatArray, who: str, method: str, *, planar: bool = False) -> None:
    """Raise when positions are all equal or (for 3-D alignment) collinear.

    The spread is read from the eigenvalues of the 3x3 scatter matrix of the centred points
    (their squared singular values): one pass over the data instead of an (N, 3) SVD.
    """
    c = pts - pts.mean(axis=0)
    if planar:
        c = c[:, :2]
    ev = np.linalg.eigvalsh(np.einsum("ni,nj->ij", c, c))[::-1]
    sv = np.sqrt(np.maximum(ev, 0.0))
    size = float(np.max(np.abs(pts))) if pts.size else 0.0
    tiny = 1e-12 * max(size, 1.0) * math.sqrt(pts.shape[0])
    what = "horizontal positions" if planar else "positions"
    if sv[0] <= tiny:
        raise DegenerateInputError(
            f"cannot align with {method}: all {pts.shape[0]} {what} of the {who} are equal; "
            f"{_DEGENERATE_HINT}"
        )
    # Squared values resolve a ratio down to ~1e-8; 1e-6 is a micrometre per metre.
    if not planar and (pts.shape[0] < 3 or sv[1] <= 1e-6 * sv[0]):
        raise DegenerateInputError(
            f"cannot align with {method}: the {pts.shape[0]} positions of the {who} are "
            f"collinear, so the rotation about that line is undetermined; {_DEGENERATE_HINT}"
        )


def umeyama(
    x: FloatArray, y: FloatArray, *, with_scale: bool
) -> tuple[FloatArray, FloatArray, float]:
    """Least-squares ``R, t, c`` with ``y ≈ c R x + t`` (Umeyama 1991), points as rows ``(N, 3)``.

    Computed on centred coordinates; the reflection is removed with the sign matrix of
    eq. 39-40.  The caller checks the geometry first.
    """
    mean_x = x.mean(axis=0)
    mean_y = y.mean(axis=0)
    xc = x - mean_x
    yc = y - mean_y
    n = x.shape[0]
    sigma_x = float(np.sum(xc * xc)) / n  # variance, eq. 36
    cov = np.einsum("ni,nj->ij", yc, xc) / n  # covariance matrix, eq. 38
    U, d, Vt = np.linalg.svd(cov)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0.0:  # eq. 39-40
        S[2, 2] = -1.0
    R = U @ S @ Vt  # eq. 40
    c = float(np.trace(np.diag(d) @ S)) / sigma_x if with_scale else 1.0  # eq. 42
    t = mean_y - c * (R @ mean_x)  # eq. 41
    return R, t, c


def _yaw(x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Closed-form 4-DoF alignment: rotation about world z plus translation, ``y ≈ Rz x + t``.

    With centred points the optimal angle maximises ``sum(yc_xy · Rz xc_xy)``, which gives
    ``atan2(sum(xc × yc)_z, sum(xc · yc)_xy)``; z only enters the translation.
    """
    mean_x = x.mean(axis=0)
    mean_y = y.mean(axis=0)
    xc = x - mean_x
    yc = y - mean_y
    s = float(np.sum(xc[:, 0] * yc[:, 1] - xc[:, 1] * yc[:, 0]))
    c = float(np.sum(xc[:, 0] * yc[:, 0] + xc[:, 1] * yc[:, 1]))
    theta = math.atan2(s, c)
    cz, sz = math.cos(theta), math.sin(theta)
    R = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return R, mean_y - R @ mean_x


def align(
    est: Trajectory,
    ref: Trajectory,
    *,
    method: str | Alignment = "se3",
    n_align: int | None = None,
) -> AlignmentResult:
    """Transform that best maps the estimate onto the reference (positions only).

    Parameters
    ----------
    est, ref : Trajectory
        Already matched row by row (see :func:`associate`), same length ``N``.
    method : {"se3", "sim3", "yaw", "origin", "none"}
        ``se3``: Umeyama rotation + translation; ``sim3``: also a scale; ``yaw``: 4-DoF,
        translation and rotation about the world z axis (gravity along -z), closed form;
        ``origin``: the first estimated pose mapped onto the first reference pose (like evo's
        ``align_origin``); ``none``: identity.
    n_align : int, optional
        Use only the first ``n_align`` pairs (all by default).

    Returns
    -------
    AlignmentResult
        ``T_ref_est`` and the scale; apply it with :meth:`AlignmentResult.apply`.

    Raises
    ------
    DegenerateInputError
        All positions equal or collinear (``se3``/``sim3``), all horizontal positions equal
        (``yaw``); the message suggests ``--align yaw`` or ``--align origin``.

    References
    ----------
    S. Umeyama, "Least-squares estimation of transformation parameters between two point
    patterns", IEEE TPAMI 13(4), 1991.
    """
    m = parse_alignment(method)
    if len(est) != len(ref):
        raise IbiscapeError(
            f"align needs matched trajectories of equal length, got {len(est)} and {len(ref)}; "
            "call associate() first"
        )
    n = len(est)
    if n == 0:
        raise DegenerateInputError("cannot align empty trajectories")
    if n_align is None:
        n_used = n
    else:
        if int(n_align) != n_align or n_align < 1:
            raise IbiscapeError(f"n_align must be a positive integer, got {n_align!r}")
        n_used = int(n_align)
        if n_used > n:
            warnings.warn(
                f"n_align={n_used} exceeds the {n} matched poses; aligning on all of them",
                IbiscapeWarning,
                stacklevel=2,
            )
            n_used = n
    if m is Alignment.NONE:
        return AlignmentResult(m.value, np.eye(4), 1.0, 0)
    if m is Alignment.ORIGIN:
        T = ref.matrices()[0] @ invert_transforms(est.matrices()[0])
        return AlignmentResult(m.value, T, 1.0, 1)
    x = est.pos_m[:n_used]
    y = ref.pos_m[:n_used]
    if m is Alignment.YAW:
        _check_spread(x, "estimate", m.value, planar=True)
        _check_spread(y, "reference", m.value, planar=True)
        R, t = _yaw(x, y)
        return AlignmentResult(m.value, _se3(R, t), 1.0, n_used)
    _check_spread(x, "estimate", m.value)
    _check_spread(y, "reference", m.value)
    R, t, c = umeyama(x, y, with_scale=m is Alignment.SIM3)
    if not (math.isfinite(c) and c > 0.0):
        raise DegenerateInputError(
            f"sim3 alignment gave an invalid scale {c!r}; {_DEGENERATE_HINT}"
        )
    return AlignmentResult(m.value, _se3(R, t), c, n_used)
