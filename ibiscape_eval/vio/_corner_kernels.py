"""numba kernel of :func:`ibiscape_eval.vio.frontend.good_features`: the greedy minimum-distance
selection of OpenCV's ``goodFeaturesToTrack`` (imported lazily: numba is heavy).

The candidates come sorted by decreasing response; each one is kept when no kept corner lies
closer than ``min_dist`` in its grid cell or the 8 around it (cells of ``round(min_dist)``
pixels), until ``max_corners`` are kept: OpenCV's rule, cell for cell.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def select_spaced(xs, ys, min_dist, width, height, max_corners, keep):  # pragma: no cover - numba
    """Indices (into ``xs``/``ys``, already in order of preference) of the kept corners, written
    to ``keep``; returns how many."""
    cell = max(int(np.round(min_dist)), 1)
    gw = (width + cell - 1) // cell
    gh = (height + cell - 1) // cell
    head = np.full(gw * gh, -1, np.int64)      # first kept corner of each cell
    nxt = np.full(len(xs), -1, np.int64)       # next kept corner in the same cell
    d2 = min_dist * min_dist
    n = 0
    for i in range(len(xs)):
        x, y = xs[i], ys[i]
        cx, cy = x // cell, y // cell
        good = True
        for yy in range(max(cy - 1, 0), min(cy + 1, gh - 1) + 1):
            for xx in range(max(cx - 1, 0), min(cx + 1, gw - 1) + 1):
                j = head[yy * gw + xx]
                while j >= 0:
                    dx = np.float32(x - xs[j])
                    dy = np.float32(y - ys[j])
                    if dx * dx + dy * dy < d2:
                        good = False
                        break
                    j = nxt[j]
                if not good:
                    break
            if not good:
                break
        if good:
            c = cy * gw + cx
            nxt[i] = head[c]
            head[c] = i
            keep[n] = i
            n += 1
            if n == max_corners:
                break
    return n


@njit(cache=True, nogil=True)
def peak_keys(eig, bits, mask, thr):  # pragma: no cover - numba
    """Sort keys of OpenCV's corner candidates: the interior pixels under ``mask`` whose
    thresholded response ``t(v) = v if v > thr else 0`` is non-zero and the largest of its 3x3
    neighbourhood (``threshold(THRESH_TOZERO)``, ``dilate`` and the compare of
    ``goodFeaturesToTrack``), in row-major order (``findNonZero``'s).  Each key is the value's
    bits (``bits``: ``eig`` viewed as int32; positive floats order like their bits) above the
    flat pixel index ``y * w + x``."""
    h, w = eig.shape
    out = np.empty(max((h - 2) * (w - 2), 0), np.int64)
    flag = np.zeros(w, np.uint8)
    n = 0
    for y in range(1, h - 1):
        r0 = eig[y - 1]
        r1 = eig[y]
        r2 = eig[y + 1]
        m = mask[y]
        b = bits[y]
        # branch-free (vectorised) test of every pixel of the row, then the few peaks collected;
        # with v above the threshold a neighbour's thresholded value exceeds v only if the
        # neighbour itself does
        for x in range(1, w - 1):
            v = r1[x]
            flag[x] = ((v > thr) & (v > 0) & (m[x] != 0)
                       & (r1[x - 1] <= v) & (r1[x + 1] <= v) & (r0[x - 1] <= v) & (r0[x] <= v)
                       & (r0[x + 1] <= v) & (r2[x - 1] <= v) & (r2[x] <= v) & (r2[x + 1] <= v))
        for x in range(1, w - 1):
            if flag[x]:
                out[n] = (np.int64(b[x]) << 32) | (y * w + x)
                n += 1
    return out[:n]


@njit(cache=True, nogil=True)
def clear_discs(mask, xs, ys, dxs, dys):  # pragma: no cover - numba
    """Set ``mask`` to 0 at the pixels ``(x + dx, y + dy)`` inside the image, for every centre
    ``(xs[i], ys[i])`` and offset ``(dxs[j], dys[j])`` (a disc's pixels, see
    ``frontend.disc_offsets``)."""
    h, w = mask.shape
    for i in range(len(xs)):
        for j in range(len(dxs)):
            x = xs[i] + dxs[j]
            y = ys[i] + dys[j]
            if 0 <= x < w and 0 <= y < h:
                mask[y, x] = 0
