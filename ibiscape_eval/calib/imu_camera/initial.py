"""Initial values: per-frame PnP poses, then the time offset and the camera-IMU rotation from the
PnP rotations versus the integrated gyroscope.

The planar-target PnP is OpenCV's IPPE (Collins & Bartoli 2014), keeping both of its solutions.
``R_target_cam(t) R_cam_imu = R_target_w R_w_imu(t + s)`` is the AX = YB hand-eye problem, solved
linearly in Kronecker form (Dornaika & Horaud 1998) for each offset of a grid; rotations compared
over the whole recording are far less noisy than angular rates differentiated from PnP.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.so3 import exp_so3, log_so3

from .inputs import CameraObservations

__all__ = ["FramePoses", "RotationAlignment", "align_rotations", "frame_poses", "integrate_gyro"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class FramePoses:
    """``T_target_cam`` candidates of the frames where PnP succeeded.

    IPPE returns two poses for a planar target; far away both reproject almost equally well (the
    board's tilt flips), so both are kept and :func:`align_rotations` picks the one that agrees
    with the gyroscope.

    Attributes
    ----------
    frames : ndarray (F',) int64
        Rows of the observation's ``stamps_ns``.
    R_target_cam : ndarray (F', 2, 3, 3)
    p_target_cam_m : ndarray (F', 2, 3)
    reproj_err : ndarray (F', 2)
        RMS reprojection error of each candidate (normalised image coordinates).
    spread_px : ndarray (F',)
        RMS distance of the frame's corners from their centroid (PnP rotations are about as
        precise as ``noise / spread``).
    """

    frames: npt.NDArray[np.int64]
    R_target_cam: FloatArray
    p_target_cam_m: FloatArray
    reproj_err: FloatArray
    spread_px: FloatArray

    def subset(self, keep: npt.NDArray[np.bool_]) -> FramePoses:
        return FramePoses(self.frames[keep], self.R_target_cam[keep], self.p_target_cam_m[keep],
                          self.reproj_err[keep], self.spread_px[keep])


def frame_poses(obs: CameraObservations, corners_target_m: FloatArray, *,
                min_corners: int = 6) -> FramePoses:
    """Planar PnP (IPPE, both solutions) on the undistorted corners of every frame with
    ``min_corners`` or more."""
    import cv2

    assert obs.camera is not None
    order = np.argsort(obs.frame_index, kind="stable")
    fi = obs.frame_index[order]
    starts = np.flatnonzero(np.r_[True, np.diff(fi) > 0])
    ends = np.r_[starts[1:], fi.size]
    rays, ok = obs.camera.unproject(obs.pixels_px[order])
    obj = corners_target_m[obs.corner_ids[order]]
    frames, Rs, ps, errs, spread = [], [], [], [], []
    px_sorted = obs.pixels_px[order]
    K = np.eye(3)
    for a, b in zip(starts, ends, strict=True):  # one OpenCV call per frame (initialisation only)
        good = ok[a:b]
        if good.sum() < min_corners:
            continue
        o = np.ascontiguousarray(obj[a:b][good], dtype=np.float64)
        x = np.ascontiguousarray(rays[a:b][good][:, :2], dtype=np.float64)
        try:
            n_sol, rvecs, tvecs, rerr = cv2.solvePnPGeneric(o, x, K, None, flags=cv2.SOLVEPNP_IPPE)
        except cv2.error:
            continue
        if n_sol < 1:
            continue
        cand_R, cand_p = [], []
        for k in range(2):
            rv, tv = rvecs[min(k, n_sol - 1)], tvecs[min(k, n_sol - 1)]
            R_ct, _ = cv2.Rodrigues(rv)
            cand_R.append(R_ct.T)
            cand_p.append(-R_ct.T @ np.asarray(tv).ravel())
        e = np.asarray(rerr, dtype=np.float64).ravel()
        frames.append(int(fi[a]))
        Rs.append(cand_R)
        ps.append(cand_p)
        errs.append([e[0], e[min(1, e.size - 1)]])
        q = px_sorted[a:b][good]
        spread.append(float(np.sqrt(np.mean(np.sum((q - q.mean(axis=0)) ** 2, axis=1)))))
    if not frames:
        return FramePoses(np.zeros(0, np.int64), np.zeros((0, 2, 3, 3)), np.zeros((0, 2, 3)),
                          np.zeros((0, 2)), np.zeros(0))
    return FramePoses(np.asarray(frames, np.int64), np.asarray(Rs), np.asarray(ps), np.asarray(errs),
                      np.asarray(spread))


def integrate_gyro(gyro_rad_s: FloatArray, t_s: FloatArray) -> FloatArray:
    """Orientation ``R_w_imu(t_k)`` (n, 3, 3) from the gyroscope with ``R(t_0) = I``.

    The product of the per-interval rotations is a prefix scan done in log2(n) vectorised steps
    (Hillis-Steele), not a per-sample loop.
    """
    dt = np.diff(t_s)
    w = 0.5 * (gyro_rad_s[1:] + gyro_rad_s[:-1])
    P = np.concatenate((np.eye(3)[None], exp_so3(w * dt[:, None])))
    d = 1
    while d < len(P):
        P[d:] = P[:-d] @ P[d:]
        d *= 2
    return P


def _solve_axyb(A: FloatArray, B: FloatArray, wts: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Least-squares ``A_k X = Y B_k`` over rotations (linear, Kronecker form, then SO(3)) for a
    batch of candidate ``B`` (G, n, 3, 3) sharing ``A`` (n, 3, 3): ``X, Y`` (G, 3, 3).

    With column-major vec, ``vec(A X) = (I kron A) vec(X)`` and ``vec(Y B) = (B^T kron I) vec(Y)``;
    the normal matrix of ``[I kron A | -(B^T kron I)]`` is assembled from its Kronecker blocks
    (``I kron sum w A^T A``, ``-sum w B^T kron A^T``, ``sum w B B^T kron I``), without the
    (n, 9, 18) rows."""
    G = B.shape[0]
    I3 = np.eye(3)
    N = np.empty((G, 18, 18))
    N[:, :9, :9] = np.kron(I3, np.einsum("n,nki,nkj->ij", wts, A, A))
    # (B^T kron A^T)[(a, b), (c, d)] = B[c, a] A[d, b]
    C = np.einsum("n,gnca,ndb->gabcd", wts, B, A).reshape(G, 9, 9)
    N[:, :9, 9:] = -C
    N[:, 9:, :9] = -np.swapaxes(C, 1, 2)
    BBt = np.einsum("n,gnij,gnkj->gik", wts, B, B)
    N[:, 9:, 9:] = (BBt[:, :, None, :, None] * I3[None, None, :, None, :]).reshape(G, 9, 9)
    _, vecs = np.linalg.eigh(N)
    v = vecs[:, :, 0]
    X = np.swapaxes(v[:, :9].reshape(G, 3, 3), 1, 2)  # column-major
    Y = np.swapaxes(v[:, 9:].reshape(G, 3, 3), 1, 2)
    sgn = np.where(np.linalg.det(X) < 0, -1.0, 1.0)[:, None, None]

    def proj(R: FloatArray) -> FloatArray:
        U, _, Vt = np.linalg.svd(R)
        U[..., :, 2] *= np.sign(np.linalg.det(U @ Vt))[..., None]
        return U @ Vt

    return proj(sgn * X), proj(sgn * Y)


@dataclass(frozen=True)
class RotationAlignment:
    """Outcome of :func:`align_rotations`."""

    R_cam_imu: FloatArray
    R_target_w: FloatArray
    shift_s: float
    choice: npt.NDArray[np.int64]  # IPPE candidate per frame
    inliers: npt.NDArray[np.bool_]
    residual_deg: float


def align_rotations(t_frames_s: FloatArray, poses: FramePoses, imu_t_s: FloatArray,
                    R_w_imu: FloatArray, *, max_shift_s: float, step_s: float = 2e-3
                    ) -> RotationAlignment:
    """Time offset and ``R_cam_imu`` from PnP rotations versus the integrated gyroscope.

    Solves ``R_target_cam(t) R_cam_imu = R_target_w R_w_imu(t + s)`` (a hand-eye / AX = YB problem)
    linearly for every offset ``s`` of a grid and keeps the offset with the smallest median angle
    residual; then picks, per frame, the IPPE candidate that agrees with the prediction, drops
    outliers and refines.
    """
    from scipy.spatial.transform import Rotation, Slerp

    slerp = Slerp(imu_t_s, Rotation.from_matrix(R_w_imu))
    lo, hi = imu_t_s[0], imu_t_s[-1]
    choice = np.argmin(poses.reproj_err, axis=1)
    inl = np.ones(len(t_frames_s), bool)
    wts = poses.spread_px**2 / np.mean(poses.spread_px**2)  # rotation precision ~ spread

    def residuals_grid(ss: FloatArray, ch: npt.NDArray[np.int64], use: npt.NDArray[np.bool_]
                       ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Angle residuals (G, n) and ``X, Y`` (G, 3, 3) for the offsets ``ss`` (G,)."""
        A = poses.R_target_cam[np.arange(len(ch)), ch]
        n = len(t_frames_s)
        B = slerp(np.clip(t_frames_s[None] + ss[:, None], lo, hi).ravel()).as_matrix().reshape(-1, n, 3, 3)
        X, Y = _solve_axyb(A[use], B[:, use], wts[use])
        E = np.einsum("gnji,gnjk->gnik", A[None] @ X[:, None], Y[:, None] @ B)
        return np.linalg.norm(log_so3(E), axis=-1), X, Y

    def residuals(s: float, ch: npt.NDArray[np.int64], use: npt.NDArray[np.bool_]
                  ) -> tuple[FloatArray, FloatArray, FloatArray]:
        r, X, Y = residuals_grid(np.array([s]), ch, use)
        return r[0], X[0], Y[0]

    def search(centre: float, half: float, step: float) -> float:
        grid = np.arange(centre - half, centre + half + 0.5 * step, step)
        chunk = max(1, 20_000 // max(1, len(t_frames_s)))  # offsets per batch (bounded memory)
        costs = np.concatenate([
            np.average(residuals_grid(grid[a : a + chunk], choice, inl)[0][:, inl] ** 2, weights=wts[inl], axis=1)
            for a in range(0, len(grid), chunk)])
        k = int(np.argmin(costs))
        s = float(grid[k])
        if 0 < k < len(grid) - 1:
            c0, c1, c2 = costs[k - 1 : k + 2]
            den = c0 - 2 * c1 + c2
            if den > 0:
                s += 0.5 * step * (c0 - c2) / den
        return s

    s = search(0.0, max_shift_s, step_s) if max_shift_s > 0 else 0.0
    for _ in range(2):
        _, X, Y = residuals(s, choice, inl)
        B = slerp(np.clip(t_frames_s + s, lo, hi)).as_matrix()
        pred = Y @ B @ X.T  # predicted R_target_cam
        ang = np.stack([np.linalg.norm(log_so3(np.einsum("nji,njk->nik", poses.R_target_cam[:, k], pred)),
                                       axis=1) for k in range(2)], -1)
        choice = np.argmin(ang, axis=1)
        best = ang[np.arange(len(choice)), choice] * np.sqrt(wts)  # normalised by the precision
        inl = best <= max(3.0 * np.median(best), np.radians(0.5))
        if max_shift_s > 0:
            s = search(s, 4 * step_s, step_s / 8)
    r, X, Y = residuals(s, choice, inl)
    return RotationAlignment(X, Y, s, choice, inl, float(np.degrees(np.median(r[inl]))))
