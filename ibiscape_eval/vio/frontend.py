"""OpenCV front end: corners on a grid, KLT tracking with a gyro prior, stereo matching.

Per frame (grey 8-bit images of the raw, unrectified cameras):

1. **Temporal tracking** of the previous left corners with pyramidal Lucas-Kanade
   (``calcOpticalFlowPyrLK``), started at the position predicted by the gyro rotation between the
   frames (the infinite-depth homography ``K R_c2c1 K^-1``), kept when tracking back lands within
   ``fb_max_px`` of the start (forward-backward check, Kalal et al. 2010) and when they are inliers
   of a RANSAC fundamental matrix on rectified coordinates.
2. **Detection** of new Shi-Tomasi corners (``goodFeaturesToTrack``) away from the tracked ones,
   at most ``ceil(max_features / grid^2)`` per grid cell so that they cover the image.
3. **Stereo matching** of every left corner in the right image with KLT (started at the previous
   disparity), checked backwards and by the epipolar constraint of the rectified pair
   (``|v_L - v_R| <= epipolar_max_px``, positive disparity).

The output is :class:`~ibiscape_eval.vio.backend.StereoObservations` in rectified coordinates.
Pixel thresholds scale with the image width (given for 512 px).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from .backend import StereoObservations
from .params import VioParams
from .rig import StereoRig

__all__ = ["StereoFrontEnd", "disc_offsets", "good_features"]

FloatArray = npt.NDArray[np.float64]


def _min_eigen(img: npt.NDArray[np.uint8], block: int) -> npt.NDArray[np.float32]:
    """``cv2.cornerMinEigenVal(img, block)`` computed in horizontal strips of at most 64 K pixels
    (each with the rows its 3x3 Sobel and ``block`` box filter reach beyond it): the same numbers,
    while the whole image at once asks the allocator for 6 MB of fresh pages per call at 512 px
    (1500 page faults: 4.8 ms of CPU per call, 1.1 ms in strips)."""
    import cv2

    h, w = img.shape
    rows = max(32, 65536 // max(w, 1))
    if rows >= h:
        return np.asarray(cv2.cornerMinEigenVal(img, block), dtype=np.float32)
    out = np.empty((h, w), dtype=np.float32)
    margin = block // 2 + 2
    for y0 in range(0, h, rows):
        y1 = min(y0 + rows, h)
        lo, hi = max(y0 - margin, 0), min(y1 + margin, h)
        out[y0:y1] = cv2.cornerMinEigenVal(img[lo:hi], block)[y0 - lo:y1 - lo]
    return out


def good_features(img: npt.NDArray[np.uint8], max_corners: int, quality: float,
                  min_dist: float, mask: npt.NDArray[np.uint8], block: int = 5
                  ) -> npt.NDArray[np.float32]:
    """Shi-Tomasi corners ``(N, 2)`` (x, y) like ``cv2.goodFeaturesToTrack(img, max_corners,
    quality, min_dist, mask=mask, blockSize=block)``: the local maxima of the smaller eigenvalue
    above ``quality`` times its largest value under ``mask``, strongest first (ties: the later
    pixel first), each at least ``min_dist`` from the stronger ones kept (OpenCV's grid rule),
    at most ``max_corners``.  The eigenvalues are computed in strips (:func:`_min_eigen`)."""
    import cv2

    from ._corner_kernels import peak_keys, select_spaced

    h, w = img.shape
    eig = _min_eigen(img, block)
    top = float(cv2.minMaxLoc(eig, mask)[1])
    if max_corners <= 0:
        return np.zeros((0, 2), dtype=np.float32)
    # threshold, 3x3 dilation, compare, mask and findNonZero in one numba pass (5 fresh 256 KB
    # images less per call); one sort key per candidate: the value's bits (positive floats
    # order like their bits) above the pixel index, so that equal values put the later pixel
    # first, as OpenCV's sort does
    key = peak_keys(eig, eig.view(np.int32), mask, np.float32(top * quality))
    if len(key) == 0:
        return np.zeros((0, 2), dtype=np.float32)
    m = len(key)
    k = min(m, 8 * max_corners)  # the greedy selection rarely needs more of the strongest
    while True:
        ranked = np.sort(np.partition(key, m - k)[m - k:] if k < m else key)[::-1]
        idx = ranked & 0xFFFFFFFF
        xs, ys = idx % w, idx // w
        keep = np.empty(min(k, max_corners), dtype=np.int64)
        n = select_spaced(xs, ys, float(min_dist), w, h, len(keep), keep)
        if n == max_corners or k == m:
            break
        k = m
    return np.column_stack([xs[keep[:n]], ys[keep[:n]]]).astype(np.float32)


def disc_offsets(r: int) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """Offsets ``(dx, dy)`` of the pixels ``cv2.circle(img, centre, r, colour, -1)`` fills around
    an integer centre (the same at every centre: its rasterisation is translation invariant,
    only clipped at the image border)."""
    import cv2

    m = r + 2
    canvas = np.zeros((2 * m + 1, 2 * m + 1), dtype=np.uint8)
    cv2.circle(canvas, (m, m), r, 255, -1)
    dy, dx = np.nonzero(canvas)
    return dx.astype(np.int64) - m, dy.astype(np.int64) - m


class StereoFrontEnd:
    """Stateful tracker over a stereo image stream (see the module docstring)."""

    #: the right image is needed only for the frames that need stereo (:meth:`track` on every
    #: frame, :meth:`match` when the estimator asks); a front end that needs its second image on
    #: every frame (RGB-D's depth) says False and is driven by :meth:`process`
    stereo_on_demand: bool = True

    def __init__(self, rig: StereoRig, params: VioParams):
        self.rig = rig
        self.params = params
        self.rect = rig.rectified()
        s = params.scale_px(rig.size[0])
        self.fb_px = params.fb_max_px * max(s, 0.5)
        self.epi_px = params.epipolar_max_px * max(s, 0.5)
        self.ransac_px = params.ransac_px * max(s, 0.5)
        self.min_dist = max(params.min_distance_px * s, 3.0)
        # a multiple of 8 px: OpenCV's KLT takes each window row 8 pixels at a time (SIMD) and the
        # rest one by one (512 px, per corner: 16 px 6.5 us, 17 px 8.1, 21 px 15.7, 24 px 12.1;
        # bench_vio.py's front end 10.3 -> 6.6 ms in clear weather); at least 12 px (8 px lost
        # the track of the 128 px RGB-D test drive)
        win = max(8 * round(params.klt_window_px * math.sqrt(s) / 8), 12)
        self.win = (win, win)
        self.levels = params.klt_levels
        self.crit = (3, params.klt_iters, params.klt_eps_px)   # TERM_CRITERIA_COUNT | EPS
        self.R_bc = rig.T_body_left[:3, :3]
        self.K = rig.left.K
        self.Kinv = np.linalg.inv(self.K)
        self._prev_pyr: Any = None
        self.pts = np.zeros((0, 2), dtype=np.float32)   # left corners of the previous frame
        self.ids = np.zeros(0, dtype=np.int64)
        self.disp = np.zeros(0, dtype=np.float32)        # last raw disparity guess per corner
        self._next_id = 0
        self._tracks: StereoObservations | None = None   # the last track() result
        self._filled = 0                                  # corners held after the last detection
        self._disc = disc_offsets(round(self.min_dist))
        self._resid_px = math.inf   # largest |track - gyro prediction| of the last frame (px)

    def _pyramid(self, img: npt.NDArray[np.uint8]) -> Any:
        # OpenCV 5's Python binding no longer accepts the list of buildOpticalFlowPyramid as an
        # image argument of calcOpticalFlowPyrLK: the pyramid is rebuilt inside each call
        return np.ascontiguousarray(img)

    def _lk(self, pyr0: Any, pyr1: Any, p0: npt.NDArray[np.float32],
            guess: npt.NDArray[np.float32], levels: int | None = None
            ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.bool_]]:
        """KLT from ``p0`` in image 0 to image 1 with a start guess, plus the backward check
        (``levels`` pyramid levels, ``klt_levels`` by default)."""
        import cv2

        crit = self.crit
        levels = self.levels if levels is None else levels
        p1, st, _ = cv2.calcOpticalFlowPyrLK(pyr0, pyr1, p0.reshape(-1, 1, 2),
                                             guess.reshape(-1, 1, 2).copy(), winSize=self.win,
                                             maxLevel=levels, criteria=crit,
                                             flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        p1 = p1.reshape(-1, 2)
        w, h = self.rig.size
        ok = (st.ravel() == 1)
        ok &= (p1[:, 0] >= 0) & (p1[:, 0] <= w - 1) & (p1[:, 1] >= 0) & (p1[:, 1] <= h - 1)
        # backward check only for the forward survivors: OpenCV tracks every point on its own,
        # so the subset gets exactly the values a call with all points would give
        fwd = np.flatnonzero(ok)
        if len(fwd):
            q0 = p0.reshape(-1, 2)[fwd]
            pb, stb, _ = cv2.calcOpticalFlowPyrLK(pyr1, pyr0, p1[fwd].reshape(-1, 1, 2).copy(),
                                                  q0.reshape(-1, 1, 2).copy(), winSize=self.win,
                                                  maxLevel=levels, criteria=crit,
                                                  flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
            fb = np.linalg.norm(pb.reshape(-1, 2) - q0, axis=1)
            ok[fwd] = (stb.ravel() == 1) & (fb < self.fb_px)
        return p1.astype(np.float32), ok

    def _temporal_levels(self) -> int:
        """Pyramid levels of the next temporal KLT: ``klt_levels``, or fewer (not below
        ``klt_min_levels``) when the last frame's tracks all landed within a quarter of what
        the fewer levels reach from the gyro's prediction (half a window per level, doubling
        each level up): ``(win / 2) 2^L >= 4 r`` for the largest residual ``r`` of the last
        frame.  Each level costs every corner the same (its window), the top ones included."""
        lo = min(self.params.klt_min_levels, self.levels)
        reach = self.win[0] / 2
        for L in range(lo, self.levels):
            if reach * 2 ** L >= 4.0 * self._resid_px:
                return L
        return self.levels

    def _predict(self, R_b0_b1: FloatArray | None) -> npt.NDArray[np.float32]:
        if R_b0_b1 is None or len(self.pts) == 0:
            return self.pts.copy()
        R_c1c0 = self.R_bc.T @ R_b0_b1.T @ self.R_bc
        H = self.K @ R_c1c0 @ self.Kinv
        ph = np.column_stack([self.pts, np.ones(len(self.pts))]) @ H.T
        with np.errstate(divide="ignore", invalid="ignore"):
            pred = ph[:, :2] / ph[:, 2:3]
        bad = ~np.isfinite(pred).all(axis=1) | (ph[:, 2] <= 0)
        pred[bad] = self.pts[bad]
        return pred.astype(np.float32)

    def _ransac(self, r0: FloatArray, r1: FloatArray) -> npt.NDArray[np.bool_]:
        """Inliers of a fundamental matrix between the rectified points ``r0`` -> ``r1``."""
        import cv2

        keep = np.ones(len(r0), dtype=bool)
        if len(r0) < 12:
            return keep
        if np.median(np.linalg.norm(r1 - r0, axis=1)) < 1.0:
            return keep  # too little motion for a fundamental matrix; the back end's Huber copes
        # at most ransac_max_iters hypotheses (200: in rain, with a quarter of the tracks
        # outliers, OpenCV's adaptive count costs 1.5 ms per frame, 0.9 ms with the cap; the
        # inliers of 97.5 % of the points stay, more than re-running RANSAC on a subset keeps)
        F, mask = cv2.findFundamentalMat(r0, r1, cv2.FM_RANSAC, self.ransac_px, 0.999,
                                         self.params.ransac_max_iters)
        if F is None or mask is None:
            return keep
        return np.asarray(mask.ravel() == 1)

    def _detect(self, img: npt.NDArray[np.uint8], pts: npt.NDArray[np.float32]
                ) -> npt.NDArray[np.float32]:
        from ._corner_kernels import clear_discs

        p = self.params
        need = p.max_features - len(pts)
        if need <= 0:
            return np.zeros((0, 2), dtype=np.float32)
        h, w = img.shape
        mask = np.full((h, w), 255, dtype=np.uint8)
        # a disc per tracked corner, the pixels cv2.circle(mask, (x, y), r, 0, -1) fills (one
        # numba call instead of a few hundred Python-level ones)
        c0 = np.round(pts).astype(np.int64)
        clear_discs(mask, c0[:, 0], c0[:, 1], *self._disc)
        border = max(self.win[0] // 2, 4)
        mask[:border], mask[-border:], mask[:, :border], mask[:, -border:] = 0, 0, 0, 0
        c = good_features(img, 2 * need + p.grid * p.grid, 0.01, self.min_dist, mask, 5)
        if len(c) == 0:
            return np.zeros((0, 2), dtype=np.float32)
        g = p.grid
        cap = math.ceil(p.max_features / (g * g))

        def cell(q: np.ndarray) -> np.ndarray:
            return (np.minimum((q[:, 1] * g / h).astype(int), g - 1) * g
                    + np.minimum((q[:, 0] * g / w).astype(int), g - 1))

        have = np.bincount(cell(pts), minlength=g * g) if len(pts) else np.zeros(g * g, int)
        cc = cell(c)
        order = np.argsort(cc, kind="stable")          # quality order kept inside a cell
        sc = cc[order]
        first = np.searchsorted(sc, sc, side="left")
        rank = np.empty(len(c), dtype=int)
        rank[order] = np.arange(len(c)) - first
        keep = rank < (cap - have[cc])
        out = c[keep][:need]
        return out.astype(np.float32)

    def process(self, stamp_ns: int, left: npt.NDArray[np.uint8], right: npt.NDArray[np.uint8],
                R_b0_b1: FloatArray | None = None) -> StereoObservations:
        """Track into a new stereo pair; ``R_b0_b1`` is the body rotation since the previous
        frame (from the gyro), used as the KLT start.  Returns the rectified stereo matches
        (:meth:`track` then :meth:`match`, the matched corners only)."""
        self.track(stamp_ns, left, R_b0_b1)
        return self.match(right).matched()

    def track(self, stamp_ns: int, left: npt.NDArray[np.uint8],
              R_b0_b1: FloatArray | None = None) -> StereoObservations:
        """Track the corners into a new left image (and detect new ones): the corners held,
        rectified, with ``uR`` NaN (no stereo match yet).  :meth:`match` adds the right image's
        matches, when the frame needs them (keyframes): the right image is then the only one
        read and tracked for it."""
        pyr_l = self._pyramid(left)
        rl = np.zeros((0, 2))
        if self._prev_pyr is not None and len(self.pts) and self._tracks is not None:
            guess = self._predict(R_b0_b1)
            p1, ok = self._lk(self._prev_pyr, pyr_l, self.pts, guess, self._temporal_levels())
            idx = np.flatnonzero(ok)
            # how far the tracks moved from the gyro's prediction: the next frame's pyramid depth
            self._resid_px = (float(np.abs(p1[idx] - guess[idx]).max()) if len(idx)
                              else math.inf)
            # each point is rectified on its own: the previous frame's rectified corners and
            # these are reused below instead of rectifying again (the same numbers)
            prev = self._tracks
            r0 = (np.column_stack([prev.uL[idx], prev.v[idx]]) if len(prev.uL) == len(self.pts)
                  else self.rig.rectify_points(self.pts[idx], "left"))
            rl = self.rig.rectify_points(p1[idx], "left")
            inl = self._ransac(r0, rl)
            idx, rl = idx[inl], rl[inl]
            pts, ids, disp = p1[idx], self.ids[idx], self.disp[idx]
        else:
            pts = np.zeros((0, 2), dtype=np.float32)
            ids = np.zeros(0, dtype=np.int64)
            disp = np.zeros(0, dtype=np.float32)
        # new corners only when the tracks have thinned out (detection is the costliest step):
        # below 70 % of max_features, and (redetect_ratio < 1) below that fraction of the count
        # after the last detection unless below half of max_features (images with textureless
        # cells never fill up: not every frame then)
        p = self.params
        n = len(pts)
        if n < 0.7 * p.max_features and (p.redetect_ratio >= 1.0 or n < 0.5 * p.max_features
                                         or n < p.redetect_ratio * self._filled):
            new = self._detect(left, pts)
            self._filled = len(pts) + len(new)
        else:
            new = np.zeros((0, 2), dtype=np.float32)
        if len(new):
            rl = np.concatenate([rl, self.rig.rectify_points(new, "left")])
            pts = np.concatenate([pts, new])
            ids = np.concatenate([ids, np.arange(self._next_id, self._next_id + len(new))])
            self._next_id += len(new)
            fill = float(np.median(disp)) if len(disp) else 0.0
            disp = np.concatenate([disp, np.full(len(new), fill, dtype=np.float32)])
        self.pts, self.ids, self.disp = pts, ids, disp
        self._prev_pyr = pyr_l
        self._tracks = StereoObservations(int(stamp_ns), ids.astype(np.int64), rl[:, 0],
                                          np.full(len(pts), np.nan), rl[:, 1])
        return self._tracks

    def match(self, right: npt.NDArray[np.uint8]) -> StereoObservations:
        """Stereo matches in ``right`` of the corners of the last :meth:`track` call (every
        corner held; ``uR`` NaN where the match failed its checks)."""
        tr = self._tracks
        if tr is None:
            raise RuntimeError("StereoFrontEnd.match before track")
        pts, disp = self.pts, self.disp
        if len(pts) == 0:
            return tr
        # left -> right, started at the last disparity
        guess = pts.copy()
        guess[:, 0] -= disp
        pr, ok = self._lk(self._prev_pyr, self._pyramid(right), pts, guess)
        rr = self.rig.rectify_points(pr, "right")
        d = tr.uL - rr[:, 0]
        ok &= (np.abs(tr.v - rr[:, 1]) <= self.epi_px) & (d > 0.1)
        self.disp = np.where(ok, pts[:, 0] - pr[:, 0], disp).astype(np.float32)
        return StereoObservations(tr.stamp_ns, tr.ids, tr.uL, np.where(ok, rr[:, 0], np.nan),
                                  tr.v)

    @property
    def n_tracked(self) -> int:
        """Corners held in the left image."""
        return len(self.pts)
