"""The batch problem: spline trajectory, biases, gravity and per-camera extrinsics / time offsets;
whitened residuals and their sparse normal equations.

Unknowns (tangent-space layout of a step)::

    [ rotation control points (3 Nc) | position control points (3 Nc) | bias knots (6 Nb) |
      gravity direction (2) | per camera: rotation (3), translation (3), time offset (1) ]

- ``T_target_imu(t)``: one cumulative cubic B-spline per *piece* (a stretch of time with target
  views; long gaps without the target are cut out), knots every ``dt_s``.
- Biases ``b_g(t), b_a(t)``: linear interpolation between knots every ``bias_knot_s`` with a
  random-walk prior between consecutive knots (Kalibr's densities).
- Gravity ``g = R_g (0, 0, -|g|)`` in the target frame; a step rotates ``R_g`` about its x and y axes.
- Camera ``c``: ``T_cam_imu = [R_ci | t_ci]`` (step: ``R_ci <- R_ci Exp(d)``, ``t_ci += d``) and
  ``timeshift_cam_imu`` ``s_c``: the image stamped ``t`` on the camera clock shows the pose at
  ``t + s_c`` on the IMU clock (Kalibr's convention).

Residuals, each divided by its standard deviation:

- gyroscope ``w(t_k) + b_g(t_k) - gyro_k``, sigma ``N_g sqrt(rate)``;
- accelerometer ``R(t_k)^T (p''(t_k) - g) + b_a(t_k) - accel_k``, sigma ``N_a sqrt(rate)``;
- reprojection ``pi(R_ci R(t)^T (X - p(t)) + t_ci) - uv`` at ``t = t_frame + s_c``, sigma ``sigma_px``.

Jacobians: exact, vectorised over samples: positions, biases, translations, the time offset
(through the spline's velocity and angular rate) and the camera rotation directly; the rotation
control points through the cumulative spline's chain rule (:func:`.spline.rotation_jacobians`), the
projection through the distortion model (:func:`ibiscape_eval.calib._lsq.project_jacobian`).  Per-block
``J^T J`` (IMU samples sharing a segment stacked into one product) is summed by ``np.bincount``
straight into the blocks the solver factorises (:class:`Normal`: a band of the control points, its
border with the other parameters, their dense block).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.so3 import exp_so3, hat

from .._lsq import project_jacobian
from .spline import basis, position, rotation, rotation_jacobians

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

_ARANGE4 = np.arange(4)


class Piece(NamedTuple):
    """One spline piece: knots ``t0_s + k dt_s`` for ``k = 0..n_seg`` (``n_seg`` segments), control
    points ``offset .. offset + n_seg + 2``."""

    t0_s: float
    n_seg: int
    offset: int
    dt_s: float

    @property
    def t1_s(self) -> float:
        """The last knot."""
        return self.t0_s + self.n_seg * self.dt_s

    @property
    def n_ctrl(self) -> int:
        """Control points of the piece (a cubic B-spline: segments + 3)."""
        return self.n_seg + 3

    def covers(self, t_s: FloatArray) -> npt.NDArray[np.bool_]:
        """Which times lie between the first and the last knot."""
        return (t_s >= self.t0_s) & (t_s <= self.t1_s)


@dataclass(frozen=True, eq=False)
class CameraBlock:
    """Static data of one camera: frames with the target, padded corners."""

    name: str
    camera: CameraModel
    t_s: FloatArray  # (F,) frame times on the camera clock, s from t_ref
    X: FloatArray  # (F, M, 3) target corners
    uv: FloatArray  # (F, M, 2) observations
    mask: FloatArray  # (F, M) 1 observed, 0 padding
    #: this camera's corner noise [px] (None: the problem's ``sigma_px``)
    sigma_px: float | None = None


@dataclass(frozen=True, eq=False, kw_only=True)
class Problem:
    """The data, weights and layout of one batch problem (built by keyword; a changed problem, e.g.
    on other knots or with other camera weights, is a new value made by ``dataclasses.replace``)."""

    dt_s: float
    pieces: tuple[Piece, ...]
    n_ctrl: int
    bias_t0_s: float
    bias_dt_s: float
    n_bias: int
    imu_t_s: FloatArray
    gyro: FloatArray
    accel: FloatArray
    sigma_gyro: float
    sigma_accel: float
    bias_walk_sigma: FloatArray  # (6,) per knot interval
    gravity_m_s2: float
    cams: tuple[CameraBlock, ...]
    sigma_px: float
    bias_prior_sigma: FloatArray = field(default_factory=lambda: np.array([0.1] * 3 + [2.0] * 3))
    trans_prior_sigma_m: float = 20.0
    #: 4 when the focal lengths and principal points are refined too (fx, fy, cx, cy per camera)
    n_intr: int = 0

    def cam_sigma_px(self, c: int) -> float:
        """Corner noise of camera ``c`` [px]."""
        s = self.cams[c].sigma_px
        return self.sigma_px if s is None else s

    @property
    def cam_width(self) -> int:
        """Parameters per camera: rotation 3, translation 3, time offset 1, intrinsics."""
        return 7 + self.n_intr

    # ---- layout
    @property
    def n_params(self) -> int:
        return 6 * self.n_ctrl + 6 * self.n_bias + 2 + self.cam_width * len(self.cams)

    @property
    def i_bias(self) -> int:
        return 6 * self.n_ctrl

    @property
    def i_grav(self) -> int:
        return 6 * self.n_ctrl + 6 * self.n_bias

    def i_cam(self, c: int) -> int:
        return self.i_grav + 2 + self.cam_width * c

    def locate(self, t_s: FloatArray) -> tuple[IntArray, FloatArray, npt.NDArray[np.bool_]]:
        """Global control-point base index, segment position u and validity for times (n,)."""
        base = np.zeros(t_s.shape, np.int64)
        u = np.zeros(t_s.shape)
        ok = np.zeros(t_s.shape, bool)
        for pc in self.pieces:
            x = (t_s - pc.t0_s) / self.dt_s
            inside = (x >= 0) & (x <= pc.n_seg) & ~ok
            i = np.clip(np.floor(x).astype(np.int64), 0, pc.n_seg - 1)
            base = np.where(inside, pc.offset + i, base)
            u = np.where(inside, x - i, u)
            ok |= inside
        return base, u, ok

    def bias_locate(self, t_s: FloatArray) -> tuple[IntArray, FloatArray]:
        x = (t_s - self.bias_t0_s) / self.bias_dt_s
        k = np.clip(np.floor(x).astype(np.int64), 0, self.n_bias - 2)
        return k, np.clip(x - k, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class State:
    """The unknowns at one iterate (a step makes a new value: :meth:`retract`)."""

    R_ctrl: FloatArray  # (Nc, 3, 3) R_target_imu control points
    P_ctrl: FloatArray  # (Nc, 3)
    bias: FloatArray  # (Nb, 6) gyro, accel
    R_g: FloatArray  # (3, 3)
    R_ci: FloatArray  # (C, 3, 3)
    t_ci: FloatArray  # (C, 3)
    shift_s: FloatArray  # (C,)
    intr: FloatArray | None = None  # (C, 4) fx, fy, cx, cy when refined

    def camera(self, prob: Problem, c: int) -> CameraModel:
        """Camera ``c`` with the current intrinsics."""
        cam = prob.cams[c].camera
        if self.intr is None:
            return cam
        fx, fy, cx, cy = (float(v) for v in self.intr[c])
        return replace(cam, fx=fx, fy=fy, cx=cx, cy=cy)

    def gravity(self, g: float) -> FloatArray:
        return self.R_g @ np.array([0.0, 0.0, -g])

    def retract(self, prob: Problem, d: FloatArray) -> State:
        """The state moved by the tangent step ``d`` (layout: the module's docstring)."""
        n = prob.n_ctrl
        R_ci, t_ci, shift_s = self.R_ci.copy(), self.t_ci.copy(), self.shift_s.copy()
        intr = None if self.intr is None else self.intr.copy()
        for c in range(len(prob.cams)):
            k = prob.i_cam(c)
            R_ci[c] = self.R_ci[c] @ exp_so3(d[k : k + 3])
            t_ci[c] = self.t_ci[c] + d[k + 3 : k + 6]
            shift_s[c] = self.shift_s[c] + d[k + 6]
            if prob.n_intr and intr is not None and self.intr is not None:
                intr[c] = self.intr[c] + d[k + 7 : k + 11]
        dg = d[prob.i_grav : prob.i_grav + 2]
        return State(self.R_ctrl @ exp_so3(d[: 3 * n].reshape(n, 3)),
                     self.P_ctrl + d[3 * n : 6 * n].reshape(n, 3),
                     self.bias + d[prob.i_bias : prob.i_grav].reshape(-1, 6),
                     self.R_g @ exp_so3(np.array([dg[0], dg[1], 0.0])), R_ci, t_ci, shift_s, intr)


#: rows per partial product in :func:`tdot` / :func:`rows_dot`: OpenBLAS runs a product of more
#: than ~2.6e5 multiply-adds on all its threads, and on a busy 2-core machine (the test suite on
#: two xdist workers) those threads wait for each other: a (3618, 34)^T (3618, 34) product took
#: 15 ms CPU / 30 ms wall against 0.2 ms for the same sum over blocks of 256 rows (measured)
_BLOCK_ROWS = 256


def tdot(A: FloatArray, B: FloatArray) -> FloatArray:
    """``A^T B`` of tall matrices (n, p), (n, q) summed over blocks of rows (each block's product
    small enough to run on one BLAS thread; the same sum, another order of the additions)."""
    out = np.zeros((A.shape[1], B.shape[1]))
    for a in range(0, A.shape[0], _BLOCK_ROWS):
        out += A[a : a + _BLOCK_ROWS].T @ B[a : a + _BLOCK_ROWS]
    return out


def rows_dot(A: FloatArray, B: FloatArray) -> FloatArray:
    """``A B`` of a tall ``A`` (n, p) computed over blocks of rows (see :func:`tdot`)."""
    out = np.empty((A.shape[0], *B.shape[1:]))
    for a in range(0, A.shape[0], _BLOCK_ROWS):
        out[a : a + _BLOCK_ROWS] = A[a : a + _BLOCK_ROWS] @ B
    return out


# ------------------------------------------------------------------------------------------------
# residual blocks


def _spline_at(prob: Problem, st: State, base: IntArray, u: FloatArray, *, jac: bool
               ) -> tuple[IntArray, FloatArray, FloatArray, FloatArray | None, FloatArray | None, FloatArray]:
    """Control-point indices (n, 4) of the spline segments ``base`` at fractions ``u``, the
    rotation, the angular rate, with ``jac`` their Jacobians on the rotation control points (else
    None), and the segments' position control points."""
    idx = base[:, None] + _ARANGE4
    if jac:
        R, w, J_R, J_w = rotation_jacobians(st.R_ctrl[idx], u, prob.dt_s)
        return idx, R, w, J_R, J_w, st.P_ctrl[idx]
    R, w_ = rotation(st.R_ctrl[idx], u, prob.dt_s)
    assert w_ is not None
    return idx, R, w_, None, None, st.P_ctrl[idx]


def imu_block(prob: Problem, st: State, *, jac: bool
              ) -> tuple[FloatArray, FloatArray | None, IntArray | None, IntArray | None]:
    """IMU residuals (n, 6); with ``jac``: local Jacobians (n, 6, 38), their global column indices
    (n, 38) and a group key per sample (samples with equal keys share all columns)."""
    t = prob.imu_t_s
    base, u, _ = prob.locate(t)
    idx, R, w, J_R, J_w, Pl = _spline_at(prob, st, base, u, jac=jac)
    _, _, acc = position(Pl, u, prob.dt_s)
    k, al = prob.bias_locate(t)
    b = (1.0 - al)[:, None] * st.bias[k] + al[:, None] * st.bias[k + 1]
    g = st.gravity(prob.gravity_m_s2)
    sg, sa = prob.sigma_gyro, prob.sigma_accel
    r = np.empty((t.size, 6))
    r[:, :3] = (w + b[:, :3] - prob.gyro) / sg
    f = np.einsum("nji,nj->ni", R, acc - g)
    r[:, 3:] = (f + b[:, 3:] - prob.accel) / sa
    if not jac:
        return r, None, None, None
    assert J_R is not None and J_w is not None
    n = t.size
    J = np.zeros((n, 6, 38))
    # rotation control points: w exactly; f = R^T (acc - g) moves by [f]x J_R delta
    J[:, :3, :12] = J_w / sg
    J[:, 3:, :12] = hat(f) @ J_R / sa
    _, _, ddb = basis(u)
    ddb = ddb / prob.dt_s**2
    for j in range(4):  # positions: f = R^T (sum_j ddb_j P_j - g)
        J[:, 3:, 12 + 3 * j : 15 + 3 * j] = ddb[:, j, None, None] * np.swapaxes(R, 1, 2) / sa
    eye = np.eye(3)
    J[:, :3, 24:27] = (1 - al)[:, None, None] * eye / sg
    J[:, 3:, 27:30] = (1 - al)[:, None, None] * eye / sa
    J[:, :3, 30:33] = al[:, None, None] * eye / sg
    J[:, 3:, 33:36] = al[:, None, None] * eye / sa
    g0 = np.array([0.0, 0.0, -prob.gravity_m_s2])
    dg = st.R_g @ hat(g0)  # g(d) = R_g Exp(d) g0  ->  dg/dd = -R_g [g0]x ; r_a has -R^T g
    for a in range(2):
        J[:, 3:, 36 + a] = np.einsum("nji,j->ni", R, dg[:, a]) / sa
    cols = np.empty((n, 38), np.int64)
    cols[:, :12] = (3 * idx[:, :, None] + np.arange(3)).reshape(n, 12)
    cols[:, 12:24] = 3 * prob.n_ctrl + cols[:, :12]
    cols[:, 24:30] = prob.i_bias + 6 * k[:, None] + np.arange(6)
    cols[:, 30:36] = cols[:, 24:30] + 6
    cols[:, 36:38] = prob.i_grav + np.arange(2)
    key = base * (prob.n_bias + 1) + k
    return r, J, cols, key


def camera_block(prob: Problem, st: State, c: int, *, jac: bool
                 ) -> tuple[FloatArray, FloatArray | None, IntArray | None, npt.NDArray[np.bool_]]:
    """Reprojection residuals (F, M, 2) of camera ``c`` (zero on padding and outside the spline);
    with ``jac``: local Jacobians (F, M, 2, 31 [+ 4 intrinsics]) and global columns (F, 31 [+ 4])."""
    cb = prob.cams[c]
    t = cb.t_s + st.shift_s[c]
    base, u, inside = prob.locate(t)
    idx, R, w, J_R, _, Pl = _spline_at(prob, st, base, u, jac=jac)
    p, v, _ = position(Pl, u, prob.dt_s)
    Rci, tci = st.R_ci[c], st.t_ci[c]
    D = cb.X - p[:, None, :]  # (F, M, 3)
    q = D @ R  # R^T (X - p) per corner, as rows
    pc = q @ Rci.T + tci
    z = pc[..., 2]
    valid = (cb.mask > 0) & inside[:, None] & (z > 1e-3)
    camera = st.camera(prob, c)
    uv = camera.project(np.where(valid[..., None], pc, np.array([0.0, 0.0, 1.0])))
    s = prob.cam_sigma_px(c)
    r = np.where(valid[..., None], (uv - cb.uv) / s, 0.0)
    if not jac:
        return r, None, None, valid
    assert J_R is not None
    F, M = z.shape
    # projection Jacobian (F, M, 2, 3), exact (pinhole with radtan or equidistant distortion)
    pcv = np.where(valid[..., None], pc, np.array([0.0, 0.0, 1.0]))
    intr = np.array([camera.fx, camera.fy, camera.cx, camera.cy, *camera.coeffs])
    _, _, Jp = project_jacobian(camera.distortion, intr, pcv.reshape(-1, 3))
    Jp = Jp.reshape(F, M, 2, 3) * (valid[..., None, None] / s)
    # J = Jp dpc/dx with pc = R_ci R^T (X - p) + t_ci, in products of one frame's rows (F items,
    # not F M): q = R^T (X - p) moves by [q]x J_R delta (rotation control points), R_ci by -[q]x d
    J = np.empty((F, M, 2, 31 + prob.n_intr))
    JpR = (Jp.reshape(-1, 3) @ Rci).reshape(F, M, 2, 3)
    JRq = np.cross(JpR, q[:, :, None, :])  # Jp R_ci [q]x, row-wise: x^T [q]x = x cross q
    J[..., :12] = (JRq.reshape(F, 2 * M, 3) @ J_R).reshape(F, M, 2, 12)
    b, _, _ = basis(u)
    A = -np.einsum("ij,nkj->nik", Rci, R)  # -R_ci R^T  (F, 3, 3)
    JA = (Jp.reshape(F, 2 * M, 3) @ A).reshape(F, M, 2, 3)
    for j in range(4):
        J[..., 12 + 3 * j : 15 + 3 * j] = b[:, j, None, None, None] * JA
    J[..., 24:27] = -JRq
    J[..., 27:30] = Jp
    # d q / d t = -[w]x q - R^T v
    dq_dt = -np.cross(w[:, None, :], q) - np.einsum("nji,nj->ni", R, v)[:, None, :]
    J[..., 30] = np.einsum("fmij,fmj->fmi", Jp, dq_dt @ Rci.T)
    if prob.n_intr:  # u = fx xd + cx, v = fy yd + cy (pinhole with radtan or equidistant)
        Ji = J[..., 31:]
        Ji[...] = 0.0
        Ji[..., 0, 0] = (uv[..., 0] - camera.cx) / camera.fx
        Ji[..., 1, 1] = (uv[..., 1] - camera.cy) / camera.fy
        Ji[..., 0, 2] = 1.0
        Ji[..., 1, 3] = 1.0
        Ji *= valid[..., None, None] / s
    cols = np.empty((F, 31 + prob.n_intr), np.int64)
    cols[:, :12] = (3 * idx[:, :, None] + np.arange(3)).reshape(F, 12)
    cols[:, 12:24] = 3 * prob.n_ctrl + cols[:, :12]
    cols[:, 24:] = prob.i_cam(c) + np.arange(7 + prob.n_intr)
    return r, J, cols, valid


def prior_block(prob: Problem, st: State) -> tuple[FloatArray, FloatArray, IntArray]:
    """Bias random walk between knots, weak priors on biases and translations: (r, J, cols) with
    one row per residual (dense rows of a few entries)."""
    rows_r, rows_J, rows_c = [], [], []
    nb = prob.n_bias
    if nb > 1:
        sw = prob.bias_walk_sigma
        d = (st.bias[1:] - st.bias[:-1]) / sw  # (nb-1, 6)
        kk = np.arange(nb - 1)
        for a in range(6):
            rows_r.append(d[:, a])
            rows_J.append(np.stack((-np.ones(nb - 1), np.ones(nb - 1)), -1) / sw[a])
            rows_c.append(np.stack((prob.i_bias + 6 * kk + a, prob.i_bias + 6 * (kk + 1) + a), -1))
    sp = prob.bias_prior_sigma
    kb = np.arange(nb)
    for a in range(6):
        rows_r.append(st.bias[:, a] / sp[a])
        rows_J.append(np.stack((np.full(nb, 1.0 / sp[a]), np.zeros(nb)), -1))
        rows_c.append(np.stack((prob.i_bias + 6 * kb + a, prob.i_bias + 6 * kb + a), -1))
    for c in range(len(prob.cams)):
        i0 = prob.i_cam(c) + 3
        rows_r.append(st.t_ci[c] / prob.trans_prior_sigma_m)
        rows_J.append(np.tile([1.0 / prob.trans_prior_sigma_m, 0.0], (3, 1)))
        rows_c.append(np.stack((i0 + np.arange(3), i0 + np.arange(3)), -1))
    return np.concatenate(rows_r), np.concatenate(rows_J), np.concatenate(rows_c)


# ------------------------------------------------------------------------------------------------
# cost and normal equations


def residuals(prob: Problem, st: State) -> dict[str, FloatArray]:
    """Whitened residuals by kind: ``imu`` (n, 6), ``cam<c>`` (F, M, 2), ``prior``."""
    out: dict[str, FloatArray] = {"imu": imu_block(prob, st, jac=False)[0]}
    for c in range(len(prob.cams)):
        out[f"cam{c}"] = camera_block(prob, st, c, jac=False)[0]
    out["prior"] = prior_block(prob, st)[0]
    return out


def cost(prob: Problem, st: State) -> float:
    return 0.5 * float(sum(np.sum(r * r) for r in residuals(prob, st).values()))


#: local columns of the IMU and camera Jacobians that are control points (rotation, position)
_N_CTRL_LOCAL = 24


@dataclass(frozen=True, eq=False)
class Normal:
    """``H = J^T J`` in the solver's blocks: the control points, reordered so that the rotation and
    position of each knot are neighbours (``ctrl``: parameter index of each position), form a band
    of half-width 23 (``band``, LAPACK's lower storage, (24, 6 Nc)); ``border`` (6 Nc, m) couples
    them with the ``m`` other parameters (biases, gravity, cameras), whose block is ``dense``."""

    band: FloatArray
    border: FloatArray
    dense: FloatArray
    ctrl: IntArray

    @property
    def n(self) -> int:
        return self.ctrl.size + self.dense.shape[0]

    def diagonal(self) -> FloatArray:
        """The diagonal in the parameter layout."""
        d = np.empty(self.n)
        d[self.ctrl] = self.band[0]
        d[self.ctrl.size :] = np.diagonal(self.dense)
        return d

    def plus_diagonal(self, add: FloatArray) -> Normal:
        """``H + diag(add)`` (``add`` in the parameter layout)."""
        band, dense = self.band.copy(), self.dense.copy()
        band[0] += add[self.ctrl]
        dense[np.diag_indices_from(dense)] += add[self.ctrl.size :]
        return Normal(band, self.border, dense, self.ctrl)

    def sparse(self) -> Any:
        """The whole matrix as a scipy CSC matrix in the parameter layout."""
        import scipy.sparse as sp

        nc6 = self.ctrl.size
        rows, cols, vals = [], [], []
        for k in range(self.band.shape[0]):
            j = np.arange(nc6 - k)
            rows += [self.ctrl[j + k], self.ctrl[j]] if k else [self.ctrl[j]]
            cols += [self.ctrl[j], self.ctrl[j + k]] if k else [self.ctrl[j]]
            vals += [self.band[k, : nc6 - k]] * (2 if k else 1)
        bi, bj = np.nonzero(self.border)
        di, dj = np.nonzero(self.dense)
        rows += [self.ctrl[bi], nc6 + bj, nc6 + di]
        cols += [nc6 + bj, self.ctrl[bi], nc6 + dj]
        vals += [self.border[bi, bj]] * 2 + [self.dense[di, dj]]
        return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(self.n, self.n))


def _sum_at(index: IntArray, values: FloatArray, n: int) -> FloatArray:
    """``out[index] += values`` with repeated indices summed, (n,)."""
    return np.asarray(np.bincount(index.ravel(), values.ravel(), n), np.float64)


class _Assembly:
    """Square blocks of ``J^T J`` (local Jacobian columns: ``_N_CTRL_LOCAL`` control-point columns,
    then other parameters) summed into a :class:`Normal` by ``np.bincount`` (no sparse matrix,
    no sort of duplicates)."""

    def __init__(self, prob: Problem):
        nc = prob.n_ctrl
        k = np.arange(nc)
        self.ctrl = np.stack([3 * k, 3 * k + 1, 3 * k + 2, 3 * nc + 3 * k, 3 * nc + 3 * k + 1,
                              3 * nc + 3 * k + 2], -1).ravel()
        self.nc6, self.m = 6 * nc, prob.n_params - 6 * nc
        self.where = np.empty(prob.n_params, np.int64)  # band position / border column
        self.where[self.ctrl] = np.arange(self.nc6)
        self.where[self.nc6 :] = np.arange(self.m)
        self.bw = min(_N_CTRL_LOCAL, self.nc6)
        self.band = np.zeros(self.bw * self.nc6)
        self.border = np.zeros(self.nc6 * self.m)
        self.dense = np.zeros(self.m * self.m)

    def add(self, H: FloatArray, cols: IntArray, n_ctrl: int = _N_CTRL_LOCAL) -> None:
        """Blocks ``H`` (K, w, w) on the parameters ``cols`` (K, w), the first ``n_ctrl`` of them
        control points."""
        w = self.where[cols]
        if n_ctrl:
            pr, pc = w[:, :n_ctrl, None], w[:, None, :n_ctrl]
            lower = np.broadcast_to(pr >= pc, (H.shape[0], n_ctrl, n_ctrl))
            idx = (pr - pc) * self.nc6 + pc
            self.band += _sum_at(idx[lower], H[:, :n_ctrl, :n_ctrl][lower], self.band.size)
            idx = w[:, :n_ctrl, None] * self.m + w[:, None, n_ctrl:]
            self.border += _sum_at(idx, H[:, :n_ctrl, n_ctrl:], self.border.size)
        idx = w[:, n_ctrl:, None] * self.m + w[:, None, n_ctrl:]
        self.dense += _sum_at(idx, H[:, n_ctrl:, n_ctrl:], self.dense.size)

    def normal(self) -> Normal:
        return Normal(self.band.reshape(self.bw, self.nc6), self.border.reshape(self.nc6, self.m),
                      self.dense.reshape(self.m, self.m), self.ctrl)


def _imu_normal(prob: Problem, st: State, asm: _Assembly) -> tuple[FloatArray, float]:
    """The IMU rows' ``J^T J`` added to ``asm`` (the samples that share all columns, one spline
    segment and bias interval, stacked into one product each); returns ``J^T r`` and ``r^T r``."""
    r, J, cols, key = imu_block(prob, st, jac=True)
    assert J is not None and cols is not None and key is not None
    n = key.size
    starts = np.flatnonzero(np.r_[True, np.diff(key) != 0])
    group = np.cumsum(np.r_[True, np.diff(key) != 0]) - 1
    slot = np.arange(n) - starts[group]
    m = int(slot.max(initial=0)) + 1
    pad = np.zeros((starts.size, m, 6, J.shape[2]))
    pad[group, slot] = J
    Jg = pad.reshape(starts.size, 6 * m, J.shape[2])
    asm.add(np.swapaxes(Jg, 1, 2) @ Jg, cols[starts])
    gl = np.einsum("nij,ni->nj", J, r)
    return _sum_at(cols, gl, prob.n_params), float(np.sum(r * r))


def normal_equations(prob: Problem, st: State) -> tuple[Normal, FloatArray, float]:
    """``H = J^T J`` (:class:`Normal`), gradient ``J^T r`` and the cost at ``st``."""
    n = prob.n_params
    asm = _Assembly(prob)
    grad, total = _imu_normal(prob, st, asm)
    for c in range(len(prob.cams)):
        rc, Jc, colc, _ = camera_block(prob, st, c, jac=True)
        assert Jc is not None and colc is not None
        total += float(np.sum(rc * rc))
        Jf = Jc.reshape(Jc.shape[0], -1, Jc.shape[-1])  # (F, 2M, 31)
        Jft = np.swapaxes(Jf, 1, 2)
        asm.add(Jft @ Jf, colc)
        gc = (Jft @ rc.reshape(rc.shape[0], -1, 1))[..., 0]
        grad += _sum_at(colc, gc, n)
    rp, Jp, colp = prior_block(prob, st)
    total += float(np.sum(rp * rp))
    asm.add(np.einsum("np,nq->npq", Jp, Jp), colp, 0)
    grad += _sum_at(colp, Jp * rp[:, None], n)
    return asm.normal(), grad, 0.5 * total


# ------------------------------------------------------------------------------------------------
# covariance of the estimate


def estimate_covariance(prob: Problem, st: State, solve: Callable[[FloatArray], FloatArray],
                        columns: IntArray, *, n_probe: int = 16, chunk: int = 2048,
                        block_s: float = 1.0, intrinsics_cov: dict[int, FloatArray] | None = None
                        ) -> tuple[FloatArray, dict[str, Any]]:
    """Covariance of the least-squares estimate of the parameters ``columns``, with the noise the
    residuals show rather than the noise the weights assume (a sandwich estimator).

    With ``X = H^-1 E`` (``solve``: ``H^-1`` times a matrix; ``E`` selects ``columns``) the
    estimate moves by ``dx = -X^T J^T r`` when the whitened residuals at the truth are ``r``, so
    ``Cov = sum over residual groups of G_g^T Cov(r_g) G_g`` with ``G_g = J_g X``.  The plain
    ``E^T H^-1 E`` assumes ``Cov(r) = I``; here:

    - every residual group (gyroscope, accelerometer, each camera) is scaled by its measured
      variance ``SSR_g / (n_g - p_g)``, where ``p_g = trace(H^-1 J_g^T J_g)`` is the share of the
      parameters the group's residuals absorb (the spline takes a quarter of the IMU's degrees
      of freedom at 50 Hz knots; without it the IMU would look 25 % quieter than it is),
      estimated with ``n_probe`` seeded Rademacher probes (Hutchinson; the eigenvalues lie in
      [0, 1], so 16 probes give the trace within about 1 %).  An ``imu.yaml`` whose densities are
      10x the truth (Kalibr's advice for real IMUs) or a ``sigma_px`` far from the corner noise
      then no longer scales the reported std by the same factor;
    - the bias is a random walk that the model interpolates linearly between knots
      ``bias_dt_s`` apart: at the truth the IMU residuals carry the walk's deviation from that
      line (a Brownian bridge, variance ``K^2 tau (T - tau) / T``, correlated over seconds).
      Its contribution is summed exactly over the walk's increments (reverse cumulative sums of
      ``G`` within each knot interval).

    Errors that the model takes for white but that are correlated over a fraction of a second
    to a second (a detector's bias that follows the board's slowly changing pose in the image,
    motion faster than the knots) are not in either term.  They are measured from the residuals
    by batch means: the scores ``G_i^T r_i`` of all residuals (IMU and cameras) are summed over
    blocks of ``block_s`` seconds, and ``B / (B - 1) sum_b U_b U_b^T`` (``B`` blocks) is a
    covariance that holds whatever the correlation within a block.  Per parameter the larger of
    the two variances is reported (with the model's correlations).

    Intrinsics held in the solve (the distortion; all eight when they are not refined) are
    known only as well as the camera calibration they come from: with ``intrinsics_cov[c]``
    (8x8, ``fx, fy, cx, cy, d0..d3``) their error propagates as ``S Cov_held S^T`` with the
    response ``S = -G^T J_held`` (central differences of the projection).  On the 24 s rendered
    drive with its own camera calibration this term is most of the error (0.44 deg, 45 mm).

    Returns the (k, k) covariance and ``{"residual_scale": {group: variance ratio},
    "dof_absorbed": {group: p_g}, "batch_means_ratio": [std ratio per column]}``.
    """
    probes = _Probes.of(prob, solve, columns, n_probe)
    k = probes.k
    r_imu, _, _, _ = imu_block(prob, st, jac=False)
    blocks = _TimeBlocks.of(prob, block_s)
    U = np.zeros((blocks.n + 1, k))  # batch-means scores per block of time
    A_imu = _imu_responses(prob, st, probes.W, chunk)
    np.add.at(U, blocks.index(prob.imu_t_s), np.einsum("nak,na->nk", A_imu[..., :k], r_imu))
    groups: list[_Group] = []
    for name, ax in (("gyro", slice(0, 3)), ("accel", slice(3, 6))):
        GtG, p_abs = probes.part(A_imu[:, ax].reshape(-1, probes.W.shape[1]))
        groups.append(_Group(name, float(np.sum(r_imu[:, ax] ** 2)), 3.0 * r_imu.shape[0], p_abs, GtG))
    held_cov = np.zeros((k, k))
    for c in range(len(prob.cams)):
        group, held = _camera_group(prob, st, c, probes, U, blocks,
                                    None if intrinsics_cov is None else intrinsics_cov.get(c))
        groups.append(group)
        held_cov += held
    cov, info = _scaled_groups(groups, k)
    cov = _add_bias_bridge(cov, prob, A_imu[..., :k])
    _, Jp, colp = prior_block(prob, st)
    Gp = np.einsum("nj,njk->nk", Jp, probes.W[colp, :k])
    cov += tdot(Gp, Gp)
    cov = 0.5 * (cov + cov.T) + 0.5 * (held_cov + held_cov.T)
    if intrinsics_cov:
        info["held_intrinsics_share"] = (np.diag(held_cov) / np.maximum(np.diag(cov), 1e-300)).tolist()
    return _batch_means(U, cov, info), info


@dataclass(frozen=True, eq=False)
class _Probes:
    """``W = [X | H^-1 Z | Z]``: the responses ``X = H^-1 E`` of the ``k`` reported columns and
    ``n_probe`` Rademacher probes ``Z`` (Hutchinson's trace estimate)."""

    W: FloatArray
    k: int
    n_probe: int

    @classmethod
    def of(cls, prob: Problem, solve: Callable[[FloatArray], FloatArray], columns: IntArray,
           n_probe: int) -> _Probes:
        n_par = prob.n_params
        k = columns.size
        E = np.zeros((n_par, k))
        E[columns, np.arange(k)] = 1.0
        Z = np.random.default_rng(0).choice([-1.0, 1.0], size=(n_par, n_probe))
        return cls(np.hstack([solve(np.hstack([E, Z])), Z]), k, n_probe)

    def part(self, A: FloatArray) -> tuple[FloatArray, float]:
        """Rows' responses (r, k + 2q) -> (G^T G of the columns, absorbed dof)."""
        q0, q1 = self.k, self.k + self.n_probe
        G = A[:, : self.k]
        return tdot(G, G), float(np.sum(A[:, q0:q1] * A[:, q1:])) / self.n_probe


@dataclass(frozen=True)
class _TimeBlocks:
    """The batch-means blocks: ``block_s`` seconds from the first knot, ``n + 1`` of them."""

    t_lo: float
    block_s: float
    n: int

    @classmethod
    def of(cls, prob: Problem, block_s: float) -> _TimeBlocks:
        t_lo = float(prob.pieces[0].t0_s)
        n = max(1, math.ceil((float(prob.imu_t_s.max(initial=t_lo)) - t_lo) / block_s) + 1)
        return cls(t_lo, block_s, n)

    def index(self, t_s: FloatArray) -> IntArray:
        return np.clip(((t_s - self.t_lo) / self.block_s).astype(np.int64), 0, self.n)


class _Group(NamedTuple):
    """One residual group of the sandwich: its SSR, rows, absorbed dof and ``G^T G``."""

    name: str
    ssr: float
    rows: float
    p_abs: float
    GtG: FloatArray


def _imu_responses(prob: Problem, st: State, W: FloatArray, chunk: int) -> FloatArray:
    """``J_i W`` of every IMU sample (n, 6, W columns), in chunks of ``chunk`` samples."""
    n = prob.imu_t_s.size
    A_imu = np.empty((n, 6, W.shape[1]))
    for a in range(0, n, chunk):
        sl = slice(a, min(n, a + chunk))
        _, J, cols, _ = _imu_rows(prob, st, sl)
        A_imu[sl] = J @ W[cols]
    return A_imu


def _camera_group(prob: Problem, st: State, c: int, probes: _Probes, U: FloatArray,
                  blocks: _TimeBlocks, intr_cov: FloatArray | None) -> tuple[_Group, FloatArray]:
    """Camera ``c``'s residual group (its batch-means scores added to ``U``) and the covariance
    its held intrinsics propagate (zero without ``intr_cov``)."""
    k, W = probes.k, probes.W
    rc, Jc, colc, valid = camera_block(prob, st, c, jac=True)
    assert Jc is not None and colc is not None
    F = Jc.shape[0]
    Jf = Jc.reshape(F, -1, Jc.shape[-1])  # (F, 2M, 31 [+ 4])
    GtG, p_abs = np.zeros((k, k)), 0.0
    rf = rc.reshape(F, -1)
    blk = blocks.index(prob.cams[c].t_s + st.shift_s[c])
    for a in range(0, F, 64):
        Af = Jf[a:a + 64] @ W[colc[a:a + 64]]
        np.add.at(U, blk[a:a + 64], np.einsum("frk,fr->fk", Af[..., :k], rf[a:a + 64]))
        g, pa = probes.part(Af.reshape(-1, W.shape[1]))
        GtG += g
        p_abs += pa
    held_cov = np.zeros((k, k))
    if intr_cov is not None:
        held = np.arange(4 if prob.n_intr else 0, 8)
        Jh = camera_param_jacobian(prob, st, c)[..., held].reshape(F, -1, held.size)
        S = np.zeros((k, held.size))
        for a in range(0, F, 64):
            Gf = (Jf[a:a + 64] @ W[colc[a:a + 64], :k])
            S -= np.einsum("frk,frh->kh", Gf, Jh[a:a + 64])
        Ch = np.asarray(intr_cov, dtype=np.float64)[np.ix_(held, held)]
        held_cov += S @ Ch @ S.T
    return _Group(f"cam{c}", float(np.sum(rc**2)), 2.0 * int(valid.sum()), p_abs, GtG), held_cov


def _scaled_groups(groups: list[_Group], k: int) -> tuple[FloatArray, dict[str, Any]]:
    """``sum_g s2_g G_g^T G_g`` with each group's measured variance ratio ``s2_g``."""
    cov = np.zeros((k, k))
    info: dict[str, Any] = {"residual_scale": {}, "dof_absorbed": {}}
    for name, ssr, rows, p_abs, GtG in groups:
        p_abs = min(max(p_abs, 0.0), rows)  # a probe estimate: keep it inside [0, rows]
        s2 = ssr / (rows - p_abs) if rows - p_abs > 1 else 1.0
        info["residual_scale"][name] = s2
        info["dof_absorbed"][name] = p_abs
        cov += s2 * GtG
    return cov, info


def _add_bias_bridge(cov: FloatArray, prob: Problem, A_imu: FloatArray) -> FloatArray:
    """``cov`` plus the bias random walk's deviation from the linear interpolation between knots
    (``A_imu``: the IMU rows' responses of the reported columns, (n, 6, k))."""
    k = A_imu.shape[-1]
    n = prob.imu_t_s.size
    kb, al = prob.bias_locate(prob.imu_t_s)
    walk = prob.bias_walk_sigma / np.sqrt(prob.bias_dt_s)  # K per axis
    sig = np.array([prob.sigma_gyro] * 3 + [prob.sigma_accel] * 3)
    dt_inc = np.diff(prob.imu_t_s, prepend=prob.imu_t_s[0] if n else 0.0)
    for i in np.unique(kb):
        sel = np.flatnonzero(kb == i)
        if sel.size < 2:
            continue
        g = A_imu[sel] / sig[None, :, None]  # response to the bias in physical units
        s_tau = np.einsum("n,nak->ak", al[sel], g)
        coef = np.cumsum(g[::-1], axis=0)[::-1] - s_tau[None]  # response to each increment
        w = walk[None, :] ** 2 * dt_inc[sel][:, None]  # (m, 6) increment variances
        w[0] = 0.0  # the walk's value at the first sample belongs to the knots
        coef *= np.sqrt(w)[..., None]
        cov += tdot(coef.reshape(-1, k), coef.reshape(-1, k))
    return cov


def _batch_means(U: FloatArray, cov: FloatArray, info: dict[str, Any]) -> FloatArray:
    """``cov`` scaled up per parameter where the batch means of the scores ``U`` (one row per
    block of time) say the variance is larger (their ratio goes to ``info``)."""
    used = np.flatnonzero(np.any(U != 0, axis=1))
    B = used.size
    if B < 4:
        return cov
    Ub = U[used]
    cov_bm = B / (B - 1) * tdot(Ub, Ub)
    ratio = np.sqrt(np.diag(cov_bm) / np.maximum(np.diag(cov), 1e-300))
    info["batch_means_ratio"] = ratio.tolist()
    f = np.maximum(ratio, 1.0)
    return cov * np.outer(f, f)


def camera_param_jacobian(prob: Problem, st: State, c: int, *, h: float = 1e-6) -> FloatArray:
    """Whitened reprojection residuals of camera ``c`` differentiated by its intrinsics
    ``fx, fy, cx, cy, d0..d3`` (F, M, 2, 8); zero on padding (central differences)."""
    cb = prob.cams[c]
    base, u, inside = prob.locate(cb.t_s + st.shift_s[c])
    idx = base[:, None] + _ARANGE4
    R, _ = rotation(st.R_ctrl[idx], u, prob.dt_s, angular_velocity=False)
    p, _, _ = position(st.P_ctrl[idx], u, prob.dt_s)
    pc = ((cb.X - p[:, None, :]) @ R) @ st.R_ci[c].T + st.t_ci[c]
    valid = (cb.mask > 0) & inside[:, None] & (pc[..., 2] > 1e-3)
    pcv = np.where(valid[..., None], pc, np.array([0.0, 0.0, 1.0]))
    cam = st.camera(prob, c)
    x0 = np.array([cam.fx, cam.fy, cam.cx, cam.cy, *cam.coeffs])
    out = np.zeros((*valid.shape, 2, 8))
    for j in range(8):
        step = h * max(abs(float(x0[j])), 1.0)
        uv = []
        for sgn in (1.0, -1.0):
            x = x0.copy()
            x[j] += sgn * step
            uv.append(replace(cam, fx=float(x[0]), fy=float(x[1]), cx=float(x[2]), cy=float(x[3]),
                              coeffs=(float(x[4]), float(x[5]), float(x[6]), float(x[7]))).project(pcv))
        out[..., j] = (uv[0] - uv[1]) / (2 * step)
    return out * (valid[..., None, None] / prob.cam_sigma_px(c))


def _imu_rows(prob: Problem, st: State, sl: slice
              ) -> tuple[FloatArray, FloatArray, IntArray, IntArray]:
    """:func:`imu_block` with Jacobians on the IMU samples ``sl`` only."""
    sub = replace(prob, imu_t_s=prob.imu_t_s[sl], gyro=prob.gyro[sl], accel=prob.accel[sl])
    r, J, cols, key = imu_block(sub, st, jac=True)
    assert J is not None and cols is not None and key is not None
    return r, J, cols, key
