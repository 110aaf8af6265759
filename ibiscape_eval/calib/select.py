"""Informative-frame selection: blur rejection before detection, pose diversity and coverage after.

- :func:`preselect_frames`: a long sequence (thousands of 20 Hz frames) is cut into ``budget``
  equal time slices; in every slice the sharpest of a few frames (variance of the Laplacian) is
  kept, so detection runs on ``budget`` frames that are spread in time and not motion-blurred.
- :func:`select_views`: among the views with detections, farthest-point sampling on a descriptor
  of where the target is in each image (centre, size, foreshortening and its direction, per
  camera) keeps ``max_views`` views that cover the image and vary the pose.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from .detect import Detection

__all__ = ["preselect_frames", "select_views", "view_descriptor"]


def preselect_frames(n_frames: int, budget: int, sharpness: Callable[[int], float] | None = None, *,
                     candidates: int = 3) -> list[int]:
    """Indices of at most ``budget`` frames spread over ``n_frames``, the sharpest of ``candidates``
    per slice when ``sharpness`` is given."""
    if n_frames <= budget:
        return list(range(n_frames))
    edges = np.linspace(0, n_frames, budget + 1)
    out = []
    for a, b in itertools.pairwise(edges):
        lo, hi = int(np.ceil(a)), max(int(np.ceil(b)) - 1, int(np.ceil(a)))
        cands = np.unique(np.linspace(lo, hi, min(candidates, hi - lo + 1)).round().astype(int))
        if sharpness is None or len(cands) == 1:
            out.append(int(cands[len(cands) // 2]))
            continue
        scores = [sharpness(int(i)) for i in cands]
        out.append(int(cands[int(np.argmax(scores))]))
    return sorted(set(out))


def view_descriptor(det: Detection | None) -> npt.NDArray[np.float64]:
    """Six numbers per detection: centre (x, y) / size, scale, foreshortening (cos, sin of twice its
    direction, times the anisotropy).  Missing detections give -1s."""
    if det is None or len(det) < 3:
        return np.full(6, -1.0)
    w, h = det.image_size
    p = det.corners_px
    c = p.mean(axis=0)
    cov = np.cov((p - c).T)
    ev, vec = np.linalg.eigh(cov)
    scale = float(np.sqrt(max(ev.sum(), 1e-12)) / np.hypot(w, h))
    aniso = float(1.0 - np.sqrt(max(ev[0], 0.0) / max(ev[1], 1e-12)))
    ang = float(np.arctan2(vec[1, 1], vec[0, 1]))
    return np.array([c[0] / w, c[1] / h, 4.0 * scale, aniso * np.cos(2 * ang), aniso * np.sin(2 * ang),
                     0.0])


def select_views(detections: Sequence[Sequence[Detection | None]], max_views: int) -> list[int]:
    """Choose at most ``max_views`` view indices among those where some camera saw the target.

    ``detections[camera][view]``.  Views seen by more cameras are preferred (the stereo
    extrinsics need them): the first pick is the view with most corners over all cameras, then
    farthest-point sampling on the concatenated per-camera descriptors, with a bonus for views
    seen by every camera.
    """
    n_cam = len(detections)
    n_v = len(detections[0]) if n_cam else 0
    seen = [v for v in range(n_v) if any(detections[k][v] is not None for k in range(n_cam))]
    if len(seen) <= max_views:
        return seen
    feats = np.array([np.concatenate([view_descriptor(detections[k][v]) for k in range(n_cam)])
                      for v in seen])
    n_seen = np.array([sum(detections[k][v] is not None for k in range(n_cam)) for v in seen])
    corners = np.array([sum(len(d) for k in range(n_cam) if (d := detections[k][v]) is not None)
                        for v in seen])
    weight = 0.5 + 0.5 * n_seen / n_cam
    first = int(np.argmax(corners * weight))
    chosen = [first]
    dist = np.linalg.norm(feats - feats[first], axis=1)
    while len(chosen) < max_views:
        score = dist * weight
        score[chosen] = -1.0
        nxt = int(np.argmax(score))
        chosen.append(nxt)
        dist = np.minimum(dist, np.linalg.norm(feats - feats[nxt], axis=1))
    return sorted(seen[i] for i in chosen)
