"""numba kernel for the overlapping Allan variance sums (imported lazily: numba is heavy).

For every averaging factor ``m`` the cost is one pass over the integrated signal ``x``:
``S(m) = sum_k (x[k + 2m] - 2 x[k + m] + x[k])^2`` for ``k = 0 .. n - 2m - 1``.

The loop runs over blocks of ``k`` (in parallel) and, inside a block, over all ``m``: the block
``x[k0:k0 + B]`` stays in cache for every ``m``, the two shifted streams are read sequentially
(prefetch-friendly), and for small ``m`` they overlap the block itself.  Each block keeps its own
partial sums (no shared accumulator), which are added afterwards by numpy's pairwise sum.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

BLOCK = 1 << 14


@njit(parallel=True, cache=True, fastmath={"reassoc", "contract"})
def oadev_sums(x: np.ndarray, ms: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Return ``S`` of shape (n_axes, n_m): the sums of squared second differences.

    ``x`` has shape (n_axes, n) (C order, the integrated signal of each axis including the
    leading zero); ``ms`` holds the averaging factors, each in ``1 .. (n - 1) // 2``.
    """
    n_axes, n = x.shape
    n_m = ms.size
    n_blocks = (n + BLOCK - 1) // BLOCK
    partial = np.zeros((n_blocks, n_axes, n_m))
    for b in prange(n_blocks):
        k0 = b * BLOCK
        for a in range(n_axes):
            row = x[a]
            for j in range(n_m):
                m = ms[j]
                k1 = min(k0 + BLOCK, n - 2 * m)
                s = 0.0
                if k1 > k0:
                    # views starting at 0 let LLVM drop the negative-index checks and vectorise
                    x0 = row[k0:k1]
                    x1 = row[k0 + m : k1 + m]
                    x2 = row[k0 + 2 * m : k1 + 2 * m]
                    for i in range(k1 - k0):
                        d = x2[i] - 2.0 * x1[i] + x0[i]
                        s += d * d
                partial[b, a, j] = s
    out = np.zeros((n_axes, n_m))
    for a in range(n_axes):
        for j in range(n_m):
            out[a, j] = np.sum(partial[:, a, j])
    return out
