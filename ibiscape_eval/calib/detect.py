"""Target corner detection with sub-pixel refinement, in parallel over frames.

- Checkerboards: OpenCV's ``findChessboardCornersSB`` (Duda & Frese, BMVC 2018; the exhaustive
  search as a fallback) finds the grid, on a reduced copy of images wider than 800 px, and
  ``cornerSubPix`` refines every corner at full resolution.  The whole inner-corner grid must be
  visible.
- AprilGrids: ``cv2.aruco`` with the AprilTag 36h11 dictionary and a 2-cell marker border (Kalibr
  prints its tags that way); the small black squares at the tag corners make every tag corner an
  X-junction, refined by ``cornerSubPix`` in a window smaller than those squares.  Partially visible
  grids give the corners of the tags that were found.  Frames reconstructed from events
  (``event_frame=True``) blur the tags' cells, which aruco's decoding rejects: there aruco only
  proposes quads, which are read by correlation with the board's own codes, and the corners of
  the tags next to the read ones are added where the image has an X-junction.

Corner ids follow Kalibr's numbering (:mod:`ibiscape_eval.core.kalibr`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.kalibr import CalibrationTarget

__all__ = ["Detection", "detect_corners", "detect_many", "neighbour_residuals_px", "sharpness"]

#: images wider than this are searched at reduced size, then refined at full size
_SEARCH_WIDTH_PX = 800
#: a checkerboard is first searched in a copy this wide (the search costs 2x less at 400 px than
#: at 640 px; all 50 boards of 25 real 640x512 stereo pairs were found there, and cornerSubPix at
#: full size gives the same corners within 1e-4 px, in one of 50 views 0.13 px where the
#: refinement window came out 1 px larger), then at :data:`_SEARCH_WIDTH_PX`
_FAST_SEARCH_WIDTH_PX = 400
#: a tag's 4 corners as OpenCV reports them (on Kalibr's 180-degree-rotated print: bottom-right,
#: bottom-left, top-left, top-right) -> positions in CalibrationTarget.tag_corner_ids
_ARUCO_TO_KALIBR = np.array([1, 0, 3, 2])
#: event frames: AprilGrid tag candidates are searched on a copy upsampled this many times
_EVENT_UPSAMPLE = 2
#: event frames: smallest half-size of the corner refinement window (5x5 px): where the corner
#: squares are 3-4 px the 7x7 window of RGB frames reaches the neighbouring tags (corner RMS vs
#: truth on the 346x260 AprilGrid drive 1.0 px with 7x7, 0.51 px with 5x5)
_EVENT_MIN_HALF_PX = 2.0
#: soft decoding of event frames: samples per tag cell of the warped candidate
_SOFT_CELL_PX = 4
#: a candidate is read as the board tag whose code correlates best with its cells, at least this
#: much and this far ahead of the runner-up (tag or rotation); a read must also agree with the
#: board homography of the others
_SOFT_MIN_SCORE, _SOFT_MIN_LEAD = 0.5, 0.1
#: when no 2 reads agree on a board homography: only reads this sure
_SOFT_SURE_SCORE, _SOFT_SURE_LEAD = 0.65, 0.15


@dataclass(frozen=True, eq=False)
class Detection:
    """Corners found in one image.

    Attributes
    ----------
    ids : ndarray (K,) int64
        Corner ids in the target's numbering, increasing.
    corners_px : ndarray (K, 2) float64
        Pixel coordinates (OpenCV: pixel centres at integers).
    image_size : (int, int)
        Width, height of the image.
    """

    ids: npt.NDArray[np.int64]
    corners_px: npt.NDArray[np.float64]
    image_size: tuple[int, int]

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    def __repr__(self) -> str:
        return f"Detection({len(self)} corners in {self.image_size[0]}x{self.image_size[1]})"


def _gray(image: npt.NDArray[Any]) -> npt.NDArray[np.uint8]:
    import cv2

    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    if img.dtype != np.uint8:
        f = img.astype(np.float64)
        lo, hi = np.nanpercentile(f, [0.5, 99.5]) if f.size else (0.0, 1.0)
        img = np.clip((f - lo) / max(hi - lo, 1e-12) * 255.0, 0, 255).astype(np.uint8)
    return np.ascontiguousarray(img)


def sharpness(image: npt.NDArray[Any]) -> float:
    """Variance of the Laplacian of a 2x-downscaled grey copy (a blur measure; higher is sharper)."""
    import cv2

    g = _gray(image)
    small = cv2.resize(g, (max(1, g.shape[1] // 2), max(1, g.shape[0] // 2)), interpolation=cv2.INTER_AREA)
    return float(cv2.Laplacian(small, cv2.CV_64F).var())


def _subpix(gray: npt.NDArray[np.uint8], pts: npt.NDArray[np.float64], half_win: int) -> npt.NDArray[np.float64]:
    import cv2

    if len(pts) == 0:
        return pts
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
    p = np.ascontiguousarray(pts.reshape(-1, 1, 2), dtype=np.float32)
    w = max(2, int(half_win))
    out = cv2.cornerSubPix(gray, p, (w, w), (-1, -1), crit)
    return np.asarray(out, np.float64).reshape(-1, 2)


def _near_box(near: npt.NDArray[np.float64], gray: npt.NDArray[np.uint8],
              grow: float) -> tuple[int, int, int, int] | None:
    """The search box around a neighbouring frame's corners: their bounding box grown by ``grow``
    times its size on every side (20 Hz frames of a moving board stay inside it); None when it
    would cover most of the image anyway."""
    h, w = gray.shape
    lo, hi = near.min(axis=0), near.max(axis=0)
    pad = grow * float(max(hi[0] - lo[0], hi[1] - lo[1])) + 8.0
    x0, y0 = max(0, int(lo[0] - pad)), max(0, int(lo[1] - pad))
    x1, y1 = min(w, int(np.ceil(hi[0] + pad)) + 1), min(h, int(np.ceil(hi[1] + pad)) + 1)
    if (x1 - x0) * (y1 - y0) > 0.6 * w * h or x1 - x0 < 16 or y1 - y0 < 16:
        return None
    return x0, y0, x1, y1


def _checkerboard(gray: npt.NDArray[np.uint8], target: CalibrationTarget, near: npt.NDArray[np.float64] | None,
                  exhaustive: bool, fast: bool = True, photo: bool = False) -> Detection | None:
    import cv2

    h, w = gray.shape
    size = (target.cols, target.rows)
    pts = None
    box = None if near is None else _near_box(near, gray, 0.5)
    if box is not None:
        # the board of the previous frame: search its neighbourhood first (2.2x cheaper per frame than
        # the whole image on the 512 px calibration drive; benchmarks/bench_detect.py)
        x0, y0, x1, y1 = box
        ok, corners = cv2.findChessboardCornersSB(np.ascontiguousarray(gray[y0:y1, x0:x1]), size, flags=0)
        if ok and corners is not None:
            pts = np.asarray(corners, np.float64).reshape(-1, 2) + np.array([x0, y0], np.float64)
    if pts is None:
        pts = _classic_checkerboard(gray, size, photo) if fast else None
    if pts is None:
        pts = _search_checkerboard(gray, size, exhaustive, fast)
    if pts is None:
        return None
    if len(pts) != target.n_corners:
        return None
    # refinement window: a third of the smallest spacing between neighbouring corners
    grid = pts.reshape(target.rows, target.cols, 2)
    d = min(np.linalg.norm(np.diff(grid, axis=0), axis=-1).min(),
            np.linalg.norm(np.diff(grid, axis=1), axis=-1).min())
    pts = _subpix(gray, pts, int(min(d / 3.0, 15)))
    return Detection(np.arange(target.n_corners, dtype=np.int64), pts, (w, h))


def _classic_checkerboard(gray: npt.NDArray[np.uint8], size: tuple[int, int],
                          photo: bool) -> npt.NDArray[np.float64] | None:
    """OpenCV's classic quad-based search (adaptive threshold, normalised image; its quick check
    for a board first unless ``photo``) in a :data:`_FAST_SEARCH_WIDTH_PX` wide copy, then in one
    at most :data:`_SEARCH_WIDTH_PX` wide: the grid in full-size pixels, or None.  On OpenCV's 13
    real 640x480 stereo pairs: 2.8 ms per photo at 400 px (4.0 ms at 640 px) against 32 ms for the
    sector-based search at 400 px, every board found by both."""
    import cv2

    h, w = gray.shape
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    if not photo:
        flags |= cv2.CALIB_CB_FAST_CHECK
    for scale in sorted({min(1.0, _FAST_SEARCH_WIDTH_PX / w), min(1.0, _SEARCH_WIDTH_PX / w)}):
        # INTER_AREA (0.65 ms for a 640x480 photo, bilinear 0.13): the first guess of a bilinear
        # copy sets cornerSubPix's window 1 px off in some views, which moved rendered corners by
        # 0.15 px against the search around the previous board (tests/calib/test_calib_detect.py)
        img = gray if scale == 1.0 else cv2.resize(gray, (round(w * scale), round(h * scale)),
                                                   interpolation=cv2.INTER_AREA)
        ok, corners = cv2.findChessboardCorners(img, size, flags=flags)
        if ok and corners is not None:
            pts = np.asarray(corners, np.float64).reshape(-1, 2)
            return pts if scale == 1.0 else (pts + 0.5) / scale - 0.5
    return None


def _search_checkerboard(gray: npt.NDArray[np.uint8], size: tuple[int, int],
                         exhaustive: bool, fast: bool) -> npt.NDArray[np.float64] | None:
    """The whole image searched for the grid: in a :data:`_FAST_SEARCH_WIDTH_PX` copy (``fast``),
    then a :data:`_SEARCH_WIDTH_PX` one, then (``exhaustive``) by the exhaustive search; the
    corners in full-size pixels, or None."""
    import cv2

    h, w = gray.shape
    # the plain search finds the grid (5x cheaper than with CALIB_CB_ACCURACY, whose corner
    # model is biased by up to 0.3 px on tilted rendered boards); cornerSubPix at full
    # resolution gives the corners.  The exhaustive search is the fallback for hard views.
    scales = sorted({min(1.0, (_FAST_SEARCH_WIDTH_PX if fast else _SEARCH_WIDTH_PX) / w),
                     min(1.0, _SEARCH_WIDTH_PX / w)})
    tries = [(s, 0) for s in scales] + ([(scales[-1], cv2.CALIB_CB_EXHAUSTIVE)] if exhaustive else [])
    small: dict[float, npt.NDArray[Any]] = {}
    for scale, flags in tries:
        if scale not in small:
            small[scale] = gray if scale == 1.0 else cv2.resize(
                gray, (round(w * scale), round(h * scale)), interpolation=cv2.INTER_AREA)
        ok, corners = cv2.findChessboardCornersSB(small[scale], size, flags=flags)
        if ok and corners is not None:
            pts = np.asarray(corners, np.float64).reshape(-1, 2)
            return pts if scale == 1.0 else (pts + 0.5) / scale - 0.5
    return None


def _aruco_detector() -> Any:
    import cv2

    aruco = cv2.aruco
    params = aruco.DetectorParameters()
    params.markerBorderBits = 2
    params.cornerRefinementMethod = aruco.CORNER_REFINE_NONE
    return aruco.ArucoDetector(aruco.getPredefinedDictionary(aruco.DICT_APRILTAG_36h11), params,
                               aruco.RefineParameters())


def _aruco_tags(gray: npt.NDArray[np.uint8], box: tuple[int, int, int, int] | None
                ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """Tags decoded by ``cv2.aruco`` (ids, quads (T, 4, 2) in aruco's corner order), searched in
    ``box`` first and in the whole image when nothing is found there."""
    detector = _aruco_detector()
    found: Any = None
    offset = np.zeros(2)
    if box is not None:
        # around where the previous frame puts the whole grid; the whole image when nothing is
        # found there
        x0, y0, x1, y1 = box
        found = detector.detectMarkers(np.ascontiguousarray(gray[y0:y1, x0:x1]))
        offset = np.array([x0, y0], np.float64)
    if found is None or found[1] is None or len(found[1]) == 0:
        found, offset = detector.detectMarkers(gray), np.zeros(2)
    corners, ids = found[0], found[1]
    if ids is None or len(ids) == 0:
        return np.zeros(0, np.int64), np.zeros((0, 4, 2))
    return (np.asarray(ids, np.int64).ravel(),
            np.asarray(corners, np.float64).reshape(-1, 4, 2) + offset)


def _aprilgrid(gray: npt.NDArray[np.uint8], target: CalibrationTarget,
               near: npt.NDArray[np.float64] | None = None, event_frame: bool = False) -> Detection | None:
    box = None if near is None else _near_box(near, gray, 0.25)
    if event_frame:
        ids, quads = _soft_tags(gray, target, box)
    else:
        ids, quads = _aruco_tags(gray, box)
    keep = (ids >= 0) & (ids < target.rows * target.cols)
    ids, quads = ids[keep], quads[keep]
    if len(ids) == 0:
        return None
    # one detection per id (a duplicate id means a misread: drop both)
    uniq, counts = np.unique(ids, return_counts=True)
    single = np.isin(ids, uniq[counts == 1])
    ids, quads = ids[single], quads[single]
    corner_ids = target.tag_corner_ids(ids)[:, _ARUCO_TO_KALIBR]
    pts = quads.reshape(-1, 2)
    # OpenCV's quad corners sit ~2 px off: the corner squares touch the tag's border and bend its
    # contour.  Refine in a window that stays inside the corner squares (tagSpacing * tagSize).
    edge = np.linalg.norm(quads - np.roll(quads, 1, axis=1), axis=-1).min(axis=1)
    half = np.repeat(np.clip(0.5 * target.tag_spacing * edge, _EVENT_MIN_HALF_PX if event_frame else 3.0, 10.0), 4)
    refined = _refine_tag_corners(gray, pts, half)
    moved = np.linalg.norm(refined - pts, axis=1) <= 2.0 + half
    cid = corner_ids.ravel()[moved]
    refined = refined[moved]
    if event_frame:
        cid, refined = _complete_grid(gray, target, cid, refined, float(np.median(half)))
    good = _locally_consistent(target.object_points()[cid, :2], refined)
    cid, refined = cid[good], refined[good]
    if len(cid) == 0:
        return None
    order = np.argsort(cid)
    h, w = gray.shape
    return Detection(cid[order], refined[order], (w, h))


def _refine_tag_corners(gray: npt.NDArray[np.uint8], pts: npt.NDArray[np.float64],
                        half: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Two ``cornerSubPix`` passes per corner, in windows of half-size ``floor(half)``."""
    refined = pts.copy()
    for hw in np.unique(np.floor(half)):
        sel = np.floor(half) == hw
        for _ in range(2):
            refined[sel] = _subpix(gray, refined[sel], int(hw))
    return refined


@lru_cache(maxsize=4)
def _tag_codes(n_tags: int) -> npt.NDArray[np.float64]:
    """The 36h11 data bits of tags ``0..n_tags-1`` in their 4 rotations ``np.rot90(bits, k)``,
    each as a zero-mean unit vector (n_tags, 4, 36): a correlation with sampled cells."""
    import cv2

    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    bits = np.array([dictionary.generateImageMarker(i, 8, borderBits=1)[1:7, 1:7] > 0 for i in range(n_tags)])
    codes = np.stack([np.rot90(bits, k, axes=(1, 2)).reshape(n_tags, 36) for k in range(4)], axis=1)
    c = codes.astype(np.float64) * 2.0 - 1.0
    c -= c.mean(axis=-1, keepdims=True)
    return np.asarray(c / np.linalg.norm(c, axis=-1, keepdims=True), np.float64)


def _tag_cells(gray: npt.NDArray[np.uint8], quads: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """The mean grey level of the 10x10 cells (2-cell black border, 6x6 data) of every quad (outer
    corners of a tag, in order around it): (T, 10, 10).  Each cell is sampled (bilinear) at the
    ``_SOFT_CELL_PX - 2`` squared points of its interior that the quad's homography maps into
    the image."""
    import cv2

    n, px = 10, _SOFT_CELL_PX
    if len(quads) == 0:
        return np.zeros((0, n, n))
    # homographies (T, 3, 3) from the tag's cell coordinates (corners (0,0), (n,0), (n,n), (0,n)) to
    # the quads, all at once: h33 = 1 and 8 equations per quad
    src = np.array([[0, 0], [n, 0], [n, n], [0, n]], np.float64)
    x, y = src[:, 0], src[:, 1]
    u, v = quads[..., 0], quads[..., 1]
    A = np.zeros((len(quads), 8, 8))
    A[:, 0::2, 0], A[:, 0::2, 1], A[:, 0::2, 2] = x, y, 1.0
    A[:, 1::2, 3], A[:, 1::2, 4], A[:, 1::2, 5] = x, y, 1.0
    A[:, 0::2, 6], A[:, 0::2, 7] = -x * u, -y * u
    A[:, 1::2, 6], A[:, 1::2, 7] = -x * v, -y * v
    b = np.empty((len(quads), 8))
    b[:, 0::2], b[:, 1::2] = u, v
    h = np.full((len(quads), 8), np.nan)  # a degenerate quad samples nothing (NaN cells: no read)
    ok = np.linalg.cond(A) < 1e12
    if ok.any():
        h[ok] = np.linalg.solve(A[ok], b[ok][..., None])[..., 0]
    H = np.concatenate([h, np.ones((len(quads), 1))], axis=1).reshape(-1, 3, 3)
    # sample points of every cell: the interior of a px x px grid over the cell
    off = (np.arange(1, px - 1) + 0.5) / px
    g = (np.arange(n)[:, None] + off[None, :]).ravel()  # (n * (px - 2),)
    gy, gx = np.meshgrid(g, g, indexing="ij")
    pts = np.stack([gx.ravel(), gy.ravel(), np.ones(gx.size)])  # (3, P)
    img = H @ pts  # (T, 3, P)
    with np.errstate(divide="ignore", invalid="ignore"):
        mx = (img[:, 0] / img[:, 2]).astype(np.float32)
        my = (img[:, 1] / img[:, 2]).astype(np.float32)
    vals = cv2.remap(gray, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    m = px - 2
    return np.asarray(vals, np.float64).reshape(len(quads), n, m, n, m).mean(axis=(2, 4))


def _soft_tags(gray: npt.NDArray[np.uint8], target: CalibrationTarget, box: tuple[int, int, int, int] | None
               ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """Tags of an event frame (ids, quads (T, 4, 2) in aruco's corner order).

    Event frames blur the tags' 1-2 px cells, which ``cv2.aruco`` reads bit by bit against its
    587 codes and rejects.  Here aruco only proposes the quads (accepted and rejected
    candidates) on a 2x bicubic copy of the frame, and each quad's 6x6 data cells, sampled on that
    copy, are correlated with the codes of the board's own tags in the 4 rotations: the best
    (tag, rotation) is taken when its correlation and its lead over the runner-up are high
    enough, and the inner ring of its border is dark.  On the rendered drives every false read
    (a patch of the scene) correlated at most 0.6; the reads are kept when a board homography
    (RANSAC over their corners) explains at least 2 of them, else only the surer ones."""
    import cv2

    n_tags = target.rows * target.cols
    codes = _tag_codes(n_tags)
    detector = _aruco_detector()
    f = _EVENT_UPSAMPLE
    regions = ([box] if box is not None else []) + [None]
    ids = np.zeros(0, np.int64)
    quads = np.zeros((0, 4, 2))
    score = lead = np.zeros(0)
    for region in regions:
        x0, y0 = (0, 0) if region is None else region[:2]
        sub = gray if region is None else np.ascontiguousarray(gray[region[1]:region[3], region[0]:region[2]])
        up = np.asarray(cv2.resize(sub, (sub.shape[1] * f, sub.shape[0] * f), interpolation=cv2.INTER_CUBIC),
                        np.uint8)
        found, _, rejected = detector.detectMarkers(up)
        cand = [np.asarray(c, np.float64).reshape(4, 2) for c in (*found, *rejected)]
        if not cand:
            continue
        q_up = np.stack(cand)
        cells = _tag_cells(up, q_up)
        data = cells[:, 2:8, 2:8].reshape(len(q_up), 36)
        v = data - data.mean(axis=1, keepdims=True)
        v /= np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-9)
        corr = (v @ codes.reshape(-1, 36).T).reshape(len(q_up), -1)
        order = np.argsort(-corr, axis=1)[:, :2]
        best = np.take_along_axis(corr, order, axis=1)
        tag, rot = np.divmod(order[:, 0], 4)
        # the inner ring of the black border must be about as dark as the black data cells (the
        # outer ring straddles the quad's edge): on the rendered drives the tags' ring is at most
        # 0.06 of the way from black to white cells, three quarters of the false reads above 0.25
        white = codes.reshape(-1, 36)[order[:, 0]] > 0
        hi = (data * white).sum(axis=1) / np.maximum(white.sum(axis=1), 1)
        lo = (data * ~white).sum(axis=1) / np.maximum((~white).sum(axis=1), 1)
        ring = np.concatenate([cells[:, 1, 1:9], cells[:, 8, 1:9], cells[:, 2:8, 1], cells[:, 2:8, 8]], axis=1)
        dark = ring.mean(axis=1) <= lo + 0.25 * (hi - lo)
        ok = (best[:, 0] >= _SOFT_MIN_SCORE) & (best[:, 0] - best[:, 1] >= _SOFT_MIN_LEAD) & dark
        # the quad's corners rolled so that the first is the tag's own first corner (aruco's order)
        rolled = np.take_along_axis(q_up[ok], ((np.arange(4)[None, :] - rot[ok, None]) % 4)[..., None], axis=1)
        ids, quads = tag[ok].astype(np.int64), (rolled + 0.5) / f - 0.5 + np.array([x0, y0], np.float64)
        score, lead = best[ok, 0], best[ok, 0] - best[ok, 1]
        if len(ids) >= 4 or region is None:
            break
    if len(ids) == 0:
        return ids, quads
    # the same tag proposed twice at one place (nested contours): keep the better read
    centre = quads.mean(axis=1)
    edge = float(np.median(np.linalg.norm(quads - np.roll(quads, 1, axis=1), axis=-1)))
    keep = np.ones(len(ids), bool)
    for i in np.flatnonzero(np.bincount(ids) > 1):
        same = np.flatnonzero(ids == i)
        near_best = np.linalg.norm(centre[same] - centre[same[np.argmax(score[same])]], axis=1) < 0.25 * edge
        if near_best.all():
            keep[same] = False
            keep[same[np.argmax(score[same])]] = True
    ids, quads, centre, score, lead = ids[keep], quads[keep], centre[keep], score[keep], lead[keep]
    sure = (score >= _SOFT_SURE_SCORE) & (lead >= _SOFT_SURE_LEAD)
    if len(ids) >= 2:
        # the reads that one board homography explains (3 of a tag's 4 corners within half a tag)
        board = target.object_points()[:, :2][target.tag_corner_ids(ids)[:, _ARUCO_TO_KALIBR]]
        _, inl = cv2.findHomography(board.reshape(-1, 2), quads.reshape(-1, 2), cv2.RANSAC, 0.5 * edge)
        agree = np.zeros(len(ids), bool) if inl is None else inl.reshape(-1, 4).sum(axis=1) >= 3
        if agree.sum() >= 2:
            return ids[agree], quads[agree]
    return ids[sure], quads[sure]


def _complete_grid(gray: npt.NDArray[np.uint8], target: CalibrationTarget, cid: npt.NDArray[np.int64],
                   uv: npt.NDArray[np.float64], half: float
                   ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """Add the corners of tags that were not decoded, next to decoded ones (a tag step away at
    most): each predicted by a homography of its 8 nearest decoded corners on the board, refined
    like the others and kept when the refinement stays within ``max(1, half / 3)`` px of the
    prediction (an X-junction where the board puts one).  Needs the corners of 4 tags (16)."""
    import cv2

    if len(cid) < 16:
        return cid, uv
    board = target.object_points()[:, :2]
    missing = np.setdiff1d(np.arange(target.n_corners), cid)
    if len(missing) == 0:
        return cid, uv
    d = np.linalg.norm(board[missing][:, None, :] - board[cid][None, :, :], axis=-1)
    # only next to decoded corners (a tag step at most): further out the prediction strays
    near = d.min(axis=1) <= 1.01 * (1.0 + target.tag_spacing) * target.tag_size_m
    missing, d = missing[near], d[near]
    nn = np.argsort(d, axis=1)[:, :8]
    pred = np.full((len(missing), 2), np.nan)
    for j in range(len(missing)):  # <= 144 corners per view: one small fit each
        H, _ = cv2.findHomography(board[cid[nn[j]]], uv[nn[j]], 0)
        if H is not None:
            p = H @ np.array([board[missing[j], 0], board[missing[j], 1], 1.0])
            if p[2] > 0:
                pred[j] = p[:2] / p[2]
    h, w = gray.shape
    m = int(np.floor(half)) + 2
    inside = np.all(np.isfinite(pred), axis=1)
    inside[inside] = ((pred[inside, 0] >= m) & (pred[inside, 0] <= w - 1 - m)
                      & (pred[inside, 1] >= m) & (pred[inside, 1] <= h - 1 - m))
    if not inside.any():
        return cid, uv
    new_id, guess = missing[inside], pred[inside]
    refined = _refine_tag_corners(gray, guess, np.full(len(guess), half))
    ok = np.linalg.norm(refined - guess, axis=1) <= max(1.0, half / 3.0)
    return np.concatenate([cid, new_id[ok]]), np.concatenate([uv, refined[ok]])


def _locally_consistent(board_xy: npt.NDArray[np.float64], uv: npt.NDArray[np.float64], *,
                        k: int = 12, tol_px: float = 1.0) -> npt.NDArray[np.bool_]:
    """Keep corners that a homography of their ``k`` nearest neighbours on the board predicts
    within ``tol_px`` (a refinement caught by a neighbouring edge lands pixels away)."""
    if len(uv) < 6:
        return np.ones(len(uv), bool)
    return ~(neighbour_residuals_px(board_xy, uv, k=k) > tol_px)  # no homography (NaN): kept


def neighbour_residuals_px(board_xy: npt.ArrayLike, uv: npt.ArrayLike, *, k: int) -> npt.NDArray[np.float64]:
    """Per corner, the distance [px] from where a homography of its ``k`` nearest neighbours on the
    board puts it (NaN where that homography is degenerate): corner noise without a camera model,
    since a local homography absorbs the lens distortion.  Needs at least 2 corners."""
    import cv2

    xy = np.asarray(board_xy, np.float64).reshape(-1, 2)
    px = np.asarray(uv, np.float64).reshape(-1, 2)
    n = len(px)
    d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=-1)
    nn = np.argsort(d, axis=1)[:, 1:min(k, n - 1) + 1]
    res = np.full(n, np.nan)
    for i in range(n):  # n <= a few hundred corners per view: one small fit each
        H, _ = cv2.findHomography(xy[nn[i]], px[nn[i]], 0)
        if H is None:
            continue
        p = H @ np.array([xy[i, 0], xy[i, 1], 1.0])
        res[i] = np.hypot(p[0] / p[2] - px[i, 0], p[1] / p[2] - px[i, 1])
    return res


def detect_corners(image: npt.NDArray[Any], target: CalibrationTarget, *,
                   near: Detection | None = None, exhaustive: bool = True,
                   event_frame: bool = False, fast: bool = True, photo: bool = False) -> Detection | None:
    """Detect the target in one image (grey or BGR, any dtype); None when it is not found.

    Parameters
    ----------
    near
        The detection in a neighbouring frame of a sequence: the search starts around its corners
        (and covers the whole image when nothing is found there).
    exhaustive
        Checkerboards: retry a missed board with OpenCV's exhaustive search (about 8x the time).
        Worth it for sparse image sets; in a dense sequence the neighbouring frames supply the views
        (on the 60 s calibration drive it rescued none of the frames the plain search missed).
    event_frame
        The image is a frame reconstructed from events (:mod:`ibiscape_eval.calib.events`).
        AprilGrids: the tags are read by correlating their cells with the board's own codes
        instead of aruco's bit-by-bit decoding, which rejects the blurred 1-2 px cells of event
        frames, and once 4 tags are read the corners of the others are predicted from their
        neighbours and kept where the image has an X-junction.  Checkerboards: no change.
    fast
        Checkerboards: search the whole image first in a :data:`_FAST_SEARCH_WIDTH_PX` wide copy
        (2x less CPU on 640x512 photos); False for images that often hold no board (event-frame
        reconstructions under trial), where a miss would cost that search on top of the full one.
        Before that, OpenCV's classic quad-based ``findChessboardCorners`` is tried the same way
        (2.8 ms on a 640x480 photo at 400 px, the sector-based search 32 ms): with its quick check
        for a board first, unless ``photo``.
    photo
        The image is a photo of the board (``--images``), not a frame of a video that may miss it:
        the classic search runs without its quick check (4.0 instead of 6.6 ms per 640x480 photo;
        without a board it costs 99 ms instead of 14).
    """
    gray = _gray(image)
    if target.target_type == "checkerboard":
        return _checkerboard(gray, target, None if near is None else near.corners_px, exhaustive, fast,
                             photo)
    return _aprilgrid(gray, target, None if near is None else _grid_outline(near, target), event_frame)


def _grid_outline(near: Detection, target: CalibrationTarget) -> npt.NDArray[np.float64] | None:
    """Where a neighbouring frame's homography puts the whole grid (its four outer corners), so
    that the search box also covers tags that were out of view or missed there."""
    import cv2

    if len(near) < 8:
        return None
    board = target.object_points()[:, :2]
    H, _ = cv2.findHomography(board[near.ids], near.corners_px, 0)
    if H is None:
        return None
    lo, hi = board.min(axis=0), board.max(axis=0)
    quad = np.array([[lo[0], lo[1], 1.0], [hi[0], lo[1], 1.0], [hi[0], hi[1], 1.0], [lo[0], hi[1], 1.0]])
    p = quad @ H.T
    if np.any(p[:, 2] <= 1e-9 * np.abs(p[:, :2]).max()):
        return None  # the grid's plane reaches behind the camera: no useful box
    out = np.asarray(p[:, :2] / p[:, 2:], np.float64)
    return out if np.all(np.isfinite(out)) else None


def detect_many(load: Callable[[int], npt.NDArray[Any] | None], n: int, target: CalibrationTarget, *,
                workers: int | None = None, progress: Callable[[int], Any] | None = None
                ) -> list[Detection | None]:
    """Detect the target in ``n`` images in parallel threads (OpenCV releases the GIL).

    Parameters
    ----------
    load
        ``load(i)`` returns image ``i`` (or None when it cannot be read; its result is None).
    workers
        Threads; default: the CPUs this process may use.
    progress
        Called with 1 after every image.
    """
    from ibiscape_eval.core.cpus import usable_cpus

    from ._threads import thread_map

    if n < 0:
        raise IbiscapeError(f"number of images {n}: give >= 0")

    def one(i: int) -> Detection | None:
        img = load(i)
        det = None if img is None else detect_corners(img, target)
        if progress is not None:
            progress(1)
        return det

    return thread_map(one, range(n), max(1, workers or usable_cpus()))


def detections_from_points(ids: Sequence[int], corners_px: npt.ArrayLike, image_size: tuple[int, int]) -> Detection:
    """A :class:`Detection` from given points (e.g. for tests or external detectors)."""
    i = np.asarray(ids, np.int64)
    c = np.asarray(corners_px, np.float64).reshape(-1, 2)
    order = np.argsort(i)
    return Detection(i[order], c[order], (int(image_size[0]), int(image_size[1])))
