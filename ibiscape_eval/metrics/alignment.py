"""Aligning an estimate to a reference: Umeyama SE(3)/Sim(3), 4-DoF yaw, origin, none."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, IbiscapeWarning, Trajectory
from ibiscape_eval.core.errors import Remedy
from ibiscape_eval.core.numbers import finite_or_none
from ibiscape_eval.core.rotations import quat_from_matrix
from ibiscape_eval.core.transforms import invert_transforms

from ._fast import moments, transform_poses, trusted

__all__ = ["Alignment", "AlignmentConditioning", "AlignmentResult", "align", "conditioning_warnings",
           "parse_alignment"]

FloatArray = npt.NDArray[np.float64]

_DEGENERATE_HINT = (Remedy("align", "yaw"), Remedy("align", "origin"))  # "use {0} or {1}"
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


@dataclass(frozen=True, eq=False)
class AlignmentConditioning:
    """How well the alignment's rotation, translation and scale are determined by the positions.

    The alignment minimises ``sum |y_i - s R x_i - t|^2``; with independent position noise of
    ``sigma_pos_m`` per axis, the Hessian of that sum at the optimum gives the covariance of the
    parameters (Gauss-Newton / Fisher information, e.g. Kanatani 1994).  For the rotation,
    perturbed as ``R exp([theta]x)``, the Hessian is ``s (tr(M) I - sym(M)) / sigma^2`` with
    ``M = R^T Y^T X`` the cross-covariance of the centred points, so it is built from how the
    two point sets *agree*, not only from how far they spread: two noise clouds that do not
    correlate give a small ``M`` and a large sigma.  ``sigma_pos_m`` is estimated from the
    residual sum of squares with ``3 N - p`` degrees of freedom (``p`` = 6 se3, 7 sim3, 4 yaw),
    so it holds every unmodelled error too (drift included), and the covariances are inflated by
    the residuals' lag-1 autocorrelation (:attr:`variance_inflation`), since drift is not
    independent noise.  ``tests/metrics/test_metrics_conditioning.py`` measures their coverage
    over seeds: close to Gaussian for independent noise, conservative for correlated residuals.

    Attributes
    ----------
    method : str
        The alignment (``se3``, ``sim3``, ``yaw``).
    n_used : int
        Pose pairs the alignment was computed from.
    sigma_pos_m : float
        Residual position scatter per axis after the alignment, metres (NaN when ``3N <= p``).
    spread_m : ndarray, shape (3,)
        RMS extent of the centred estimate positions along their principal axes, metres,
        largest first (a 2 mm cloud has all three near 0.001).
    rotation_cov_rad2 : ndarray, shape (3, 3)
        Covariance of the alignment rotation, rad^2, as a small rotation vector in the
        reference frame (``yaw``: only the z entry is non-zero).
    rotation_sigma_deg : ndarray, shape (3,)
        1-sigma of the rotation about each principal axis of ``rotation_cov_rad2``, degrees,
        largest first; ``rotation_axes`` holds these axes (rows, reference frame).
    rotation_axes : ndarray, shape (3, 3)
        Unit axes (rows) of ``rotation_sigma_deg``.
    rotation_sigma_total_deg : float
        ``sqrt(trace(rotation_cov))`` in degrees: the expected RMS rotation angle by which the
        alignment itself is off; every pose's rotation error contains this constant part.
    translation_sigma_m : ndarray, shape (3,)
        1-sigma of each component of ``t`` (reference frame), metres (lever arm included).
    scale_sigma : float or None
        1-sigma of the scale (``sim3`` only).
    residual_rho : float
        Lag-1 autocorrelation of the residuals in time order (clipped to [0, 0.956]).
    variance_inflation : float
        ``(1 + rho) / (1 - rho)``: every covariance above is multiplied by it, because drift
        makes neighbouring residuals alike and the alignment then rests on fewer independent
        samples (without it, AR(1) residuals with rho 0.9 left the true rotation inside the
        1-sigma ellipsoid 4 % of the time instead of 68 %).
    """

    method: str
    n_used: int
    sigma_pos_m: float
    spread_m: FloatArray
    rotation_cov_rad2: FloatArray
    rotation_sigma_deg: FloatArray
    rotation_axes: FloatArray
    rotation_sigma_total_deg: float
    translation_sigma_m: FloatArray
    scale_sigma: float | None = None
    residual_rho: float = 0.0
    variance_inflation: float = 1.0

    def to_dict(self) -> dict[str, Any]:
        """Strict JSON (an undetermined value, infinite or NaN, becomes ``None``)."""

        return {
            "method": self.method,
            "n_used": int(self.n_used),
            "sigma_pos_m": finite_or_none(self.sigma_pos_m),
            "spread_m": [finite_or_none(v) for v in self.spread_m],
            "rotation_sigma_deg": [finite_or_none(v) for v in self.rotation_sigma_deg],
            "rotation_axes": [[finite_or_none(v) for v in row] for row in self.rotation_axes],
            "rotation_sigma_total_deg": finite_or_none(self.rotation_sigma_total_deg),
            "translation_sigma_m": [finite_or_none(v) for v in self.translation_sigma_m],
            "scale_sigma": finite_or_none(self.scale_sigma),
            "residual_rho": finite_or_none(self.residual_rho),
            "variance_inflation": finite_or_none(self.variance_inflation),
        }

    def __repr__(self) -> str:
        return (f"AlignmentConditioning({self.method}, rotation 1-sigma "
                f"{self.rotation_sigma_total_deg:.3g} deg (axes {np.round(self.rotation_sigma_deg, 3)}"
                f" deg), spread {np.round(self.spread_m, 4)} m, residual {self.sigma_pos_m:.3g} m)")


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
    conditioning : AlignmentConditioning or None
        How well the transform is determined (``se3``, ``sim3``, ``yaw``; None for ``none`` and
        ``origin``, which do not estimate anything from the positions).
    """

    method: str
    transform: FloatArray
    scale: float
    n_used: int
    conditioning: AlignmentConditioning | None = field(default=None, compare=False)

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
        """Strict JSON: ``method, scale, n_used, transform`` (4x4 nested lists) and
        ``conditioning`` (:meth:`AlignmentConditioning.to_dict` or None)."""
        return {"method": self.method, "scale": float(self.scale), "n_used": int(self.n_used),
                "transform": self.transform.tolist(),
                "conditioning": None if self.conditioning is None else self.conditioning.to_dict()}

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
            "use {0} or {1}", hint=_DEGENERATE_HINT)
    # Squared values resolve a ratio down to ~1e-8; 1e-6 is a micrometre per metre.
    if not planar and (n < 3 or sv[1] <= 1e-6 * sv[0]):
        raise DegenerateInputError(
            f"cannot align with {method}: the {n} positions of the {who} are "
            "collinear, so the rotation about that line is undetermined; use {0} or {1}",
            hint=_DEGENERATE_HINT)


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


#: Largest lag-1 autocorrelation used for the inflation (a factor of at most ~45 in variance).
_RHO_MAX = 0.956


def _residual_rho(x: FloatArray, y: FloatArray, R: FloatArray, t: FloatArray, c: float) -> float:
    """Lag-1 autocorrelation (rows in time order) of the residuals ``y - (c R x + t)``, pooled
    over the axes and clipped to ``[0, _RHO_MAX]``."""
    if x.shape[0] < 3:
        return 0.0
    r = y - (c * x) @ R.T - t
    r -= r.mean(axis=0)
    den = float(np.einsum("ij,ij->", r, r))
    if den <= 0.0:
        return 0.0
    rho = float(np.einsum("ij,ij->", r[1:], r[:-1])) / den
    return min(max(rho, 0.0), _RHO_MAX)


def _conditioning(m: _Moments, method: str, R: FloatArray, c: float,
                  rho: float = 0.0) -> AlignmentConditioning:
    """Covariances of the rotation, translation and scale from the moments (see
    :class:`AlignmentConditioning`); O(1) after the moments.  ``rho``: lag-1 autocorrelation of
    the residuals; every covariance is multiplied by ``(1 + rho) / (1 - rho)`` (the variance
    inflation of a mean of an AR(1) series: ``N / (that factor)`` independent samples)."""
    n = m.n
    p = {"se3": 6, "sim3": 7, "yaw": 4}[method]
    M = R.T @ m.syx  # at the optimum M is symmetric (se3/sim3); Y^T X in the estimate's axes
    # residual sum of squares of the centred points: |Y - c X R^T|^2
    rss = float(np.trace(m.syy) - 2.0 * c * np.trace(M) + c * c * np.trace(m.sxx))
    dof = 3 * n - p
    sigma2 = max(rss, 0.0) / dof if dof > 0 else math.nan
    inflation = (1.0 + rho) / (1.0 - rho)
    sigma2_white = sigma2
    sigma2 = sigma2 * inflation
    ev_x = np.linalg.eigvalsh(m.sxx)[::-1]
    spread = np.sqrt(np.maximum(ev_x, 0.0) / n)
    inf = math.inf
    if method == "yaw":
        a = float(m.syx[0, 0] + m.syx[1, 1])
        b = float(m.syx[1, 0] - m.syx[0, 1])
        curv = math.hypot(a, b)  # -d2f/dtheta2 of f = a cos + b sin at its maximum
        var_yaw = sigma2 / curv if curv > 0.0 else inf
        cov = np.zeros((3, 3))
        cov[2, 2] = var_yaw
    else:
        Ms = 0.5 * (M + M.T)
        H = c * (np.trace(Ms) * np.eye(3) - Ms)
        w, V = np.linalg.eigh(H)
        with np.errstate(divide="ignore"):
            inv_w = np.where(w > 0.0, 1.0 / np.where(w > 0.0, w, 1.0), inf)
        # covariance in the estimate's axes, rotated into the reference frame (delta R = R e^th)
        if np.isinf(inv_w).any() or not math.isfinite(sigma2):
            cov = np.full((3, 3), inf if math.isfinite(sigma2) else math.nan)
        else:
            cov_est = (V * (sigma2 * inv_w)) @ V.T
            cov = R @ cov_est @ R.T
    if np.all(np.isfinite(cov)):
        var, axes = np.linalg.eigh(cov)
        var, axes = var[::-1], axes[:, ::-1].T
        rot_sigma = np.degrees(np.sqrt(np.maximum(var, 0.0)))
        total = math.degrees(math.sqrt(max(float(np.trace(cov)), 0.0)))
        # translation of T_ref_est: t = mean_y - c R mean_x; delta t = delta tau + c [R mx]x^T dth
        lever = c * (R @ m.mean_x)
        L = np.array([[0.0, lever[2], -lever[1]], [-lever[2], 0.0, lever[0]],
                      [lever[1], -lever[0], 0.0]])
        cov_t = sigma2 / n * np.eye(3) + L @ cov @ L.T
    else:
        rot_sigma = np.full(3, math.nan if not math.isfinite(sigma2) else inf)
        axes = np.eye(3)
        total = float(rot_sigma[0])
        cov_t = np.full((3, 3), total)
    scale_sigma = None
    if method == "sim3":
        tr = float(np.trace(m.sxx))
        scale_sigma = math.sqrt(sigma2 / tr) if tr > 0.0 else inf
        if np.all(np.isfinite(cov_t)):
            cov_t = cov_t + np.outer(R @ m.mean_x, R @ m.mean_x) * scale_sigma**2
    return AlignmentConditioning(
        method=method,
        n_used=n,
        sigma_pos_m=math.sqrt(sigma2_white) if math.isfinite(sigma2_white) else math.nan,
        residual_rho=rho,
        variance_inflation=inflation,
        spread_m=_ro(spread),
        rotation_cov_rad2=_ro(cov),
        rotation_sigma_deg=_ro(rot_sigma),
        rotation_axes=_ro(axes),
        rotation_sigma_total_deg=total,
        translation_sigma_m=_ro(np.sqrt(np.maximum(np.diag(cov_t), 0.0))),
        scale_sigma=scale_sigma,
    )


def _ro(a: FloatArray) -> FloatArray:
    out = np.array(a, dtype=np.float64)
    out.flags.writeable = False
    return out


def _n_used(n: int, n_align: int | None) -> int:
    """Pairs to align on: ``n_align`` (at most ``n``, with a warning when it asks for more)."""
    if n == 0:
        raise DegenerateInputError("cannot align empty trajectories")
    if n_align is None:
        return n
    if int(n_align) != n_align or n_align < 1:
        raise IbiscapeError(f"n_align must be a positive integer, got {n_align!r}")
    n_used = int(n_align)
    if n_used > n:
        warnings.warn(
            f"n_align={n_used} exceeds the {n} matched poses; aligning on all of them",
            IbiscapeWarning,
            stacklevel=3,
        )
        n_used = n
    return n_used


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
        ``T_ref_est`` and the scale; apply it with :meth:`AlignmentResult.apply`.  Its
        ``conditioning`` (:class:`AlignmentConditioning`) says how well rotation, translation and
        scale are determined; :func:`conditioning_warnings` turns it into warnings.

    Raises
    ------
    DegenerateInputError
        All positions equal or collinear (``se3``/``sim3``), all horizontal positions equal
        (``yaw``); the error's hint suggests ``align="yaw"`` or ``align="origin"``.

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
    n_used = _n_used(len(est), n_align)
    if m is Alignment.NONE:
        return AlignmentResult(m.value, np.eye(4), 1.0, 0)
    if m is Alignment.ORIGIN:
        T = ref.matrices()[0] @ invert_transforms(est.matrices()[0])
        return AlignmentResult(m.value, T, 1.0, 1)
    mo = _moments(est.pos_m[:n_used], ref.pos_m[:n_used])  # one pass serves every check
    planar = m is Alignment.YAW
    _check_scatter(mo.sxx, mo.size_x, n_used, est.describe("estimate"), m.value, planar=planar)
    _check_scatter(mo.syy, mo.size_y, n_used, ref.describe("reference"), m.value, planar=planar)
    x, y = est.pos_m[:n_used], ref.pos_m[:n_used]
    if planar:
        R, t = _yaw(mo)
        return AlignmentResult(m.value, _se3(R, t), 1.0, n_used, conditioning=_conditioning(
            mo, m.value, R, 1.0, _residual_rho(x, y, R, t, 1.0)))
    R, t, c = _umeyama(mo, with_scale=m is Alignment.SIM3)
    if not (math.isfinite(c) and c > 0.0):
        raise DegenerateInputError(
            f"sim3 alignment gave an invalid scale {c!r}; use {{0}} or {{1}}", hint=_DEGENERATE_HINT)
    return AlignmentResult(m.value, _se3(R, t), c, n_used, conditioning=_conditioning(
        mo, m.value, R, c, _residual_rho(x, y, R, t, c)))


#: A rotation error (RMS) below this many degrees is negligible whatever dominates it.
ROTATION_FLOOR_DEG = 0.1
#: The alignment's rotation dominates when its 1-sigma is at least this fraction of the rotation
#: error RMS it is part of: 1/sqrt(2), half of the mean squared rotation error.
DOMINANT_FRACTION = 0.7
#: Beyond this 1-sigma (degrees) the rotation is undetermined whatever error is reported.
UNDETERMINED_DEG = 5.0
#: A sim3 scale whose relative 1-sigma exceeds this is reported as poorly determined.
SCALE_REL_SIGMA = 0.05


def _length(v: float) -> str:
    return f"{v:.3g} m" if not math.isfinite(v) or v >= 1.0 else f"{v * 1000:.3g} mm"


def _axis_name(axis: FloatArray) -> str:
    a = np.asarray(axis, dtype=np.float64)
    k = int(np.argmax(np.abs(a)))
    if abs(a[k]) > 0.95:
        return f"{'xyz'[k]} axis"
    return f"axis [{a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f}]"


def conditioning_warnings(
    al: AlignmentResult, *, rotation_rmse_deg: float | None = None, who: str = "estimate"
) -> list[str]:
    """Warnings (sentences in library terms) when the alignment is too poorly determined for
    the numbers computed after it.

    - The rotation error is dominated by the alignment: the alignment's rotation 1-sigma
      (:attr:`AlignmentConditioning.rotation_sigma_total_deg`) is at least
      ``DOMINANT_FRACTION`` of ``rotation_rmse_deg`` (itself above ``ROTATION_FLOOR_DEG``: a
      rotation error that small is negligible whatever it is made of), or any
      axis is undetermined (1-sigma above ``UNDETERMINED_DEG``, e.g. a 2 mm cloud, or the roll
      about a nearly straight path).  ``rotation_rmse_deg=None`` (RPE, which does not depend on
      the alignment's rotation) checks only the scale.
    - ``sim3``: the scale's relative 1-sigma exceeds ``SCALE_REL_SIGMA``.
    """
    cond = al.conditioning
    if cond is None:
        return []
    out: list[str] = []
    spread = ", ".join(_length(v) for v in cond.spread_m)
    geometry = (f"the {cond.n_used} aligned positions of the {who} spread {spread} (RMS along "
                f"their principal axes) against a residual of {_length(cond.sigma_pos_m)}"
                + (f" correlated along the path (lag-1 {cond.residual_rho:.2f})"
                   if cond.residual_rho > 0.5 else ""))
    if rotation_rmse_deg is not None:
        worst = float(cond.rotation_sigma_deg[0])
        total = cond.rotation_sigma_total_deg
        undetermined = not math.isfinite(worst) or worst > UNDETERMINED_DEG
        dominant = (math.isfinite(total) and rotation_rmse_deg >= ROTATION_FLOOR_DEG
                    and total >= DOMINANT_FRACTION * rotation_rmse_deg)
        if undetermined or dominant:
            sig = "undetermined" if not math.isfinite(worst) else f"1-sigma {worst:.3g} deg"
            what = (f"the rotation of the {al.method} alignment is poorly determined ({sig} about "
                    f"the {_axis_name(cond.rotation_axes[0])}; {geometry})")
            if dominant and math.isfinite(total):
                what += (f", so the rotation error (rmse {rotation_rmse_deg:.3g} deg) is dominated "
                         f"by the alignment (its own error alone: {total:.3g} deg)")
            else:
                what += f"; the rotation error (rmse {rotation_rmse_deg:.3g} deg) means little"
            hint = ('align on a longer or less straight stretch, use align="yaw" (gravity known) '
                    'or align="origin", or read only the translation error')
            if al.method == "yaw":
                hint = ('align on a longer stretch or use align="origin", or read only the '
                        'translation error')
            out.append(f"{what}; {hint}")
    if cond.scale_sigma is not None and al.scale > 0:
        rel = cond.scale_sigma / al.scale
        if not math.isfinite(rel) or rel > SCALE_REL_SIGMA:
            out.append(
                f"the scale of the sim3 alignment is poorly determined (scale {al.scale:.4g} "
                f"+- {cond.scale_sigma:.2g}; {geometry}); errors after it are unreliable: "
                'align on a longer stretch or use align="se3" if the estimate has metric scale'
            )
    return out
