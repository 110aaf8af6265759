"""Aligning an estimate to a reference: Umeyama SE(3)/Sim(3), 4-DoF yaw, origin, none."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from enum import Enum
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, IbiscapeWarning, Trajectory
from ibiscape_eval.core.rotations import quat_from_matrix
from ibiscape_eval.core.transforms import invert_transforms

from ._fast import moments, transform_poses, trusted

__all__ = ["Alignment", "AlignmentResult", "align", "parse_alignment"]

FloatArray = npt.NDArray[np.float64]

_DEGENERATE_HINT = "use --align yaw or --align origin"
_EYE4 = np.eye(4)


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
        if self.scale == 1.0 and np.array_equal(self.transform, _EYE4):
            return trusted(traj.stamps_ns, traj.pos_m, traj.quat_xyzw, traj.name)
        pos, quat = transform_poses(traj.pos_m, traj.quat_xyzw, *self._coefficients())
        return trusted(traj.stamps_ns, pos, quat, traj.name)

    def _coefficients(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``s R``, ``t`` and the quaternion of ``R``: ``p' = (s R) p + t``, ``q' = q_R * q``."""
        R = self.transform[:3, :3]
        return (np.ascontiguousarray(self.scale * R), np.ascontiguousarray(self.transform[:3, 3]),
                quat_from_matrix(R))

    def to_dict(self) -> dict[str, Any]:
        """Strict JSON: ``method, scale, n_used, transform`` (4x4 nested lists)."""
        return {"method": self.method, "scale": float(self.scale), "n_used": int(self.n_used),
                "transform": self.transform.tolist()}

    def __repr__(self) -> str:
        from scipy.spatial.transform import Rotation

        t = self.translation_m
        angle = float(np.degrees(Rotation.from_matrix(self.rotation).magnitude()))
        return (f"AlignmentResult({self.method}, scale={self.scale:.6g}, rotation {angle:.4g} deg, "
                f"translation [{t[0]:.4g}, {t[1]:.4g}, {t[2]:.4g}] m, {self.n_used} pairs)")

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


class _Moments(NamedTuple):
    """First and second moments of the matched positions (see ``_fast.moments``)."""

    n: int
    mean_x: FloatArray
    mean_y: FloatArray
    sxx: FloatArray  # scatter of the centred estimate, X^T X
    syy: FloatArray
    syx: FloatArray  # Y^T X
    size_x: float  # largest absolute coordinate
    size_y: float


def _moments(x: FloatArray, y: FloatArray) -> _Moments:
    mx, my, sxx, syy, syx, big_x, big_y = moments(x, y)
    return _Moments(x.shape[0], mx, my, sxx, syy, syx, float(big_x), float(big_y))


def _check_scatter(
    scatter: FloatArray, size: float, n: int, who: str, method: str, *, planar: bool = False
) -> None:
    """Raise when positions are all equal or (for 3-D alignment) collinear.

    The spread is read from the eigenvalues of the 3x3 scatter matrix ``C^T C`` of the centred
    points (their squared singular values): one pass over the data instead of an (N, 3) SVD.
    """
    if planar:
        scatter = scatter[:2, :2]
    ev = np.linalg.eigvalsh(scatter)[::-1]
    sv = np.sqrt(np.maximum(ev, 0.0))
    tiny = 1e-12 * max(size, 1.0) * math.sqrt(n)
    what = "horizontal positions" if planar else "positions"
    if sv[0] <= tiny:
        raise DegenerateInputError(
            f"cannot align with {method}: all {n} {what} of the {who} are equal; "
            f"{_DEGENERATE_HINT}"
        )
    # Squared values resolve a ratio down to ~1e-8; 1e-6 is a micrometre per metre.
    if not planar and (n < 3 or sv[1] <= 1e-6 * sv[0]):
        raise DegenerateInputError(
            f"cannot align with {method}: the {n} positions of the {who} are "
            f"collinear, so the rotation about that line is undetermined; {_DEGENERATE_HINT}"
        )


def umeyama(
    x: FloatArray, y: FloatArray, *, with_scale: bool
) -> tuple[FloatArray, FloatArray, float]:
    """Least-squares ``R, t, c`` with ``y ≈ c R x + t`` (Umeyama 1991), points as rows ``(N, 3)``.

    Computed on centred coordinates; the reflection is removed with the sign matrix of
    eq. 39-40.  The caller checks the geometry first.
    """
    return _umeyama(_moments(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)),
                    with_scale=with_scale)


def _umeyama(m: _Moments, *, with_scale: bool) -> tuple[FloatArray, FloatArray, float]:
    sigma_x = float(np.trace(m.sxx)) / m.n  # variance, eq. 36
    cov = m.syx / m.n  # covariance matrix, eq. 38
    U, d, Vt = np.linalg.svd(cov)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0.0:  # eq. 39-40
        S[2, 2] = -1.0
    R = U @ S @ Vt  # eq. 40
    c = float(np.trace(np.diag(d) @ S)) / sigma_x if with_scale else 1.0  # eq. 42
    t = m.mean_y - c * (R @ m.mean_x)  # eq. 41
    return R, t, c


def _yaw(m: _Moments) -> tuple[FloatArray, FloatArray]:
    """Closed-form 4-DoF alignment: rotation about world z plus translation, ``y ≈ Rz x + t``.

    With centred points the optimal angle maximises ``sum(yc_xy · Rz xc_xy)``, which gives
    ``atan2(sum(xc × yc)_z, sum(xc · yc)_xy)``; z only enters the translation.
    """
    s = float(m.syx[1, 0] - m.syx[0, 1])
    c = float(m.syx[0, 0] + m.syx[1, 1])
    theta = math.atan2(s, c)
    cz, sz = math.cos(theta), math.sin(theta)
    R = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return R, m.mean_y - R @ m.mean_x


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
    mo = _moments(est.pos_m[:n_used], ref.pos_m[:n_used])  # one pass serves every check
    planar = m is Alignment.YAW
    _check_scatter(mo.sxx, mo.size_x, n_used, est.describe("estimate"), m.value, planar=planar)
    _check_scatter(mo.syy, mo.size_y, n_used, ref.describe("reference"), m.value, planar=planar)
    if planar:
        R, t = _yaw(mo)
        return AlignmentResult(m.value, _se3(R, t), 1.0, n_used)
    R, t, c = _umeyama(mo, with_scale=m is Alignment.SIM3)
    if not (math.isfinite(c) and c > 0.0):
        raise DegenerateInputError(
            f"sim3 alignment gave an invalid scale {c!r}; {_DEGENERATE_HINT}"
        )
    return AlignmentResult(m.value, _se3(R, t), c, n_used)
