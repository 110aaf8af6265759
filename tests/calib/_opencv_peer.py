"""A careful OpenCV stereo calibration on given detections (the peer of tests/calib/test_calib_vs_opencv.py
and benchmarks/bench_calib.py)."""

from __future__ import annotations

import numpy as np

from ibiscape_eval.calib.detect import Detection


def opencv_stereo(target, obs, size, *, equi: bool = False):
    """calibrateCamera (or fisheye.calibrate) per camera, then stereoCalibrate, on the corners both
    cameras saw in a view (OpenCV 5's fisheye.stereoCalibrate needs the same number of corners in
    every view: whole checkerboards there); a square board's numbering in the right camera is the
    one whose corners lie nearest the left camera's (small baseline)."""
    import cv2

    obj = target.object_points()
    op, lp, rp = [], [], []
    for dl, dr in zip(obs[0].detections, obs[1].detections, strict=True):
        if dl is None or dr is None:
            continue
        best = min(target.symmetries(), key=lambda p: _spread(dl, dr, p))
        r_ids = best[dr.ids]
        common = np.intersect1d(dl.ids, r_ids)
        if len(common) < 8 or (equi and len(common) < target.n_corners):
            continue
        op.append(obj[common].astype(np.float32))
        lp.append(dl.corners_px[np.searchsorted(dl.ids, common)].astype(np.float32))
        order = np.argsort(r_ids)
        rp.append(dr.corners_px[order][np.searchsorted(r_ids[order], common)].astype(np.float32))
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    if equi:
        flags = cv2.CALIB_RECOMPUTE_EXTRINSIC | cv2.CALIB_FIX_SKEW
        opf = [o.reshape(1, -1, 3).astype(np.float64) for o in op]
        lpf = [p.reshape(1, -1, 2).astype(np.float64) for p in lp]
        rpf = [p.reshape(1, -1, 2).astype(np.float64) for p in rp]
        _, K1, D1, _, _ = cv2.fisheye.calibrate(opf, lpf, size, None, None, flags=flags, criteria=crit)
        _, K2, D2, _, _ = cv2.fisheye.calibrate(opf, rpf, size, None, None, flags=flags, criteria=crit)
        out = cv2.fisheye.stereoCalibrate([o.reshape(-1, 1, 3) for o in opf], [p.reshape(-1, 1, 2) for p in lpf],
                                          [p.reshape(-1, 1, 2) for p in rpf], K1, D1, K2, D2, size,
                                          flags=cv2.CALIB_FIX_INTRINSIC, criteria=crit)
    else:
        flags = cv2.CALIB_FIX_K3
        _, K1, D1, _, _ = cv2.calibrateCamera(op, lp, size, None, None, flags=flags, criteria=crit)
        _, K2, D2, _, _ = cv2.calibrateCamera(op, rp, size, None, None, flags=flags, criteria=crit)
        out = cv2.stereoCalibrate(op, lp, rp, K1, D1, K2, D2, size, flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS,
                                  criteria=crit)
    rms, K1, _, K2, _, _, T = out[:7]
    views = [i for i, (a, b) in enumerate(zip(obs[0].detections, obs[1].detections, strict=True))
             if a is not None and b is not None]
    return {"K": (np.asarray(K1), np.asarray(K2)), "baseline_m": float(np.linalg.norm(T)), "rms_px": float(rms),
            "views": views, "n_views": len(op)}


def _spread(dl: Detection, dr: Detection, perm: np.ndarray) -> float:
    r_ids = perm[dr.ids]
    common, il, ir = np.intersect1d(dl.ids, r_ids, return_indices=True)
    if len(common) == 0:
        return np.inf
    return float(np.median(np.linalg.norm(dl.corners_px[il] - dr.corners_px[ir], axis=1)))


def opencv_detect(gray: np.ndarray, target) -> Detection | None:
    """OpenCV's own detection: ``findChessboardCornersSB`` with its accuracy mode, or tag36h11
    ``aruco`` (2-bit border, Kalibr's print) with ``cornerSubPix`` on the tag corners."""
    import cv2

    h, w = gray.shape[:2]
    if target.target_type == "checkerboard":
        ok, c = cv2.findChessboardCornersSB(gray, (target.cols, target.rows),
                                            flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
        if not ok:
            return None
        return Detection(np.arange(target.n_corners, dtype=np.int64), np.asarray(c, np.float64).reshape(-1, 2),
                         (w, h))
    params = cv2.aruco.DetectorParameters()
    params.markerBorderBits = 2
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11), params,
                                  cv2.aruco.RefineParameters())
    corners, ids, _ = det.detectMarkers(gray)
    if ids is None:
        return None
    ids = ids.ravel()
    keep = (ids >= 0) & (ids < target.rows * target.cols)
    if not keep.any():
        return None
    quads = np.asarray(corners, np.float32).reshape(-1, 4, 2)[keep]
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
    pts = cv2.cornerSubPix(gray, quads.reshape(-1, 1, 2).copy(), (4, 4), (-1, -1), crit).reshape(-1, 2)
    cid = target.tag_corner_ids(ids[keep])[:, [1, 0, 3, 2]].ravel()  # OpenCV's order on Kalibr's print
    order = np.argsort(cid)
    return Detection(cid[order].astype(np.int64), pts[order].astype(np.float64), (w, h))
