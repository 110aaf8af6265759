"""Mono and multi-camera (chain) calibration from planar-target detections.

Pipeline (one function, :func:`calibrate`):

1. Per camera, an initial pinhole + radtan estimate with OpenCV's ``calibrateCamera`` (Zhang 2000)
   on the views with enough corners, then a target pose per view with ``solvePnP``.
2. Consistent corner numbering across cameras (checkerboards only): a square corner grid has no
   preferred orientation, so OpenCV may number a view's corners from a different starting corner
   in each camera.  For every pair of neighbouring cameras and every common view all symmetric
   renumberings are tried; the relative pose that most views agree on is kept and each view takes
   the numbering that agrees with it.
3. Joint refinement of everything by sparse nonlinear least squares (scipy ``least_squares``,
   trust-region reflective, finite-difference Jacobian with its sparsity pattern): per camera
   ``fx, fy, cx, cy`` and four distortion coefficients (radtan or equidistant, through
   :class:`~ibiscape_eval.core.camera.CameraModel`), a target pose per view in camera 0 and the
   chain ``T_cn_cnm1``.  Corners whose residual exceeds ``outlier_sigma`` robust standard
   deviations are removed and the problem re-solved until none is.
4. Parameter standard deviations from sandwich covariances around ``(J^T J)^-1``: the larger, per
   parameter, of one with each camera's own residual variance and a per-view cluster-robust one
   (:func:`_covariance`; coverage measured by ``benchmarks/bench_coverage.py --camera``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.errors import CalibrationError, IbiscapeError
from ibiscape_eval.core.kalibr import CalibrationTarget
from ibiscape_eval.core.so3 import exp_so3, left_jacobian_so3

from ._lsq import (
    BlockJacobian,
    leading_inverse,
    normal_equations,
    project_jacobian,
    rotvec_from_matrix,
    solve_damped,
)
from .detect import Detection

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = [
    "MIN_VIEW_SPREAD_DEG",
    "MODELS",
    "CalibrationResult",
    "CameraCalibration",
    "Observations",
    "ResidualStats",
    "calibrate",
    "evaluate",
]

#: Kalibr's model names -> CameraModel distortion
MODELS = {"pinhole-radtan": "radtan", "pinhole-equi": "equidistant"}
FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

PARAM_NAMES = ("fx", "fy", "cx", "cy", "d0", "d1", "d2", "d3")
#: factor on every reported standard deviation beyond the per-camera / per-view covariance
#: (:func:`_covariance`), measured by ``benchmarks/bench_coverage.py --camera``
STD_INFLATION = 1.0


# --------------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class ResidualStats:
    """Reprojection residuals of one camera [px]: Kalibr's ``[mean_x, mean_y] +- [std_x, std_y]``."""

    mean_px: tuple[float, float]
    std_px: tuple[float, float]
    rms_px: float
    max_px: float
    n_corners: int
    n_views: int

    @classmethod
    def of(cls, res: FloatArray, n_views: int) -> ResidualStats:
        if len(res) == 0:
            return cls((0.0, 0.0), (0.0, 0.0), 0.0, 0.0, 0, n_views)
        m, s = res.mean(axis=0), res.std(axis=0)
        norm = np.hypot(res[:, 0], res[:, 1])
        return cls((float(m[0]), float(m[1])), (float(s[0]), float(s[1])),
                   float(np.sqrt(np.mean(norm**2))), float(norm.max()), len(res), n_views)

    def kalibr(self) -> str:
        """``[mean_x, mean_y] +- [std_x, std_y]`` as Kalibr prints it."""
        m = [0.0 if abs(v) < 5e-7 else v for v in self.mean_px]  # no "-0.000000"
        return f"[{m[0]:.6f}, {m[1]:.6f}] +- [{self.std_px[0]:.6f}, {self.std_px[1]:.6f}]"

    def to_dict(self) -> dict[str, Any]:
        return {"mean_px": list(self.mean_px), "std_px": list(self.std_px), "rms_px": self.rms_px,
                "max_px": self.max_px, "n_corners": self.n_corners, "n_views": self.n_views}


@dataclass(frozen=True, eq=False)
class CameraCalibration:
    """One camera's estimate and its statistics.

    Attributes
    ----------
    name : str
    camera : CameraModel
    std : dict
        Standard deviations of ``fx, fy, cx, cy`` [px] and the distortion coefficients (Kalibr's
        order), named like :meth:`CameraModel.to_kalibr` (``intrinsics``, ``distortion_coeffs``).
    residuals : ResidualStats
    residuals_px : ndarray (K, 2)
        Residuals (projected minus detected) of the corners used.
    corners_px : ndarray (K, 2)
        The detected corners used (for coverage plots).
    view_rms_px : dict
        RMS residual per view index used.
    n_rejected : int
        Corners removed as outliers.
    """

    name: str
    camera: CameraModel
    std: dict[str, list[float]]
    residuals: ResidualStats
    residuals_px: FloatArray
    corners_px: FloatArray
    view_rms_px: dict[int, float]
    n_rejected: int
    #: covariance (8, 8) of ``fx, fy, cx, cy`` and the distortion coefficients (what ``std`` is
    #: the square root of the diagonal of); e.g. for ``calibrate_imu_camera``'s propagation
    covariance: FloatArray | None = None

    def to_dict(self) -> dict[str, Any]:
        d = self.camera.to_kalibr()
        return {"name": self.name, **d, "intrinsics_std": self.std["intrinsics"],
                "distortion_coeffs_std": self.std["distortion_coeffs"],
                "reprojection_error": self.residuals.to_dict(),
                "reprojection_error_kalibr": self.residuals.kalibr(),
                "n_rejected_corners": self.n_rejected,
                "view_rms_px": {str(k): v for k, v in sorted(self.view_rms_px.items())}}

    def __repr__(self) -> str:
        return f"CameraCalibration({self.name}: {self.camera!r}, rms {self.residuals.rms_px:.3f} px)"


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """A calibrated camera chain.

    Attributes
    ----------
    model : str
        ``pinhole-radtan`` or ``pinhole-equi``.
    target : CalibrationTarget
    cameras : tuple of CameraCalibration
    T_cn_cnm1 : tuple of ndarray (4, 4)
        Camera n-1 to camera n, one per camera after the first.
    T_cn_cnm1_std : tuple of dict
        ``rotation_deg`` (3, about the rotation-vector axes) and ``translation_m`` (3) std devs.
    baselines_m, baselines_std_m : tuple of float
        ``|t|`` of every ``T_cn_cnm1`` and its standard deviation.
    n_views : int
        Views (instants) with at least one camera used.
    view_ids : tuple of int
        Indices of the views used (into the input lists).
    renumbered_views : int
        Views whose corner numbering was changed to agree across cameras.
    iterations : int
        Outlier-rejection rounds.
    """

    model: str
    target: CalibrationTarget
    cameras: tuple[CameraCalibration, ...]
    T_cn_cnm1: tuple[FloatArray, ...]
    T_cn_cnm1_std: tuple[dict[str, list[float]], ...]
    baselines_m: tuple[float, ...]
    baselines_std_m: tuple[float, ...]
    n_views: int
    view_ids: tuple[int, ...]
    renumbered_views: int = 0
    iterations: int = 1
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def rms_px(self) -> float:
        """RMS reprojection error over all cameras [px]."""
        n = sum(c.residuals.n_corners for c in self.cameras)
        ss = sum(c.residuals.rms_px**2 * c.residuals.n_corners for c in self.cameras)
        return float(np.sqrt(ss / n)) if n else 0.0

    def to_dict(self) -> dict[str, Any]:
        chain = []
        for i, T in enumerate(self.T_cn_cnm1):
            chain.append({"from": self.cameras[i].name, "to": self.cameras[i + 1].name,
                          "T_cn_cnm1": T.tolist(), "baseline_m": self.baselines_m[i],
                          "baseline_std_m": self.baselines_std_m[i], **self.T_cn_cnm1_std[i]})
        return {"model": self.model, "target": self.target.to_kalibr(),
                "cameras": [c.to_dict() for c in self.cameras], "chain": chain,
                "rms_px": self.rms_px, "n_views": self.n_views,
                "renumbered_views": self.renumbered_views, "iterations": self.iterations,
                **self.extra}

    def plot(self, camera: int = 0, *, kind: str = "residuals") -> Figure:
        """The ``kind`` figure (``residuals``: reprojection residual scatter, ``coverage``: corner
        heat map) of the ``camera``-th camera; a new Figure."""
        from .plots import calibration_figures

        figures = dict(calibration_figures(self))
        return figures[f"{self.cameras[camera].name}_{kind}.png"]

    def __repr__(self) -> str:
        b = ", ".join(f"{1e3 * v:.2f} mm" for v in self.baselines_m)
        return (f"CalibrationResult({self.model}, {len(self.cameras)} cameras, {self.n_views} views, "
                f"rms {self.rms_px:.3f} px{', baselines ' + b if b else ''})")


@dataclass(frozen=True, eq=False)
class Observations:
    """Detections of one camera, one entry per view (None: target not seen)."""

    name: str
    image_size: tuple[int, int]
    detections: Sequence[Detection | None]


# ------------------------------------------------------------------------------------- geometry
def _T(rvec: npt.ArrayLike, tvec: npt.ArrayLike) -> FloatArray:
    import cv2

    T = np.eye(4)
    T[:3, :3], _ = cv2.Rodrigues(np.asarray(rvec, np.float64).reshape(3, 1))
    T[:3, 3] = np.asarray(tvec, np.float64).ravel()
    return T


def _rt(T: FloatArray) -> FloatArray:
    return np.concatenate([rotvec_from_matrix(T[:3, :3]), T[:3, 3]])


def _median(a: FloatArray) -> FloatArray:
    """``np.median(a, axis=0)`` (the same numbers) without loading ``numpy.ma``, which
    ``np.median`` and ``np.unique`` import on first use (9 ms of CPU)."""
    s = np.sort(a, axis=0)
    m = len(s) // 2
    return np.asarray(s[m] if len(s) % 2 else 0.5 * (s[m - 1] + s[m]), np.float64)


def _camera(base: CameraModel, p: FloatArray) -> CameraModel:
    return replace(base, fx=float(p[0]), fy=float(p[1]), cx=float(p[2]), cy=float(p[3]),
                   coeffs=(float(p[4]), float(p[5]), float(p[6]), float(p[7])))


def _equi_from_radtan(k1: float, k2: float, fmax: float) -> tuple[float, float, float, float]:
    """Equidistant coefficients whose radial mapping best matches radtan's ``r (1 + k1 r^2 + k2 r^4)``
    over normalised radii ``[0, fmax]`` (linear least squares in k1..k4)."""
    r = np.linspace(1e-3, max(fmax, 1e-2), 200)
    rd = r * (1 + k1 * r**2 + k2 * r**4)
    th = np.arctan(r)
    A = np.stack([th**3, th**5, th**7, th**9], axis=1)
    sol, *_ = np.linalg.lstsq(A, rd - th, rcond=None)
    return tuple(float(v) for v in sol)  # type: ignore[return-value]


# --------------------------------------------------------------------------------- initialisation
def _usable(det: Detection | None, target: CalibrationTarget, min_corners: int) -> bool:
    if det is None or len(det) < min_corners:
        return False
    if target.target_type == "checkerboard" and len(det) == target.n_corners:
        return True
    # corners must span two dimensions of the board (not one row of tags or corners)
    r, c = np.divmod(det.ids, target.corner_cols)
    return len(set(r.tolist())) >= 2 and len(set(c.tolist())) >= 2


def _init_camera(obs: Observations, target: CalibrationTarget, views: list[int], distortion: str,
                 max_init_views: int = 40) -> tuple[CameraModel, dict[int, FloatArray]]:
    """OpenCV's ``calibrateCamera`` on (up to ``max_init_views`` of) the usable ``views``: the
    initial camera and the target pose ``T_cam_target`` it found for each view it used (a start
    for the joint refinement, so those views are not solved again by PnP)."""
    import cv2

    obj = target.object_points().astype(np.float32)
    pick = views if len(views) <= max_init_views else [
        views[i] for i in np.linspace(0, len(views) - 1, max_init_views).round().astype(int)]
    o_pts, i_pts = [], []
    for v in pick:
        d = obs.detections[v]
        assert d is not None
        o_pts.append(obj[d.ids])
        i_pts.append(d.corners_px.astype(np.float32))
    w, h = obs.image_size
    try:
        # 10 iterations instead of OpenCV's 30: the joint refinement polishes the start (on 13
        # real views its RMS agrees to 1e-9 px after 5; 9 ms instead of 12 per camera); its steps
        # by LU instead of SVD (8.3 ms instead of 9.7, the same start to 1e-8)
        _, K, dist, rvecs, tvecs = cv2.calibrateCamera(
            o_pts, i_pts, (w, h), None, None, flags=cv2.CALIB_FIX_K3 | cv2.CALIB_USE_LU,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 10, float(np.finfo(float).eps)))
    except cv2.error as e:
        raise CalibrationError(f"{obs.name}: OpenCV could not initialise the intrinsics "
                               f"({str(e).strip().splitlines()[-1]}); give more varied views") from None
    dist = np.asarray(dist, np.float64).ravel()
    cam = CameraModel(w, h, float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]),
                      "radtan", (float(dist[0]), float(dist[1]), float(dist[2]), float(dist[3])))
    if distortion == "equidistant":
        corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], np.float64)
        rmax = float(np.max(np.hypot((corners[:, 0] - cam.cx) / cam.fx, (corners[:, 1] - cam.cy) / cam.fy)))
        cam = replace(cam, distortion="equidistant",
                      coeffs=_equi_from_radtan(cam.coeffs[0], cam.coeffs[1], rmax))
    poses = {v: _T(r, t) for v, r, t in zip(pick, rvecs, tvecs, strict=True)}
    return cam, {v: T for v, T in poses.items() if T[2, 3] > 0 and np.all(np.isfinite(T))}


def _init_cameras(observations: Sequence[Observations], target: CalibrationTarget, usable: list[list[int]],
                  distortion: str) -> list[tuple[CameraModel, dict[int, FloatArray]]]:
    """:func:`_init_camera` of every camera, in parallel threads (OpenCV releases the GIL)."""
    from ibiscape_eval.core.cpus import usable_cpus

    from ._threads import thread_map

    def one(n: int) -> tuple[CameraModel, dict[int, FloatArray]]:
        return _init_camera(observations[n], target, usable[n], distortion)

    return thread_map(one, range(len(observations)), usable_cpus())


Rays = dict[int, tuple[FloatArray, npt.NDArray[np.bool_]]]


def _view_rays(cam: CameraModel, dets: dict[int, Detection]) -> Rays:
    """Per view, the undistorted rays of its corners and where the inversion succeeded: one
    :meth:`CameraModel.unproject` for all views (each view's rays are reused by every PnP of it)."""
    if not dets:
        return {}
    rays, ok = cam.unproject(np.concatenate([d.corners_px for d in dets.values()]))
    out: Rays = {}
    i = 0
    for v, d in dets.items():
        out[v] = (rays[i:i + len(d)], ok[i:i + len(d)])
        i += len(d)
    return out


def _pnp(cam: CameraModel, obj: FloatArray, uv: FloatArray) -> FloatArray | None:
    """Target pose ``T_cam_target`` from corners: undistort with ``cam``, then planar PnP."""
    return _pnp_rays(obj, *cam.unproject(uv))


def _pnp_rays(obj: FloatArray, rays: FloatArray, ok: npt.NDArray[np.bool_]) -> FloatArray | None:
    """Target pose ``T_cam_target`` from the undistorted rays of its corners (planar PnP)."""
    import cv2

    if ok.sum() < 4:
        return None
    good, rvec, tvec = cv2.solvePnP(obj[ok].astype(np.float64), rays[ok, :2].astype(np.float64),
                                    np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
    if not good:
        return None
    good, rvec, tvec = cv2.solvePnP(obj[ok], rays[ok, :2], np.eye(3), None, rvec, tvec, True,
                                    flags=cv2.SOLVEPNP_ITERATIVE)
    if not good or tvec[2, 0] <= 0:
        return None
    return _T(rvec, tvec)


# ------------------------------------------------------------------------- numbering consistency
def _pose_distances(Ra: FloatArray, ta: FloatArray, Rb: FloatArray, tb: FloatArray,
                    scale_m: float) -> FloatArray:
    """The distance of every pose ``a`` (rotations (A, 3, 3), translations (A, 3)) to every pose
    ``b``: (A, B), the rotation between them [deg] plus their translations' difference in units of
    1 % of ``scale_m``."""
    cos = (np.einsum("aij,bij->ab", Ra, Rb) - 1.0) / 2.0
    return np.asarray(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
                      + np.linalg.norm(ta[:, None, :] - tb[None, :, :], axis=-1) / (0.01 * scale_m))


def _board_symmetries(obj: FloatArray, perms: list[IntArray]) -> list[FloatArray]:
    """The rigid motion ``S`` (4x4, board frame) of every corner permutation: ``obj[perm] = S obj``
    (Kabsch's least-squares rotation, exact for a symmetry of the board)."""
    out = []
    ca = obj.mean(axis=0)
    for perm in perms:
        b = obj[perm]
        cb = b.mean(axis=0)
        U, _, Vt = np.linalg.svd((obj - ca).T @ (b - cb))
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
        S = np.eye(4)
        S[:3, :3] = Vt.T @ D @ U.T
        S[:3, 3] = cb - S[:3, :3] @ ca
        out.append(S)
    return out


def _consistent_numbering(ref_poses: dict[int, FloatArray], dets: list[Detection | None],
                          target: CalibrationTarget, own: dict[int, FloatArray]
                          ) -> tuple[dict[int, tuple[Detection, FloatArray]], FloatArray | None, int]:
    """Renumber camera n's detections so that ``T_cn_ref = T_cn_t T_ref_t^-1`` agrees over views.

    ``own``: camera n's poses ``T_cn_t`` of its views in their current numbering.  A renumbering
    moves every corner by one rigid motion ``S`` of the board onto itself, so its pose is
    ``T_cn_t S^-1`` (what a PnP of the renumbered corners finds, without solving it again).  Returns
    per common view the renumbered detection and its pose ``T_cn_t``, the consensus relative pose
    and the number of views whose numbering changed.
    """
    perms = target.symmetries()
    S_inv = [np.linalg.inv(S) for S in _board_symmetries(target.object_points(), perms)]
    cands: list[tuple[int, int, FloatArray, FloatArray]] = []  # (view, perm index, T_cn_ref, T_cn_t)
    for v, T_ref in ref_poses.items():
        T0 = own.get(v)
        if dets[v] is None or T0 is None:
            continue
        T_ref_inv = np.linalg.inv(T_ref)
        for k in range(len(perms)):
            T = T0 @ S_inv[k]
            if T[2, 3] > 0:  # the board's origin in front of the camera (as PnP requires)
                cands.append((v, k, T @ T_ref_inv, T))
    if not cands:
        return {}, None, 0
    scale = float(_median(np.array([np.linalg.norm(T_ref[:3, 3]) for T_ref in ref_poses.values()])))
    # consensus: the candidate that the most views agree with (within 2 deg + 2 % of the distance),
    # all candidates against (a sample of at most ~400 of) them at once
    views = np.array([c[0] for c in cands])
    Rs = np.stack([c[2][:3, :3] for c in cands])
    ts = np.stack([c[2][:3, 3] for c in cands])
    view_ids = sorted(set(views.tolist()))  # (np.unique would load numpy.ma: 9 ms)
    onehot = (views[:, None] == np.array(view_ids)[None, :]).astype(np.float64)  # (C, views)
    step = max(1, len(cands) // 400)
    near = _pose_distances(Rs[::step], ts[::step], Rs, ts, scale) < 4.0  # (samples, C)
    score = np.count_nonzero((near.astype(np.float64) @ onehot) > 0, axis=1)  # views agreeing
    best = cands[int(np.argmax(score)) * step][2]  # the first of the best
    dist = _pose_distances(best[None, :3, :3], best[None, :3, 3], Rs, ts, scale)[0]
    out: dict[int, tuple[Detection, FloatArray]] = {}
    changed = 0
    for v in view_ids:
        mine = np.flatnonzero(views == v)
        i = int(mine[np.argmin(dist[mine])])
        if dist[i] > 20.0:  # no numbering of this view agrees: leave the view out of the pair
            continue
        v_, k, _, T_cn_t = cands[i]
        d = dets[v_]
        assert d is not None
        ids = perms[k][d.ids]
        order = np.argsort(ids)
        out[int(v_)] = (Detection(ids[order], d.corners_px[order], d.image_size), T_cn_t)
        changed += int(k != 0)
    return out, best, changed


# ----------------------------------------------------------------------------- joint refinement
@dataclass
class _Problem:
    cams: list[CameraModel]
    obj: FloatArray            # (M, 3) target points of all observations
    uv: FloatArray             # (M, 2) detected corners
    cam_i: IntArray            # (M,) camera index
    view_i: IntArray           # (M,) index into the pose block
    n_views: int
    free_intrinsics: bool = True
    free_chain: bool = True
    _memo: dict[Any, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def n_cams(self) -> int:
        return len(self.cams)

    def layout(self) -> tuple[int, int, int]:
        ni = 8 * self.n_cams if self.free_intrinsics else 0
        nc = 6 * (self.n_cams - 1) if self.free_chain else 0
        return ni, nc, 6 * self.n_views

    def split(self, x: FloatArray, intr: FloatArray, chain: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        ni, nc, _ = self.layout()
        i = x[:ni].reshape(-1, 8) if self.free_intrinsics else intr
        c = x[ni:ni + nc].reshape(-1, 6) if self.free_chain else chain
        return i, c, x[ni + nc:].reshape(-1, 6)

    def _camera_rows(self, n: int) -> npt.NDArray[np.bool_]:
        key = ("rows", n)
        if key not in self._memo:
            self._memo[key] = self.cam_i == n
        rows: npt.NDArray[np.bool_] = self._memo[key]
        return rows

    def _target_points(self, poses: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The target points of the observations rotated into camera 0 (``R X``) and placed there
        (``R X + t``); kept for the last poses (the Jacobian at a point follows its residuals)."""
        key = poses.tobytes()
        last = self._memo.get("points")
        if last is not None and last[0] == key:
            return last[1], last[2]
        RX = np.einsum("mij,mj->mi", exp_so3(poses[:, :3])[self.view_i], self.obj)
        p = RX + poses[self.view_i, 3:]
        self._memo["points"] = (key, RX, p)
        return RX, p

    def _camera_points(self, chain: FloatArray, poses: FloatArray) -> list[FloatArray | None]:
        """Per camera, the target points of its observations in its frame (None: no observation);
        kept for the last chain and poses (the finite differences of the intrinsics leave them
        unchanged, those of the chain leave the target points in camera 0 unchanged)."""
        key = (chain.tobytes(), poses.tobytes())
        last = self._memo.get("cameras")
        if last is not None and last[0] == key:
            kept: list[FloatArray | None] = last[1]
            return kept
        _, p = self._target_points(poses)
        out: list[FloatArray | None] = []
        # chain: T_cn_c0 = T_cn_cnm1 ... T_c1_c0
        Rn, tn = np.eye(3), np.zeros(3)
        for n in range(self.n_cams):
            if n > 0:
                Rc = exp_so3(chain[n - 1, :3])
                Rn, tn = Rc @ Rn, Rc @ tn + chain[n - 1, 3:]
            sel = self._camera_rows(n)
            out.append(p[sel] @ Rn.T + tn if sel.any() else None)
        self._memo["cameras"] = (key, out)
        return out

    def residuals(self, intr: FloatArray, chain: FloatArray, poses: FloatArray) -> FloatArray:
        out = np.empty_like(self.uv)
        for n, pc in enumerate(self._camera_points(chain, poses)):
            if pc is None:
                continue
            sel = self._camera_rows(n)
            try:
                cam = _camera(self.cams[n], intr[n])
            except IbiscapeError:
                out[sel] = 1e3
                continue
            out[sel] = cam.project(pc) - self.uv[sel]
        return np.nan_to_num(out, nan=1e3, posinf=1e3, neginf=-1e3)

    def jacobian(self, intr: FloatArray, chain: FloatArray, poses: FloatArray) -> BlockJacobian:
        """Exact derivatives of :meth:`residuals` by ``a`` (the free intrinsics and chain) and by
        each corner's view pose; rows whose residual is a placeholder (behind the camera, invalid
        intrinsics) are zero, as the derivative of a constant."""
        ni, nc, _ = self.layout()
        m = len(self.uv)
        Ja, Jp = np.zeros((m, 2, ni + nc)), np.zeros((m, 2, 6))
        RX, p0 = self._target_points(poses)
        Jlv = left_jacobian_so3(poses[:, :3])[self.view_i]
        Rc = exp_so3(chain[:, :3]) if len(chain) else np.zeros((0, 3, 3))
        Jlc = left_jacobian_so3(chain[:, :3]) if len(chain) else np.zeros((0, 3, 3))
        for n in range(self.n_cams):
            sel = self._camera_rows(n)
            if not sel.any():
                continue
            try:
                _camera(self.cams[n], intr[n])
            except IbiscapeError:
                continue
            p, qs = p0[sel], []
            for k in range(n):  # through the chain: q = R_k p_(k-1), p_k = q + t_k
                q = p @ Rc[k].T
                qs.append(q)
                p = q + chain[k, 3:]
            uv, J_i, G = project_jacobian(self.cams[n].distortion, intr[n], p)
            Jn = np.zeros((len(p), 2, ni + nc))
            if self.free_intrinsics:
                Jn[:, :, 8 * n:8 * n + 8] = J_i
            for k in range(n - 1, -1, -1):  # back through the chain: G = d uv / d p_k
                if self.free_chain:
                    c = ni + 6 * k
                    Jn[:, :, c:c + 3] = _cross_rows(qs[k], G) @ Jlc[k]
                    Jn[:, :, c + 3:c + 6] = G
                G = G @ Rc[k]
            Jpn = np.concatenate([_cross_rows(RX[sel], G) @ Jlv[sel], G], axis=2)
            bad = ~np.all(np.isfinite(uv), axis=1)
            Jn[bad], Jpn[bad] = 0.0, 0.0
            Ja[sel], Jp[sel] = Jn, Jpn
        return BlockJacobian(Ja, Jp, self.view_i, self.n_views)


def _cross_rows(q: FloatArray, G: FloatArray) -> FloatArray:
    """``G @ -[q]_x`` for rows ``G`` (M, 2, 3) and vectors ``q`` (M, 3): each row ``g`` becomes
    ``q x g`` (the derivative of a rotated point ``q`` by its rotation, before the left Jacobian)."""
    q0, q1, q2 = q[:, 0, None], q[:, 1, None], q[:, 2, None]
    g0, g1, g2 = G[:, :, 0], G[:, :, 1], G[:, :, 2]
    return np.stack([q1 * g2 - q2 * g1, q2 * g0 - q0 * g2, q0 * g1 - q1 * g0], axis=-1)


@dataclass(frozen=True, eq=False)
class _Solution:
    x: FloatArray
    jac: BlockJacobian | None  # at x; None when the last accepted step converged (not evaluated)
    cost: float  # 0.5 * sum of squares (scipy's convention)
    iterations: int
    damping: float  # the last Levenberg-Marquardt damping


#: Levenberg-Marquardt stops when a step lowers the cost by less than this fraction (scipy's
#: ``ftol`` default): on 13 real stereo views the next steps moved the focal lengths by 1e-5 of
#: their standard deviation
_FTOL = 1e-8


def _levenberg_marquardt(fun: Callable[[FloatArray], FloatArray], jac: Callable[[FloatArray], BlockJacobian],
                         x0: FloatArray, *, max_iter: int = 100, lam0: float = 1e-3) -> _Solution:
    """Levenberg-Marquardt with Marquardt's diagonal scaling on the normal equations.

    The normal equations keep their block structure (intrinsics and chain beside a 6x6 block per
    view): the poses are eliminated block by block and a ``K x K`` system is left
    (:func:`~ibiscape_eval.calib._lsq.solve_damped`).  A dense Cholesky of the 172 x 172 system of
    25 stereo views took 0.2-0.5 s per step on a loaded 2-core machine (OpenBLAS threads waiting
    for each other), a sparse LU 2-4 ms (with 0.3 s of scipy imports), the reduced system well
    under 1 ms.  The Jacobian is exact (:meth:`_Problem.jacobian`): one evaluation, where finite
    differences took 20; it is evaluated after an accepted step only when another step follows
    (the caller evaluates it at the solution when it needs it: a solve followed by another
    round of outlier rejection does not).  ``lam0``: the first damping (a problem re-solved
    from a nearby solution starts with the damping it ended with)."""
    x = x0.copy()
    r = fun(x)
    cost = float(np.sum(r * r))
    lam = lam0
    J: BlockJacobian | None = jac(x)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007
        assert J is not None
        N = normal_equations(J, r)
        d_a, d_p = (np.maximum(d, 1e-12) for d in N.diagonal())
        improved = False
        while lam < 1e12:
            try:
                dx_a, dx_p = solve_damped(N, lam, d_a, d_p)
            except np.linalg.LinAlgError:  # exactly singular
                lam *= 10.0
                continue
            dx = np.concatenate([dx_a, dx_p.ravel()])
            if not np.all(np.isfinite(dx)):
                lam *= 10.0
                continue
            xn = x + dx
            rn = fun(xn)
            cn = float(np.sum(rn * rn))
            if cn < cost:
                rel = (cost - cn) / max(cost, 1e-300)
                x, r, cost = xn, rn, cn
                lam = max(lam / 5.0, 1e-12)
                improved = True
                break
            lam *= 5.0
        if not improved:
            break
        J = None
        if rel < _FTOL or np.max(np.abs(dx) / np.maximum(np.abs(x), 1.0)) < 1e-12:
            break
        J = jac(x)
    return _Solution(x, J, 0.5 * cost, it, lam)


def _solve(prob: _Problem, intr: FloatArray, chain: FloatArray, poses: FloatArray, lam0: float = 1e-3
           ) -> tuple[FloatArray, FloatArray, FloatArray, _Solution]:
    parts = []
    if prob.free_intrinsics:
        parts.append(intr.ravel())
    if prob.free_chain:
        parts.append(chain.ravel())
    parts.append(poses.ravel())
    x0 = np.concatenate(parts)

    def fun(x: FloatArray) -> FloatArray:
        i, c, p = prob.split(x, intr, chain)
        return prob.residuals(i, c, p)

    def jac(x: FloatArray) -> BlockJacobian:
        i, c, p = prob.split(x, intr, chain)
        return prob.jacobian(i, c, p)

    sol = _levenberg_marquardt(fun, jac, x0, lam0=lam0)
    i, c, p = prob.split(sol.x, intr, chain)
    return i.copy(), c.copy(), p.copy(), sol


def _per_view_sums(values: FloatArray, view_rows: IntArray, n_views: int) -> FloatArray:
    """Sums (V, ...) of ``values`` (rows, ...) over the rows of every view (rows by view, as
    :func:`_stack` orders them, are summed slice by slice: ``np.add.at`` took 10x longer)."""
    out = np.zeros((n_views, *values.shape[1:]))
    if len(view_rows) and np.all(view_rows[1:] >= view_rows[:-1]):
        seen = np.bincount(view_rows, minlength=n_views) > 0
        out[seen] = np.add.reduceat(values, np.searchsorted(view_rows, np.flatnonzero(seen)), axis=0)
    else:
        np.add.at(out, view_rows, values)
    return out


def _covariance(sol: _Solution, n_fixed_tail: int, res: FloatArray, cam_i: IntArray,
                view_i: IntArray) -> tuple[FloatArray, dict[str, Any]]:
    """Covariance of the leading (non-pose) parameters of the least-squares estimate.

    ``s^2 (J^T J)^-1`` with one pooled ``s^2`` assumes white corner noise of one size in every
    camera.  Two estimates that do not are formed and the larger variance kept per parameter
    (the estimate itself is unweighted least squares, so both are sandwiches around
    ``(J^T J)^-1``):

    - per camera: ``(J^T J)^-1 (sum_c s_c^2 J_c^T J_c) (J^T J)^-1`` with each camera's own
      residual variance ``s_c^2 = SSR_c / (m_c - p_c)`` (a poor camera beside a good one);
    - per view (cluster-robust, CR1): ``(J^T J)^-1 (sum_v u_v u_v^T) (J^T J)^-1`` with the score
      ``u_v = J_v^T r_v`` of every view's corners (all cameras), scaled by
      ``V / (V - 1) (m - 1) / (m - p)``: corner errors that share a sign within a view (blur,
      lighting, a detector bias that depends on the board's pose) do not average out over the
      view's corners, and white-noise covariances understate them (a per-view offset as large as
      the corner noise leaves the plain extrinsics' 1-sigma covering 43 % instead of 68 %).

    The result is multiplied by :data:`STD_INFLATION` squared (see there).
    """
    J = sol.jac
    assert J is not None
    m, p = J.shape
    k = p - n_fixed_tail
    X_a, X_p = leading_inverse(normal_equations(J, res), J)  # (J^T J)^-1 [:, :k] in blocks
    r = res.ravel()
    Ja = J.Ja.reshape(m, k)
    Jp = J.Jp.reshape(m, 6)
    JX = (J.Ja @ X_a + J.Jp @ X_p[view_i]).reshape(m, k)  # J (J^T J)^-1 [:, :k]
    rows_cam = np.repeat(cam_i, 2)
    rows_view = np.repeat(view_i, 2)
    n_cams = int(cam_i.max()) + 1 if cam_i.size else 0
    # per camera: its share of the parameters is the columns its rows touch
    cov_cam = np.zeros((k, k))
    s2_cam = []
    for n in range(n_cams):
        sel = rows_cam == n
        touched = _per_view_sums(np.abs(Jp[sel]), rows_view[sel], J.n_views)
        pc = int(np.count_nonzero(np.abs(Ja[sel]).sum(axis=0))) + int(np.count_nonzero(touched))
        s2 = float(r[sel] @ r[sel]) / max(int(sel.sum()) - pc, 1)
        s2_cam.append(s2)
        cov_cam += s2 * (JX[sel].T @ JX[sel])
    # per view: cluster-robust, the score u_v = J_v^T r_v of every view
    n_v = int(view_i.max()) + 1 if view_i.size else 0
    UX = (_per_view_sums(Ja * r[:, None], rows_view, J.n_views) @ X_a
          + np.einsum("vj,vjk->vk", _per_view_sums(Jp * r[:, None], rows_view, J.n_views), X_p))
    corr = n_v / max(n_v - 1, 1) * (m - 1) / max(m - p, 1)
    cov_view = (UX.T @ UX) * corr
    d = np.maximum(np.diag(cov_cam), np.diag(cov_view))
    sc = np.sqrt(d / np.maximum(np.diag(cov_cam), 1e-300))
    cov = cov_cam * np.outer(sc, sc)  # the larger variance, the per-camera correlations
    cov *= STD_INFLATION**2
    info = {"method": "max(per-camera residual variance, per-view cluster-robust)",
            "residual_variance_px2": s2_cam, "inflation": STD_INFLATION,
            "std_plain": np.sqrt(np.clip(np.diag(X_a) * float(r @ r) / max(m - p, 1), 0, None)).tolist(),
            "std_per_camera": np.sqrt(np.clip(np.diag(cov_cam), 0, None)).tolist(),
            "std_per_view": np.sqrt(np.clip(np.diag(cov_view), 0, None)).tolist()}
    return cov, info


#: Views whose target normals all lie within this angle [deg] of each other are refused: the
#: focal length is then weakly constrained (one tilted plane and its perspective only), and any
#: unmodelled error (blur, rolling shutter, detector bias) goes into it unseen by the covariance
#: (4 near-identical real EuRoC V1_01 views, 0.05 deg apart: fx 1620 +- 29 px, truth 458.65 px).
#: The generated well-posed test sets spread 48 deg or more; Zhang's method wants views tilted in
#: different directions.
MIN_VIEW_SPREAD_DEG = 5.0


def _normal_spread_deg(poses: Sequence[FloatArray]) -> float:
    """Largest angle [deg] between the target normals of two views (``T_cam_target`` poses).

    Zhang's method takes the focal length from how the target plane changes orientation between
    views; views whose target planes are (nearly) parallel leave it unconstrained, whatever the
    in-plane rotation or the translation."""
    if len(poses) < 2:
        return 0.0
    n = np.array([T[:3, 2] for T in poses])
    c = np.clip(n @ n.T, -1.0, 1.0)
    return float(np.degrees(np.arccos(c.min())))


# ----------------------------------------------------------------------------------- public API
def _min_corners(target: CalibrationTarget, min_corners: int | None) -> int:
    """Corners a view needs: ``min_corners``, else all of a checkerboard, 8 of an AprilGrid."""
    return min_corners or (target.n_corners if target.target_type == "checkerboard" else 8)


def _usable_views(observations: Sequence[Observations], target: CalibrationTarget, min_c: int,
                  n_v: int) -> list[list[int]]:
    """Per camera, the views with enough corners; :class:`CalibrationError` below 3."""
    usable = [[v for v in range(n_v) if _usable(o.detections[v], target, min_c)] for o in observations]
    for o, views in zip(observations, usable, strict=True):
        if len(views) < 3:
            seen = sum(d is not None for d in o.detections)
            raise CalibrationError(
                f"{o.name}: only {len(views)} usable views (target found in {seen} of {n_v} frames, "
                f"{min_c} corners needed per view); at least 3 varied views are needed, 10+ recommended")
    return usable


def _camera_poses(observations: Sequence[Observations], cams: Sequence[CameraModel],
                  dets: list[list[Detection | None]], usable: list[list[int]], obj: FloatArray,
                  min_view_spread_deg: float, known: Sequence[dict[int, FloatArray]] = ()
                  ) -> list[dict[int, FloatArray]]:
    """Per camera, the target pose of every usable view (``known[n]``'s, the initialisation's,
    where given; else by PnP); a camera whose views' target normals spread less than
    ``min_view_spread_deg`` is refused."""
    poses_cam: list[dict[int, FloatArray]] = []
    for n, cam in enumerate(cams):
        given = known[n] if n < len(known) else {}
        rest = [v for v in usable[n] if v not in given]
        rays = _view_rays(cam, {v: d for v in rest if (d := dets[n][v]) is not None})
        pc: dict[int, FloatArray] = {}
        for v in usable[n]:
            d = dets[n][v]
            assert d is not None
            T = given[v] if v in given else _pnp_rays(obj[d.ids], *rays[v])
            if T is not None:
                pc[v] = T
        poses_cam.append(pc)
        spread = _normal_spread_deg(list(pc.values()))
        if spread < min_view_spread_deg:
            raise CalibrationError(
                f"{observations[n].name}: the target's orientation varies by only {spread:.2f} deg over "
                f"{len(pc)} views (at least {min_view_spread_deg:g} deg needed: the focal length comes from "
                "differently tilted views); record views with the target tilted by 20-40 deg in "
                "different directions, or evaluate known intrinsics with --check camchain.yaml")
    return poses_cam


def _chain_init(observations: Sequence[Observations], cams: Sequence[CameraModel],
                dets: list[list[Detection | None]], poses_cam: list[dict[int, FloatArray]],
                target: CalibrationTarget) -> tuple[list[FloatArray], int]:
    """Initial ``T_cn_cnm1`` of every neighbouring pair, with every camera's corner numbering made
    consistent with the camera before it (``dets`` and ``poses_cam`` updated in place); returns
    the chain and the number of views renumbered."""
    chain_T: list[FloatArray] = []
    renumbered = 0
    for n in range(1, len(cams)):
        common = {v: T for v, T in poses_cam[n - 1].items() if v in poses_cam[n]}
        if not common:
            raise CalibrationError(
                f"{observations[n - 1].name} and {observations[n].name} share no view in which both "
                "see the target; the stereo extrinsics need simultaneous views (check the pairing "
                "of the image sets)")
        fixed, T_rel, changed = _consistent_numbering(common, dets[n], target, poses_cam[n])
        if T_rel is None or not fixed:
            raise CalibrationError(f"{observations[n].name}: no consistent relative pose to "
                                   f"{observations[n - 1].name} over {len(common)} common views")
        renumbered += changed
        for v, (d, T) in fixed.items():  # the pose of the chosen numbering, solved above
            dets[n][v] = d
            poses_cam[n][v] = T
        # views of camera n not shared with n-1: keep their numbering only if no other camera sees
        # them (their pose is then free); otherwise drop them from camera n
        for v in list(poses_cam[n]):
            if v not in fixed and any(dets[k][v] is not None for k in range(n)):
                dets[n][v] = None
                del poses_cam[n][v]
        chain_T.append(T_rel)
    return chain_T, renumbered


def _stack(cams: Sequence[CameraModel], dets: Sequence[Sequence[Detection | None]], view_ids: list[int],
           obj: FloatArray, posed: Sequence[dict[int, FloatArray]] | None = None, *,
           free: bool = True) -> _Problem:
    """The least-squares problem of the detections of ``view_ids`` (of views in ``posed[n]`` only,
    when given); ``free=False``: only the poses are estimated (intrinsics and chain given)."""
    vindex = {v: i for i, v in enumerate(view_ids)}
    o_pts, uv, cam_i, view_i = [], [], [], []
    for v in view_ids:  # rows by view (the normal equations take each view's rows as one slice)
        for n in range(len(cams)):
            d = dets[n][v]
            if d is None or (posed is not None and v not in posed[n]):
                continue
            o_pts.append(obj[d.ids])
            uv.append(d.corners_px)
            cam_i.append(np.full(len(d), n))
            view_i.append(np.full(len(d), vindex[v]))
    return _Problem(list(cams), np.concatenate(o_pts), np.concatenate(uv),
                    np.concatenate(cam_i).astype(np.int64), np.concatenate(view_i).astype(np.int64),
                    len(view_ids), free_intrinsics=free, free_chain=free)


def _first_poses(poses_cam: list[dict[int, FloatArray]], chain_T: list[FloatArray],
                 n_v: int) -> tuple[list[int], FloatArray]:
    """The views seen by any camera and each one's initial target pose in camera 0 (rotation
    vector, translation), from the first camera that sees it."""
    T_cn_c0 = [np.eye(4)]
    for T in chain_T:
        T_cn_c0.append(T @ T_cn_c0[-1])
    view_ids: list[int] = []
    pose0: list[FloatArray] = []
    for v in range(n_v):
        for n in range(len(poses_cam)):
            if v in poses_cam[n]:
                view_ids.append(v)
                pose0.append(_rt(np.linalg.inv(T_cn_c0[n]) @ poses_cam[n][v]))
                break
    return view_ids, np.array(pose0)


@dataclass(frozen=True, eq=False)
class _Refined:
    """The outcome of the outlier-rejection rounds: the last problem solved and its solution."""

    prob: _Problem
    intr: FloatArray
    chain: FloatArray
    poses: FloatArray
    sol: _Solution
    keep: npt.NDArray[np.bool_]
    rounds: int


def _outliers(full: _Problem, res: FloatArray, keep: npt.NDArray[np.bool_],
              outlier_sigma: float) -> npt.NDArray[np.bool_]:
    """Corners beyond ``outlier_sigma`` robust standard deviations (1.4826 MAD per axis, at least
    0.02 px) of their camera's kept residuals."""
    bad = np.zeros(len(res), bool)
    for n in range(full.n_cams):
        r = res[keep & (full.cam_i == n)]
        med = _median(r)
        sigma = np.maximum(1.4826 * _median(np.abs(r - med)), 0.02)
        out = np.abs(res - med) > outlier_sigma * sigma
        bad |= (full.cam_i == n) & (out[:, 0] | out[:, 1])
    return bad


def _refine(full: _Problem, intr: FloatArray, chain: FloatArray, poses: FloatArray, *,
            outlier_sigma: float, max_rounds: int, say: Callable[[str], Any]) -> _Refined:
    """Solve, remove the outlying corners, solve again until none is removed (``max_rounds``)."""
    keep = np.ones(len(full.uv), bool)
    prob = full
    rounds = 0
    sol = None
    for rounds in range(1, max_rounds + 1):
        say(f"refining (round {rounds})")
        prob = _Problem(full.cams, full.obj[keep], full.uv[keep], full.cam_i[keep], full.view_i[keep],
                        full.n_views)
        intr, chain, poses, sol = _solve(prob, intr, chain, poses, 1e-3 if sol is None else sol.damping)
        new_keep = ~_outliers(full, full.residuals(intr, chain, poses), keep, outlier_sigma)
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
        if any(not (keep & (full.cam_i == n)).any() for n in range(full.n_cams)):
            raise CalibrationError("outlier rejection removed every corner of a camera; the "
                                   "detections are inconsistent (wrong target description?)")
    assert sol is not None
    if sol.jac is None:  # the covariance needs the Jacobian at the solution
        sol = replace(sol, jac=prob.jacobian(intr, chain, poses))
    return _Refined(prob, intr, chain, poses, sol, keep, rounds)


def _view_rms(r: FloatArray, vi: IntArray, view_ids: Sequence[int]) -> dict[int, float]:
    """RMS residual [px] of every view index in ``vi`` (named by ``view_ids``)."""
    return {view_ids[int(k)]: float(np.sqrt(np.mean(np.sum(r[vi == k] ** 2, axis=1))))
            for k in sorted(set(vi.tolist()))}


def _camera_results(observations: Sequence[Observations], cams: Sequence[CameraModel], ref: _Refined,
                    full: _Problem, res: FloatArray, cov: FloatArray,
                    view_ids: list[int]) -> list[CameraCalibration]:
    """Every camera's estimate, standard deviations and residual statistics."""
    out = []
    prob = ref.prob
    for n, o in enumerate(observations):
        sd = np.sqrt(np.clip(np.diag(cov)[8 * n:8 * n + 8], 0, None))
        sel = prob.cam_i == n
        r = res[sel]
        view_rms = _view_rms(r, prob.view_i[sel], view_ids)
        out.append(CameraCalibration(
            o.name, _camera(cams[n], ref.intr[n]), {"intrinsics": [float(v) for v in sd[:4]],
                                                    "distortion_coeffs": [float(v) for v in sd[4:]]},
            ResidualStats.of(r, len(view_rms)), r.copy(), prob.uv[sel].copy(), view_rms,
            int((~ref.keep & (full.cam_i == n)).sum()), cov[8 * n:8 * n + 8, 8 * n:8 * n + 8].copy()))
    return out


def _chain_results(chain: FloatArray, cov: FloatArray, ni: int
                   ) -> tuple[list[FloatArray], list[dict[str, list[float]]], list[float], list[float]]:
    """Every ``T_cn_cnm1``, its rotation and translation standard deviations, baseline and its std."""
    Ts, Tstd, base, base_sd = [], [], [], []
    for k in range(len(chain)):
        T = _T(chain[k, :3], chain[k, 3:])
        C = cov[ni + 6 * k: ni + 6 * k + 6, ni + 6 * k: ni + 6 * k + 6]
        t = T[:3, 3]
        u = t / max(float(np.linalg.norm(t)), 1e-12)
        Ts.append(T)
        Tstd.append({"rotation_std_deg": [float(v) for v in np.degrees(np.sqrt(np.clip(np.diag(C)[:3], 0, None)))],
                     "translation_std_m": [float(v) for v in np.sqrt(np.clip(np.diag(C)[3:], 0, None))]})
        base.append(float(np.linalg.norm(t)))
        base_sd.append(float(np.sqrt(max(float(u @ C[3:, 3:] @ u), 0.0))))
    return Ts, Tstd, base, base_sd


def _check_observations(observations: Sequence[Observations], model: str) -> int:
    """The number of views; :class:`IbiscapeError` for an unknown model or inconsistent input."""
    if model not in MODELS:
        raise IbiscapeError(f"model {model!r}: use one of {', '.join(MODELS)}")
    if not observations:
        raise IbiscapeError("no cameras to calibrate")
    n_v = len(observations[0].detections)
    if any(len(o.detections) != n_v for o in observations):
        raise IbiscapeError("every camera needs one detection entry per view")
    return n_v


def calibrate(target: CalibrationTarget, observations: Sequence[Observations], *,
              model: str = "pinhole-radtan", outlier_sigma: float = 5.0, min_corners: int | None = None,
              max_rounds: int = 4, progress: Callable[[str], Any] | None = None,
              min_view_spread_deg: float = MIN_VIEW_SPREAD_DEG) -> CalibrationResult:
    """Calibrate one camera or a chain of cameras from per-view detections.

    Parameters
    ----------
    target
        The planar target whose corners were detected.
    observations
        One :class:`Observations` per camera in chain order; ``detections[v]`` of every camera is
        the same instant ``v`` (None where the target was not found).
    model
        ``"pinhole-radtan"`` or ``"pinhole-equi"`` (Kalibr's names).
    outlier_sigma
        Corners with a residual beyond this many robust standard deviations (1.4826 MAD per axis)
        are removed, then the problem is solved again.
    min_corners
        Corners a view needs to be used (default: all corners of a checkerboard, 8 of an AprilGrid).
    progress
        Called with a short stage name.
    min_view_spread_deg
        Largest angle between the target normals of two views a camera needs (see
        :data:`MIN_VIEW_SPREAD_DEG`).

    Raises
    ------
    CalibrationError
        Too few views, views of (nearly) one target orientation, no common views between
        neighbouring cameras, a failed initialisation.
    """
    n_v = _check_observations(observations, model)
    min_c = _min_corners(target, min_corners)
    obj = target.object_points()
    say = progress or (lambda _s: None)
    usable = _usable_views(observations, target, min_c, n_v)
    say("initialising")
    inits = _init_cameras(observations, target, usable, MODELS[model])
    cams = [c for c, _ in inits]
    ok_views = [set(views) for views in usable]
    dets: list[list[Detection | None]] = [[d if v in ok else None for v, d in enumerate(o.detections)]
                                          for o, ok in zip(observations, ok_views, strict=True)]
    poses_cam = _camera_poses(observations, cams, dets, usable, obj, min_view_spread_deg,
                              [T for _, T in inits])
    chain_T, renumbered = _chain_init(observations, cams, dets, poses_cam, target)
    view_ids, pose0 = _first_poses(poses_cam, chain_T, n_v)
    full = _stack(cams, dets, view_ids, obj, poses_cam)
    intr = np.array([[c.fx, c.fy, c.cx, c.cy, *c.coeffs] for c in cams])
    chain = np.array([_rt(T) for T in chain_T]).reshape(-1, 6)
    ref = _refine(full, intr, chain, pose0, outlier_sigma=outlier_sigma, max_rounds=max_rounds, say=say)
    say("uncertainties")
    ni, _nc, npose = ref.prob.layout()
    res = ref.prob.residuals(ref.intr, ref.chain, ref.poses)
    cov, unc = _covariance(ref.sol, npose, res, ref.prob.cam_i, ref.prob.view_i)
    cam_results = _camera_results(observations, cams, ref, full, res, cov, view_ids)
    Ts, Tstd, base, base_sd = _chain_results(ref.chain, cov, ni)
    return CalibrationResult(model, target, tuple(cam_results), tuple(Ts), tuple(Tstd), tuple(base),
                             tuple(base_sd), len(view_ids), tuple(view_ids), renumbered, ref.rounds,
                             extra={"uncertainty": unc})


def _align_numbering(target: CalibrationTarget, cam: CameraModel, d: Detection, T_cn_t: FloatArray) -> Detection:
    """``d`` renumbered by the target symmetry whose corners, at pose ``T_cn_t``, project closest."""
    obj = target.object_points()
    best, best_e = None, np.inf
    for perm in target.symmetries():
        ids = perm[d.ids]
        pred = cam.project(obj[ids] @ T_cn_t[:3, :3].T + T_cn_t[:3, 3])
        e = float(np.nanmean(np.sum((pred - d.corners_px) ** 2, axis=1)))
        if e < best_e:
            best, best_e = ids, e
    assert best is not None
    order = np.argsort(best)
    return Detection(best[order], d.corners_px[order], d.image_size)


def _given_poses(target: CalibrationTarget, cameras: Sequence[CameraModel], dets: list[list[Detection | None]],
                 T_cn_c0: list[FloatArray]) -> tuple[list[int], list[FloatArray]]:
    """Per view, the target pose in camera 0 from the first camera that sees it, and every other
    camera's numbering aligned to it through the given chain (``dets`` updated in place)."""
    obj = target.object_points()
    view_ids, pose0 = [], []
    for v in range(len(dets[0])):
        T0 = None
        for n, cam in enumerate(cameras):
            d = dets[n][v]
            if d is None:
                continue
            if T0 is None:
                Tp = _pnp(cam, obj[d.ids], d.corners_px)
                if Tp is not None:
                    T0 = np.linalg.inv(T_cn_c0[n]) @ Tp
                continue
            dets[n][v] = _align_numbering(target, cam, d, T_cn_c0[n] @ T0)
        if T0 is not None:
            view_ids.append(v)
            pose0.append(_rt(T0))
    return view_ids, pose0


def evaluate(target: CalibrationTarget, observations: Sequence[Observations], cameras: Sequence[CameraModel],
             T_cn_cnm1: Sequence[FloatArray], *, min_corners: int | None = None,
             outlier_px: float = 1.0) -> dict[str, Any]:
    """Check a given calibration on detections without re-estimating it (``--check``).

    Only the target pose of every view is estimated (from all cameras jointly, with the given
    intrinsics and extrinsics); then reprojection statistics per camera and per view.  Views
    whose RMS exceeds ``outlier_px`` are listed as outliers.
    """
    if len(cameras) != len(observations) or len(T_cn_cnm1) != len(cameras) - 1:
        raise IbiscapeError(f"the calibration has {len(cameras)} cameras but {len(observations)} image "
                            "sets were given; give one image set per camera of the chain")
    min_c = _min_corners(target, min_corners)
    T_cn_c0 = [np.eye(4)]
    for T in T_cn_cnm1:
        T_cn_c0.append(np.asarray(T) @ T_cn_c0[-1])
    for o, cam in zip(observations, cameras, strict=True):
        if tuple(o.image_size) != (cam.width_px, cam.height_px):
            raise IbiscapeError(f"{o.name}: images are {o.image_size[0]}x{o.image_size[1]} but the "
                                f"calibration says {cam.width_px}x{cam.height_px}; is it the right file?")
    dets = [[d if _usable(d, target, min_c) else None for d in o.detections] for o in observations]
    view_ids, pose0 = _given_poses(target, cameras, dets, T_cn_c0)
    if not view_ids:
        raise CalibrationError("the target was not found with enough corners in any view")
    prob = _stack(cameras, dets, view_ids, target.object_points(), free=False)
    intr = np.array([[c.fx, c.fy, c.cx, c.cy, *c.coeffs] for c in cameras])
    chain = np.array([_rt(np.asarray(T)) for T in T_cn_cnm1]).reshape(-1, 6)
    _, _, poses, _ = _solve(prob, intr, chain, np.array(pose0))
    res = prob.residuals(intr, chain, poses)
    cams_out = []
    outliers = []
    for n, o in enumerate(observations):
        sel = prob.cam_i == n
        r = res[sel]
        per_view = _view_rms(r, prob.view_i[sel], view_ids)
        stats = ResidualStats.of(r, len(per_view))
        cams_out.append({"name": o.name, "reprojection_error": stats.to_dict(),
                         "reprojection_error_kalibr": stats.kalibr(),
                         "view_rms_px": {str(k): v for k, v in per_view.items()}})
        outliers += [{"camera": o.name, "view": int(k), "rms_px": v} for k, v in per_view.items()
                     if v > outlier_px]
    rms = float(np.sqrt(np.mean(np.sum(res**2, axis=1))))
    return {"cameras": cams_out, "rms_px": rms, "n_views": len(view_ids), "outlier_px": outlier_px,
            "outlier_views": outliers}
