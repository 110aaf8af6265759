"""Synthetic stereo measurements: random landmarks around a ground-truth path, projected into the
rig with :class:`~ibiscape_eval.core.camera.CameraModel`, with pixel noise.

This tests the back end and the initialisation without images: the observations go through the
same :class:`~ibiscape_eval.vio.estimator.Estimator` as the image front end's.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.trajectory import Trajectory

from .backend import StereoObservations
from .rig import StereoRig

__all__ = ["random_landmarks", "synthetic_observations"]

FloatArray = npt.NDArray[np.float64]


def random_landmarks(path: Trajectory, *, per_metre: float = 8.0, lateral_m: tuple[float, float] = (4.0, 25.0),
                     height_m: tuple[float, float] = (-2.0, 10.0), seed: int = 0) -> FloatArray:
    """Points (N, 3) scattered on both sides of the path (like building facades and poles),
    ``per_metre`` per metre of path, ``lateral_m`` from it, ``height_m`` above its height."""
    rng = np.random.default_rng(seed)
    s = path.path_length_m()
    n = max(int(per_metre * max(s[-1], 10.0)), 200)
    along = rng.uniform(-20.0, s[-1] + 40.0, n)
    # positions along the path (extrapolated linearly beyond its ends)
    d = np.gradient(path.pos_m, axis=0)
    base = np.stack([np.interp(along, s, path.pos_m[:, i]) for i in range(3)], axis=1)
    tang = np.stack([np.interp(np.clip(along, 0, s[-1]), s, d[:, i]) for i in range(3)], axis=1)
    tang[:, 2] = 0.0
    nrm = np.linalg.norm(tang, axis=1, keepdims=True)
    fallback = np.tile([1.0, 0.0, 0.0], (n, 1))
    tang = np.where(nrm > 1e-9, tang / np.maximum(nrm, 1e-12), fallback)
    base += tang * (np.minimum(along, 0.0) + np.maximum(along - s[-1], 0.0))[:, None]
    side = np.stack([-tang[:, 1], tang[:, 0], np.zeros(n)], axis=1)
    off = rng.uniform(*lateral_m, n) * rng.choice([-1.0, 1.0], n)
    up = rng.uniform(*height_m, n)
    return base + side * off[:, None] + np.array([0.0, 0.0, 1.0]) * up[:, None]


def synthetic_observations(groundtruth: Trajectory, rig: StereoRig, stamps_ns: npt.ArrayLike,
                           landmarks: FloatArray, *, pixel_sigma_px: float = 0.5,
                           max_per_frame: int = 150, max_depth_m: float = 60.0, seed: int = 0,
                           blackout: tuple[int, int] | None = None) -> list[StereoObservations]:
    """Rectified stereo observations of ``landmarks`` at ``stamps_ns`` (ground truth poses
    interpolated linearly / by slerp), noisy by ``pixel_sigma_px`` in each coordinate.

    Observations are kept when the point is in front of both cameras, inside both images and
    nearer than ``max_depth_m``; at most ``max_per_frame`` per frame, preferring low landmark
    indices so that the same points stay tracked.  ``blackout = (t0_ns, t1_ns)`` removes every
    observation in that span (a tracking failure).
    """
    from scipy.spatial.transform import Rotation, Slerp

    st = np.asarray(stamps_ns, dtype=np.int64)
    gt = groundtruth
    t_rel = (gt.stamps_ns - gt.stamps_ns[0]) * 1e-9
    q_rel = (st - gt.stamps_ns[0]) * 1e-9
    pos = np.stack([np.interp(q_rel, t_rel, gt.pos_m[:, i]) for i in range(3)], axis=1)
    rot = Slerp(t_rel, Rotation.from_quat(gt.quat_xyzw))(np.clip(q_rel, t_rel[0], t_rel[-1]))
    rng = np.random.default_rng(seed)
    w, h = rig.size
    out = []
    for i, t in enumerate(st):
        if blackout is not None and blackout[0] <= t <= blackout[1]:
            out.append(StereoObservations.empty(int(t)))
            continue
        T_wb = np.eye(4)
        T_wb[:3, :3] = rot[i].as_matrix()
        T_wb[:3, 3] = pos[i]
        sides = []
        for T_bc, cam in ((rig.T_body_left, rig.left), (rig.T_body_right, rig.right)):
            T_cw = np.linalg.inv(T_wb @ T_bc)
            pc = landmarks @ T_cw[:3, :3].T + T_cw[:3, 3]
            uv = cam.project(pc)
            ok = (pc[:, 2] > 0.5) & (pc[:, 2] < max_depth_m)
            ok &= (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
            sides.append((uv, ok))
        vis = np.flatnonzero(sides[0][1] & sides[1][1])[:max_per_frame]
        uvl = sides[0][0][vis] + rng.normal(0.0, pixel_sigma_px, (len(vis), 2))
        uvr = sides[1][0][vis] + rng.normal(0.0, pixel_sigma_px, (len(vis), 2))
        rl = rig.rectify_points(uvl, "left")
        rr = rig.rectify_points(uvr, "right")
        out.append(StereoObservations(int(t), vis.astype(np.int64), rl[:, 0], rr[:, 0],
                                      0.5 * (rl[:, 1] + rr[:, 1])))
    return out
